"""The round gas charges against their 1D radial reference: how far each interpolator and remedy runs,
and how smooth and how accurate it stays.

The scenes are ``jaxmpm.BlastDisk`` (2D, a quarter with symmetry planes) at pressure ratios 1.5, 10
and 100 (``P0 = ratio p_atm``, ``p_atm`` = 1 bar, 1.5 kg/m^3 of gas, gamma 1.4, radius 0.5 m) and
``jaxmpm.BlastSphere`` (3D, an octant) at 10. Every run goes to two sound transits of the radius,
``2 radius / c0``, with ``cfl`` 0.3, two particles per cell and axis, 32 cells across the radius of
the disk and 16 of the sphere. The configurations are every interpolator of ``jaxmpm.INTERPOLATORS``
plain (FLIP, USL, no remedy), and CPDI, MPQ and CPDI2 with each remedy: MUSL, APIC, J-bar
(``volume_average="node"``), a shear viscosity (``c_shear`` 0.5, no bulk terms) and APIC with that
shear viscosity.

Each run is measured at its final state against the reference (``scene.reference``) at that time, at
every particle's reference radius ``R``: the radial velocity's relative L1 error ``sum |v_r - v_ref| /
sum |v_ref|`` and the density's, the outer ring's radius error (the particles within 0.6 h of the
charge's surface, ``max |r / r_ref - 1|``), the angular spread of ``v_r`` (``jaxmpm.metrics.
angular_spread``, detrended, one bin per cell, its max), the largest spurious rotation
(``spurious_rotation``) and the folded domains (``folded_domains``). A run that breaks down stops at its
last good state: it is reported as broken down, with when (a fraction of two transits) and why
(``jaxmpm.status.describe``), and its measures are those of that state, marked so.

Then the best CPDI configuration at 10:1, APIC with shear viscosity 0.5, refined (16, 32 and 64 cells
across the radius) for the observed order of its errors, and CPDI2 (the tracked-corner method) with
the same remedy, refined the same way. Last, the planar analogue of the disk, the 1D slab of the same
gas as thick as the radius (``make_slab``), with CPDI under FLIP and APIC at 16 to 128 cells against
the 1D reference: the error the method makes in 1D at the disk's resolution.

``jaxmpm study blast --out DIR`` writes ``table.md``, ``blast.json`` and the figures
``radial_velocity.png`` and ``domains.png``.
"""

from __future__ import annotations

import math
import pathlib
import time

import jax
import numpy as np

import jaxmpm as jm
from jaxmpm import metrics
from jaxmpm._json import dumps

from ._output import Files
from ._runtime import machine, require_float64

CFL = 0.3
"""The Courant number of every run."""
P_ATM = 1.0e5
"""The atmosphere's pressure (Pa); the charge is at ``ratio P_ATM``."""
TRANSITS = 2.0
"""Every run's end time, in sound transits of the radius."""
RING = 0.6
"""The outer ring: the particles whose reference radius is within ``RING h`` of the charge's surface."""
SHEAR = 0.5
"""The shear viscosity's coefficient (``ArtificialViscosity.c_shear``) of the remedies that have one."""
REMEDIES = {
    "plain": dict(),
    "MUSL": dict(ordering="musl"),
    "APIC": dict(transfer="apic"),
    "J-bar": dict(volume_average="node"),
    f"shear {SHEAR:g}": dict(shear=SHEAR),
    f"APIC + shear {SHEAR:g}": dict(transfer="apic", shear=SHEAR),
}
"""Each remedy's settings: ``transfer`` (a key of ``jaxmpm.TRANSFERS``, default FLIP), ``ordering``
(default USL), ``volume_average`` (J-bar) and ``shear`` (``c_shear`` of a viscosity without bulk terms)."""
REMEDIED = ("cpdi", "mpq", "cpdi2")
"""The interpolators run with every remedy (the others plain only)."""
BEST = ("cpdi", f"APIC + shear {SHEAR:g}")
"""The configuration refined (``refinement``)."""
TRACKED = ("cpdi2", BEST[1])
"""The tracked-corner configuration refined (``refinement_tracked``)."""
PAD_RADII = {("disk", 1.5): 2.5, ("disk", 10.0): 2.5, ("disk", 100.0): 6.0, ("sphere", 10.0): 2.0}
"""The grid beyond the charge, in radii, of each scene: the reference's free surface reaches 1.26, 3.0
and 4.9 radii for the disk at 1.5, 10 and 100 by two transits, and 2.3 for the sphere at 10. The grid
ends at ``1 + pad`` radii: a particle that runs that far ahead stops the run (``LEFT_GRID``)."""
SLAB_PAD = {1.5: 2.5, 10.0: 4.5, 100.0: 7.0}
"""The grid beyond the slab, in thicknesses, at each ratio: the reference's free surface reaches 1.3, 3.8
and 5.8 thicknesses by two transits (the planar charge expands further than the round ones)."""
SLAB_CONFIGS = {("cpdi", "plain"): f"shear {SHEAR:g}", ("cpdi", "APIC"): f"APIC + shear {SHEAR:g}"}
"""The configurations of the 1D slab (``slab``), FLIP and APIC, each with the disk's remedy it is the 1D
form of: the shear viscosity is zero in 1D (the deviator of a 1 x 1 strain rate vanishes), and CPDI2
is CPDI there while the domains stay contiguous."""
FULL = dict(
    cases=(("disk", 1.5, 32), ("disk", 10.0, 32), ("disk", 100.0, 32), ("sphere", 10.0, 16)),
    configs=None,
    refinement=(16, 32, 64),
    slab=dict(ratios=(1.5, 10.0, 100.0), cells=(16, 32, 64, 128)),
)
SMALL = dict(
    cases=(("disk", 10.0, 8),),
    configs=(
        ("spq", "plain"),
        ("cpdi", "plain"),
        BEST,
        ("mpq", "plain"),
        ("mpq", BEST[1]),
        TRACKED,
    ),
    refinement=(4, 8),
    slab=dict(ratios=(10.0,), cells=(4, 8)),
)
OUTPUTS = Files("table.md", "blast.json", "radial_velocity.png", "domains.png")
"""The files the study writes."""
MEASURES = ("v_r_L1", "rho_L1", "ring_radius_error", "spread_max", "rotation_max", "folded")
"""The numbers of a row, all measured at the run's final state (its last good one after a breakdown)."""


def configurations(small: bool = False) -> tuple[tuple[str, str], ...]:
    """The study's configurations, ``(interpolator, remedy)``.

    Args:
        small: the reduced set (SPQ, CPDI and MPQ plain, CPDI, MPQ and CPDI2 with APIC and shear).

    Returns:
        Every interpolator of ``jaxmpm.INTERPOLATORS`` plain, then those of ``REMEDIED`` with each remedy of
        ``REMEDIES`` (the full study); ``SMALL["configs"]`` (the reduced one).
    """
    if small:
        return SMALL["configs"]
    out = [(name, "plain") for name in jm.INTERPOLATORS]
    out += [(name, remedy) for name in REMEDIED for remedy in REMEDIES if remedy != "plain"]
    return tuple(out)


def settings(small: bool = False) -> dict:
    """The study's sizes.

    Args:
        small: the reduced version (the disk at 10:1 only, 8 cells across the radius, six
            configurations, refinements at 4 and 8 cells, the slab at 10:1 at 4 and 8 cells).

    Returns:
        ``dict(cases, configs, refinement, slab)``: the scenes as ``(kind, ratio, cells)`` (kind
        ``"disk"`` or ``"sphere"``, cells across the radius), the configurations (``configurations``),
        the cells of the refinements of ``BEST`` and ``TRACKED`` (on the disk at 10:1) and the 1D
        slab's ``ratios`` and ``cells`` (``slab``).
    """
    out = dict(SMALL if small else FULL)
    out["configs"] = configurations(small)
    return out


def make_scene(kind: str, ratio: float, cells: int):
    """The charge of the study.

    Args:
        kind: ``"disk"`` (``BlastDisk``) or ``"sphere"`` (``BlastSphere``).
        ratio: ``P0 / p_atm``.
        cells: cells across the radius.

    Returns:
        The scene, two particles per cell and axis, its grid ``PAD_RADII`` radii beyond the charge.
    """
    cls = jm.BlastDisk if kind == "disk" else jm.BlastSphere
    pad = int(round(PAD_RADII[(kind, float(ratio))] * cells))
    return cls(P0=ratio * P_ATM, p_atm=P_ATM, cells=cells, ppc=2, pad=pad)


def max_steps(cells: int) -> int:
    """The scan's bound: ten times the steps of two transits at the charge's initial sound speed.

    The free surface moves at a few times ``c0``, which shortens the step: the runs that ran through
    took 2 times the estimate at 10:1 and 3.4 times at 100:1 (measured at 32 cells). A run that needs
    more than the bound stops with ``MAX_STEPS``, reported as a breakdown. One bound per resolution,
    so that the scenes of equal size share a compiled program.

    Args:
        cells: cells across the radius.

    Returns:
        ``10 TRANSITS cells / CFL``.
    """
    return int(math.ceil(10.0 * TRANSITS * cells / CFL))


def run_options(remedy: str) -> dict:
    """The keyword arguments of ``jaxmpm.simulate`` for a remedy.

    Args:
        remedy: a key of ``REMEDIES``.

    Returns:
        ``transfer``, ``ordering``, ``volume_average`` and ``viscosity``.
    """
    r = REMEDIES[remedy]
    shear = r.get("shear")
    return dict(
        transfer=jm.TRANSFERS[r.get("transfer", "flip")](),
        ordering=r.get("ordering", "usl"),
        volume_average=r.get("volume_average"),
        viscosity=None if shear is None else jm.ArtificialViscosity(c_quad=0.0, c_lin=0.0, c_shear=shear),
    )


def _finite(x) -> float | None:
    """A finite float, or ``None`` (JSON has no NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None


class References:
    """The radial references of the study's charges and of their 1D slabs, solved once per charge and time."""

    def __init__(self):
        self._done: dict = {}

    def __call__(self, scene, t: float):
        """The reference of ``scene`` at time ``t``.

        Args:
            scene: the charge.
            t: the time (> 0).

        Returns:
            The ``RadialSolution`` at ``[t]``.
        """
        return self._solved((scene.dim, float(scene.P0)), t, scene.reference)

    def slab(self, slab, disk, t: float):
        """The 1D reference of ``make_slab``'s slab at time ``t`` (``jaxmpm.reference.gas_radial`` with
        ``dim=1``, 1,600 cells, the viscosity on).

        Args:
            slab: the ``GasSlab``.
            disk: the disk it is the analogue of (its radius is the slab's thickness).
            t: the time (> 0).

        Returns:
            The ``RadialSolution`` at ``[t]``.
        """
        params = (slab.P0, slab.gamma, slab.p_atm, slab.rho0, disk.radius)

        def solve(ts):
            return jm.reference.gas_radial(*params, 1, ts, cells=1600, viscosity=True)

        return self._solved(("slab", *(float(p) for p in params)), t, solve)

    def _solved(self, what: tuple, t: float, solve):
        """``solve(np.array([t]))``, solved once per ``what`` and ``t`` (to 12 digits)."""
        key = (*what, float(f"{t:.12g}"))
        if key not in self._done:
            self._done[key] = solve(np.array([t]))
        return self._done[key]


def measure(scene, sol, reference) -> dict:
    """A run's measures at its final state against the reference at that time.

    Args:
        scene: the charge.
        sol: the run's ``Solution`` (its last good state after a breakdown).
        reference: the ``RadialSolution`` at the state's time.

    Returns:
        ``MEASURES`` (``None`` for a relative error whose reference is zero, at ``t = 0``), and the
        profile ``R``, ``v_r``, the domains' ``corners`` and the reference's ``R_line``, ``v_line`` and
        ``r_free`` for the figures.
    """
    st, body = sol.state, sol.body
    centre = scene.centre
    R = np.asarray(metrics.reference_radius(body, centre))
    at = reference.at(R)
    v_ref, rho_ref, r_ref = (np.asarray(at[k][0]) for k in ("v", "rho", "r"))
    # after a breakdown the last good state, measured: the row says which state it is
    v_r = np.asarray(metrics.radial_velocity(st, body, centre, allow_broken=True))
    rho = np.asarray(metrics.density(st, body, allow_broken=True))
    r = np.linalg.norm(np.asarray(st.x) - np.asarray(centre)[None, :], axis=1)
    ring = R > float(scene.radius) - RING * float(scene.h)
    spread = metrics.angular_spread(st, body, centre, bins=scene.cells, detrend=True, allow_broken=True)
    corners = metrics.domain_corners(st, body, allow_broken=True)
    v_norm = np.sum(np.abs(v_ref))
    R_line = np.linspace(0.0, float(scene.radius), 401)
    return dict(
        v_r_L1=_finite(np.sum(np.abs(v_r - v_ref)) / v_norm) if v_norm > 0 else None,
        rho_L1=_finite(np.sum(np.abs(rho - rho_ref)) / np.sum(np.abs(rho_ref))),
        ring_radius_error=_finite(np.max(np.abs(r[ring] / r_ref[ring] - 1.0))),
        spread_max=_finite(spread["max"]),
        rotation_max=_finite(metrics.spurious_rotation(st, body, allow_broken=True)["max"]),
        folded=int(metrics.folded_domains(corners, body)),
        profile=dict(
            R=R,
            v_r=v_r,
            corners=np.asarray(corners),
            R_line=R_line,
            v_line=np.asarray(reference.at(R_line)["v"][0]),
            r_free=float(reference.r_free[0]),
        ),
    )


def _run(scene, cells: int, interpolator: str, remedy: str, t_end: float):
    """A run of the study to ``t_end`` (``CFL``, ``max_steps(cells)``, the remedy's options): the
    ``Solution``, its failure (``Solution.failure`` with the fraction of ``t_end`` reached, or ``None``)
    and the wall time, compile included."""
    t0 = time.perf_counter()
    sol = jm.simulate(
        scene,
        jm.INTERPOLATORS[interpolator](),
        t_end=t_end,
        cfl=CFL,
        max_steps=max_steps(cells),
        throw=False,
        **run_options(remedy),
    )
    jax.block_until_ready(sol.state)
    wall = time.perf_counter() - t0
    fail = sol.failure()
    if fail is not None:
        fail = dict(fail, fraction=float(sol.state.t) / t_end)
    return sol, fail, wall


def run_row(kind: str, ratio: float, cells: int, interpolator: str, remedy: str, refs: References) -> dict:
    """One run to two transits and its measures.

    Args:
        kind: ``"disk"`` or ``"sphere"``.
        ratio: ``P0 / p_atm``.
        cells: cells across the radius.
        interpolator: a key of ``jaxmpm.INTERPOLATORS``.
        remedy: a key of ``REMEDIES``.
        refs: the references (filled).

    Returns:
        The row: the scene (``kind``, ``dim``, ``ratio``, ``cells``, ``pad``, ``particles``), the
        configuration, ``steps``, ``t``, ``fraction`` (of two transits), ``status`` (the bitmask, 0 for a
        run that ran through), ``finished``, ``failure`` (``Solution.failure``, with the fraction, or
        ``None``), ``measured_at`` (``"end"`` or ``"last good state"``), the numbers of ``MEASURES``, the
        wall time (compile included) and ``profile`` (``measure``'s, for the figures).
    """
    scene = make_scene(kind, ratio, cells)
    t_end = TRANSITS * float(scene.transit_time)
    sol, fail, wall = _run(scene, cells, interpolator, remedy, t_end)
    st = sol.state
    t = float(st.t)
    row = dict(
        kind=kind,
        dim=scene.dim,
        ratio=float(ratio),
        cells=cells,
        pad=scene.pad,
        particles=int(sol.body.n),
        interpolator=interpolator,
        remedy=remedy,
        steps=int(st.step),
        t=t,
        t_end=t_end,
        fraction=t / t_end,
        status=int(st.status),
        finished=fail is None,
        failure=fail,
        measured_at="end" if fail is None else "last good state",
    )
    row.update(measure(scene, sol, refs(scene, t)))
    row["wall_s"] = wall
    return row


def scene_info(kind: str, ratio: float, cells: int, refs: References) -> dict:
    """A scene's sizes and its reference's free surface at two transits.

    Args:
        kind: ``"disk"`` or ``"sphere"``.
        ratio: ``P0 / p_atm``.
        cells: cells across the radius.
        refs: the references (filled).

    Returns:
        ``kind``, ``ratio``, ``cells``, ``pad``, ``t_end``, ``c0``, ``grid_radii`` (the grid's extent
        over the radius) and ``r_free_radii`` (the reference's free surface at ``t_end`` over the radius).
    """
    scene = make_scene(kind, ratio, cells)
    t_end = TRANSITS * float(scene.transit_time)
    radius = float(scene.radius)
    return dict(
        kind=kind,
        ratio=float(ratio),
        cells=cells,
        pad=scene.pad,
        t_end=t_end,
        c0=float(scene.c0),
        grid_radii=(cells + scene.pad) * float(scene.h) / radius,
        r_free_radii=float(refs(scene, t_end).r_free[0]) / radius,
    )


def observed_orders(h, e) -> tuple[float | None, list[float | None]]:
    """Observed orders of ``e`` against ``h``.

    Args:
        h: the grid spacings, coarse to fine.
        e: the errors (``None`` for one not usable: left out).

    Returns:
        ``(fit, pairs)``: the least-squares slope of ``log e`` on ``log h`` (``None`` with fewer than two
        usable errors) and the order of each successive pair (``None`` where either is not usable).
    """
    h = np.asarray(h, dtype=float)
    e = np.asarray([np.nan if v is None else v for v in e], dtype=float)
    ok = np.isfinite(e) & (e > 0)
    fit = float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 2 else None
    pairs = [
        float(np.log(e[k] / e[k + 1]) / np.log(h[k] / h[k + 1])) if ok[k] and ok[k + 1] else None
        for k in range(len(e) - 1)
    ]
    return fit, pairs


def refinement(cells_list, rows: list[dict], refs: References, config: tuple[str, str] = BEST) -> dict:
    """A configuration on the disk at 10:1, refined.

    Args:
        cells_list: cells across the radius, coarse to fine.
        rows: the study's rows (a run already done is reused).
        refs: the references (filled).
        config: ``(interpolator, remedy)``: ``BEST`` or ``TRACKED``.

    Returns:
        ``dict(rows, orders)``: one row per resolution (``run_row``'s) and, per measure of ``v_r_L1``,
        ``rho_L1`` and ``ring_radius_error``, ``{measure}_order_fit`` and ``{measure}_order_pairs``
        over the runs that ran through.
    """
    out = []
    for cells in cells_list:
        done = [
            r
            for r in rows
            if (r["kind"], r["ratio"], r["cells"], r["interpolator"], r["remedy"])
            == ("disk", 10.0, cells, *config)
        ]
        out.append(done[0] if done else run_row("disk", 10.0, cells, *config, refs))
    h = [1.0 / r["cells"] for r in out]
    orders = {}
    for q in ("v_r_L1", "rho_L1", "ring_radius_error"):
        orders[f"{q}_order_fit"], orders[f"{q}_order_pairs"] = observed_orders(
            h, [r[q] if r["finished"] else None for r in out]
        )
    return dict(rows=out, orders=orders)


def make_slab(ratio: float, cells: int):
    """The planar analogue of the disk: ``jaxmpm.GasSlab`` of the disk's gas, as thick as its radius,
    with its grid spacing and particles per cell (a wall at 0, the slab's plane of symmetry).

    Args:
        ratio: ``P0 / p_atm``.
        cells: cells across the thickness.

    Returns:
        ``(slab, disk)``: the slab, ``SLAB_PAD[ratio]`` thicknesses of grid beyond it, and the disk it
        is the analogue of (``make_scene("disk", ratio, cells)``).
    """
    disk = make_scene("disk", ratio, cells)
    slab = jm.GasSlab(
        P0=disk.P0,
        gamma=disk.gamma,
        p_atm=disk.p_atm,
        rho0=disk.rho0,
        h=disk.h,
        cells=cells,
        ppc=disk.ppc,
        pad=int(round(SLAB_PAD[float(ratio)] * cells)),
    )
    return slab, disk


def slab_row(
    ratio: float, cells: int, interpolator: str, remedy: str, refs: References | None = None
) -> dict:
    """The 1D slab (``make_slab``) run as the disk is (to two transits of its thickness, ``CFL``,
    ``max_steps``), measured against the 1D reference (``jaxmpm.reference.gas_radial`` with ``dim=1``)
    as the disk is: ``v_L1`` and ``rho_L1`` (relative L1 errors over the particles),
    ``ring_radius_error`` (the particles within ``RING h`` of the surface, ``max |x / x_ref - 1|``)
    and ``outer`` (the outermost particle's ``x / x_ref - 1``, signed: > 0 ahead of the reference).

    Args:
        ratio: ``P0 / p_atm``.
        cells: cells across the thickness.
        interpolator: a key of ``jaxmpm.INTERPOLATORS``.
        remedy: a key of ``REMEDIES``.
        refs: the ``References`` to take the reference from (solved once per slab and time), or
            ``None`` for a reference of this row alone.

    Returns:
        The row: ``ratio``, ``cells``, ``interpolator``, ``remedy``, ``steps``, ``t``, ``fraction``,
        ``status``, ``finished``, ``failure`` (as ``run_row``'s), the measures (of the last good state
        after a breakdown) and ``wall_s``.
    """
    slab, disk = make_slab(ratio, cells)
    t_end = TRANSITS * float(disk.transit_time)
    sol, fail, wall = _run(slab, cells, interpolator, remedy, t_end)
    st = sol.state
    t = float(st.t)
    ref = (References() if refs is None else refs).slab(slab, disk, t)
    X = np.asarray(sol.body.X)[:, 0]
    at = ref.at(X)
    v_ref, rho_ref, x_ref = (np.asarray(at[k][0]) for k in ("v", "rho", "r"))
    x, v = np.asarray(st.x)[:, 0], np.asarray(st.v)[:, 0]
    rho = float(slab.rho0) / np.asarray(st.F)[:, 0, 0]
    ring = X > float(disk.radius) - RING * float(slab.h)
    v_norm = np.sum(np.abs(v_ref))
    return dict(
        ratio=float(ratio),
        cells=cells,
        interpolator=interpolator,
        remedy=remedy,
        steps=int(st.step),
        t=t,
        fraction=t / t_end,
        status=int(st.status),
        finished=fail is None,
        failure=fail,
        v_L1=_finite(np.sum(np.abs(v - v_ref)) / v_norm) if v_norm > 0 else None,
        rho_L1=_finite(np.sum(np.abs(rho - rho_ref)) / np.sum(np.abs(rho_ref))),
        ring_radius_error=_finite(np.max(np.abs(x[ring] / x_ref[ring] - 1.0))),
        outer=_finite(x[-1] / x_ref[-1] - 1.0),
        wall_s=wall,
    )


def slab(ratios, cells_list, refs: References | None = None) -> dict:
    """The 1D slab of each ratio with each configuration of ``SLAB_CONFIGS``, refined: what the same
    method does in 1D at the disk's resolution.

    Args:
        ratios: pressure ratios.
        cells_list: cells across the thickness, coarse to fine.
        refs: the ``References`` the rows share (a new one if ``None``).

    Returns:
        ``dict(rows, orders)``: the rows (``slab_row``'s), and per ``"{ratio}/{interpolator} {remedy}"``
        the observed orders of ``v_L1`` and ``ring_radius_error`` (``{measure}_order_fit`` and
        ``{measure}_order_pairs``, over the runs that ran through).
    """
    refs = References() if refs is None else refs
    rows, orders = [], {}
    for ratio in ratios:
        for config in SLAB_CONFIGS:
            mine = [slab_row(ratio, cells, *config, refs=refs) for cells in cells_list]
            rows += mine
            h = [1.0 / r["cells"] for r in mine]
            o = {}
            for q in ("v_L1", "ring_radius_error"):
                o[f"{q}_order_fit"], o[f"{q}_order_pairs"] = observed_orders(
                    h, [r[q] if r["finished"] else None for r in mine]
                )
            orders[f"{float(ratio):g}/{config[0]} {config[1]}"] = o
    return dict(rows=rows, orders=orders)


def best(rows: list[dict], interpolator: str, kind: str = "disk", ratio: float = 10.0) -> dict | None:
    """The best configuration of an interpolator on a scene: one that ran through with the smallest
    ``v_r`` L1 error, else the one that broke down latest.

    Args:
        rows: the study's rows.
        interpolator: the interpolator.
        kind: the scene's kind.
        ratio: its pressure ratio.

    Returns:
        The row, or ``None`` where the interpolator has none on that scene.
    """
    mine = [r for r in rows if (r["interpolator"], r["kind"], r["ratio"]) == (interpolator, kind, ratio)]
    if not mine:
        return None

    def key(r):
        err = r["v_r_L1"] if r["v_r_L1"] is not None else math.inf
        return (not r["finished"], -r["fraction"], err)

    return min(mine, key=key)


def _num(x, fmt: str = ".3f") -> str:
    return "-" if x is None else format(x, fmt)


def short_failure(fail: dict) -> str:
    """A breakdown in a few words: when (a fraction of two transits) and what failed.

    Args:
        fail: a row's ``failure``.

    Returns:
        E.g. ``"broken down at 0.89 (step 380): F <= 0"``.
    """
    what = ", ".join(q.split(" (")[0] for q in fail["quantities"])
    return f"broken down at {fail['fraction']:.2f} (step {fail['step']}): {what}"


def status_cell(r: dict) -> str:
    """A row's status in the table: ``ran through``, or ``**broken down** ...`` (``short_failure``).

    Args:
        r: a row.

    Returns:
        The cell's text.
    """
    return "ran through" if r["finished"] else "**" + short_failure(r["failure"]) + "**"


def _measure_cell(r: dict, key: str, fmt: str) -> str:
    """A measure; a broken-down run's (of its last good state) in italics with a dagger."""
    text = _num(r[key], fmt) if key != "folded" else str(r[key])
    return text if r["finished"] or text == "-" else f"*{text}*&dagger;"


def _title(kind: str, ratio: float) -> str:
    return f"{'Disk (2D quarter)' if kind == 'disk' else 'Sphere (3D octant)'} at {ratio:g}:1"


def _markdown(result: dict) -> str:
    rows, info = result["rows"], result["scenes"]
    lines = [
        "# Round gas charges against the radial reference: jaxmpm study blast",
        "",
        f"Gas (gamma 1.4, 1.5 kg/m^3) at P0 = ratio x {P_ATM / 1e5:g} bar in a charge of radius 0.5 m, "
        f"expanding against {P_ATM / 1e5:g} bar, to {TRANSITS:g} sound transits of the radius "
        f"(2 radius / c0), CFL {CFL:g}, 2 particles per cell and axis. Plain is FLIP with USL and no "
        f'remedy; J-bar is `volume_average="node"`; shear {SHEAR:g} is `ArtificialViscosity(c_quad=0, '
        f"c_lin=0, c_shear={SHEAR:g})`. Measures at the final state against the 1D radial reference "
        "(`scene.reference`, 1600 cells, with its viscosity) at that time, at each particle's reference "
        "radius R: v_r and rho L1 are relative L1 errors (sum |f - f_ref| / sum |f_ref| over the "
        f"particles); ring is the outer ring's (R within {RING:g} h of the surface) largest relative "
        "radius error; spread is the largest detrended angular spread of v_r (one bin per cell); "
        "rotation is the largest spurious rotation angle (rad); folded counts folded or inverted "
        "particle domains.",
        "",
        "A run that broke down is marked **broken down**, with when (the fraction of two transits it "
        "reached) and what failed; its measures (in italics, &dagger;) are those of its last good state, "
        "not of two transits, and are not comparable with those of the runs that ran through. The wall "
        "time includes compiling for the first run of each program only: the disk at 10:1 reuses the "
        "programs of the disk at 1.5:1 (the same sizes), and a run that breaks down early stops early.",
    ]
    for s in info:
        mine = [r for r in rows if (r["kind"], r["ratio"]) == (s["kind"], s["ratio"])]
        lines += [
            "",
            f"## {_title(s['kind'], s['ratio'])}, {s['cells']} cells across the radius",
            "",
            f"{mine[0]['particles']} particles; c0 = {s['c0']:.0f} m/s, two transits = "
            f"{s['t_end'] * 1e3:.4g} ms; the reference's free surface is at {s['r_free_radii']:.2f} radii "
            f"then, the grid reaches {s['grid_radii']:.2f} radii.",
            "",
            "| interpolator | remedy | status | v_r L1 | rho L1 | ring r error | spread | rotation (rad) "
            "| folded | steps taken | wall s |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in mine:
            lines.append(
                f"| {r['interpolator']} | {r['remedy']} | {status_cell(r)} "
                f"| {_measure_cell(r, 'v_r_L1', '.3f')} | {_measure_cell(r, 'rho_L1', '.3f')} "
                f"| {_measure_cell(r, 'ring_radius_error', '.3f')} | {_measure_cell(r, 'spread_max', '.3f')} "
                f"| {_measure_cell(r, 'rotation_max', '.3f')} | {_measure_cell(r, 'folded', '')} "
                f"| {r['steps']} | {r['wall_s']:.1f} |"
            )
    for key, config in (("refinement", BEST), ("refinement_tracked", TRACKED)):
        ref = result[key]
        o = ref["orders"]
        lines += [
            "",
            f"## Refinement: {config[0]} {config[1]}, disk at 10:1",
            "",
            "Observed orders against h = radius / cells: the order of each successive pair on the finer "
            "row, and the least-squares fit over the runs that ran through.",
            "",
            "| cells | particles | status | v_r L1 | order | rho L1 | order | ring r error | order "
            "| steps taken | wall s |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for k, r in enumerate(ref["rows"]):
            pair = {
                q: (None if k == 0 else o[f"{q}_order_pairs"][k - 1])
                for q in ("v_r_L1", "rho_L1", "ring_radius_error")
            }
            lines.append(
                f"| {r['cells']} | {r['particles']} | {status_cell(r)} | {_measure_cell(r, 'v_r_L1', '.4f')} "
                f"| {_num(pair['v_r_L1'], '.2f')} | {_measure_cell(r, 'rho_L1', '.4f')} "
                f"| {_num(pair['rho_L1'], '.2f')} | {_measure_cell(r, 'ring_radius_error', '.4f')} "
                f"| {_num(pair['ring_radius_error'], '.2f')} | {r['steps']} | {r['wall_s']:.1f} |"
            )
        lines += [
            "",
            f"Fitted orders: v_r L1 {_num(o['v_r_L1_order_fit'], '.2f')}, "
            f"rho L1 {_num(o['rho_L1_order_fit'], '.2f')}, "
            f"ring radius {_num(o['ring_radius_error_order_fit'], '.2f')}.",
        ]
    lines += _slab_markdown(result)
    figs = result["figures"]
    lines += ["", "Figures (disk at 10:1, the best configuration of each interpolator):", ""]
    for name, f in figs.items():
        lines.append(f"- {name}: {f['remedy']} ({status_cell(f)})")
    lines += ["", f"Machine: {result['machine']}; total {result['wall_s']:.0f} s.", ""]
    return "\n".join(lines)


def _slab_markdown(result: dict) -> list[str]:
    sl, rows = result["slab"], result["rows"]
    lines = [
        "",
        "## The 1D slab at the same resolution",
        "",
        "The planar analogue of the disk (`jaxmpm.GasSlab`: the same gas, as thick as the disk's radius, "
        "a wall at 0 as its plane of symmetry, the same h, particles per cell, CFL and end time), against "
        "the 1D reference (`gas_radial` with dim = 1, 1600 cells, with its viscosity), measured as the "
        "disk is: v and rho L1 over the particles, the ring (within "
        f"{RING:g} h of the surface) and the outermost particle's signed radius error (> 0: ahead of the "
        "reference). It is the error the same interpolator and transfer make in 1D, with no spurious "
        "shear or rotation to cause it. The shear viscosity vanishes in 1D, so FLIP and APIC here are "
        f"the 1D forms of the disk's shear {SHEAR:g} and APIC + shear {SHEAR:g}; the last columns give "
        "the disk's ring with those, where the study ran them. Orders are of each successive pair, on "
        "the finer row.",
    ]
    for ratio in dict.fromkeys(r["ratio"] for r in sl["rows"]):
        lines += [
            "",
            f"### Slab at {ratio:g}:1",
            "",
            "| interpolator | remedy | cells | status | v L1 | order | rho L1 | ring r error | order "
            "| outer particle | disk's remedy | disk: ring r error | steps taken | wall s |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        mine = [r for r in sl["rows"] if r["ratio"] == ratio]
        for config in dict.fromkeys((r["interpolator"], r["remedy"]) for r in mine):
            o = sl["orders"][f"{ratio:g}/{config[0]} {config[1]}"]
            runs = [r for r in mine if (r["interpolator"], r["remedy"]) == config]
            for k, r in enumerate(runs):
                pair = {
                    q: (None if k == 0 else o[f"{q}_order_pairs"][k - 1])
                    for q in ("v_L1", "ring_radius_error")
                }
                disk = [
                    d
                    for d in rows
                    if (d["kind"], d["ratio"], d["cells"], d["interpolator"], d["remedy"])
                    == ("disk", ratio, r["cells"], config[0], SLAB_CONFIGS[config])
                ]
                disk_ring = _measure_cell(disk[0], "ring_radius_error", ".4f") if disk else ""
                lines.append(
                    f"| {r['interpolator']} | {r['remedy']} | {r['cells']} | {status_cell(r)} "
                    f"| {_measure_cell(r, 'v_L1', '.4f')} | {_num(pair['v_L1'], '.2f')} "
                    f"| {_measure_cell(r, 'rho_L1', '.4f')} | {_measure_cell(r, 'ring_radius_error', '.4f')} "
                    f"| {_num(pair['ring_radius_error'], '.2f')} | {_measure_cell(r, 'outer', '+.4f')} "
                    f"| {SLAB_CONFIGS[config]} | {disk_ring} | {r['steps']} | {r['wall_s']:.1f} |"
                )
    return lines


def _save(fig, path: pathlib.Path) -> pathlib.Path:
    fig.tight_layout()
    return OUTPUTS.figure(fig, path, dpi=130)


def _panel_title(r: dict) -> str:
    when = (
        f"t = {r['t'] * 1e3:.3g} ms (2 transits)"
        if r["finished"]
        else f"broke down at {r['fraction']:.2f} of 2 transits: last good state, t = {r['t'] * 1e3:.3g} ms"
    )
    return f"{r['interpolator'].upper()} {r['remedy']}\n{when}"


def _figures(result: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    from matplotlib.collections import PolyCollection

    from ..plotting import figure

    chosen = [r for r in result["figure_rows"] if r is not None]
    paths = []
    fig = figure(figsize=(5.0 * len(chosen), 4.0))
    axes = fig.subplots(1, len(chosen), squeeze=False)[0]
    for ax, r in zip(axes, chosen):
        p = r["profile"]
        radius = p["R_line"][-1]
        ax.plot(p["R"] / radius, p["v_r"], ".", ms=2.0, color="tab:blue", label="particles")
        ax.plot(p["R_line"] / radius, p["v_line"], "k-", lw=1.0, label="1D radial reference")
        ax.set_xlabel("reference radius R / radius")
        ax.set_ylabel("radial velocity v_r (m/s)")
        ax.set_title(_panel_title(r), fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Disk at 10:1: radial velocity against reference radius")
    paths.append(_save(fig, outdir / "radial_velocity.png"))

    fig = figure(figsize=(5.0 * len(chosen), 5.0))
    axes = fig.subplots(1, len(chosen), squeeze=False)[0]
    around = [0, 1, 3, 2]  # corners (-,-), (-,+), (+,+), (+,-): around the quadrilateral
    for ax, r in zip(axes, chosen):
        p = r["profile"]
        ax.add_collection(
            PolyCollection(
                p["corners"][:, around, :], facecolors="tab:blue", edgecolors="k", linewidths=0.2, alpha=0.35
            )
        )
        theta = np.linspace(0.0, 0.5 * np.pi, 200)
        ax.plot(
            p["r_free"] * np.cos(theta),
            p["r_free"] * np.sin(theta),
            "r--",
            lw=1.0,
            label="reference free surface",
        )
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(_panel_title(r) + f", {r['folded']} folded", fontsize=9)
        ax.legend(fontsize=8, loc="upper right")
    fig.suptitle(
        "Disk at 10:1 (quarter, symmetry planes at x = 0 and y = 0): particle domains at the end\n"
        "(a run that broke down: at its last good state)"
    )
    paths.append(_save(fig, outdir / "domains.png"))
    return paths


def _jsonable(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "profile"} for r in rows]


def main(out: str, small: bool = False) -> dict:
    """Run the study; write ``table.md``, ``blast.json``, ``radial_velocity.png`` and ``domains.png`` to
    ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: the reduced version (``settings(small=True)``; well under a minute).

    Returns:
        ``settings``, ``scenes`` (``scene_info`` of each case), ``rows`` (one per case and
        configuration, ``run_row``'s), ``refinement`` and ``refinement_tracked`` (rows and orders of
        ``BEST`` and ``TRACKED``), ``slab`` (the 1D slab's rows and orders, ``slab``), ``figure_rows``
        (the best CPDI, MPQ and CPDI2 rows at 10:1, ``best``), ``figures`` (their configurations),
        ``machine`` and ``wall_s``.

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("blast")
    t0 = time.perf_counter()
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    cfg = settings(small)
    refs = References()
    rows = []
    for kind, ratio, cells in cfg["cases"]:
        for interpolator, remedy in cfg["configs"]:
            rows.append(run_row(kind, ratio, cells, interpolator, remedy, refs))
            r = rows[-1]
            print(
                f"{kind} {ratio:g}:1 {cells} cells, {interpolator} {remedy}: {status_cell(r)}; v_r L1 "
                f"{_num(r['v_r_L1'])}, {r['wall_s']:.1f} s",
                flush=True,
            )
    figure_rows = [best(rows, name) for name in REMEDIED]
    result = dict(
        settings=dict(cfg, small=small, cfl=CFL, p_atm=P_ATM, transits=TRANSITS, shear=SHEAR),
        scenes=[scene_info(kind, ratio, cells, refs) for kind, ratio, cells in cfg["cases"]],
        rows=rows,
        refinement=refinement(cfg["refinement"], rows, refs, BEST),
        refinement_tracked=refinement(cfg["refinement"], rows, refs, TRACKED),
        slab=slab(cfg["slab"]["ratios"], cfg["slab"]["cells"], refs),
        figure_rows=figure_rows,
        figures={
            r["interpolator"]: dict(remedy=r["remedy"], finished=r["finished"], failure=r["failure"])
            for r in figure_rows
            if r is not None
        },
        machine=machine(),
    )
    result["wall_s"] = time.perf_counter() - t0
    text = _markdown(result)
    OUTPUTS.text(outdir / "table.md", text)
    saved = {k: v for k, v in result.items() if k != "figure_rows"}
    saved["rows"] = _jsonable(rows)
    for key in ("refinement", "refinement_tracked"):
        saved[key] = dict(result[key], rows=_jsonable(result[key]["rows"]))
    OUTPUTS.text(outdir / "blast.json", dumps(saved, indent=1, default=str))
    paths = _figures(result, outdir)
    print(text)
    print("wrote " + ", ".join(str(p) for p in [outdir / "table.md", outdir / "blast.json", *paths]))
    return result
