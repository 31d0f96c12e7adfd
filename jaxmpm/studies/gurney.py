"""A cylinder of explosive driving its metal tube, in 2D: the ring's radial velocity against Gurney's.

The scene is ``jaxmpm.GurneyCylinder``: a Comp B charge of radius 4 cm (its JWL row with the energy
equation, time burn, lit on the axis) in a 4340 steel tube 4-5 cm (Mie-Grueneisen, with or without an
elastic-perfectly-plastic deviatoric part), a quarter with planes of symmetry. Gurney's cylinder formula
gives the velocity the tube tends to as the products expand without limit, ``sqrt(2E) (M/C +
1/2)^(-1/2)`` (a model, accurate to a few per cent, that neglects the metal's strength).

1. **Resolution.** CPDI with APIC and the shear viscosity (the configuration under which 2D gas stays
   smooth, ``docs/multid.md``), refined: the ring's velocity at each time, and against Gurney's.
2. **Interpolators.** Every interpolator of ``jaxmpm.INTERPOLATORS`` with the same remedies, and CPDI
   without them (FLIP, no shear viscosity), at one resolution.
3. **Strength.** The hydrodynamic ring against one with the steel's strength (``strength=True``).

Every run also reports the angular spread of the radial velocity (``jaxmpm.metrics.angular_spread``,
detrended, over the whole body: a radially symmetric motion has none) and its folded domains (CPDI,
MPQ and CPDI2). A run that broke down is reported as such and none of its numbers is used.
``jaxmpm study gurney --out DIR`` writes ``gurney.md``, ``gurney.json`` and the figures
``ring_velocity.png`` and ``ring_particles.png``.
"""

from __future__ import annotations

import pathlib
import time

import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps

from ._output import Files
from ._runtime import machine, number, require_float64, run_status, status_cell

CFL = 0.3
"""The Courant number of every run."""
C_SHEAR = 0.3
"""The shear viscosity's coefficient of the remedied runs (``ArtificialViscosity(c_shear=...)``)."""
FRAMES = 60
"""About how many frames of the ring's velocity each run keeps."""
OUTPUTS = Files("gurney.md", "gurney.json", "ring_velocity.png", "ring_particles.png")
"""The files the study writes."""
FULL = dict(cells=(20, 40, 80), all_at=40, t_end=6e-5, times=(2e-5, 4e-5, 6e-5))
SMALL = dict(cells=(6,), all_at=6, t_end=7e-6, times=(5e-6, 7e-6))


def settings(small: bool = False) -> dict:
    """The study's sizes.

    Args:
        small: the reduced version (6 cells across the tube's outer radius, to 7 us; the
            interpolators' table with CPDI and MPQ only).

    Returns:
        ``dict(cells, all_at, t_end, times, names)``: the resolutions of table 1 (cells across ``R``),
        that of tables 2 and 3, the end time (s), the times of the tables (s), and table 2's
        interpolators.
    """
    out = dict(SMALL if small else FULL)
    out["names"] = ("cpdi", "mpq") if small else tuple(jm.INTERPOLATORS)
    return out


def run(cells: int, name: str, t_end: float, times, remedied: bool = True, strength: bool = False) -> dict:
    """One run of the cylinder and its measures.

    Args:
        cells: cells across the tube's outer radius ``R``.
        name: the interpolator (a key of ``jaxmpm.INTERPOLATORS``).
        t_end: the end time (s).
        times: the times (s) at which the ring's velocity and radius are reported.
        remedied: APIC and the shear viscosity (else FLIP and the plain artificial viscosity).
        strength: the steel's elastic-perfectly-plastic deviatoric part.

    Returns:
        The row: settings, status, failure, the ring's velocity ``v_<t>`` and radius ``r_<t>`` at each
        time (``None`` after a breakdown), Gurney's velocity, the angular spread and folded domains at
        the end, the histories ``t``, ``v_ring``, ``r_ring``, the particles' mass ratio, and the run's
        wall time; and, for the figures (not saved), ``x_end`` and ``region``.
    """
    scene = jm.GurneyCylinder(cells=cells, pad=2 * cells, strength=strength)
    # the detonation front (D) sets the step while it runs; then the steel's sound speed
    steps = int(np.ceil(1.5 * float(scene.cj()["D"]) * t_end / (CFL * float(scene.h))))
    every = max(1, steps // FRAMES)
    viscosity = jm.ArtificialViscosity(c_shear=C_SHEAR if remedied else None)
    transfer = jm.APIC() if remedied else jm.FLIP()
    t0 = time.perf_counter()
    sol = jm.simulate(
        scene,
        jm.INTERPOLATORS[name](),
        t_end=t_end,
        cfl=CFL,
        max_steps=4 * steps,
        transfer=transfer,
        viscosity=viscosity,
        saveat=jm.SaveAt(every=every, fields=("x", "v")),
        throw=False,
    )
    status, fail = run_status(sol)
    body = sol.body
    ring = np.asarray(body.region) == 1
    m = np.asarray(body.m)[ring]
    x = np.asarray(sol.history["x"])[:, ring]
    v = np.asarray(sol.history["v"])[:, ring]
    r = np.linalg.norm(x, axis=-1)
    v_ring = np.sum(m * np.sum(v * x, axis=-1) / r, axis=1) / m.sum()
    r_ring = r @ m / m.sum()
    ts = np.asarray(sol.ts)
    keep = np.concatenate([[True], np.diff(ts) > 0])  # frames after t_end repeat the last state
    row = dict(
        interpolator=name,
        cells=cells,
        particles=int(body.X.shape[0]),
        remedied=remedied,
        strength=strength,
        status=status,
        failure=fail,
        gurney=float(scene.gurney_velocity()),
        mass_ratio=float(scene.mass_ratio),
        mass_ratio_particles=float(m.sum() / np.asarray(body.m)[~ring].sum()),
        r0=float(np.linalg.norm(np.asarray(body.X)[ring], axis=-1) @ m / m.sum()),
    )
    for t in times:  # linear between the saved frames (about a microsecond apart)
        ok = fail is None and t <= ts[keep][-1]
        row[f"v_{t:g}"] = float(np.interp(t, ts[keep], v_ring[keep])) if ok else None
        row[f"r_{t:g}"] = float(np.interp(t, ts[keep], r_ring[keep])) if ok else None
    spread = folded = ring_spread = None
    if fail is None:
        ring_spread = _ring_spread(x[-1], v[-1], m)
        centre = np.zeros(2)
        spread = float(jm.metrics.angular_spread(sol.state, body, centre, cells, detrend=True)["rms"])
        if name in ("cpdi", "mpq", "cpdi2"):  # the interpolators whose domains can fold
            corners = jm.metrics.domain_corners(sol.state, body)
            folded = int(jm.metrics.folded_domains(corners, body))
    row.update(
        spread_rms=spread,
        ring_spread=ring_spread,
        folded=folded,
        t=ts[keep].tolist(),
        v_ring=v_ring[keep].tolist(),
        r_ring=r_ring[keep].tolist(),
        x_end=None if fail is not None else np.asarray(sol.state.x),
        region=np.asarray(body.region),
        wall_s=time.perf_counter() - t0,
    )
    return row


SECTORS = 8
"""The ring's angular sectors of ``ring_spread``."""


def _ring_spread(x, v, m) -> float:
    """The spread of the ring's radial velocity over the angle: the standard deviation of the mass-mean
    radial velocity of ``SECTORS`` equal sectors of the quarter, over the ring's mean."""
    r = np.linalg.norm(x, axis=-1)
    v_r = np.sum(v * x, axis=-1) / r
    sector = np.minimum((np.arctan2(x[:, 1], x[:, 0]) / (0.5 * np.pi) * SECTORS).astype(int), SECTORS - 1)
    means = np.array([np.sum((m * v_r)[sector == k]) / np.sum(m[sector == k]) for k in range(SECTORS)])
    return float(np.std(means) / abs(np.sum(m * v_r) / np.sum(m)))


def resolution_order(rows: list[dict], t: float) -> dict | None:
    """The observed order of the ring's velocity at ``t`` over the three finest resolutions, and the
    Richardson extrapolation to ``h -> 0``.

    With ``v_1, v_2, v_3`` at cells ``n, 2n, 4n``: ``order = log2((v_2 - v_1) / (v_3 - v_2))`` and
    ``v_inf = v_3 + (v_3 - v_2) / (2^order - 1)``.

    Args:
        rows: the resolution rows (``run``), refined by factors of 2.
        t: the time.

    Returns:
        ``dict(order, extrapolated, t)``, or ``None`` with fewer than three finished runs, or where the
        differences do not shrink monotonically (no order to speak of).
    """
    v = [r[f"v_{t:g}"] for r in rows[-3:]]
    cells = [r["cells"] for r in rows[-3:]]
    if len(v) < 3 or any(x is None for x in v) or cells[1] != 2 * cells[0] or cells[2] != 2 * cells[1]:
        return None
    d1, d2 = v[1] - v[0], v[2] - v[1]
    if d1 == 0.0 or d2 / d1 <= 0.0 or abs(d2) >= abs(d1):
        return None
    order = float(np.log2(d1 / d2))
    return dict(order=order, extrapolated=v[2] + d2 / (2.0**order - 1.0), t=t)


def _table(rows: list[dict], times, lead: tuple[str, ...]) -> list[str]:
    head = " | ".join(lead)
    lines = [
        f"| {head} | status | "
        + " | ".join(f"v at {1e6 * t:g} us (m/s)" for t in times)
        + f" | r / R0 at {1e6 * times[-1]:g} us | last / Gurney | particles' M/C | ring's spread over the "
        "angle | angular spread (RMS) | folded | wall s |",
        "|" + "---|" * (len(lead) + len(times) + 8),
    ]
    for r in rows:
        last = r[f"v_{times[-1]:g}"]
        r_last = r[f"r_{times[-1]:g}"]
        cells = []
        for key in lead:
            cells.append(
                {
                    "interpolator": r["interpolator"],
                    "cells": str(r["cells"]),
                    "remedies": "APIC + shear viscosity" if r["remedied"] else "FLIP, none",
                    "strength": "elastic-perfectly-plastic" if r["strength"] else "none (hydrodynamic)",
                }[key]
            )
        lines.append(
            "| "
            + " | ".join(cells)
            + f" | {status_cell(r)} | "
            + " | ".join(number(r[f"v_{t:g}"], ".1f") for t in times)
            + f" | {number(None if r_last is None else r_last / r['r0'], '.3f')}"
            + f" | {number(None if last is None else last / r['gurney'], '.4f')}"
            + f" | {r['mass_ratio_particles']:.4f} | {number(r['ring_spread'], '.2e')}"
            + f" | {number(r['spread_rms'], '.2e')} | {number(r['folded'], 'd')} | {r['wall_s']:.1f} |"
        )
    return lines


def _markdown(result: dict) -> str:
    cfg = result["settings"]
    times = cfg["times"]
    first = result["resolution"][0]
    lines = [
        "# Explosive driving a metal tube: jaxmpm study gurney",
        "",
        "A Comp B charge of radius 4 cm (JWL with its energy, time burn, lit on the axis) in a 4340 steel "
        "tube 4-5 cm (Mie-Grueneisen), a quarter cross-section with planes of symmetry, CFL "
        f"{CFL:g}, the default artificial viscosity. M/C = {first['mass_ratio']:.4f}; Gurney's cylinder "
        f"formula with sqrt(2E) = 2.70 km/s gives {first['gurney']:.1f} m/s, the velocity the tube tends "
        "to as the products expand without limit (a model accurate to a few per cent, without the metal's "
        "strength). The ring's velocity is its radial momentum over its mass; r / R0 is its mean radius "
        "(weighted by mass) over that of its particles at rest (the annulus 4-5 cm's is 4.52 cm). The "
        "ring's spread over the angle is the standard deviation of its radial velocity over "
        f"{SECTORS} equal sectors of the quarter, over its mean, at the last time. The "
        "angular spread is that of the radial velocity of the whole body (products and ring) at equal "
        "reference radius, detrended, RMS over radial bins of one cell; both are 0 for a radially "
        "symmetric motion. folded counts the CPDI, MPQ or CPDI2 domains turned inside out. A run that "
        "broke down is marked `broken down` and none of its numbers is used.",
        "",
        f"## 1. Resolution (CPDI, APIC and the shear viscosity c_shear = {C_SHEAR:g})",
        "",
        *_table(result["resolution"], times, ("cells",)),
        "",
        *_order_lines(result),
        f"## 2. Interpolators ({cfg['all_at']} cells across R)",
        "",
        *_table(result["interpolators"], times, ("interpolator", "remedies")),
        "",
        f"## 3. Strength ({cfg['all_at']} cells across R, CPDI, APIC and the shear viscosity)",
        "",
        "The steel's elastic-perfectly-plastic deviatoric stress (G = 77.5 GPa, von Mises yield 792 MPa: "
        "`jaxmpm.STRENGTH['steel-4340']`) against the hydrodynamic ring.",
        "",
        *_table(result["strength"], times, ("strength",)),
        "",
        f"Machine: {result['machine']}; total {result['wall_s']:.0f} s.",
        "",
    ]
    return "\n".join(lines)


def _order_lines(result: dict) -> list[str]:
    o = result["orders"]
    if o is None:
        return []
    v_g = result["resolution"][0]["gurney"]
    return [
        f"The velocity at {1e6 * o['t']:g} us converges at the observed order {o['order']:.2f} (the three "
        f"finest resolutions); Richardson's extrapolation to h -> 0 gives {o['extrapolated']:.0f} m/s, "
        f"{100.0 * (o['extrapolated'] / v_g - 1.0):+.1f}% from Gurney's formula (itself a model accurate "
        "to a few per cent, of the velocity after the products' full expansion). The ring still gains "
        "speed at the last time.",
        "",
    ]


def _figures(result: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    from ..plotting import figure

    paths = []
    fig = figure(figsize=(6.4, 4.0))
    ax = fig.subplots()
    v_g = result["resolution"][0]["gurney"]
    for r in result["resolution"] + result["strength"][1:]:
        label = f"CPDI, {r['cells']} cells" + (", strength" if r["strength"] else "")
        if r["failure"] is not None:  # named in the legend, not drawn
            ax.plot([], [], " ", label=f"{label}: broke down, not shown")
            continue
        ax.plot(1e6 * np.asarray(r["t"]), r["v_ring"], "--" if r["strength"] else "-", label=label)
    ax.axhline(v_g, color="k", lw=0.8, ls=":", label=f"Gurney {v_g:.0f} m/s")
    ax.set_xlabel("t (us)")
    ax.set_ylabel("ring's radial velocity (m/s)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    paths.append(OUTPUTS.figure(fig, outdir / "ring_velocity.png", dpi=130))

    rows = result["interpolators"]
    fig = figure(figsize=(3.0 * len(rows), 3.2))
    axes = np.atleast_1d(fig.subplots(1, len(rows), sharex=True, sharey=True))
    for ax, r in zip(axes, rows):
        title = r["interpolator"] + ("" if r["remedied"] else ", FLIP")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("x (cm)")
        ax.set_aspect("equal")
        if r["x_end"] is None:  # broke down: no end state to draw
            ax.text(
                0.5,
                0.5,
                status_cell(r),
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=7,
                wrap=True,
            )
            continue
        x = 100.0 * np.asarray(r["x_end"])
        reg = np.asarray(r["region"])
        ax.scatter(x[reg == 0, 0], x[reg == 0, 1], s=0.3, color="tab:orange", lw=0)
        ax.scatter(x[reg == 1, 0], x[reg == 1, 1], s=0.3, color="tab:gray", lw=0)
    axes[0].set_ylabel("y (cm)")
    fig.tight_layout()
    paths.append(OUTPUTS.figure(fig, outdir / "ring_particles.png", dpi=130))
    return paths


def main(out: str, small: bool = False) -> dict:
    """Run the study; write ``gurney.md``, ``gurney.json`` and two figures to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: the reduced version (``settings(small=True)``).

    Returns:
        ``settings``, ``resolution``, ``interpolators`` and ``strength`` (the tables' rows, ``run``),
        ``orders`` (``resolution_order``), ``machine`` and ``wall_s``.

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("gurney")
    t0 = time.perf_counter()
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    cfg = settings(small)
    t_end, times, at = cfg["t_end"], cfg["times"], cfg["all_at"]
    resolution = [run(c, "cpdi", t_end, times) for c in cfg["cells"]]
    base = next(r for r in resolution if r["cells"] == at)
    interpolators = [base if n == "cpdi" else run(at, n, t_end, times) for n in cfg["names"]]
    interpolators.append(run(at, "cpdi", t_end, times, remedied=False))
    strength = [base, run(at, "cpdi", t_end, times, strength=True)]
    result = dict(
        settings=dict(cfg, small=small),
        resolution=resolution,
        interpolators=interpolators,
        strength=strength,
        machine=machine(),
    )
    result["orders"] = resolution_order(resolution, times[-1])
    paths = _figures(result, outdir)
    for r in resolution + interpolators + strength:  # the end state drawn, not kept
        r.pop("x_end", None)
        r.pop("region", None)
    result["wall_s"] = time.perf_counter() - t0
    text = _markdown(result)
    OUTPUTS.text(outdir / "gurney.md", text)
    OUTPUTS.text(outdir / "gurney.json", dumps(result, indent=1, default=str))
    print(text)
    print("wrote " + ", ".join(str(p) for p in [outdir / "gurney.md", outdir / "gurney.json", *paths]))
    return result
