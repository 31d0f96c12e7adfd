"""The talk's study (Bonifasi-Lista, Brannon & Wiskin, 7th MPM Workshop 2013), reproduced.

For each interpolator (SPQ, uGIMP, cpGIMP, CPDI, MPQ), with and without artificial cells, and a few
velocity gradients beta, the 1D gas expansion ``u = beta t X`` runs to the talk's times 0.0001 and
0.00125. It writes F, position and velocity along the bar against the manufactured solution, the
domain-separation diagnostic over time, and a markdown table of errors with run and compile times.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import textwrap

import jax.numpy as jnp
import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps

from ._methods import METHODS
from ._output import Files
from ._runtime import require_float64

TIMES = (1.0e-4, 1.25e-3)
DT = 1.0e-5
OUTPUTS = Files(
    "table.md",
    "results.csv",
    "results.json",
    *(f"{q}_t{t:g}.png" for t in TIMES for q in ("F", "x", "v")),
    "separation.png",
)
"""The files the study writes."""
COLUMNS = (
    "method",
    "artificial_cells",
    "beta",
    "t",
    "F_max_rel",
    "F_max_rel_boundary",
    "F_max_rel_interior",
    "x_max_abs",
    "v_max_abs",
    "separation_max",
    "status",
    "wall_s",
    "compile_s",
)


@dataclasses.dataclass
class Run:
    """One run of the study.

    Attributes:
        method: the interpolator's label (``METHODS``).
        artificial_cells: layers of artificial cells (0 or 1).
        beta: the velocity gradient (1/s).
        scene: the scene that ran.
        solution: its solution, every step saved.
        wall_s: run time (s).
        compile_s: compile time (s; 0 where the run compiled for an earlier beta was reused).
    """

    method: str
    artificial_cells: int
    beta: float
    scene: jm.GasExpansion
    solution: jm.Solution
    wall_s: float
    compile_s: float


def run_all(betas, cells: int, ppc: int) -> list[Run]:
    """Run every interpolator, with and without artificial cells, at each beta to the talk's later time.

    Args:
        betas: velocity gradients (1/s).
        cells: cells of the bar.
        ppc: particles per cell.

    Returns:
        The runs, every step saved.
    """
    steps = int(round(TIMES[-1] / DT))
    saveat = jm.SaveAt(every=1, fields=("x", "v", "F", "sigma"))
    runs = []
    for method, make in METHODS.items():
        for ac in (0, 1):
            for beta in betas:
                scene = jm.GasExpansion(beta=beta, cells=cells, ppc=ppc)
                sol, compile_s, wall_s = jm.simulate_timed(
                    scene, make(), dt=DT, steps=steps, artificial_cells=ac, saveat=saveat, throw=False
                )
                runs.append(Run(method, ac, beta, scene, sol, wall_s, compile_s))
    return runs


def state_at(sol: jm.Solution, k: int) -> jm.State:
    """The saved state at history index ``k``.

    Args:
        sol: a solution saved every step.
        k: the step (``t = k DT``).

    Returns:
        Its state at step ``k`` (``t``, ``x``, ``v``, ``F`` and ``sigma`` from the history), healthy
        (status 0) before a breakdown and with the run's status from it on.
    """
    h = sol.history
    st = sol.state
    failed_at = int(st.fail_step)
    healthy = {}
    if failed_at >= 0 and k < failed_at:  # a state the run reached before it broke down
        none = jnp.full_like(st.fail_step, -1)
        healthy = dict(status=jnp.zeros_like(st.status), fail_step=none, fail_particle=none)
    return dataclasses.replace(
        st, t=sol.ts[k], x=h["x"][k], v=h["v"][k], F=h["F"][k], sigma=h["sigma"][k], **healthy
    )


def rows(runs: list[Run]) -> list[dict]:
    """The errors of each run at each of the talk's times (NaN after a breakdown).

    Args:
        runs: the runs.

    Returns:
        One row per run and time, with the keys ``COLUMNS``.
    """
    out = []
    for r in runs:
        for t in TIMES:
            k = int(round(t / DT))
            failed_at = int(r.solution.state.fail_step)
            reached = failed_at < 0 or k < failed_at
            err = jm.errors(r.scene, state_at(r.solution, k), r.solution.body) if reached else None
            row = dict(
                method=r.method,
                artificial_cells=r.artificial_cells,
                beta=r.beta,
                t=t,
                status="ok" if reached else f"broke down at step {failed_at}",
                wall_s=r.wall_s,
                compile_s=r.compile_s,
            )
            for key in COLUMNS[4:10]:
                row[key] = float(err[key]) if reached and err[key] is not None else float("nan")
            out.append(row)
    return out


def markdown_table(table: list[dict]) -> str:
    """The rows as a markdown table.

    Args:
        table: what ``rows`` returns.

    Returns:
        The table, one line per row.
    """
    head = (
        "| method | AC | beta (1/s) | t (s) | max rel F err | boundary | interior | max abs x err (m) "
        "| max abs v err (m/s) | max separation | status | run (ms) | compile (s) |"
    )
    lines = [head, "|" + "---|" * 13]

    def e(v):  # a run's error, or "-" where it has none (after a breakdown)
        return "-" if math.isnan(v) else f"{v:.3e}"

    for r in table:
        lines.append(
            f"| {r['method']} | {r['artificial_cells']} | {r['beta']:g} | {r['t']:g} | "
            f"{e(r['F_max_rel'])} | {e(r['F_max_rel_boundary'])} | {e(r['F_max_rel_interior'])} | "
            f"{e(r['x_max_abs'])} | {e(r['v_max_abs'])} | {e(r['separation_max'])} | {r['status']} | "
            f"{1e3 * r['wall_s']:.2f} | {r['compile_s']:.2f} |"
        )
    return "\n".join(lines) + "\n"


def figures(runs: list[Run], out: pathlib.Path, betas) -> list[pathlib.Path]:
    """F, x and v along the bar against the exact solution at each time, and the domain separation
    over time (at the largest beta), as PNGs.

    Args:
        runs: the runs.
        out: the output directory.
        betas: the velocity gradients, in the order of the colours.

    Returns:
        The paths written.
    """
    from .. import plotting

    colours = dict(zip(betas, ("tab:blue", "tab:orange", "tab:red", "tab:green", "tab:purple")))
    paths = []
    wrap = 55 * len({r.method for r in runs})  # characters of 7 pt across the grid's width
    for t in TIMES:
        k = int(round(t / DT))
        for qty, ylabel in (
            ("F", "F / F_exact"),
            ("x", "(x - x_exact) / h"),
            ("v", "(v - v_exact) / (beta L)"),
        ):
            panels: dict = {}
            left_out = []
            for r in runs:
                sol = r.solution
                row = "artificial cells" if r.artificial_cells else "no artificial cells"
                failed_at = int(sol.state.fail_step)
                if failed_at >= 0 and k >= failed_at:  # never plot a state the run did not reach
                    panels.setdefault((row, r.method), [])
                    left_out.append(f"{r.method}, {row}, beta = {r.beta:g}: broke down at step {failed_at}")
                    continue
                X = np.asarray(sol.body.X[:, 0])
                L = float(r.scene.length)
                st = state_at(sol, k)
                ex = jm.metrics.exact_fields(r.scene, sol.body, st.t)
                if qty == "F":
                    y = np.asarray(st.F[:, 0, 0]) / np.asarray(ex["F"][:, 0, 0])
                elif qty == "x":
                    y = (np.asarray(st.x[:, 0]) - np.asarray(ex["x"][:, 0])) / float(r.scene.h)
                else:
                    y = (np.asarray(st.v[:, 0]) - np.asarray(ex["v"][:, 0])) / (r.beta * L)
                style = dict(color=colours[r.beta], marker="o", ms=3, lw=1)
                panels.setdefault((row, r.method), []).append((f"beta = {r.beta:g}", X / L, y, style))
            path = OUTPUTS.check(out / f"{qty}_t{t:g}.png")
            plotting.profile_grid(
                panels,
                ylabel=ylabel,
                path=path,
                exact_line=1.0 if qty == "F" else 0.0,
                title=f"Gas expansion u = beta t X at t = {t:g} s: {ylabel} along the bar",
                overwrite=True,  # a rerun of the study replaces its own figures
                note=textwrap.fill("Not drawn, broke down before this time: " + "; ".join(left_out), wrap)
                if left_out
                else None,
            )
            paths.append(path)
    beta = max(betas)
    series: dict = {}
    for r in runs:
        if r.beta != beta:
            continue
        body = r.solution.body
        ts = np.asarray(r.solution.ts)
        n = len(ts) if int(r.solution.state.fail_step) < 0 else int(r.solution.state.fail_step)
        sep = [float(np.max(np.abs(jm.separation(state_at(r.solution, k), body)))) for k in range(n)]
        panel = "artificial cells" if r.artificial_cells else "no artificial cells"
        failed_at = int(r.solution.state.fail_step)
        label = r.method if failed_at < 0 else f"{r.method} (broke down at step {failed_at})"
        series.setdefault(panel, []).append((label, ts[:n], np.maximum(sep, 1e-17)))
    path = OUTPUTS.check(out / "separation.png")
    plotting.time_series(
        series,
        ylabel="max |x_{p+1} - x_p - (F_{p+1} + F_p) r0| / (2 r0)",
        path=path,
        title=f"Domain separation over time, beta = {beta:g} 1/s",
        overwrite=True,
    )
    paths.append(path)
    return paths


def main(out: str, small: bool = False) -> dict:
    """Run the study and write ``table.md``, ``results.csv``, ``results.json`` and PNG figures to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: one beta and 4 cells instead of three betas and 8 cells.

    Returns:
        ``table`` (the rows of ``results.csv``) and ``figures`` (the paths written).

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("talk")
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    betas = (200.0,) if small else (100.0, 200.0, 400.0)
    cells = 4 if small else 8
    runs = run_all(betas, cells=cells, ppc=2)
    table = rows(runs)
    scene = runs[0].scene
    params = {
        k: (getattr(scene, k) if isinstance(v, int) else float(getattr(scene, k)))
        for k, v in scene.parameters().items()
        if k not in ("beta", "dim")
    }
    header = (
        f"# The talk's study: 1D gas expansion u = beta t X\n\n"
        f"Scene gas-expansion with {', '.join(f'{k}={v}' for k, v in params.items())}; "
        f"beta in {', '.join(f'{b:g}' for b in betas)} 1/s; dt = {DT:g} s; FLIP; float64. "
        f"Errors over real particles; 'boundary' is the first and last cell of the body. "
        f"Run time is one compiled run of {int(round(TIMES[-1] / DT))} steps saving every step; "
        f"compile time is measured apart, and is 0.00 where the run compiled for the first beta was "
        f"reused for the next (beta is a traced parameter: no recompilation). Both rows of a run "
        f"(t = {TIMES[0]:g} and {TIMES[1]:g}) come from the same run.\n\n"
    )
    OUTPUTS.text(outdir / "table.md", header + markdown_table(table))
    OUTPUTS.csv(outdir / "results.csv", table, COLUMNS)
    OUTPUTS.text(
        outdir / "results.json", dumps(dict(params=params, betas=list(betas), dt=DT, rows=table), indent=1)
    )
    paths = figures(runs, outdir, betas)
    print(header + markdown_table(table))
    print(
        "wrote "
        + ", ".join(
            str(p) for p in [outdir / "table.md", outdir / "results.csv", outdir / "results.json", *paths]
        )
    )
    return dict(table=table, figures=paths)
