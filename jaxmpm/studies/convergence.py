"""Observed orders of convergence on the verification ladder.

Every scene with an exact answer runs to a fixed end time with the CFL-limited step (``dt`` shrinks
with ``h``) at four or more resolutions, for each interpolator and transfer. The shock cases (Sod's
shock tube, Noh's problem: gas with an energy equation) are measured by L1 errors against the exact
solution of the Euler equations, with artificial viscosity; the planar detonation (a programmed
burn of gamma-law explosive against a wall) by the relative RMS errors of ``F`` and of the pressure
against the exact CJ-Taylor wave over the burnt particles away from the front. The observed order of an
error ``e`` is the least-squares slope of ``log e`` against ``log(1/h)`` over the resolutions that
finished; the order of the finest pair is reported beside it. Scenes with fronts (vacuum expansion,
Riemann problem) are measured away from them (``scene.smooth``). A run that broke down is listed
with its step, particle and quantity, and left out of the fit.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import time
from collections.abc import Callable

import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps

from ._methods import METHODS
from ._output import Files
from ._runtime import require_float64

OUTPUTS = Files(
    "orders.md",
    "orders.csv",
    "runs.csv",
    "orders.json",
    "shocks.md",
    "shocks.csv",
    "shock_runs.csv",
    "shocks.json",
)
"""The files the study writes."""

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


EULER_ERRORS = ("rho_L1", "u_L1", "p_L1", "e_L1")
"""The shock cases' errors (``jaxmpm.metrics.euler_errors``): L1 norms of density, velocity, pressure
and specific internal energy against the exact solution of the Euler equations."""
DETONATION_ERRORS = ("F_rms_rel", "p_rms_rel")
"""The detonation's errors (``detonation_errors``): the relative RMS errors of ``F`` and of the pressure
against the exact CJ-Taylor wave over the burnt particles away from the front (``scene.smooth``)."""
DETONATION_L = 0.1
"""The detonation case's slab length, m."""


@dataclasses.dataclass(frozen=True)
class ShockCase:
    """A shock problem at several resolutions: the Euler equations (gas with an energy equation),
    measured by ``EULER_ERRORS``, or a detonation, measured by ``DETONATION_ERRORS``."""

    name: str
    make: Callable[[int], jm.AbstractScene]  # cells -> scene
    t_end: float
    cells: tuple[int, ...]
    cfl: float = 0.2
    note: str = ""
    artificial_cells: int = 0
    errors: tuple[str, ...] = EULER_ERRORS


def shock_cases(small: bool = False) -> list[ShockCase]:
    """The shock rungs: Sod's shock tube, Noh's problem and the planar detonation, with artificial
    viscosity.

    Args:
        small: coarser grids (the detonation: a coarse pair).

    Returns:
        One ``ShockCase`` per problem.
    """
    res = (50, 100, 200) if small else (100, 200, 400)
    t_valid = float(jm.Detonation(L=DETONATION_L).t_valid)
    return [
        ShockCase(
            "shock-tube (Sod)",
            lambda n: jm.ShockTube(cells=n, h=1.0 / n),
            0.2,
            res,
            note="walls at 0 and 1, t = 0.2",
        ),
        ShockCase(
            "noh",
            lambda n: jm.Noh(cells=n, h=1.0 / n),
            0.6,
            res,
            note="gamma = 5/3, wall at 0, t = 0.6: shock at 0.2, rho = 4 behind it",
        ),
        ShockCase(
            "detonation",
            lambda n: jm.Detonation(L=DETONATION_L, gamma=3.0, ends="wall", cells=n, ppc=1),
            0.8 * t_valid,
            (50, 100) if small else (100, 200, 400),
            cfl=0.3,
            note=(
                "gamma-law products on their CJ isentrope, gamma = 3, D = 8000 m/s, "
                f"L = {DETONATION_L:g} m lit against a wall at 0, time burn over 1.5 particles, "
                "1 particle per cell, 1 artificial cell, t = 0.8 L / D; errors of F and p over the burnt "
                "particles 12 h behind the front"
            ),
            artificial_cells=1,
            errors=DETONATION_ERRORS,
        ),
    ]


def _noh_measures(scene, sol) -> dict:
    """Noh's shock position (where the density falls through 2.5) in cells from ``t / 3``, the mean
    density between 0.05 and 3 cells short of the shock, and how many particles from the wall the
    density stays below 90% of 4 (the wall heating)."""
    x = np.asarray(sol.state.x[:, 0])
    rho = np.asarray(jm.density(sol.state, sol.body))
    h, shock = float(scene.h), float(scene.shock_speed) * float(sol.state.t)
    front = float(x[np.argmax((rho < 2.5) & (x > 0.5 * shock))])
    plateau = (x > 0.05) & (x < shock - 3 * h)
    return dict(
        shock_cells=(front - shock) / h,
        plateau_rho=float(rho[plateau].mean()),
        wall_heated=int(np.argmax(rho > 0.9 * 4.0)),
    )


def detonation_errors(scene: jm.Detonation, state, body) -> dict:
    """A detonation's errors against its exact CJ-Taylor wave over the burnt particles away from the
    front (``jaxmpm.metrics.smooth_mask``).

    Args:
        scene: the ``jaxmpm.Detonation``.
        state: the state at the end time.
        body: the reference configuration.

    Returns:
        ``DETONATION_ERRORS`` (``F_rms_rel``; ``p_rms_rel``, ``jaxmpm.metrics.pressure_error``), the
        largest relative ``F`` error ``F_max_rel`` and the number of particles measured, ``smooth``.
    """
    where = jm.metrics.smooth_mask(scene, body, state.t)
    err = jm.errors(scene, state, body, where=where)
    return dict(
        F_rms_rel=float(err["F_rms_rel"]),
        p_rms_rel=float(jm.metrics.pressure_error(scene, state, body, where=where)),
        F_max_rel=float(err["F_max_rel"]),
        smooth=int(np.sum(np.asarray(where))),
    )


def run_shock_case(case: ShockCase, method: str, transfer: str) -> list[dict]:
    """Run one shock case at each of its resolutions, with artificial viscosity.

    Args:
        case: the case.
        method: the interpolator's label (``METHODS``).
        transfer: the transfer's label (``TRANSFERS``).

    Returns:
        One row per resolution and the status: the relative drift of the total energy (kinetic plus
        internal; the walls do no work, and the detonation's particles start with their detonation
        energy, which the burn does not add to); for an Euler case ``EULER_ERRORS`` and for Noh its
        shock position and plateau; for the detonation what ``detonation_errors`` returns. NaN where
        the run broke down.
    """
    euler = case.errors == EULER_ERRORS
    rows = []
    for n in case.cells:
        sc = case.make(n)
        model = jm.Model(
            sc,
            METHODS[method](),
            TRANSFERS[transfer](),
            artificial_cells=case.artificial_cells,
            viscosity=jm.ArtificialViscosity(),
        )
        prepared = jm.setup(model)
        e0 = float(jm.diagnostics(sc, jm.initial_state(model, prepared), prepared.body)["energy"])
        t0 = time.perf_counter()
        sol = jm.simulate(
            sc,
            METHODS[method](),
            t_end=case.t_end,
            cfl=case.cfl,
            max_steps=int(10 * n / case.cfl) + 100,
            transfer=TRANSFERS[transfer](),
            artificial_cells=case.artificial_cells,
            viscosity=jm.ArtificialViscosity(),
            throw=False,
        )
        seconds = time.perf_counter() - t0
        row = dict(
            scene=case.name, method=method, transfer=transfer, cells=n, h=float(sc.h), t_end=case.t_end
        )
        row.update(steps=int(sol.state.step), seconds=seconds)
        extra = ("shock_cells", "plateau_rho", "wall_heated") if isinstance(sc, jm.Noh) else ()
        fail = sol.failure()
        if not euler:
            if fail is None:
                row.update(detonation_errors(sc, sol.state, sol.body))
                row["energy_drift"] = float(jm.diagnostics(sc, sol.state, sol.body)["energy"]) / e0 - 1.0
                row["status"] = "ok"
            else:
                keys = DETONATION_ERRORS + ("F_max_rel", "smooth", "energy_drift")
                row.update(dict.fromkeys(keys, float("nan")))
                what = "; ".join(fail["quantities"])
                row["status"] = f"broke down at step {fail['step']}, particle {fail['particle']}: {what}"
        elif fail is None:
            err = jm.euler_errors(sc, sol.state, sol.body)
            row.update({k: float(err[k]) for k in EULER_ERRORS})
            row["energy_drift"] = float(jm.diagnostics(sc, sol.state, sol.body)["energy"]) / e0 - 1.0
            if extra:
                row.update(_noh_measures(sc, sol))
            row["status"] = "ok"
        else:
            row.update(dict.fromkeys(EULER_ERRORS + ("energy_drift",) + extra, float("nan")))
            what = "; ".join(fail["quantities"])
            row["status"] = f"broke down at step {fail['step']}, particle {fail['particle']}: {what}"
        rows.append(row)
    return rows


def energy_drift(method: str, cells: int) -> dict:
    """The total energy's drift where nothing dissipates it: an ideal-gas slab (``rho = 1``, ``p = 1``,
    ``gamma = 1.4``, at rest) expanding into vacuum from both free ends, without viscosity or walls,
    to ``t = 0.2`` (FLIP, CFL 0.2).

    Args:
        method: the interpolator's label (``METHODS``).
        cells: cells of the slab (``h = 1 / cells``).

    Returns:
        ``method``, ``cells``, ``steps``, ``energy_drift`` (relative) and ``status``.
    """
    from jaxmpm.geometry import Box

    gas = jm.IdealGas(gamma=1.4)
    sc = jm.Bodies(
        parts=(jm.Region(Box(0.0, float(cells)), gas, 1.0, 0.0, 2.5),),
        cells=cells,
        h=1.0 / cells,
        pad=2 * cells,
    )
    model = jm.Model(sc, METHODS[method](), TRANSFERS["FLIP"]())
    prepared = jm.setup(model)
    e0 = float(jm.diagnostics(sc, jm.initial_state(model, prepared), prepared.body)["energy"])
    sol = jm.simulate(sc, METHODS[method](), t_end=0.2, cfl=0.2, max_steps=40 * cells, throw=False)
    fail = sol.failure()
    row = dict(method=method, cells=cells, steps=int(sol.state.step))
    if fail is None:
        row.update(
            energy_drift=float(jm.diagnostics(sc, sol.state, sol.body)["energy"]) / e0 - 1.0, status="ok"
        )
    else:
        what = "; ".join(fail["quantities"])
        row.update(energy_drift=float("nan"), status=f"broke down at step {fail['step']}: {what}")
    return row


def shock_orders(rows: list[dict]) -> list[dict]:
    """The observed orders of the shock cases' errors, per scene, method and transfer.

    Args:
        rows: the ``run_shock_case`` rows.

    Returns:
        One row per scene, method and transfer: each error's order (fit and finest pair) and finest
        value, the energy drift at the finest resolution, Noh's measures there, the
        detonation's largest ``F`` error there, and the breakdowns. A run that broke down has NaN
        errors and is left out of the fit.
    """
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["scene"], r["method"], r["transfer"]), []).append(r)
    out = []
    for (scene, method, transfer), rs in groups.items():
        o = dict(scene=scene, method=method, transfer=transfer)
        for k in EULER_ERRORS if EULER_ERRORS[0] in rs[0] else DETONATION_ERRORS:
            o[f"{k}_order"], o[f"{k}_order_finest"] = fit_order([r["h"] for r in rs], [r[k] for r in rs])
            o[f"{k}_finest"] = rs[-1][k]
        if "energy_drift" in rs[-1]:
            o["energy_drift_finest"] = rs[-1]["energy_drift"]
        if "F_max_rel" in rs[-1]:
            o["F_max_rel_finest"] = rs[-1]["F_max_rel"]
        for k in ("shock_cells", "plateau_rho", "wall_heated"):
            if k in rs[-1]:
                o[f"{k}_finest"] = rs[-1][k]
        o["failures"] = "; ".join(f"{r['cells']} cells: {r['status']}" for r in rs if r["status"] != "ok")
        out.append(o)
    return out


def shock_markdown(order_rows: list[dict], all_cases: list[ShockCase]) -> str:
    """The shock cases' orders as markdown tables, one per case.

    Args:
        order_rows: what ``shock_orders`` returns.
        all_cases: the cases, in order.

    Returns:
        The tables.
    """
    lines = []
    for case in all_cases:
        rs = [o for o in order_rows if o["scene"] == case.name]
        if not rs:
            continue
        if case.errors != EULER_ERRORS:
            lines.append(_detonation_table(case, rs))
            continue
        noh = "shock_cells_finest" in rs[0]
        lines.append(
            f"**{case.name}** ({case.note}; cells {', '.join(map(str, case.cells))}, CFL {case.cfl})\n"
        )
        head = (
            "| method | transfer | order rho | order u | order p | order e | rho L1 (finest) | energy drift "
        )
        head += "| shock - t/3 (cells) | plateau rho | wall-heated particles " if noh else ""
        lines.append(head + "| breakdowns |")
        lines.append("|---" * (9 + (3 if noh else 0)) + "|")
        for o in rs:
            row = (
                f"| {o['method']} | {o['transfer']} "
                + "".join(f"| {_f(o[f'{k}_order'])} ({_f(o[f'{k}_order_finest'])}) " for k in EULER_ERRORS)
                + f"| {_f(o['rho_L1_finest'], '.2e')} | {_f(o['energy_drift_finest'], '.1e')} "
            )
            if noh:
                row += (
                    f"| {_f(o['shock_cells_finest'], '.1f')} | {_f(o['plateau_rho_finest'], '.3f')} "
                    f"| {_f(float(o['wall_heated_finest']), '.0f')} "
                )
            lines.append(row + f"| {o['failures'] or '-'} |")
        lines.append("")
    return "\n".join(lines)


def _detonation_table(case: ShockCase, rs: list[dict]) -> str:
    """The detonation's table: orders of the relative RMS errors of F and p, their finest values."""
    lines = [
        f"**{case.name}** ({case.note}; cells {', '.join(map(str, case.cells))}, CFL {case.cfl})\n",
        "| method | transfer | order F | order p | F rms err (finest) | F max err (finest) "
        "| p rms err (finest) | energy drift | breakdowns |",
        "|---" * 9 + "|",
    ]
    for o in rs:
        lines.append(
            f"| {o['method']} | {o['transfer']} "
            + "".join(f"| {_f(o[f'{k}_order'])} ({_f(o[f'{k}_order_finest'])}) " for k in DETONATION_ERRORS)
            + f"| {_f(o['F_rms_rel_finest'], '.2e')} | {_f(o['F_max_rel_finest'], '.2e')} "
            + f"| {_f(o['p_rms_rel_finest'], '.2e')} | {_f(o['energy_drift_finest'], '.1e')} "
            + f"| {o['failures'] or '-'} |"
        )
    lines.append("")
    return "\n".join(lines)


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
        e: errors at them (non-finite or zero ones, those of runs that broke down among them, are left
            out of the fit).

    Returns:
        ``(least-squares order, finest-pair order)``: the fit over the errors left, NaN with fewer than
        two; the order between the two finest spacings, NaN unless both their errors are finite and
        > 0 (a pair of coarser runs is not the finest pair).
    """
    h, e = np.asarray(h, float), np.asarray(e, float)
    ok = np.isfinite(e) & (e > 0)
    if ok.sum() < 2:
        return float("nan"), float("nan")
    slope = np.polyfit(np.log(1 / h[ok]), np.log(e[ok]), 1)[0]
    finest = np.argsort(h)[:2][::-1]  # the two finest spacings, the coarser first
    if not np.all(ok[finest]):
        return float(-slope), float("nan")
    hh, ee = h[finest], e[finest]
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
    """Run the ladder; write ``orders.md``, ``orders.csv``, ``runs.csv`` and ``orders.json`` to ``out``, and
    for the shock cases (Sod, Noh, the detonation) ``shocks.md``, ``shocks.csv``, ``shock_runs.csv`` and
    ``shocks.json``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: FLIP only, SPQ, CPDI and MPQ, coarser grids.
        transfers: labels in ``TRANSFERS`` to run (default: all, or FLIP when ``small``; the shock
            cases run FLIP unless ``transfers`` is given).
        methods: labels in ``METHODS`` to run (default: all, or SPQ, CPDI and MPQ when ``small``).
        scenes: case names to run (default: all).
        release: called after each case, whose compiled programs (one per resolution) are not used
            again (the command line passes ``jax.clear_caches``).

    Returns:
        ``runs`` (one row per run) and ``orders`` (one row per scene, method and transfer), and
        ``shock_runs``, ``shock_orders`` and ``energy_drift`` (empty without an Euler case) for the shock
        cases.

    Raises:
        RuntimeError: float64 is off.
        ValueError: a name in ``transfers``, ``methods`` or ``scenes`` that is not one of them (before
            anything runs).
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("convergence")
    known = [c.name for c in cases(small)] + [c.name for c in shock_cases(small)]
    for name, given, allowed in (
        ("transfers", transfers, list(TRANSFERS)),
        ("methods", methods, list(METHODS)),
        ("scenes", scenes, known),
    ):
        if given is None:
            continue
        if isinstance(given, str) or not given or not all(isinstance(g, str) for g in given):
            raise ValueError(f"{name} must be a sequence of names, one or more of {allowed}, got {given!r}")
        unknown = [g for g in given if g not in allowed]
        if unknown:
            raise ValueError(f"{name}: {unknown[0]!r} is not one of {allowed}")
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    all_cases = [c for c in cases(small) if scenes is None or c.name in scenes]
    all_shocks = [c for c in shock_cases(small) if scenes is None or c.name in scenes]
    shock_transfers = ("FLIP",) if transfers is None else tuple(transfers)
    transfers = tuple(transfers) if transfers is not None else ("FLIP",) if small else tuple(TRANSFERS)
    methods = tuple(methods) if methods is not None else ("SPQ", "CPDI", "MPQ") if small else tuple(METHODS)
    result = {}
    if all_cases:
        result = _ladder(outdir, all_cases, methods, transfers, release)
    if all_shocks:
        result.update(_shocks(outdir, all_shocks, methods, shock_transfers, release))
    return result


def _write_csv(path: pathlib.Path, table: list[dict]) -> None:
    """Write rows to a CSV file, whole, with every key any row has as a column (in first-seen order)."""
    OUTPUTS.csv(path, table, dict.fromkeys(k for r in table for k in r))


def _shocks(outdir, all_cases, methods, transfers, release) -> dict:
    """Run the shock cases with ``transfers`` and, with an Euler case, the energy drift at its
    resolutions; write ``shocks.md``, ``shocks.csv``, ``shock_runs.csv`` and ``shocks.json``."""
    rows = []
    for case in all_cases:
        for method in methods:
            for transfer in transfers:
                rows.extend(run_shock_case(case, method, transfer))
        if release is not None:
            release()
    order_rows = shock_orders(rows)
    euler = [c for c in all_cases if c.errors == EULER_ERRORS]
    res = euler[0].cells if euler else ()
    drift = [energy_drift(method, n) for method in methods for n in res]
    if release is not None and drift:
        release()
    head = (
        "# Shocks: observed orders of convergence\n\n"
        "L1 errors at the end time of density, velocity, pressure and specific internal energy against "
        "the exact solution, at the particles' positions (`jaxmpm.metrics.euler_errors`). Order: "
        "least-squares slope over the resolutions that finished with a non-zero error (in brackets: the "
        "finest pair, - where one of its runs broke down or has an error of exactly 0). Ideal "
        "gas with the energy equation, artificial viscosity (c_quad 2, c_lin 0.2), 2 particles per "
        f"cell, {', '.join(transfers)}, USL, float64, dt = CFL h / max(c + |v|) every step. Energy drift: "
        "the total (kinetic plus internal) energy's relative change at the finest resolution. The "
        "detonation (`jaxmpm.Detonation`): relative RMS errors of F and of the pressure "
        "(`jaxmpm.metrics.pressure_error`) against the exact CJ-Taylor wave over the burnt particles "
        "12 h behind the front (`scene.smooth`), the same viscosity, and its energy drift (each particle "
        "starts with its detonation energy, which the burn does not add to: it switches the pressure on; "
        "the drift comes from the burn's fixed number of steps a particle, first order in the time step, "
        "so it does not shrink with h at a fixed CFL); a run that broke down is listed, never fitted.\n\n"
    )
    text = head + shock_markdown(order_rows, all_cases)
    if not drift:
        return _write_shocks(outdir, text, rows, order_rows, drift)
    text += (
        "\n**Energy without dissipation** (an ideal-gas slab, rho = 1, p = 1, gamma = 1.4, expanding into "
        "vacuum from both free ends: no viscosity, no walls, FLIP, CFL 0.2, to t = 0.2): the total "
        "energy's relative drift.\n\n"
        "| method | " + " | ".join(f"{n} cells" for n in res) + " |\n"
        "|---|" + "---|" * len(res) + "\n"
    )
    for method in methods:
        cells = [r for r in drift if r["method"] == method]
        text += (
            f"| {method} | "
            + " | ".join(_f(r["energy_drift"], ".1e") if r["status"] == "ok" else r["status"] for r in cells)
            + " |\n"
        )
    return _write_shocks(outdir, text, rows, order_rows, drift)


def _write_shocks(outdir, text, rows, order_rows, drift) -> dict:
    """Write ``shocks.md``, ``shock_runs.csv``, ``shocks.csv`` and ``shocks.json``; print the tables."""
    OUTPUTS.text(outdir / "shocks.md", text)
    _write_csv(outdir / "shock_runs.csv", rows)
    _write_csv(outdir / "shocks.csv", order_rows)
    OUTPUTS.text(outdir / "shocks.json", dumps(dict(runs=rows, orders=order_rows, energy=drift), indent=1))
    print(text)
    return dict(shock_runs=rows, shock_orders=order_rows, energy_drift=drift)


def _ladder(outdir, all_cases, methods, transfers, release) -> dict:
    """Run the smooth cases; write ``orders.md``, ``orders.csv``, ``runs.csv`` and ``orders.json``."""
    rows = []
    for case in all_cases:
        for method in methods:
            for transfer in transfers:
                rows.extend(run_case(case, method, transfer))
        if release is not None:
            release()
    return write_ladder(outdir, rows, all_cases)


def write_ladder(outdir: pathlib.Path, rows: list[dict], all_cases: list) -> dict:
    """Write the smooth cases' ``orders.md``, ``orders.csv``, ``runs.csv`` and ``orders.json`` from the
    runs' rows (``run_case``'s), and print the table.

    Args:
        outdir: the output folder.
        rows: one row per run.
        all_cases: the cases they ran (``cases``), for the table's notes.

    Returns:
        ``runs`` (the rows) and ``orders`` (one row per scene, method and transfer).
    """
    order_rows = orders(rows)
    head = (
        "# Observed orders of convergence\n\n"
        "RMS errors over real particles at the end time: x (absolute), F (relative), v (absolute). "
        "Order: least-squares slope over the resolutions that finished with a non-zero error (in "
        "brackets: the finest pair, - where one of its runs broke down or has an error of exactly 0). "
        "USL, no artificial cells unless stated, float64, dt = CFL h / max(c + |v|) every step.\n\n"
    )
    text = head + markdown(order_rows, all_cases)
    OUTPUTS.text(outdir / "orders.md", text)
    _write_csv(outdir / "runs.csv", rows)
    _write_csv(outdir / "orders.csv", order_rows)
    OUTPUTS.text(outdir / "orders.json", dumps(dict(runs=rows, orders=order_rows), indent=1))
    print(text)
    return dict(runs=rows, orders=order_rows)
