"""2D and 3D: the talk's first step along every axis, the axis-aligned manufactured solution's orders,
the blast's domain gaps (MPQ against CPDI), and a 100,000-particle 2D run.

``jaxmpm study multid --out DIR`` writes ``multid.md``, ``multid.json`` and three figures.
"""

from __future__ import annotations

import pathlib
import time

import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps
from jaxmpm.particles import parallelogram_corners

from ._output import Files
from ._runtime import machine, number, require_float64

BETA, DT = 200.0, 1e-5
OUTPUTS = Files(
    "multid.md", "multid.json", "blast_domains.png", "blast_gap.png", "axis_aligned_convergence.png"
)
"""The files the study writes."""


def first_steps(dims=(2, 3)) -> list[dict]:
    """The first step of the gas expansion, ``(F_aa - 1) / (beta dt)`` over all particles and axes:
    5/8 in boundary cells and 1 inside without artificial cells, 1 everywhere with them.

    Args:
        dims: the dimensions (2, 3).

    Returns:
        One row per dimension, interpolator and artificial-cell setting: the range over boundary and
        interior particles, and the largest off-diagonal entry.
    """
    rows = []
    for dim in dims:
        for name in jm.INTERPOLATORS:
            for ac in (0, 1):
                scene = jm.GasExpansion(cells=3, ppc=2, beta=BETA, dim=dim, pad=3)
                sol = jm.simulate(
                    scene, jm.INTERPOLATORS[name](), dt=DT, steps=1, artificial_cells=ac, throw=False
                )
                fail = sol.failure()
                row = dict(dim=dim, interpolator=name, artificial_cells=ac, failure=None)
                if fail is not None:  # no step was taken: nothing to measure
                    keys = (
                        "boundary_min",
                        "boundary_max",
                        "interior_min",
                        "interior_max",
                        "off_diagonal_max",
                    )
                    row.update(dict.fromkeys(keys, float("nan")), failure=fail["quantities"][0])
                    rows.append(row)
                    continue
                F = np.asarray(sol.state.F)
                g = (np.diagonal(F, axis1=1, axis2=2) - 1.0) / (BETA * DT)
                off = np.abs(F * (1 - np.eye(dim))).max() / (BETA * DT)
                b = np.asarray(sol.body.boundary)
                row.update(
                    boundary_min=float(g[b].min()),
                    boundary_max=float(g[b].max()),
                    interior_min=float(g[~b].min()),
                    interior_max=float(g[~b].max()),
                    off_diagonal_max=float(off),
                )
                rows.append(row)
    return rows


def axis_aligned(dim: int, cells_list, names=("spq", "gimp", "cpdi", "mpq")) -> list[dict]:
    """RMS position error of the axis-aligned solution at a quarter period, ``dt = 0.2 h / c``.

    Args:
        dim: 2 or 3.
        cells_list: cells per side, coarse to fine.
        names: the interpolators (keys of ``jaxmpm.INTERPOLATORS``).

    Returns:
        One row per interpolator and resolution, with the observed orders (fit and finest pair).
    """
    rows = []
    for name in names:
        errs = []
        for cells in cells_list:
            scene = jm.AxisAligned(cells=cells, h=1.0 / cells, dim=dim)
            c = float(scene.wave_speed)
            t_end = 0.5 / c
            steps = int(np.ceil(t_end / (0.2 / cells / c)))
            t0 = time.perf_counter()
            sol = jm.simulate(scene, jm.INTERPOLATORS[name](), dt=t_end / steps, steps=steps, throw=False)
            wall = time.perf_counter() - t0
            fail = sol.failure()
            e = jm.errors(scene, sol.state, sol.body) if fail is None else None
            errs.append(float(e["x_rms_abs"]) if fail is None else float("nan"))
            rows.append(
                dict(
                    dim=dim,
                    interpolator=name,
                    cells=cells,
                    particles=sol.body.n,
                    steps=steps,
                    x_rms_abs=errs[-1],
                    F_rms_rel=float(e["F_rms_rel"]) if fail is None else float("nan"),
                    wall_s=wall,
                    failure=None if fail is None else f"{fail['quantities'][0]} at step {fail['step']}",
                )
            )
        h = 1.0 / np.asarray(cells_list, dtype=float)
        e = np.asarray(errs)
        ok = np.isfinite(e) & (e > 0)  # a run that broke down (NaN) or an error of exactly 0: no log
        order = float(np.polyfit(np.log(1 / h[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")
        finest = float(np.log(e[-2] / e[-1]) / np.log(h[-2] / h[-1])) if ok[-2:].all() else float("nan")
        for r in rows:
            if r["interpolator"] == name and r["dim"] == dim:
                r["order_fit"], r["order_finest"] = -order if np.isfinite(order) else order, finest
    return rows


def blast(steps: int, every: int, cells: int = 8) -> dict:
    """The quarter blast with CPDI and MPQ (MUSL, FLIP): corner gaps against time, diagnostics.

    Args:
        steps: steps.
        every: save every this many steps.
        cells: cells per side of the charge.

    Returns:
        Per interpolator: times, largest corner gaps (own domains and the parallelograms from x, F),
        the domains mid-run and at the end, the failure, energies and the parameters. After a
        breakdown the times and gaps stop at the last frame saved before it, ``corners`` are that
        frame's domains (for the figure, titled so), and the mass and energies are ``None``.
    """
    out = {}
    for name in ("cpdi", "mpq"):
        scene = jm.Blast(cells=cells, h=0.5 / cells, pad=3 * cells)
        dt = 0.25 * float(scene.h) / float(scene.wave_speed)
        fields = ("x", "F", "corners") if name == "mpq" else ("x", "F")
        sol = jm.simulate(
            scene,
            jm.INTERPOLATORS[name](),
            dt=dt,
            steps=steps,
            ordering="musl",
            saveat=jm.SaveAt(every=every, fields=fields),
            throw=False,
        )
        body = sol.body
        fail = sol.failure()
        ts = np.asarray(sol.ts)
        # the saves of steps 0, every, 2 every, ...; after a breakdown those past the last good
        # step repeat its state: left out
        frames = len(ts) if fail is None else min(len(ts), int(sol.state.step) // every + 1)
        gaps, implied, mid = [], [], None
        for k in range(frames):
            parallelograms = parallelogram_corners(body.r0, sol.history["x"][k], sol.history["F"][k])
            own = body.particle_corners(sol.history["corners"][k]) if name == "mpq" else parallelograms
            if k == frames // 2:
                mid = dict(t=float(sol.ts[k]), corners=np.asarray(own).tolist())
            gaps.append(float(np.max(jm.corner_gap(own, body))))
            last = own
            implied.append(float(np.max(jm.corner_gap(parallelograms, body))))
        d = jm.diagnostics(scene, sol.state, body) if fail is None else {}
        out[name] = dict(
            t=[float(t) for t in ts[:frames]],
            gap_own=gaps,
            gap_implied=implied,
            # a broken run's last frame before the breakdown, drawn as such (``_figures``)
            corners=np.asarray(jm.domain_corners(sol.state, body) if fail is None else last).tolist(),
            mid=mid,
            steps_taken=int(sol.state.step),
            failure=fail,
            mass=float(d["mass"]) if d else None,
            energy=float(d["energy"]) if d else None,
            energy_kinetic=float(d["energy_kinetic"]) if d else None,
            dt=dt,
            params=scene.parameter_values(),
        )
    return out


def large_2d(cells: int = 158, steps: int = 20) -> list[dict]:
    """A 2D gas expansion of ``cells^2 * 4`` particles (99,856 at 158 cells): compile and run time.

    Args:
        cells: cells per side.
        steps: steps.

    Returns:
        One row per interpolator: times, particle-steps per second, the failure (``None``: it ran
        through) and the max relative F error (the last two ``None`` after a breakdown: the run's time
        then covers steps that were not all taken).
    """
    rows = []
    for name in ("spq", "cpdi", "mpq"):
        scene = jm.GasExpansion(dim=2, cells=cells, h=1.0 / cells, pad=4)
        sol, compile_s, run_s = jm.simulate_timed(
            scene, jm.INTERPOLATORS[name](), dt=1e-6, steps=steps, artificial_cells=1, throw=False
        )
        fail = sol.failure()
        rows.append(
            dict(
                interpolator=name,
                particles=sol.body.n,
                steps=steps,
                compile_s=compile_s,
                run_s=run_s,
                mparticle_steps_per_s=sol.body.n * steps / run_s / 1e6 if fail is None else None,
                failure=None if fail is None else f"{fail['quantities'][0]} at step {fail['step']}",
                F_max_rel=float(jm.errors(scene, sol.state, sol.body)["F_max_rel"]) if fail is None else None,
            )
        )
    return rows


def _save(fig, path: pathlib.Path) -> pathlib.Path:
    fig.tight_layout()
    return OUTPUTS.figure(fig, path, dpi=130)


def _figures(result: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    from matplotlib.collections import PolyCollection

    from ..plotting import figure

    paths = []
    b = result["blast"]
    fig = figure(figsize=(10, 10))
    axes = fig.subplots(2, 2, sharex=True, sharey=True)
    order = [0, 1, 3, 2]  # corners (-,-), (-,+), (+,+), (+,-): around the quadrilateral
    for row, when in enumerate(("mid", "end")):
        for ax, name in zip(axes[row], ("cpdi", "mpq")):
            r = b[name]
            k = len(r["t"]) // 2 if when == "mid" else len(r["t"]) - 1
            corners = r["mid"]["corners"] if when == "mid" else r["corners"]
            last = (
                ""
                if when == "mid" or r["failure"] is None
                else f"\nthe last frame before it broke down at step {r['failure']['step']}"
            )
            c = np.asarray(corners)[:, order, :]
            ax.add_collection(
                PolyCollection(c, facecolors="tab:blue", edgecolors="k", linewidths=0.3, alpha=0.35)
            )
            ax.autoscale()
            ax.set_aspect("equal")
            ax.set_title(
                f"{name.upper()}, t = {r['t'][k] * 1e3:.2f} ms: largest corner gap "
                f"{r['gap_own'][k]:.3g} r0{last}",
                fontsize=9,
            )
        axes[row][0].set_ylabel("y (m)")
    for ax in axes[1]:
        ax.set_xlabel("x (m)")
    fig.suptitle("Blast (quarter, symmetry planes at x = 0 and y = 0): particle domains")
    paths.append(_save(fig, outdir / "blast_domains.png"))

    fig = figure(figsize=(6.5, 4))
    ax = fig.subplots()

    def broke(name):  # the curves of a run that broke down stop at its last good frame: say so
        failure = b[name]["failure"]
        return "" if failure is None else f" (broke down at step {failure['step']})"

    for name, style in (("cpdi", "-"), ("mpq", "--")):
        t = np.asarray(b[name]["t"]) * 1e3
        ax.plot(t, b[name]["gap_own"], style, label=f"{name.upper()}: its own domains{broke(name)}")
    ax.plot(
        np.asarray(b["mpq"]["t"]) * 1e3,
        b["mpq"]["gap_implied"],
        ":",
        label=f"MPQ: parallelograms from x, F{broke('mpq')}",
    )
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("largest corner gap / r0")
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.legend(fontsize=8)
    ax.set_title("Shared corners: MPQ's coincide (0), CPDI's separate")
    paths.append(_save(fig, outdir / "blast_gap.png"))

    fig = figure(figsize=(6.5, 4))
    ax = fig.subplots()
    rows = result["axis_aligned_2d"]
    for name in sorted({r["interpolator"] for r in rows}):
        rr = [r for r in rows if r["interpolator"] == name]
        broken = [str(r["cells"]) for r in rr if r["failure"] is not None]
        note = f"; not shown, broke down: {', '.join(broken)} cells" if broken else ""
        ax.loglog(
            [1 / r["cells"] for r in rr if r["failure"] is None],
            [r["x_rms_abs"] for r in rr if r["failure"] is None],
            "o-",
            label=f"{name} (order {_finite(rr[0]['order_fit'], '.2f')}{note})",
        )
    ax.set_xlabel("h")
    ax.set_ylabel("RMS position error at t = L / (2c)")
    ax.set_title("Axis-aligned manufactured solution, 2D")
    ax.legend(fontsize=8)
    paths.append(_save(fig, outdir / "axis_aligned_convergence.png"))
    return paths


def axis_aligned_markdown(rows: list[dict], title: str) -> list[str]:
    """The table of ``axis_aligned``'s rows: a run that broke down says so in its status, and its
    errors (and orders over fewer than two finished resolutions) are left out.

    Args:
        rows: the rows of one dimension.
        title: ``"2D"`` or ``"3D"``.

    Returns:
        The lines of the section.
    """
    lines = [
        f"## Axis-aligned manufactured solution (Wallstedt & Guilkey 2008), {title}, t = L / (2c)",
        "",
        "Errors of a run that broke down are left out (-), and so are the orders over fewer than "
        "two finished resolutions.",
        "",
        "| interpolator | cells | particles | steps | status | x RMS error | F RMS rel. error "
        "| order (fit) | order (finest pair) | wall s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['interpolator']} | {r['cells']} | {r['particles']} | {r['steps']} | "
            f"{'ok' if r['failure'] is None else 'broken down: ' + r['failure']} | "
            f"{_finite(r['x_rms_abs'], '.3e')} | {_finite(r['F_rms_rel'], '.3e')} | "
            f"{_finite(r['order_fit'], '.2f')} | {_finite(r['order_finest'], '.2f')} | "
            f"{r['wall_s']:.1f} |"
        )
    return lines


def _finite(x, fmt: str) -> str:
    """A table cell: ``x`` formatted, or ``-`` where it is missing or not finite."""
    return number(x if x is not None and np.isfinite(x) else None, fmt)


def first_step_markdown(rows: list[dict]) -> list[str]:
    """The table of ``first_steps``'s rows: a run that broke down says so, with its quantity.

    Args:
        rows: what ``first_steps`` returns.

    Returns:
        The lines of the table, its heading first.
    """
    lines = [
        "## Gas expansion, first step, (F_aa - 1) / (beta dt) over every particle and axis",
        "",
        "| dim | interpolator | AC | boundary cells | interior | off-diagonal |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["failure"] is not None:
            lines.append(
                f"| {r['dim']} | {r['interpolator']} | {r['artificial_cells']} | broke down at step 1: "
                f"{r['failure']} | - | - |"
            )
            continue
        lines.append(
            f"| {r['dim']} | {r['interpolator']} | {r['artificial_cells']} | {r['boundary_min']:.15g} .. "
            f"{r['boundary_max']:.15g} | {r['interior_min']:.15g} .. {r['interior_max']:.15g} | "
            f"{r['off_diagonal_max']:.1e} |"
        )
    return lines


def _markdown(result: dict) -> str:
    lines = ["# 2D and 3D: jaxmpm study multid", "", *first_step_markdown(result["first_step"])]
    for key, title in (("axis_aligned_2d", "2D"), ("axis_aligned_3d", "3D")):
        if result.get(key):
            lines += ["", *axis_aligned_markdown(result[key], title)]
    b = result["blast"]
    lines += [
        "",
        "## Blast (quarter charge, symmetry planes, MUSL + FLIP)",
        "",
        f"Parameters: {b['mpq']['params']}, dt = {b['mpq']['dt']:.4g} s.",
        "",
        "| interpolator | steps taken | failure | max corner gap / r0 (own domains) "
        "| (parallelograms from x, F) | total energy (J/m) |",
        "|---|---|---|---|---|---|",
    ]
    for name in ("cpdi", "mpq"):
        r = b[name]
        ok = r["failure"] is None
        fail = "none" if ok else f"step {r['failure']['step']}: {r['failure']['quantities'][0]}"
        lines.append(  # the end's numbers; none for a run that broke down
            f"| {name} | {r['steps_taken']} | {fail} | {number(r['gap_own'][-1] if ok else None, '.3g')} "
            f"| {number(r['gap_implied'][-1] if ok else None, '.3g')} | {number(r['energy'], '.4g')} |"
        )
    lines += [
        "",
        f"## 2D run of {result['large_2d'][0]['particles']:,} particles (gas expansion, artificial cells)",
        "",
        "| interpolator | particles | steps | compile s | run s | M particle-steps/s | F max rel. error |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in result["large_2d"]:
        error = number(r["F_max_rel"]) if r["failure"] is None else f"broken down: {r['failure']}"
        lines.append(
            f"| {r['interpolator']} | {r['particles']} | {r['steps']} | {r['compile_s']:.2f} | "
            f"{r['run_s']:.2f} | {number(r['mparticle_steps_per_s'], '.2f')} | {error} |"
        )
    lines += ["", f"Machine: {result['machine']}; total {result['wall_s']:.0f} s.", ""]
    return "\n".join(lines)


def main(out: str, small: bool = False) -> dict:
    """Run the study; write ``multid.md``, ``multid.json`` and three figures to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: a reduced version (2D only, coarser grids, fewer steps).

    Returns:
        ``first_step``, ``axis_aligned_2d``, ``axis_aligned_3d``, ``blast``, ``large_2d``, ``machine``
        and ``wall_s``.

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("multid")
    t0 = time.perf_counter()
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    result = dict(
        first_step=first_steps((2,) if small else (2, 3)),
        axis_aligned_2d=axis_aligned(2, (8, 16) if small else (8, 16, 32, 64)),
        axis_aligned_3d=[] if small else axis_aligned(3, (4, 8, 16), names=("gimp", "cpdi", "mpq")),
        blast=blast(60 if small else 300, 10, cells=4 if small else 8),
        large_2d=large_2d(cells=16 if small else 158, steps=5 if small else 20),
        machine=machine(),
    )
    result["wall_s"] = time.perf_counter() - t0
    OUTPUTS.text(outdir / "multid.json", dumps(result, indent=1, default=str))
    OUTPUTS.text(outdir / "multid.md", _markdown(result))
    paths = _figures(result, outdir)
    print(_markdown(result))
    print("wrote " + ", ".join(str(p) for p in [outdir / "multid.md", outdir / "multid.json", *paths]))
    return result
