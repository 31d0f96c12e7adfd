"""The planar detonation with numbers: the deformation gradient of the converted particles by
interpolator, its convergence away from the front, and the peak pressure against P_CJ by burn model.

The scene is ``jaxmpm.scenes.Detonation``: a slab of explosive on ``[0, L]`` lit at ``X = 0`` against a
wall, a programmed burn of an inert reactant into its products, and the exact CJ-Taylor wave.

1. **F by interpolator.** Gamma-law products (gamma = 3), 400 particles per 10 cm (one per cell, and
   two per cell on half the cells), every interpolator of ``jaxmpm.INTERPOLATORS`` with 0 and 1
   artificial cells: ``F`` over the burnt particles away from the front (``scene.smooth``), the
   pressure there, and the products at rest against the wall (exact ``F = 9/8``, ``p = 8/27 P_CJ``).
2. **Convergence away from the front.** CPDI and MPQ with one artificial cell, one particle per cell,
   100 to 800 cells per 10 cm: RMS errors of ``F`` and ``p`` over ``scene.smooth`` and their orders.
3. **Peak pressure.** The largest EOS pressure (without the artificial viscosity's ``q``) over the
   particles and ~50 saved frames, over ``P_CJ``, for each burn criterion (time, volume, max) and
   products (gamma-law, Comp B on its JWL principal isentrope), by resolution.

A run that broke down is reported as such (the failed quantity and step) and none of its numbers is
used. ``jaxmpm study detonation --out DIR`` writes ``detonation.md``, ``detonation.json``,
``detonation_runs.csv`` and the figures ``F_by_interpolator.png``, ``convergence.png`` and
``peak_pressure.png``.
"""

from __future__ import annotations

import math
import pathlib
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps
from jaxmpm.explosives import BURNS

from ._output import Files
from ._runtime import machine, number, require_float64, run_status, status_cell

OUTPUTS = Files(
    "detonation.md",
    "detonation.json",
    "detonation_runs.csv",
    "F_by_interpolator.png",
    "convergence.png",
    "peak_pressure.png",
)
"""The files the study writes."""

CFL = 0.3
"""The Courant number of every run."""
GAMMA = 3.0
"""The gamma-law products' exponent."""
F_REST = 9.0 / 8.0
"""Exact ``F`` of gamma = 3 products at rest against the wall."""
P_REST = 8.0 / 27.0
"""Exact pressure at rest against the wall, over ``P_CJ`` (gamma = 3)."""
REST_FRACTION = 0.4
"""The products counted at rest: ``X < REST_FRACTION * D t / F_REST`` (the rest region ends at
``x = D t / 2``, ``X = D t / 2 / F_REST``)."""
GOAL = 0.02
"""The goals' tolerance: F within 2% of exact, the wall plateau within 2% of ``8/27 P_CJ``."""
FRAMES = 50
"""About how many frames the peak pressure is taken over."""
UNLIT = 1e-6
"""A peak pressure below ``UNLIT P_CJ`` is a run that never lit (round-off compression of the inert
reactant leaves a pressure of order 1e-14 P_CJ)."""
LIT = 0.5
"""A peak pressure above ``LIT P_CJ`` is a detonation that reached the products' CJ region: the orders of
the peak's deficit are taken over those runs only."""
PRODUCTS = ("gamma-law", "compb")
"""The products of the peak-pressure table: gamma-law (gamma = 3) and Comp B's JWL principal isentrope
(the reduced study: gamma-law only)."""
PEAK_RUN = ("mpq", 1)
"""The interpolator and artificial cells of the peak-pressure table."""
CONVERGENCE_NAMES = ("cpdi", "mpq")
"""The interpolators of the convergence table."""
PER_10CM = 0.1
"""The reference length of a resolution: cells per 10 cm."""
FULL = dict(
    L=0.1,
    t_end=1e-5,
    cases=((1, 400), (2, 200)),
    convergence=(100, 200, 400, 800),
    peak=(100, 200, 400, 800),
    products=PRODUCTS,
    gurney=dict(cells=(100, 200, 400), all_at=200, t_end=4e-5, times=(2e-5, 3e-5, 4e-5)),
)
SMALL = dict(
    L=0.02,
    t_end=2e-6,
    cases=((1, 80), (2, 40)),
    convergence=(200, 400),
    peak=(200, 400),
    products=PRODUCTS[:1],
    gurney=dict(cells=(50,), all_at=None, t_end=1e-5, times=(5e-6, 1e-5)),
)


def settings(small: bool = False) -> dict:
    """The study's sizes.

    Args:
        small: the reduced version (a 2 cm slab, the front at 1.6 cm; the first two interpolators of
            the registry with CPDI and MPQ; two resolutions per table, gamma-law products only in table 3).

    Returns:
        ``dict(L, t_end, cases, names, convergence, peak, products)``: the slab's length (m), the end time
        of tables 1 and 2 (s), the ``(ppc, cells)`` of table 1, its interpolators (keys of
        ``jaxmpm.INTERPOLATORS``), the cells per 10 cm of tables 2 and 3, and the products of table 3.
    """
    out = dict(SMALL if small else FULL)
    names = list(jm.INTERPOLATORS)
    if small:
        names = [n for n in names if n in names[:2] or n in CONVERGENCE_NAMES]
    out["names"] = tuple(names)
    return out


def _cells(per_10cm: int, L: float) -> int:
    return int(round(per_10cm * L / PER_10CM))


def _finite(x) -> float | None:
    """A finite float, or ``None`` (JSON has no NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None


def expected_steps(scene, t_end: float) -> int:
    """The steps a run to ``t_end`` is expected to take: ``1.25 D t_end / (cfl h)``.

    The step is ``cfl h / max(c + |v|)``; behind a CJ front ``c + |v| = D``, and the artificial
    viscosity's overshoot raises it by ~20% (1302 steps measured against 1067 at 400 cells).

    Args:
        scene: the detonation scene.
        t_end: the end time.

    Returns:
        The estimate.
    """
    return int(math.ceil(1.25 * float(scene.speed) * t_end / (CFL * float(scene.h))))


def simulate(
    scene,
    name: str,
    artificial_cells: int,
    t_end: float,
    max_steps: int | None = None,
    cache: dict | None = None,
    frames: bool = True,
):
    """One run of the study: CFL 0.3, default artificial viscosity, no exception on breakdown, and
    ``F``, ``e`` and ``internal`` saved about ``FRAMES`` times.

    Every table's runs share this form, so that a run two tables need (table 1's MPQ at 400 particles
    per 10 cm is in table 2, and table 2's MPQ runs are table 3's gamma-law time burn) runs once.

    Args:
        scene: the detonation scene.
        name: the interpolator (a key of ``jaxmpm.INTERPOLATORS``).
        artificial_cells: layers of artificial cells at the free end.
        t_end: the end time.
        max_steps: the scan's bound; default twice ``expected_steps`` and 50.
        cache: runs already done, by their settings, or ``None``; filled.
        frames: whether to save the frames (a cached run with them serves a call without).

    Returns:
        ``(solution, wall_s)``: the ``Solution`` and the wall time of the call (compile included).
    """
    key = (scene.explosive, scene.burn, float(scene.L), scene.cells, scene.ppc, name, artificial_cells)
    key += (float(f"{t_end:.12g}"), max_steps)
    if cache is not None:
        for k in ((key, True), (key, False)) if not frames else ((key, True),):
            if k in cache:
                return cache[k]
    est = expected_steps(scene, t_end)
    t0 = time.perf_counter()
    sol = jm.simulate(
        scene,
        jm.INTERPOLATORS[name](),
        t_end=t_end,
        cfl=CFL,
        max_steps=max_steps or 2 * est + 50,
        artificial_cells=artificial_cells,
        viscosity=jm.ArtificialViscosity(),
        saveat=jm.SaveAt(every=max(1, est // FRAMES), fields=("F", "e", "internal")) if frames else None,
        throw=False,
    )
    jax.block_until_ready(sol.state)
    out = (sol, time.perf_counter() - t0)
    if cache is not None:
        cache[(key, frames)] = out
    return out


@eqx.filter_jit
def _metrics(scene, state, body):
    """Over ``scene.smooth``: the errors, the RMS pressure error; and every particle's pressure."""
    where = jm.metrics.smooth_mask(scene, body, state.t)
    err = jm.errors(scene, state, body, where=where)
    return where, err, jm.metrics.pressure_error(scene, state, body, where=where), jm.pressure(state)


ERROR_KEYS = ("F_max_rel", "F_rms_rel", "p_rms_rel", "plateau_p", "plateau_F", "plateau_F_spread")
"""The numbers of a row of tables 1 and 2 (all ``None`` for a run that broke down)."""


def interpolator_row(
    scene,
    name: str,
    artificial_cells: int,
    t_end: float,
    max_steps: int | None = None,
    cache: dict | None = None,
) -> dict:
    """One gamma-law run at a wall and its errors against the exact CJ-Taylor wave.

    Over ``scene.smooth`` (the burnt particles more than 12 h behind the front): ``F_max_rel`` and
    ``F_rms_rel`` (``jaxmpm.errors``) and ``p_rms_rel`` (``jaxmpm.metrics.pressure_error``). Over the
    burnt particles at rest against the wall (``X < 0.4 D t / F_REST``): their mean pressure over
    ``8/27 P_CJ`` (``plateau_p``), their mean ``F`` over ``9/8`` (``plateau_F``) and the spread of ``F``,
    ``(max - min) / (9/8)`` (``plateau_F_spread``).

    Args:
        scene: a gamma = 3 ``Detonation`` with ``ends="wall"``.
        name: the interpolator (a key of ``jaxmpm.INTERPOLATORS``).
        artificial_cells: layers of artificial cells at the free end.
        t_end: the end time.
        max_steps: the scan's bound (default: ``simulate``'s).
        cache: ``simulate``'s.

    Returns:
        The row: the run (interpolator, ppc, cells, particles, artificial cells, steps, wall time),
        ``status`` (``"ok"`` or the failed quantity and step), ``failure``, the numbers of
        ``ERROR_KEYS`` and the profile ``X``, ``F`` at ``t_end`` (all ``None`` if the run broke down).
    """
    # the runs table 3 reuses keep their frames
    frames = (name, artificial_cells, scene.ppc, scene.burn) == (*PEAK_RUN, 1, "time")
    sol, wall = simulate(
        scene, name, artificial_cells, t_end, max_steps=max_steps, cache=cache, frames=frames
    )
    st, body = sol.state, sol.body
    status, fail = run_status(sol)
    row = dict(
        interpolator=name,
        ppc=scene.ppc,
        cells=scene.cells,
        cells_per_10cm=int(round(scene.cells * PER_10CM / float(scene.L))),
        particles=int(body.n),
        artificial_cells=artificial_cells,
        steps=int(st.step),
        t=float(st.t),
        wall_s=wall,
        status=status,
        failure=fail,
        **dict.fromkeys(ERROR_KEYS),
        X=None,
        F=None,
    )
    if fail is not None:
        return row
    where, err, p_rms, p = _metrics(scene, st, body)
    X = np.asarray(body.X[:, 0])
    F = np.asarray(st.F[:, 0, 0])
    lam = np.asarray(st.internal["lambda"])
    rest = (X < REST_FRACTION * float(scene.speed) * float(st.t) / F_REST) & (lam >= 1.0)
    p_cj = float(scene.cj()["P_CJ"])
    p = np.asarray(p)
    some = bool(rest.any())  # none at rest: no plateau numbers (never at the study's sizes)
    row.update(
        F_max_rel=_finite(err["F_max_rel"]),
        F_rms_rel=_finite(err["F_rms_rel"]),
        p_rms_rel=_finite(p_rms),
        smooth_particles=int(np.sum(np.asarray(where))),
        rest_particles=int(np.sum(rest)),
        plateau_p=_finite(np.mean(p[rest]) / (P_REST * p_cj)) if some else None,
        plateau_F=_finite(np.mean(F[rest]) / F_REST) if some else None,
        plateau_F_spread=_finite(np.ptp(F[rest]) / F_REST) if some else None,
        X=X.tolist(),
        F=F.tolist(),
    )
    return row


def by_interpolator(cfg: dict, cache: dict) -> list[dict]:
    """Table 1: every interpolator of ``cfg["names"]`` with 0 and 1 artificial cells, each ``(ppc, cells)``.

    Args:
        cfg: ``settings(small)``.
        cache: ``simulate``'s.

    Returns:
        The rows (``interpolator_row``).
    """
    rows = []
    for ppc, cells in cfg["cases"]:
        scene = jm.Detonation(L=cfg["L"], cells=cells, ppc=ppc, gamma=GAMMA)
        for name in cfg["names"]:
            for ac in (0, 1):
                rows.append(interpolator_row(scene, name, ac, cfg["t_end"], cache=cache))
    return rows


def observed_orders(h, e) -> tuple[float | None, float | None]:
    """Observed orders of ``e`` against ``h``: the least-squares slope of ``log e`` on ``log h`` and the
    finest pair's.

    Args:
        h: the grid spacings, coarse to fine.
        e: the errors (``None`` or NaN for a run that broke down: left out).

    Returns:
        ``(fit, finest)``: ``fit`` is ``None`` with fewer than two usable errors, ``finest`` where either
        of the two finest is not usable.
    """
    h = np.asarray(h, dtype=float)
    e = np.asarray([np.nan if v is None else v for v in e], dtype=float)
    ok = np.isfinite(e) & (e > 0)
    fit = float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 2 else None
    finest = float(np.log(e[-2] / e[-1]) / np.log(h[-2] / h[-1])) if len(e) >= 2 and ok[-2:].all() else None
    return fit, finest


def convergence(cfg: dict, cache: dict) -> dict:
    """Table 2: CPDI and MPQ with one artificial cell and one particle per cell, refined.

    Args:
        cfg: ``settings(small)``.
        cache: ``simulate``'s.

    Returns:
        ``dict(rows, orders)``: one row per interpolator and resolution (``interpolator_row``, without
        the profile), and per interpolator the orders (fit, finest pair) of ``F_rms_rel`` and
        ``p_rms_rel``.
    """
    rows, orders = [], []
    for name in CONVERGENCE_NAMES:
        mine = []
        for per in cfg["convergence"]:
            cells = _cells(per, cfg["L"])
            scene = jm.Detonation(L=cfg["L"], cells=cells, ppc=1, gamma=GAMMA)
            row = interpolator_row(scene, name, 1, cfg["t_end"], cache=cache)
            mine.append({k: v for k, v in row.items() if k not in ("X", "F")})
        h = [cfg["L"] / r["cells"] for r in mine]
        o = dict(interpolator=name)
        for q in ("F_rms_rel", "p_rms_rel"):
            o[f"{q}_order_fit"], o[f"{q}_order_finest"] = observed_orders(h, [r[q] for r in mine])
        rows += mine
        orders.append(o)
    return dict(rows=rows, orders=orders)


@eqx.filter_jit
def _peak(burn, m, V0, F, e, lam):
    """The largest EOS pressure of each frame, and its particle."""

    def frame(Fk, ek, lk):
        rho = m / (V0 * jax.vmap(jnp.linalg.det)(Fk))  # jaxmpm.density
        p = jax.vmap(lambda r, ee, la: burn.pressure(r, ee, {"lambda": la}))(rho, ek, lk)
        return jnp.max(p), jnp.argmax(p)

    return jax.vmap(frame)(F, e, lam)


def peak_row(
    scene,
    name: str = PEAK_RUN[0],
    artificial_cells: int = PEAK_RUN[1],
    max_steps: int | None = None,
    cache: dict | None = None,
) -> dict:
    """The peak EOS pressure of one run to ``0.8 t_valid``, over ``P_CJ``.

    The pressure is the burn's, ``burn.pressure(rho, e, {"lambda": lambda})`` with ``burn =
    scene.material()``: the artificial viscosity's ``q`` is left out. It is maximised over the
    particles and over ~50 saved frames.

    Args:
        scene: the detonation scene (its ``burn`` and ``explosive``).
        name: the interpolator.
        artificial_cells: layers of artificial cells.
        max_steps: the scan's bound (default: ``simulate``'s).
        cache: ``simulate``'s.

    Returns:
        The row: explosive, burn, cells, cells per 10 cm, steps, frames, wall time, status, failure,
        and ``peak`` (over ``P_CJ``), ``excess`` (``peak - 1``), ``lambda_max`` (the largest burn fraction
        at the end), ``t_peak``, ``X_peak`` and the front's place then over the slab, ``front_peak``
        (``D t_peak / L``); the numbers ``None`` if the run broke down.
    """
    t_end = 0.8 * float(scene.t_valid)
    sol, wall = simulate(scene, name, artificial_cells, t_end, max_steps=max_steps, cache=cache)
    status, fail = run_status(sol)
    row = dict(
        explosive=scene.explosive,
        burn=scene.burn,
        interpolator=name,
        artificial_cells=artificial_cells,
        cells=scene.cells,
        cells_per_10cm=int(round(scene.cells * PER_10CM / float(scene.L))),
        t_end=t_end,
        steps=int(sol.state.step),
        frames=int(sol.ts.shape[0]),
        wall_s=wall,
        status=status,
        failure=fail,
        peak=None,
        excess=None,
        lambda_max=None,
        t_peak=None,
        X_peak=None,
        front_peak=None,
    )
    if fail is not None:
        return row
    body, hist = sol.body, sol.history
    pk, arg = _peak(scene.material(), body.m, body.V0, hist["F"], hist["e"], hist["internal.lambda"])
    k = int(jnp.argmax(pk))
    p_cj = float(scene.cj()["P_CJ"])
    t_peak = float(sol.ts[k])
    row.update(
        peak=_finite(pk[k] / p_cj),
        excess=_finite(pk[k] / p_cj - 1.0),
        lambda_max=float(jnp.max(sol.state.internal["lambda"])),
        t_peak=t_peak,
        X_peak=float(body.X[int(arg[k]), 0]),
        front_peak=float(scene.speed) * t_peak / float(scene.L),
    )
    return row


def peak_pressure(cfg: dict, cache: dict) -> list[dict]:
    """Table 3: MPQ with one artificial cell, one particle per cell, every burn and products, refined.

    Args:
        cfg: ``settings(small)``.
        cache: ``simulate``'s.

    Returns:
        One ``peak_row`` per products (``cfg["products"]``), burn and resolution.
    """
    rows = []
    for explosive in cfg["products"]:
        for burn in BURNS:
            for per in cfg["peak"]:
                scene = jm.Detonation(
                    L=cfg["L"],
                    cells=_cells(per, cfg["L"]),
                    ppc=1,
                    gamma=GAMMA,
                    explosive=explosive,
                    burn=burn,
                )
                rows.append(peak_row(scene, cache=cache))
    return rows


def peak_orders(rows: list[dict]) -> list[dict]:
    """Observed orders of the peak's deficit ``|peak / P_CJ - 1|`` against ``h``, per products and burn.

    Args:
        rows: ``peak_pressure``'s.

    Returns:
        One entry per products and burn: ``explosive``, ``burn``, ``order_fit`` and ``order_finest``
        (``observed_orders`` over the runs that finished with a peak above ``LIT P_CJ``; ``None`` where
        fewer than two did).
    """
    out = []
    for explosive in dict.fromkeys(r["explosive"] for r in rows):
        for burn in dict.fromkeys(r["burn"] for r in rows):
            rr = sorted(
                (r for r in rows if r["explosive"] == explosive and r["burn"] == burn),
                key=lambda r: r["cells"],
            )
            e = [abs(r["excess"]) if r["peak"] is not None and r["peak"] >= LIT else None for r in rr]
            fit, finest = observed_orders([1.0 / r["cells"] for r in rr], e)
            out.append(dict(explosive=explosive, burn=burn, order_fit=fit, order_finest=finest))
    return out


GURNEY_FRAMES = 100
"""Frames of the plate's velocity history saved per Gurney run."""


def gurney(cfg: dict) -> list[dict]:
    """The Gurney slab (4 cm of Comp B, JWL with its energy, driving 1 cm of 4340 steel, lit at the
    charge's free back face): the plate's velocity at ``cfg["gurney"]["times"]`` by resolution (CPDI)
    and, at ``all_at`` cells, by interpolator; with artificial viscosity, CFL 0.3, ``pad`` 5 times the
    cells (the products escape from the back face at several km/s).

    Args:
        cfg: the study's settings.

    Returns:
        One row per run: interpolator, cells, status, the plate's velocity at each time (``None``
        after a breakdown), its ratio to Gurney's formula, and the history (``t``, ``v_plate``).
    """
    g = cfg["gurney"]
    runs = [("cpdi", n) for n in g["cells"]]
    if g["all_at"] is not None:
        runs += [(name, g["all_at"]) for name in jm.INTERPOLATORS if name != "cpdi"]
    rows = []
    for name, cells in runs:
        scene = jm.GurneySlab(cells=cells, pad=5 * cells)
        # the products escaping from the free back face set the step: max(c + |v|) is about 1.7 D
        steps = int(math.ceil(2.0 * float(scene.cj()["D"]) * g["t_end"] / (CFL * float(scene.h))))
        every = max(1, steps // GURNEY_FRAMES)
        t0 = time.perf_counter()
        sol = jm.simulate(
            scene,
            jm.INTERPOLATORS[name](),
            t_end=g["t_end"],
            cfl=CFL,
            max_steps=4 * steps,
            viscosity=jm.ArtificialViscosity(),
            saveat=jm.SaveAt(every=every, fields=("v",)),
            throw=False,
        )
        status, fail = run_status(sol)
        w = np.where(np.asarray(sol.body.region) == 1, np.asarray(sol.body.m), 0.0)
        ts = np.asarray(sol.ts)
        v = np.asarray(sol.history["v"][:, :, 0]) @ w / w.sum()
        keep = np.concatenate([[True], np.diff(ts) > 0])  # frames after t_end repeat the last state
        gurney_v = float(scene.gurney_velocity())
        row = dict(interpolator=name, cells=cells, status=status, failure=fail, gurney=gurney_v)
        for t in g["times"]:
            k = int(np.argmin(np.abs(ts - t)))
            ok = fail is None and abs(ts[k] - t) <= 0.02 * t
            row[f"v_{t:g}"] = float(v[k]) if ok else None
        row.update(
            t=ts[keep].tolist(),
            v_plate=v[keep].tolist(),
            mass_ratio=float(scene.mass_ratio),
            wall_s=time.perf_counter() - t0,
        )
        rows.append(row)
    return rows


def goals(table1: list[dict]) -> list[dict]:
    """The goals at 400 particles per 10 cm, for CPDI and MPQ with one artificial cell, each ``ppc``.

    Args:
        table1: the rows of ``by_interpolator``.

    Returns:
        One entry per goal and run: ``goal``, ``interpolator``, ``ppc``, ``value``, ``met`` (``False``
        where there is no value) and ``missing``: why ``value`` is ``None`` (``"broken down"``, or
        ``"not measured"`` for a run that finished without that measure: no wall plateau, a non-finite
        error), ``None`` where there is a value.
    """
    out = []
    for r in table1:
        if r["interpolator"] not in CONVERGENCE_NAMES or r["artificial_cells"] != 1:
            continue
        for goal, key, value in (
            ("F_max_rel < 2%", "F_max_rel", r["F_max_rel"]),
            ("|wall plateau p / (8/27 P_CJ) - 1| < 2%", "plateau_p", r["plateau_p"]),
        ):
            if value is not None and key == "plateau_p":
                value = abs(value - 1.0)
            met = value is not None and value < GOAL
            missing = None
            if value is None:
                missing = "broken down" if r["failure"] is not None else "not measured"
            row = dict(goal=goal, interpolator=r["interpolator"], ppc=r["ppc"], value=value, met=met)
            out.append(dict(row, missing=missing))
    return out


def _pct(x, signed: bool = False) -> str:
    return "-" if x is None else format(100.0 * x, "+.2f" if signed else ".2f") + "%"


def _markdown(result: dict) -> str:
    cfg = result["settings"]
    t1, conv, peaks = result["by_interpolator"], result["convergence"], result["peak_pressure"]
    front = cfg["D"] * cfg["t_end"]
    lines = [
        "# Planar detonation: jaxmpm study detonation",
        "",
        f"A slab of explosive on [0, {cfg['L']:g} m] lit at X = 0 against a wall, programmed burn of an "
        f"inert reactant into its products, CFL {CFL:g}, FLIP, default artificial viscosity. Gamma-law "
        f"products: gamma = {GAMMA:g}, D = {cfg['D']:g} m/s, P_CJ = {cfg['P_CJ']:.4g} Pa. Errors are "
        "against the exact CJ-Taylor wave, over the burnt particles more than 12 h behind the front "
        "(`scene.smooth`). A run that broke down is marked `broken down` with the quantity that failed and "
        "its step; none of its numbers is used anywhere.",
        "",
        f"## 1. F of the converted particles by interpolator (t = {cfg['t_end']:g} s, front at "
        f"{front * 100:.3g} cm)",
        "",
        "Each interpolator of the registry, without and with one layer of artificial cells at the free end, "
        "at 400 particles per 10 cm: one particle per cell, and two per cell on half the cells. F max / RMS "
        "and p RMS are relative errors over `scene.smooth` (p is the stress's, with the viscosity's q). At "
        "the wall the products are at rest, exactly F = 9/8 and p = 8/27 P_CJ: the columns give the mean "
        f"pressure of the burnt particles with X < {REST_FRACTION:g} D t (8/9) over 8/27 P_CJ, and the "
        "spread (max - min) / (9/8) of their F. A spread of a few percent with a mean close to 1 is an "
        "odd-even mode, particles of one cell alternating around the exact F, which the grid does not see.",
        "",
        "| interpolator | ppc | cells | AC | status | F max rel. | F RMS rel. | p RMS rel. "
        "| wall p / (8/27 P_CJ) | wall F spread / (9/8) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in t1:
        lines.append(
            f"| {r['interpolator']} | {r['ppc']} | {r['cells']} | {r['artificial_cells']} "
            f"| {status_cell(r)} "
            f"| {_pct(r['F_max_rel'])} | {_pct(r['F_rms_rel'])} | {_pct(r['p_rms_rel'])} "
            f"| {number(r['plateau_p'], '.4f')} | {_pct(r['plateau_F_spread'])} |"
        )
    same = _artificial_cells_agree(t1)
    if same is not None:
        lines += [
            "",
            f"With and without artificial cells, the {same} (interpolator, ppc) pairs that finished both "
            "ways agree to the last digit: the free end is unburnt explosive, at rest and without pressure "
            "until the front reaches it, so the artificial cells there change nothing before L / D."
            if same
            else "Artificial cells change the results: the free end moves before t.",
        ]
    lines += ["", "Goals (CPDI and MPQ with one artificial cell, 400 particles per 10 cm):", ""]
    for g in result["goals"]:
        value = g["missing"] if g["value"] is None else _pct(g["value"])
        lines.append(
            f"- {g['interpolator']}, ppc = {g['ppc']}: {g['goal']}: {value}, "
            f"**{'met' if g['met'] else 'not met'}**"
        )
    lines += [
        "",
        "## 2. Convergence away from the front",
        "",
        "CPDI and MPQ with one artificial cell, one particle per cell, refined at the same end time. The "
        "errors are measured 12 cells behind the front, so the region measured grows as h falls; the orders "
        "are the least-squares slope of log error against log h, and the finest pair's. A run that broke "
        "down is left out of the fit.",
        "",
        "| interpolator | cells per 10 cm | particles | status | F RMS rel. | p RMS rel. | wall s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in conv["rows"]:
        lines.append(
            f"| {r['interpolator']} | {r['cells_per_10cm']} | {r['particles']} | {status_cell(r)} "
            f"| {number(r['F_rms_rel'])} | {number(r['p_rms_rel'])} | {r['wall_s']:.1f} |"
        )
    lines += [
        "",
        "| interpolator | F RMS order (fit) | F RMS order (finest pair) | p RMS order (fit) "
        "| p RMS order (finest pair) |",
        "|---|---|---|---|---|",
    ]
    for o in conv["orders"]:
        lines.append(
            f"| {o['interpolator']} | {number(o['F_rms_rel_order_fit'], '.2f')} "
            f"| {number(o['F_rms_rel_order_finest'], '.2f')} | {number(o['p_rms_rel_order_fit'], '.2f')} "
            f"| {number(o['p_rms_rel_order_finest'], '.2f')} |"
        )
    resolutions = list(cfg["peak"])
    lines += [
        "",
        "## 3. Peak pressure against P_CJ by resolution and burn model",
        "",
        "MPQ with one artificial cell, one particle per cell, to 0.8 L / D. The peak is the largest EOS "
        "pressure `burn.pressure(rho, e, lambda)` (without the viscosity's q) over the particles and about "
        f"{FRAMES} saved frames; the table gives peak / P_CJ - 1. The time burn lights each particle as the "
        "front reaches it, the volume burn when it is compressed toward J_CJ, max the earlier of the two. "
        "Products: gamma-law (gamma = 3), and Comp B on the principal isentrope of its JWL row. A CJ "
        "detonation's products are at most at P_CJ: a negative entry is a burn that falls short of the CJ "
        "state at that resolution (Uintah's cell-based burn needed its JWL constants scaled by 1.014 to "
        "reach P_CJ in 1D), a positive one an overshoot at the front.",
        "",
        "| products | burn | "
        + " | ".join(f"{c} cells / 10 cm" for c in resolutions)
        + " | order (fit) | order (finest pair) |",
        "|---|---|" + "---|" * (len(resolutions) + 2),
    ]
    orders = {(o["explosive"], o["burn"]): o for o in result["peak_orders"]}
    for explosive in cfg["products"]:
        for burn in BURNS:
            cells = []
            for c in resolutions:
                r = next(
                    r
                    for r in peaks
                    if r["explosive"] == explosive and r["burn"] == burn and r["cells_per_10cm"] == c
                )
                if r["failure"] is not None:
                    cells.append(status_cell(r))
                elif r["peak"] is None:
                    cells.append("-")
                elif r["peak"] < UNLIT:
                    cells.append("never lit")
                elif r["peak"] < LIT:
                    cells.append(f"peak {r['peak']:.1e} P_CJ")
                else:
                    cells.append(_pct(r["excess"], signed=True))
            o = orders[(explosive, burn)]
            cells += [number(o["order_fit"], ".2f"), number(o["order_finest"], ".2f")]
            lines.append(f"| {explosive} | {burn} | " + " | ".join(cells) + " |")
    ok = [r for r in peaks if r["failure"] is None and r["peak"] is not None]
    lit = [r for r in ok if r["peak"] >= LIT]
    last = [r for r in lit if r["t_peak"] >= r["t_end"] * (1.0 - 1e-12)]
    lines += [
        "",
        f"The order is that of the deficit |peak / P_CJ - 1| against h, over the runs that finished with a "
        f"peak above {LIT:g} P_CJ. In {len(last)} of those {len(lit)} runs the peak is in the last frame: "
        "the pressure at the front is still rising when the run stops. The volume burn lights a particle by "
        "its compression alone, and the inert reactant has no pressure: only round-off compresses it, and "
        "the burn feeds that back (the products of a slightly compressed particle push on their "
        "neighbours), so lambda grows from round-off everywhere at once rather than behind a front. A peak "
        f"below {UNLIT:g} P_CJ is marked never lit, one below {LIT:g} P_CJ is that growth, not a "
        "detonation (its size given), and a run whose growth reaches ignition before t_end burns the whole "
        "slab at once: a spurious peak, or a breakdown. Under max the same growth runs ahead of the time "
        "burn's front.",
    ]
    lines += [
        "",
        f"Where the peak was, at {resolutions[-1]} cells per 10 cm: the front's place D t / L when it "
        "occurred and the particle's X / L.",
        "",
        "| products | burn | status | peak / P_CJ | D t / L | X / L | largest lambda at t_end | wall s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in peaks:
        if r["cells_per_10cm"] != resolutions[-1]:
            continue
        x_l = None if r["X_peak"] is None else r["X_peak"] / cfg["L"]
        lines.append(
            f"| {r['explosive']} | {r['burn']} | {status_cell(r)} | {number(r['peak'], '.4f')} "
            f"| {number(r['front_peak'], '.3f')} | {number(x_l, '.3f')} | {number(r['lambda_max'], '.3g')} "
            f"| {r['wall_s']:.1f} |"
        )
    lines += _gurney_markdown(result)
    lines += ["", f"Machine: {result['machine']}; total {result['wall_s']:.0f} s.", ""]
    return "\n".join(lines)


def _gurney_markdown(result: dict) -> list[str]:
    rows = result["gurney"]
    times = result["settings"]["gurney"]["times"]
    v_g = rows[0]["gurney"]
    lines = [
        "",
        "## 4. Explosive driving metal: the Gurney slab",
        "",
        "4 cm of Comp B (the JWL row with its energy, time burn) lit at its free back face drives 1 cm of "
        f"4340 steel (Mie-Grueneisen); M/C = {rows[0]['mass_ratio']:.4f}. Gurney's open-faced sandwich "
        f"with sqrt(2E) = 2.70 km/s gives {v_g:.0f} m/s (1356 m/s at the rounded M/C = 1.14), a model "
        "accurate to a few per cent. The table gives the plate's velocity (its momentum over its mass) at "
        "each time, and its ratio to Gurney's at the last.",
        "",
        "| interpolator | cells | status | "
        + " | ".join(f"v at {1e6 * t:g} us (m/s)" for t in times)
        + " | last / Gurney |",
        "|---|---|---|" + "---|" * len(times) + "---|",
    ]
    for r in rows:
        last = r[f"v_{times[-1]:g}"]
        cells = " | ".join(number(r[f"v_{t:g}"], ".1f") for t in times)
        ratio = None if last is None else last / r["gurney"]
        lines.append(
            f"| {r['interpolator']} | {r['cells']} | {status_cell(r)} | {cells} | {number(ratio, '.4f')} |"
        )
    finished = [r for r in rows if r[f"v_{times[-1]:g}"] is not None and r[f"v_{times[-2]:g}"] is not None]
    if finished and all(r[f"v_{times[-1]:g}"] > r[f"v_{times[-2]:g}"] for r in finished):
        lines += [
            "",
            "The plate still gains a little at the last time: the products behind it keep expanding, and "
            "Gurney's formula is their full expansion.",
        ]
    return lines


def _artificial_cells_agree(rows: list[dict]) -> int | bool | None:
    """How many pairs (interpolator, ppc) that finished with 0 and 1 artificial cells have the same ``F``
    (``False`` if one pair differs, ``None`` if no pair finished both ways)."""
    pairs = 0
    for r in rows:
        if r["artificial_cells"] != 0 or r["failure"] is not None:
            continue
        other = next(
            o
            for o in rows
            if o["interpolator"] == r["interpolator"] and o["ppc"] == r["ppc"] and o["artificial_cells"] == 1
        )
        if other["failure"] is not None:
            continue
        if other["F"] != r["F"]:
            return False
        pairs += 1
    return pairs or None


def _save(fig, path: pathlib.Path) -> pathlib.Path:
    fig.tight_layout()
    return OUTPUTS.figure(fig, path, dpi=130)


def _figures(result: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    from matplotlib.ticker import NullLocator

    from ..plotting import figure

    cfg = result["settings"]
    L = cfg["L"]
    paths = []
    t1 = result["by_interpolator"]
    names, cases = list(cfg["names"]), [tuple(c) for c in cfg["cases"]]
    fig = figure(figsize=(3.2 * len(names), 2.9 * len(cases)))
    axes = fig.subplots(len(cases), len(names), sharex=True, sharey=True, squeeze=False)
    ex = result["exact"]
    for i, (ppc, cells) in enumerate(cases):
        for j, name in enumerate(names):
            ax = axes[i][j]
            ax.plot(np.asarray(ex["X"]) / L, ex["F"], "k-", lw=1.0, label="exact")
            broken = []
            for ac, style in (
                (0, dict(marker="o", ms=2.5, mfc="none", mew=0.5, color="tab:red")),
                (1, dict(marker=".", ms=1.5, color="tab:blue")),
            ):
                r = next(
                    r
                    for r in t1
                    if r["interpolator"] == name and r["ppc"] == ppc and r["artificial_cells"] == ac
                )
                if r["failure"] is not None:
                    broken.append(f"AC {ac}: broken down at step {r['failure']['step']}")
                    continue
                ax.plot(np.asarray(r["X"]) / L, r["F"], ls="none", label=f"AC {ac}", **style)
            if broken:
                ax.text(0.03, 0.03, "\n".join(broken), transform=ax.transAxes, fontsize=6, va="bottom")
            ax.set_title(f"{name}, ppc {ppc}, {cells} cells", fontsize=9)
            ax.grid(alpha=0.3)
            if i == len(cases) - 1:
                ax.set_xlabel("X / L")
            if j == 0:
                ax.set_ylabel("F")
    axes[0][0].legend(fontsize=7)
    axes[0][0].set_ylim(0.6, 1.3)
    fig.suptitle(f"Detonation, gamma = {GAMMA:g}, at a wall: F at t = {cfg['t_end']:g} s")
    paths.append(_save(fig, outdir / "F_by_interpolator.png"))

    fig = figure(figsize=(9, 3.8))
    axes = fig.subplots(1, 2)
    conv = result["convergence"]
    for ax, q, label in zip(axes, ("F_rms_rel", "p_rms_rel"), ("F", "p")):
        for o in conv["orders"]:
            mine = [r for r in conv["rows"] if r["interpolator"] == o["interpolator"]]
            rr = [r for r in mine if r[q] is not None]
            left_out = [str(r["cells"]) for r in mine if r[q] is None]
            note = f"; not shown, broke down: {', '.join(left_out)} cells" if left_out else ""
            order = o[f"{q}_order_fit"]
            ax.loglog(
                [L / r["cells"] * 1e3 for r in rr],
                [r[q] for r in rr],
                "o-",
                label=f"{o['interpolator']} (order {number(order, '.2f')}{note})",
            )
        hs = [L / c * 1e3 for c in sorted({r["cells"] for r in conv["rows"]})]
        ax.set_xticks(hs, [f"{h:.3g}" for h in hs])
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel("h (mm)")
        ax.set_ylabel(f"RMS relative {label} error")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle("Away from the front (12 h behind it), one artificial cell, ppc 1")
    paths.append(_save(fig, outdir / "convergence.png"))

    products = list(cfg["products"])
    fig = figure(figsize=(4.5 * len(products), 3.8))
    axes = fig.subplots(1, len(products), sharey=True, squeeze=False)[0]
    for ax, explosive in zip(axes, products):
        broken = []
        for burn in BURNS:
            rr = [
                r
                for r in result["peak_pressure"]
                if r["explosive"] == explosive and r["burn"] == burn and r["peak"] is not None
            ]
            ax.semilogx([r["cells_per_10cm"] for r in rr], [r["peak"] for r in rr], "o-", label=burn)
            broken += [
                f"{burn}, {r['cells_per_10cm']}: broken down at step {r['failure']['step']}"
                for r in result["peak_pressure"]
                if r["explosive"] == explosive and r["burn"] == burn and r["failure"] is not None
            ]
        if broken:
            ax.text(0.03, 0.5, "\n".join(broken), transform=ax.transAxes, fontsize=7, va="center")
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_xticks(list(cfg["peak"]), [str(c) for c in cfg["peak"]])
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel("cells per 10 cm")
        ax.set_title(explosive, fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, title="burn")
    axes[0].set_ylabel("peak EOS pressure / P_CJ")
    fig.suptitle("Peak pressure, MPQ with one artificial cell, ppc 1")
    paths.append(_save(fig, outdir / "peak_pressure.png"))
    return paths


CSV_FIELDS = (
    "table",
    "interpolator",
    "explosive",
    "burn",
    "ppc",
    "cells",
    "cells_per_10cm",
    "artificial_cells",
    "steps",
    "wall_s",
    "status",
    *ERROR_KEYS,
    "peak",
    "excess",
)
"""The columns of ``detonation_runs.csv``: one line per table entry (a run two tables share is on two)."""


def _csv(result: dict, path: pathlib.Path) -> None:
    entries = [("by_interpolator", r) for r in result["by_interpolator"]]
    entries += [("convergence", r) for r in result["convergence"]["rows"]]
    entries += [("peak_pressure", r) for r in result["peak_pressure"]]
    lines = []
    for table, r in entries:
        line = {k: r.get(k) for k in CSV_FIELDS}
        line.update(table=table, explosive=r.get("explosive", "gamma-law"), burn=r.get("burn", "time"))
        lines.append(line)
    OUTPUTS.csv(path, lines, CSV_FIELDS)


def main(out: str, small: bool = False) -> dict:
    """Run the study; write ``detonation.md``, ``detonation.json``, ``detonation_runs.csv`` and three
    figures to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: the reduced version (``settings(small=True)``).

    Returns:
        ``settings``, ``by_interpolator`` (table 1's rows), ``goals``, ``convergence`` (rows and
        orders), ``peak_pressure`` (table 3's rows), ``peak_orders``, ``gurney`` (table 4's rows),
        ``exact`` (the exact F at ``t_end``), ``machine`` and ``wall_s``.

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("detonation")
    t0 = time.perf_counter()
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    cfg = settings(small)
    scene = jm.Detonation(L=cfg["L"], gamma=GAMMA)
    cj = scene.cj()
    X = jnp.linspace(0.0, cfg["L"], 801)
    F_exact = jax.vmap(scene.exact, in_axes=(0, None))(X[:, None], cfg["t_end"])["F"][:, 0, 0]
    cache: dict = {}
    table1 = by_interpolator(cfg, cache)
    result = dict(
        settings=dict(cfg, D=float(cj["D"]), P_CJ=float(cj["P_CJ"]), small=small),
        by_interpolator=table1,
        goals=goals(table1),
        convergence=convergence(cfg, cache),
        peak_pressure=peak_pressure(cfg, cache),
        gurney=gurney(cfg),
        exact=dict(X=np.asarray(X).tolist(), F=np.asarray(F_exact).tolist()),
        machine=machine(),
    )
    result["peak_orders"] = peak_orders(result["peak_pressure"])
    result["wall_s"] = time.perf_counter() - t0
    text = _markdown(result)
    OUTPUTS.text(outdir / "detonation.md", text)
    OUTPUTS.text(outdir / "detonation.json", dumps(result, indent=1, default=str))
    _csv(result, outdir / "detonation_runs.csv")
    paths = _figures(result, outdir)
    print(text)
    print(
        "wrote " + ", ".join(str(p) for p in [outdir / "detonation.md", outdir / "detonation.json", *paths])
    )
    return result
