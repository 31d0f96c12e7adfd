"""Observed orders of convergence on the verification ladder.

Every scene with an exact answer runs to a fixed end time with the CFL-limited step (``dt`` shrinks
with ``h``) at four or more resolutions, for each interpolator and transfer. The observed order of an
error ``e`` is the least-squares slope of ``log e`` against ``log(1/h)`` over the resolutions that
finished; the order of the finest pair is reported beside it. Scenes with fronts (vacuum expansion,
Riemann problem) are measured away from them (``scene.smooth``). A run that broke down is listed
with its step, particle and quantity, and left out of the fit.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import pathlib
import time
from collections.abc import Callable

import numpy as np

import jaxmpm as jm

from ._methods import METHODS
from ._runtime import require_float64

TRANSFERS = {name.upper(): make for name, make in jm.TRANSFERS.items()}
"""Every transfer of ``jaxmpm.TRANSFERS`` by its label in the tables (``FLIP``, ``PIC``, ``APIC``)."""
ERRORS = ("x_rms_abs", "F_rms_rel", "v_rms_abs")


@dataclasses.dataclass(frozen=True)
class Case:
    """One rung of the ladder: a scene family at a resolution, run to ``t_end(scene)``."""

    name: str
    make: Callable[[int], jm.AbstractScene]  # cells -> scene
    t_end: Callable[[jm.AbstractScene], float]
    cells: tuple[int, ...]
    cfl: float = 0.2
    options: dict = dataclasses.field(default_factory=dict)
    note: str = ""


def _quarter(sc) -> float:
    return 0.5 / float(sc.wave_speed)  # sin(c pi t / L) = 1: the largest displacement (L = 1)


def cases(small: bool = False) -> list[Case]:
    """The rungs of the ladder.

    Args:
        small: coarser grids.

    Returns:
        One ``Case`` per scene family.
    """
    res = (8, 16, 32, 64) if small else (16, 32, 64, 128)
    res_front = (16, 32, 64, 128) if small else (32, 64, 128, 256)
    return [
        Case(
            "manufactured neo-Hookean A=1e-4",
            lambda n: jm.Manufactured(A=1e-4, cells=n, h=1.0 / n),
            _quarter,
            res,
            note="u = A sin(pi X) sin(c pi t), walls, to t = 1/(2c)",
        ),
        Case(
            "manufactured neo-Hookean A=0.05",
            lambda n: jm.Manufactured(A=0.05, cells=n, h=1.0 / n),
            _quarter,
            res,
        ),
        Case(
            "manufactured gas A=1e-4",
            lambda n: jm.Manufactured(A=1e-4, model="gas", cells=n, h=1.0 / n),
            _quarter,
            res,
            note="gas P0 = 1, p_atm = 0: a large stress at rest",
        ),
        Case(
            "manufactured gas A=0.05",
            lambda n: jm.Manufactured(A=0.05, model="gas", cells=n, h=1.0 / n),
            _quarter,
            res,
        ),
        Case(
            "vibrating-bar",
            lambda n: jm.VibratingBar(cells=n, h=1.0 / n, pad=3),
            lambda sc: 0.5 * math.pi / float(sc.omega),
            res,
            note="to a quarter period",
        ),
        Case(
            "gas-expansion (talk)",
            lambda n: jm.GasExpansion(cells=n, h=1.0 / n, pad=n // 2 + 4),  # room for F = 1.25
            lambda sc: 1.25e-3,
            res,
            note="beta = 200, L = 1, no artificial cells",
        ),
        Case(
            "vacuum-expansion",
            lambda n: jm.VacuumExpansion(cells=n, h=1.0 / n, pad=5 * n + 4),
            lambda sc: 0.8 * float(sc.t_valid),
            res_front,
            note="errors away from the head and the front",
        ),
        Case(
            "riemann (AV)",
            lambda n: jm.Riemann(cells=n, h=1.0 / n),
            lambda sc: 0.8 * float(sc.t_valid),
            res_front,
            options=dict(viscosity=jm.ArtificialViscosity()),
            note="shock tube, artificial viscosity, errors away from the waves' edges",
        ),
    ]


def run_case(case: Case, method: str, transfer: str) -> list[dict]:
    """Run one case at each of its resolutions.

    Args:
        case: the case.
        method: the interpolator's label (``METHODS``).
        transfer: the transfer's label (``TRANSFERS``).

    Returns:
        One row per resolution: the errors ``ERRORS`` (NaN after a breakdown) and the status.
    """
    rows = []
    for n in case.cells:
        sc = case.make(n)
        t_end = case.t_end(sc)
        max_steps = int(60 * n / case.cfl) + 100
        t0 = time.perf_counter()
        sol = jm.simulate(
            sc,
            METHODS[method](),
            t_end=t_end,
            cfl=case.cfl,
            max_steps=max_steps,
            transfer=TRANSFERS[transfer](),
            throw=False,
            **case.options,
        )
        seconds = time.perf_counter() - t0
        row = dict(scene=case.name, method=method, transfer=transfer, cells=n, h=float(sc.h), t_end=t_end)
        row.update(steps=int(sol.state.step), seconds=seconds)
        fail = sol.failure()
        if fail is None:
            where = jm.metrics.smooth_mask(sc, sol.body, sol.state.t)
            err = jm.errors(sc, sol.state, sol.body, where=where)
            row.update({k: float(err[k]) for k in ERRORS}, status="ok")
        else:
            row.update(dict.fromkeys(ERRORS, float("nan")))
            what = "; ".join(fail["quantities"])
            row["status"] = f"broke down at step {fail['step']}, particle {fail['particle']}: {what}"
        rows.append(row)
    return rows


def fit_order(h, e) -> tuple[float, float]:
    """The observed order of errors against grid spacing.

    Args:
        h: grid spacings.
        e: errors at them (non-finite or zero ones are left out).

    Returns:
        ``(least-squares order, finest-pair order)``, NaN with fewer than two errors.
    """
    h, e = np.asarray(h, float), np.asarray(e, float)
    ok = np.isfinite(e) & (e > 0)
    if ok.sum() < 2:
        return float("nan"), float("nan")
    slope = np.polyfit(np.log(1 / h[ok]), np.log(e[ok]), 1)[0]
    hh, ee = h[ok][-2:], e[ok][-2:]
    return float(-slope), float(math.log(ee[0] / ee[1]) / math.log(hh[0] / hh[1]))


def orders(rows: list[dict]) -> list[dict]:
    """The observed orders of each scene, method and transfer.

    Args:
        rows: the ``run_case`` rows.

    Returns:
        One row per scene, method and transfer: each error's order (fit and finest pair), its value at
        the finest resolution, and the breakdowns.
    """
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["scene"], r["method"], r["transfer"]), []).append(r)
    out = []
    for (scene, method, transfer), rs in groups.items():
        o = dict(scene=scene, method=method, transfer=transfer)
        for k in ERRORS:
            o[f"{k}_order"], o[f"{k}_order_finest"] = fit_order([r["h"] for r in rs], [r[k] for r in rs])
            o[f"{k}_finest"] = rs[-1][k]
        bad = [f"{r['cells']} cells: {r['status']}" for r in rs if r["status"] != "ok"]
        o["failures"] = "; ".join(bad)
        out.append(o)
    return out


def _f(x, fmt=".2f"):
    return "-" if not np.isfinite(x) else format(x, fmt)


def markdown(order_rows: list[dict], all_cases: list[Case]) -> str:
    """The orders as markdown tables, one per case.

    Args:
        order_rows: what ``orders`` returns.
        all_cases: the cases, in order.

    Returns:
        The tables.
    """
    lines = []
    for case in all_cases:
        rs = [o for o in order_rows if o["scene"] == case.name]
        if not rs:
            continue
        lines.append(
            f"**{case.name}** ({case.note + '; ' if case.note else ''}"
            f"cells {', '.join(map(str, case.cells))}, CFL {case.cfl})\n"
        )
        lines.append(
            "| method | transfer | order x | order F | order v | x err (finest) | F err (finest) "
            "| breakdowns |"
        )
        lines.append("|---|---|---|---|---|---|---|---|")
        for o in rs:
            lines.append(
                f"| {o['method']} | {o['transfer']} "
                f"| {_f(o['x_rms_abs_order'])} ({_f(o['x_rms_abs_order_finest'])}) "
                f"| {_f(o['F_rms_rel_order'])} ({_f(o['F_rms_rel_order_finest'])}) "
                f"| {_f(o['v_rms_abs_order'])} ({_f(o['v_rms_abs_order_finest'])}) "
                f"| {_f(o['x_rms_abs_finest'], '.2e')} | {_f(o['F_rms_rel_finest'], '.2e')} "
                f"| {o['failures'] or '-'} |"
            )
        lines.append("")
    return "\n".join(lines)


def main(
    out: str,
    small: bool = False,
    transfers=None,
    methods=None,
    scenes=None,
    release: Callable[[], object] | None = None,
) -> dict:
    """Run the ladder; write ``orders.md``, ``orders.csv``, ``runs.csv`` and ``orders.json`` to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: FLIP only, SPQ, CPDI and MPQ, coarser grids.
        transfers: labels in ``TRANSFERS`` to run (default: all, or FLIP when ``small``).
        methods: labels in ``METHODS`` to run (default: all, or SPQ, CPDI and MPQ when ``small``).
        scenes: case names to run (default: all).
        release: called after each case, whose compiled programs (one per resolution) are not used
            again (the command line passes ``jax.clear_caches``).

    Returns:
        ``runs`` (one row per run) and ``orders`` (one row per scene, method and transfer).

    Raises:
        RuntimeError: float64 is off.
    """
    require_float64("convergence")
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    all_cases = [c for c in cases(small) if scenes is None or c.name in scenes]
    transfers = transfers or (("FLIP",) if small else tuple(TRANSFERS))
    methods = methods or (("SPQ", "CPDI", "MPQ") if small else tuple(METHODS))
    rows = []
    for case in all_cases:
        for method in methods:
            for transfer in transfers:
                rows.extend(run_case(case, method, transfer))
        if release is not None:
            release()
    order_rows = orders(rows)
    head = (
        "# Observed orders of convergence\n\n"
        "RMS errors over real particles at the end time: x (absolute), F (relative), v (absolute). "
        "Order: least-squares slope over the resolutions that finished (in brackets: the finest pair). "
        "USL, no artificial cells unless stated, float64, dt = CFL h / max(c + |v|) every step.\n\n"
    )
    text = head + markdown(order_rows, all_cases)
    (outdir / "orders.md").write_text(text)
    for name, table in (("runs.csv", rows), ("orders.csv", order_rows)):
        with open(outdir / name, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(table[0]))
            w.writeheader()
            w.writerows(table)
    (outdir / "orders.json").write_text(json.dumps(dict(runs=rows, orders=order_rows), indent=1))
    print(text)
    return dict(runs=rows, orders=order_rows)
