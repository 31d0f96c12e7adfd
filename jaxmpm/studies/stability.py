"""Stability on stiff and extreme cases: where each interpolator stays accurate, degrades, or breaks.

The talk's gas expansion ``u = beta t X`` (exact at any amplitude) is driven far from the talk's
regime: expansion to F = 100 and compression to F = 0.05, gamma from 1.1 to 5, P0 / p_atm up to
1000, each at CFL numbers from 0.1 to 1.5 (the step ``dt = CFL h / max(c + |v|)`` recomputed every
step). Each run is classified as

- ``accurate``: finished, max relative F error <= ``TOL`` (1%);
- ``inaccurate``: finished, larger error;
- ``broken``: stopped at step k on particle p, with the quantity that failed (F <= 0, non-finite
  state, left the grid, GIMP stencil overflow, max_steps).

The solver's own stable-step check (``cfl_limit``) is switched off here, so that CFL > 1 shows what
actually happens; with the default ``cfl_limit=1.0`` those runs stop at step 1 with "time step beyond
the stable limit". All members of one interpolator run as one ``vmap``-ed, compiled call, each with
its own status: one member breaking down stops nothing else.

A stiff shock tube (pressure ratio 1e5, density ratio 1e3, ideal gas with the energy equation and
artificial viscosity) runs at the same CFL numbers for each interpolator, judged by its L1 errors of
density, velocity and pressure against the exact solution at ``STIFF_T``, before the shock reaches the
wall (past that the open tube's exact solution no longer holds).

A run that broke down is listed with its step, particle and the quantity that failed; its measures
are ``None`` (its state is the last good one, not the end).

A detonation at the extremes runs the same way, with and without artificial cells: a slab of
gamma-law explosive lit against a wall (``jaxmpm.Detonation``'s programmed burn, ideal-gas products
with the detonation energy) whose far face is air at 1e-5 of the CJ pressure. The front reaches the
air, the products expand into it at about 7 km/s and drive a strong shock through it (air about 500
times lighter than the explosive, compressed about sixfold). Judged by the RMS error of the
products' ``F`` against the exact CJ-Taylor wave where no signal from the air has yet arrived.
"""

from __future__ import annotations

import math
import pathlib
import time
from collections.abc import Callable

import numpy as np

import jaxmpm as jm
from jaxmpm import status as st_bits
from jaxmpm._json import dumps
from jaxmpm.geometry import Box

from ._methods import METHODS
from ._output import Files
from ._runtime import require_float64

OUTPUTS = Files(
    "stability.md",
    "stability.csv",
    "stability.json",
    "stability.png",
    "stiff_shock.json",
    "detonation_air.json",
)
"""The files the study writes."""

TOL = 1e-2
CFLS = (0.1, 0.25, 0.5, 1.0, 1.5)
CELLS = 8
BETA = 200.0
P_ATM = 1.0e5
SHORT = {
    st_bits.NONFINITE: "NaN",
    st_bits.NONPOSITIVE_F: "F<=0",
    st_bits.LEFT_GRID: "grid",
    st_bits.CFL: "cfl",
    st_bits.STENCIL: "stencil",
    st_bits.SCENE_DATA: "data",
    st_bits.MAX_STEPS: "steps",
    st_bits.NEGATIVE_ENERGY: "e<0",
    st_bits.PRODUCTS_TENSION: "tension",
}
"""A table cell's name of each failed quantity (every bit of ``jaxmpm.status.QUANTITY``)."""


def _failure(r: dict) -> str:
    """A broken run's cell: its first failed quantity (the lowest bit set) and the step it failed."""
    first = min(b for b in st_bits.QUANTITY if r["status"] & b)
    return f"{SHORT.get(first, f'bit {first}')}@{r['fail_step']}"


def cases(small: bool = False) -> list[dict]:
    """The rows of the map.

    Args:
        small: three targets and one pressure ratio, no gamma sweep.

    Returns:
        One dict per case: ``label`` and the scene's ``beta``, ``gamma``, ``P0``, ``p_atm`` and ``t_end``.
    """
    base = dict(gamma=1.4, P0=2.0 * P_ATM, p_atm=P_ATM)
    rows = []
    targets = (2.0, 100.0, 0.05) if small else (2.0, 10.0, 100.0, 0.5, 0.2, 0.05)
    for F in targets:
        beta = BETA if F > 1 else -BETA
        kind = "expand" if F > 1 else "compress"
        rows.append(dict(label=f"{kind} to F={F:g}", beta=beta, t_end=(F - 1.0) / beta, **base))
    for g in () if small else (1.1, 2.0, 3.0, 5.0):
        rows.append(dict(label=f"gamma={g:g}, F=2", beta=BETA, t_end=1.0 / BETA, **{**base, "gamma": g}))
    for r in (1000.0,) if small else (10.0, 100.0, 1000.0):
        rows.append(
            dict(label=f"P0/p_atm={r:g}, F=2", beta=BETA, t_end=1.0 / BETA, **{**base, "P0": r * P_ATM})
        )
    return rows


def _max_steps(members, h) -> int:
    """A bound on the steps the fastest-signalling member needs (twice its exact-solution estimate)."""
    worst = 0.0
    for m in members:
        F_min = min(1.0, 1.0 + m["beta"] * m["t_end"])
        c = np.sqrt(m["gamma"] * m["P0"] * F_min ** (1.0 - m["gamma"]))
        speed = c + abs(m["beta"]) * CELLS * h
        worst = max(worst, m["t_end"] * speed / (m["cfl"] * h))
    return int(2 * worst) + 100


def sweep(method: str, artificial_cells: int, members: list[dict]) -> list[dict]:
    """Run every member in one vmapped, compiled call.

    Args:
        method: the interpolator's label (``METHODS``).
        artificial_cells: layers of artificial cells.
        members: cases with their ``cfl`` (``cases`` rows with a CFL number).

    Returns:
        One result per member: the member, its status, failure step and particle, steps, time, max
        relative F error, whether its state is finite, and its ``verdict``. A member that broke down
        has ``F_max_rel`` ``None`` (its state is its last good one, not the end; ``finite`` is that
        state's).
    """
    import jax
    import jax.numpy as jnp

    pad = 100 * (CELLS + 2) + 10  # room for F = 100, artificial cells included
    h = 1.0 / CELLS
    max_steps = _max_steps(members, h)
    keys = ("beta", "gamma", "P0", "p_atm", "t_end", "cfl")
    params = {k: jnp.asarray([m[k] for m in members]) for k in keys}
    interp = METHODS[method]()

    def one(p):
        sc = jm.GasExpansion(
            beta=p["beta"], gamma=p["gamma"], P0=p["P0"], p_atm=p["p_atm"], h=h, cells=CELLS, pad=pad
        )
        sol = jm.simulate(
            sc,
            interp,
            t_end=p["t_end"],
            cfl=p["cfl"],
            max_steps=max_steps,
            artificial_cells=artificial_cells,
            cfl_limit=None,
            throw=False,
        )
        st = sol.state
        finite = jnp.all(jnp.isfinite(st.x)) & jnp.all(jnp.isfinite(st.F)) & jnp.all(jnp.isfinite(st.v))
        finite = finite & jnp.all(jnp.isfinite(st.sigma))
        return dict(
            status=st.status,
            fail_step=st.fail_step,
            fail_particle=st.fail_particle,
            steps=st.step,
            t=st.t,
            F_max_rel=jm.errors(sc, st, sol.body)["F_max_rel"],
            finite=finite,
        )

    t0 = time.perf_counter()
    out = jax.device_get(jax.jit(jax.vmap(one))(params))
    seconds = time.perf_counter() - t0
    results = []
    for i, m in enumerate(members):
        r = dict(method=method, artificial_cells=artificial_cells, **m)
        r.update({k: (v[i].item()) for k, v in out.items()})
        if r["status"]:  # measured inside the vmap whatever the status: withheld here
            r["F_max_rel"] = None
        r["max_steps"] = max_steps
        r["batch_seconds"] = seconds
        r["verdict"] = classify(r)
        results.append(r)
    return results


SILENT = "SILENT NON-FINITE"
"""The verdict of a run that finished without a status yet with a non-finite state or error (never
expected: every step checks its state), marked ``silent NaN`` in the tables and red in the figure."""


def classify(r: dict) -> str:
    """The verdict on one run.

    Args:
        r: a ``sweep`` result.

    Returns:
        ``accurate``, ``inaccurate``, ``broken at step k on particle p: quantity``, or
        ``SILENT NON-FINITE`` (a non-finite result without a status, never expected).
    """
    if r["status"]:
        what = "; ".join(st_bits.describe(int(r["status"])))
        who = f"particle {r['fail_particle']}" if r["fail_particle"] >= 0 else "the run"
        return f"broken at step {r['fail_step']} on {who}: {what}"
    if not r["finite"] or not np.isfinite(r["F_max_rel"]):  # would be a silent NaN: never expected
        return SILENT
    return "accurate" if r["F_max_rel"] <= TOL else "inaccurate"


def _marked(r: dict) -> str | None:
    """A cell that is no measurement: a broken run's failure, or ``silent NaN`` (``None`` otherwise)."""
    if r["status"]:
        return _failure(r)
    if r["verdict"] == SILENT:
        return "silent NaN"
    return None


def _code(r: dict) -> str:
    if (mark := _marked(r)) is not None:
        return mark
    if r["verdict"] == "accurate":
        return f"{r['F_max_rel']:.0e}"
    return f"{r['F_max_rel']:.0e}" if r["F_max_rel"] < 10 else ">10"  # inaccurate


def figure(results: list[dict], labels: list[str], path: pathlib.Path) -> None:
    """The map as a PNG: one panel per interpolator and artificial-cell setting, cases against CFL.

    Args:
        results: the ``sweep`` results.
        labels: the cases, top to bottom.
        path: where to write the PNG.
    """
    from matplotlib.colors import ListedColormap

    from ..plotting import figure as new_figure

    panels = list(dict.fromkeys((r["method"], r["artificial_cells"]) for r in results))
    cols = 2
    rows = (len(panels) + cols - 1) // cols
    fig = new_figure(figsize=(6.0 * cols, 0.42 * len(labels) * rows + 1.5))
    axes = fig.subplots(rows, cols, squeeze=False)
    cmap = ListedColormap(["#4caf50", "#ffc107", "#e53935"])
    for ax, (method, ac) in zip(axes.flat, panels):
        grid = np.zeros((len(labels), len(CFLS)))
        for r in results:
            if (r["method"], r["artificial_cells"]) != (method, ac):
                continue
            i, j = labels.index(r["label"]), CFLS.index(r["cfl"])
            grid[i, j] = 0 if r["verdict"] == "accurate" else 1 if r["verdict"] == "inaccurate" else 2
            ax.text(j, i, _code(r), ha="center", va="center", fontsize=6.5)
        ax.imshow(grid, cmap=cmap, vmin=0, vmax=2, aspect="auto")
        ax.set_xticks(range(len(CFLS)), [f"{c:g}" for c in CFLS])
        ax.set_yticks(range(len(labels)), labels, fontsize=7)
        ax.set_xlabel("CFL number")
        ax.set_title(f"{method}, {'artificial cells' if ac else 'no artificial cells'}", fontsize=9)
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis("off")
    fig.suptitle(
        "Gas expansion u = beta t X: green accurate (max rel F err <= 1%, shown), amber inaccurate, "
        "red broken (quantity@step)",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.985))  # leave the top strip to the title
    OUTPUTS.figure(fig, path, dpi=120)


def markdown(results: list[dict], labels: list[str]) -> str:
    """The map as markdown tables, one per interpolator and artificial-cell setting.

    Args:
        results: the ``sweep`` results.
        labels: the cases, top to bottom.

    Returns:
        The tables; each cell the final error, or the first failed quantity and its step.
    """
    lines = []
    for method, ac in dict.fromkeys((r["method"], r["artificial_cells"]) for r in results):
        lines.append(f"**{method}, {'artificial cells' if ac else 'no artificial cells'}**\n")
        lines.append("| case | " + " | ".join(f"CFL {c:g}" for c in CFLS) + " |")
        lines.append("|---|" + "---|" * len(CFLS))
        for label in labels:
            cells = []
            for c in CFLS:
                r = next(
                    r
                    for r in results
                    if (r["method"], r["artificial_cells"], r["label"], r["cfl"]) == (method, ac, label, c)
                )
                cells.append(_code(r))
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


STIFF = dict(rho_l=1.0, p_l=1.0, rho_r=1e-3, p_r=1e-5)
"""The stiff shock tube: pressure ratio 1e5, density ratio 1e3, ideal gas gamma = 1.4, at rest."""
STIFF_T = 0.12
"""Its end time, within the time its exact solution (the open tube's) holds, ``t_valid = 0.1456``, when
the shock (speed 3.435) reaches the wall at 1: the shock is then at 0.912, 0.088 short of the wall
(9 cells at 100 cells, 18 at 200), and the rarefaction's head at 0.358."""
STIFF_TOL = 0.05
"""A stiff-tube run is accurate when its L1 errors of density, velocity and pressure are each at most
this fraction of the exact solution's L1 norm of that field (``int |f| dx``)."""


def shock_sweep(method: str, small: bool = False) -> list[dict]:
    """The stiff shock tube (``STIFF``) at each CFL number, with artificial viscosity: one compiled run
    per interpolator, the CFL number traced.

    Args:
        method: the interpolator's label (``METHODS``).
        small: 100 cells instead of 200.

    Returns:
        One result per CFL number: its status, failure step and particle, steps, the relative L1
        errors of density, velocity and pressure (``rho_L1_rel``, ``u_L1_rel``, ``p_L1_rel``), their
        largest (``L1_rel``; all four ``None`` for a run that broke down), and the ``verdict``
        (accurate, inaccurate or broken at step k on particle p).
    """
    import jax.numpy as jnp

    cells = 100 if small else 200
    scene = jm.ShockTube(cells=cells, h=1.0 / cells, **STIFF)
    x = jnp.linspace(0.0, 1.0, 20_001)
    exact = scene.solution(x, STIFF_T)
    norms = {k: float(jnp.mean(jnp.abs(exact[k]))) for k in ("rho", "u", "p")}  # int_0^1 |f| dx
    out = []
    for cfl in CFLS:
        t0 = time.perf_counter()
        sol = jm.simulate(
            scene,
            METHODS[method](),
            t_end=STIFF_T,
            cfl=cfl,
            max_steps=100 * cells,
            viscosity=jm.ArtificialViscosity(),
            cfl_limit=None,
            throw=False,
        )
        r = dict(method=method, cells=cells, cfl=cfl, seconds=time.perf_counter() - t0)
        st = sol.state
        r.update(status=int(st.status), fail_step=int(st.fail_step), fail_particle=int(st.fail_particle))
        r.update(
            steps=int(st.step),
            **dict.fromkeys(("rho_L1_rel", "u_L1_rel", "p_L1_rel", "L1_rel")),
        )
        if r["status"]:
            what = "; ".join(st_bits.describe(r["status"]))
            who = f"particle {r['fail_particle']}" if r["fail_particle"] >= 0 else "the run"
            r["verdict"] = f"broken at step {r['fail_step']} on {who}: {what}"
        else:
            err = jm.euler_errors(scene, st, sol.body)
            for k, norm in norms.items():
                r[f"{k}_L1_rel"] = float(err[f"{k}_L1"]) / norm
            r["L1_rel"] = max(r[f"{k}_L1_rel"] for k in norms)
            if not np.isfinite(r["L1_rel"]):  # would be a silent NaN: never expected
                r["verdict"] = SILENT
            else:
                r["verdict"] = "accurate" if r["L1_rel"] <= STIFF_TOL else "inaccurate"
        out.append(r)
    return out


def shock_markdown(results: list[dict]) -> str:
    """The stiff shock tube's table: one row per interpolator, one column per CFL number.

    Args:
        results: the ``shock_sweep`` results.

    Returns:
        The table; each cell the largest relative L1 error (density, velocity, pressure), or the first
        failed quantity and its step.
    """

    def code(r):
        if (mark := _marked(r)) is not None:
            return mark
        return f"{r['L1_rel']:.0e}" + ("" if r["verdict"] == "accurate" else " (inaccurate)")

    lines = ["| method | " + " | ".join(f"CFL {c:g}" for c in CFLS) + " |", "|---|" + "---|" * len(CFLS)]
    for method in dict.fromkeys(r["method"] for r in results):
        row = [code(r) for r in results if r["method"] == method]
        lines.append(f"| {method} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


DETONATION = dict(L=0.1, gamma=3.0, products="full", ratio=1e5, gamma_air=1.4, rho_air_bar=1.2)
"""The detonation against air: a gamma-law explosive slab (``jaxmpm.Detonation`` defaults: D = 8000
m/s, rho0 = 1875 kg/m^3, so p_CJ = 30 GPa; ``gamma``) of length ``L`` (m) lit against a wall, its
products an ideal gas with the detonation energy (``products="full"``: the pressure reads the energy,
as the air's does), then ideal-gas air (``gamma_air``) at ``p_CJ / ratio`` with the density
``rho_air_bar`` (kg/m^3) has at 1 bar, scaled with its pressure (same temperature), over ``L / 2`` to a
free end."""
DETONATION_T = 1.25
"""Its end time in units of the front's arrival at the air, ``L / D``."""
DETONATION_TOL = 0.05
"""A detonation run is accurate when its RMS relative F error over the undisturbed products is at most
this (the largest error stays near 7% at every resolution with these products: the start of the burn
at the wall leaves a few particles off the isentrope)."""


def detonation_scene(cells: int) -> tuple[jm.Bodies, jm.Detonation]:
    """The explosive slab against air (``DETONATION``), 1 particle per cell.

    Args:
        cells: cells of the explosive (the air has half as many).

    Returns:
        ``(scene, slab)``: the ``jaxmpm.Bodies`` of explosive (cells ``[0, cells]``) and air
        (``[cells, 3 cells / 2]``), wall at 0 and free at the far end, with the room the air's free
        end needs to expand into vacuum (twice its escape speed times the end time); and the
        ``jaxmpm.Detonation`` of the explosive alone, of the same ``h``, whose burn and exact CJ-Taylor
        wave it uses.
    """
    slab = jm.Detonation(
        L=DETONATION["L"],
        gamma=DETONATION["gamma"],
        products=DETONATION["products"],
        ends="wall",
        cells=cells,
        ppc=1,
    )
    explosive = slab.regions()[0]
    g = DETONATION["gamma_air"]
    p_air = float(slab.cj()["P_CJ"]) / DETONATION["ratio"]
    rho_air = DETONATION["rho_air_bar"] * p_air / 1e5
    escape = 2.0 * math.sqrt(g * p_air / rho_air) / (g - 1.0)
    t_end = DETONATION_T * float(slab.t_valid)
    air_cells = cells // 2
    scene = jm.Bodies(
        parts=(
            jm.Region(Box(0.0, float(cells)), explosive.material, explosive.rho0, 0.0, explosive.energy),
            jm.Region(
                Box(float(cells), float(cells + air_cells)),
                jm.IdealGas(gamma=g),
                rho_air,
                0.0,
                p_air / ((g - 1.0) * rho_air),
            ),
        ),
        h=slab.h,
        cells=cells + air_cells,
        ppc=1,
        pad=math.ceil(2.0 * escape * t_end / float(slab.h)) + 4,
        left="wall",
        right="free",
    )
    return scene, slab


def _undisturbed(slab: jm.Detonation, body, t: float) -> np.ndarray:
    """The explosive's particles, burnt and ``12 h`` behind the front, that no signal from the air can
    have reached by ``t``: those whose exact position is short of ``L - D (t - L / D) - 12 h`` (no
    signal in the products is faster than ``D``)."""
    X = np.asarray(body.X[:, 0])
    L, D, h = float(slab.L), float(slab.speed), float(slab.h)
    x = np.asarray(slab.exact_particles(body.X[:, 0], t)["x"])
    return (X < L) & (X < D * t - 12.0 * h) & (x < L - D * max(t - L / D, 0.0) - 12.0 * h)


def detonation_sweep(method: str, small: bool = False, artificial_cells=(0, 1), cfls=CFLS) -> list[dict]:
    """The explosive slab against air (``detonation_scene``) at each CFL number, with and without
    artificial cells, with artificial viscosity, to ``DETONATION_T`` times the front's arrival at the
    air: one compiled run per interpolator and artificial-cell setting, the CFL number traced.

    Args:
        method: the interpolator's label (``METHODS``).
        small: 100 cells of explosive instead of 200.
        artificial_cells: the artificial-cell settings (the body fills its box; they sit at the air's
            free end).
        cfls: the CFL numbers.

    Returns:
        One result per setting and CFL number: its status, failure step and particle, steps, and over
        the undisturbed products (``undisturbed`` particles) the relative errors of F (largest,
        ``F_max_rel``; RMS, ``F_rms_rel``) and of the pressure (RMS, ``p_rms_rel``) against the exact
        CJ-Taylor wave, the air's smallest F (``air_F_min``; the strong-shock limit is 1/6), and the
        ``verdict`` (accurate, inaccurate or broken at step k on particle p: quantity). A run that
        broke down has ``undisturbed`` and the measures ``None``.
    """
    import jax.numpy as jnp

    cells = 100 if small else 200
    scene, slab = detonation_scene(cells)
    t_end = DETONATION_T * float(slab.t_valid)
    # the step's speed max(c + |v|) peaks at about 1.7 D (the shocked air), so 4 D / CFL leaves room
    max_steps = int(4.0 * DETONATION_T * cells / min(cfls)) + 100
    air = np.asarray(scene.layout().region) == 1
    keys = ("F_max_rel", "F_rms_rel", "p_rms_rel", "air_F_min")
    out = []
    for ac in artificial_cells:
        for cfl in cfls:
            t0 = time.perf_counter()
            sol = jm.simulate(
                scene,
                METHODS[method](),
                t_end=t_end,
                cfl=cfl,
                max_steps=max_steps,
                artificial_cells=ac,
                viscosity=jm.ArtificialViscosity(),
                cfl_limit=None,
                throw=False,
            )
            st, body = sol.state, sol.body
            r = dict(method=method, cells=cells, artificial_cells=ac, cfl=cfl, t_end=t_end)
            r.update(seconds=time.perf_counter() - t0, max_steps=max_steps)
            r.update(status=int(st.status), fail_step=int(st.fail_step), fail_particle=int(st.fail_particle))
            r.update(steps=int(st.step), undisturbed=None, **dict.fromkeys(keys))
            if r["status"]:
                what = "; ".join(st_bits.describe(r["status"]))
                who = f"particle {r['fail_particle']}" if r["fail_particle"] >= 0 else "the run"
                r["verdict"] = f"broken at step {r['fail_step']} on {who}: {what}"
                out.append(r)
                continue
            where = _undisturbed(slab, body, float(st.t))
            ex = slab.exact_particles(body.X[:, 0], st.t)
            F = np.asarray(st.F[:, 0, 0])
            F_rel = np.abs(F[where] / np.asarray(ex["F"])[where] - 1.0)
            p_rel = np.asarray(jm.pressure(st))[where] / np.asarray(ex["p"])[where] - 1.0
            r.update(
                undisturbed=int(where.sum()),
                F_max_rel=float(np.max(F_rel)),
                F_rms_rel=float(np.sqrt(np.mean(np.square(F_rel)))),
                p_rms_rel=float(np.sqrt(np.mean(np.square(p_rel)))),
                air_F_min=float(np.min(F[air])),
            )
            finite = all(bool(jnp.all(jnp.isfinite(a))) for a in (st.x, st.v, st.F, st.sigma))
            if not (finite and np.isfinite(r["F_rms_rel"])):  # would be a silent NaN: never expected
                r["verdict"] = SILENT
            else:
                r["verdict"] = "accurate" if r["F_rms_rel"] <= DETONATION_TOL else "inaccurate"
            out.append(r)
    return out


def detonation_markdown(results: list[dict]) -> str:
    """The detonation's table: one row per interpolator and artificial-cell setting, one column per CFL
    number.

    Args:
        results: the ``detonation_sweep`` results.

    Returns:
        The table; each cell the RMS relative F error over the undisturbed products, or the first
        failed quantity and its step.
    """

    def code(r):
        if (mark := _marked(r)) is not None:
            return mark
        return f"{r['F_rms_rel']:.0e}" + ("" if r["verdict"] == "accurate" else " (inaccurate)")

    cfls = list(dict.fromkeys(r["cfl"] for r in results))
    lines = [
        "| method | artificial cells | " + " | ".join(f"CFL {c:g}" for c in cfls) + " |",
        "|---|---|" + "---|" * len(cfls),
    ]
    for method, ac in dict.fromkeys((r["method"], r["artificial_cells"]) for r in results):
        row = [code(r) for r in results if (r["method"], r["artificial_cells"]) == (method, ac)]
        lines.append(f"| {method} | {ac} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def run_all(
    small: bool = False,
    methods=None,
    artificial_cells=(0, 1),
    release: Callable[[], object] | None = None,
) -> tuple[list[dict], list[str]]:
    """Sweep every case and CFL number for each interpolator, with and without artificial cells.

    Args:
        small: the reduced map (fewer cases; SPQ and MPQ only).
        methods: labels in ``METHODS`` (default: all, or SPQ and MPQ when ``small``).
        artificial_cells: the artificial-cell settings.
        release: called after each interpolator's sweeps, whose compiled programs are not used again
            (the command line passes ``jax.clear_caches``).

    Returns:
        ``(results, labels)``: one dict per run, and the cases in order.
    """
    rows = cases(small)
    labels = [r["label"] for r in rows]
    members = [dict(r, cfl=c) for r in rows for c in CFLS]
    methods = methods or (("SPQ", "MPQ") if small else tuple(METHODS))
    results = []
    for method in methods:
        for ac in artificial_cells:
            results.extend(sweep(method, ac, members))
        if release is not None:
            release()
    return results, labels


def main(out: str, small: bool = False, release: Callable[[], object] | None = None) -> dict:
    """Run the sweep, the stiff shock tube and the detonation against air; write
    ``stability.{md,csv,json,png}``, ``stiff_shock.json`` and ``detonation_air.json`` to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: the reduced map.
        release: as for ``run_all``.

    Returns:
        ``results`` (one dict per run), ``labels`` (the cases), ``stiff_shock`` (one dict per
        interpolator and CFL number of the stiff shock tube) and ``detonation_air`` (one dict per
        interpolator, artificial-cell setting and CFL number of the detonation against air).

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("stability")
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    results, labels = run_all(small, release=release)
    counts = {v: 0 for v in ("accurate", "inaccurate", "broken")}
    for r in results:
        counts[r["verdict"].split(" ")[0]] = counts.get(r["verdict"].split(" ")[0], 0) + 1
    head = (
        "# Stability map\n\n"
        f"Gas expansion u = beta t X, {CELLS} cells x 2 ppc, |beta| = {BETA:g} 1/s, p_atm = {P_ATM:g} Pa "
        f"unless stated; FLIP, USL, float64, cfl_limit off. Each cell: the max relative F error at the end "
        f"(accurate <= {TOL:g}), or the first failed quantity and its step. "
        f"{counts['accurate']} accurate, {counts['inaccurate']} inaccurate, {counts['broken']} broken, "
        f"{counts.get('SILENT', 0)} silent non-finite.\n\n"
    )
    methods = list(dict.fromkeys(r["method"] for r in results))
    shocks = []
    for method in methods:
        shocks.extend(shock_sweep(method, small))
        if release is not None:
            release()
    detonations = []
    for method in methods:
        detonations.extend(detonation_sweep(method, small))
        if release is not None:
            release()
    cells = shocks[0]["cells"]
    n_exp = detonations[0]["cells"]
    ratio = f"{DETONATION['ratio']:.0e}".replace("e+0", "e")
    air = detonation_scene(n_exp)[0].parts[1]
    p_air = float(air.material.pressure(air.rho0, air.energy, None))
    text = head + markdown(results, labels)
    text += (
        f"\n**Stiff shock tube** (pressure ratio 1e5, density ratio 1e3: left rho = 1, p = 1, right rho = "
        f"1e-3, p = 1e-5, gamma = 1.4; {cells} cells x 2 ppc, artificial viscosity, to t = {STIFF_T:g}). "
        "Each cell: the largest of the L1 errors of density, velocity and pressure, each relative to the "
        f"exact field's int |f| dx (accurate <= {STIFF_TOL:g}), or the first failed quantity and its "
        "step.\n\n" + shock_markdown(shocks)
    )
    text += (
        f"\n**Detonation against air** (pressure ratio {ratio}: gamma-law explosive, "
        f"gamma = {DETONATION['gamma']:g}, D = 8000 m/s, rho0 = 1875 kg/m^3, p_CJ = 30 GPa, "
        f"L = {DETONATION['L']:g} m lit against a wall (`jaxmpm.Detonation`'s burn, products "
        f'"{DETONATION["products"]}"), then air, gamma = '
        f"{DETONATION['gamma_air']:g}, at p_CJ / {ratio} = {p_air / 1e5:g} bar and {air.rho0:g} kg/m^3, "
        f"over L / 2 to a free end; {n_exp} + {n_exp // 2} cells x 1 ppc, artificial viscosity, to "
        f"{DETONATION_T:g} L / D). Each cell: the RMS relative F error against the exact CJ-Taylor "
        "wave over the burnt products no signal from the air has reached (accurate <= "
        f"{DETONATION_TOL:g}), or the first failed quantity and its step.\n\n"
        + detonation_markdown(detonations)
    )
    OUTPUTS.text(outdir / "stability.md", text)
    OUTPUTS.csv(outdir / "stability.csv", results, list(results[0]))
    OUTPUTS.text(outdir / "stability.json", dumps(results, indent=1))
    OUTPUTS.text(outdir / "stiff_shock.json", dumps(shocks, indent=1))
    OUTPUTS.text(outdir / "detonation_air.json", dumps(detonations, indent=1))
    figure(results, labels, outdir / "stability.png")
    print(text)
    return dict(results=results, labels=labels, stiff_shock=shocks, detonation_air=detonations)
