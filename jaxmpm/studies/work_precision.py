"""Work-precision: each interpolator's error against its run time, across resolutions.

The large-amplitude neo-Hookean manufactured solution (where the interpolators differ most) runs to a
quarter period with the CFL-limited step at 16 to 1,024 cells (32 to 2,048 particles). Run time is the
best of three calls of the compiled run (results on the host); compile time is measured apart, once
per resolution. Error is the RMS displacement error (absolute) at the end time.
"""

from __future__ import annotations

import pathlib
import time

import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps

from ._methods import METHODS
from ._output import Files
from ._runtime import require_float64

OUTPUTS = Files("work_precision.md", "work_precision.csv", "work_precision.json", "work_precision.png")
"""The files the study writes."""

CFL = 0.5
COLUMNS = ("method", "cells", "particles", "steps", "x_rms_abs", "F_rms_rel", "wall_s", "compile_s", "status")


def scene(cells: int) -> jm.Manufactured:
    """The large-amplitude neo-Hookean manufactured solution (``A = 0.05``) on ``cells`` cells of [0, 1].

    Args:
        cells: cells.

    Returns:
        The scene.
    """
    return jm.Manufactured(A=0.05, cells=cells, h=1.0 / cells)


def run(method: str, cells: int, repeats: int = 3) -> dict:
    """Run one interpolator at one resolution to a quarter period, keeping the best run time.

    Args:
        method: the interpolator's label (``METHODS``).
        cells: cells.
        repeats: calls of the compiled run.

    Returns:
        One row with the keys ``COLUMNS`` (errors NaN after a breakdown).
    """
    import jax

    sc = scene(cells)
    t_end = 0.5 / float(sc.wave_speed)
    kw = dict(t_end=t_end, cfl=CFL, max_steps=int(4 * cells / CFL) + 20, throw=False)
    sol, compile_s, wall_s = jm.simulate_timed(sc, METHODS[method](), **kw)
    for _ in range(repeats - 1):  # the same compiled run again (simulate's cache): keep the best
        t0 = time.perf_counter()
        jax.block_until_ready(jm.simulate(sc, METHODS[method](), **kw))
        wall_s = min(wall_s, time.perf_counter() - t0)
    fail = sol.failure()
    err = jm.errors(sc, sol.state, sol.body) if fail is None else None
    return dict(
        method=method,
        cells=cells,
        particles=sol.body.n,
        steps=int(sol.state.step),
        x_rms_abs=float(err["x_rms_abs"]) if fail is None else float("nan"),
        F_rms_rel=float(err["F_rms_rel"]) if fail is None else float("nan"),
        wall_s=wall_s,
        compile_s=compile_s,
        status="ok"
        if fail is None
        else f"broke down at step {fail['step']}: {'; '.join(fail['quantities'])}",
    )


def markdown(rows: list[dict]) -> str:
    """The rows as a markdown table.

    Args:
        rows: the ``run`` results.

    Returns:
        The table.
    """
    lines = [
        "| method | cells | particles | steps | x RMS err | F RMS rel err | run (ms) | compile (s) "
        "| status |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ok = r["status"] == "ok"  # a run that broke down has no errors to show: its status says why
        x_err, F_err = (f"{r[k]:.3e}" if ok else "-" for k in ("x_rms_abs", "F_rms_rel"))
        lines.append(
            f"| {r['method']} | {r['cells']} | {r['particles']} | {r['steps']} | {x_err} | "
            f"{F_err} | {1e3 * r['wall_s']:.2f} | {r['compile_s']:.2f} | {r['status']} |"
        )
    return "\n".join(lines) + "\n"


def figure(rows: list[dict], path: pathlib.Path) -> None:
    """Error against run time, one curve per interpolator, as a PNG.

    Args:
        rows: the ``run`` results.
        path: where to write the PNG.
    """
    from ..plotting import figure as new_figure

    fig = new_figure(figsize=(6.5, 4.5))
    ax = fig.subplots()
    for method in dict.fromkeys(r["method"] for r in rows):
        rs = [r for r in rows if r["method"] == method and np.isfinite(r["x_rms_abs"])]
        broken = [r["cells"] for r in rows if r["method"] == method and not np.isfinite(r["x_rms_abs"])]
        label = method + (f" (not shown, broke down: {', '.join(map(str, broken))} cells)" if broken else "")
        ax.loglog([r["wall_s"] for r in rs], [r["x_rms_abs"] for r in rs], "o-", label=label)
    cells = [r["cells"] for r in rows]
    ax.set_xlabel("run time (s), compiled, best of 3")
    ax.set_ylabel("RMS displacement error (m)")
    ax.set_title(f"Work-precision: neo-Hookean, A = 0.05, {min(cells)} to {max(cells)} cells")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    OUTPUTS.figure(fig, path, dpi=120)


def main(out: str, small: bool = False) -> dict:
    """Run the study; write ``work_precision.{md,csv,json,png}`` to ``out``.

    Needs float64 on (``jaxmpm study`` switches it on).

    Args:
        out: the output directory (created).
        small: 16 to 64 cells instead of 16 to 1,024.

    Returns:
        ``rows``: one dict per interpolator and resolution.

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("work-precision")
    import jax

    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    resolutions = (16, 32, 64) if small else (16, 32, 64, 128, 256, 512, 1024)
    rows = [run(m, n) for m in METHODS for n in resolutions]
    device = jax.devices()[0]
    head = (
        "# Work-precision\n\n"
        f"Manufactured neo-Hookean solution, A = 0.05, to t = 1/(2c); CFL {CFL}; FLIP, USL, float64; "
        f"{device.platform} ({device.device_kind}). Run time: best of 3 calls of the compiled run; "
        "compile time apart.\n\n"
    )
    text = head + markdown(rows)
    OUTPUTS.text(outdir / "work_precision.md", text)
    OUTPUTS.csv(outdir / "work_precision.csv", rows, COLUMNS)
    OUTPUTS.text(outdir / "work_precision.json", dumps(rows, indent=1))
    figure(rows, outdir / "work_precision.png")
    print(text)
    return dict(rows=rows)
