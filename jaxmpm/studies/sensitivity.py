"""Sensitivity of the talk's F error to the velocity gradient beta and to the grid spacing h.

For every interpolator, with and without artificial cells, the RMS relative F error of the gas
expansion at t = 0.00125 and its derivative (``jax.grad``, batched over the parameter with
``jax.vmap``) are computed across beta (at the default h) and across h (at the default beta; the
cell count is fixed, so the bar's length scales with h). Runs that break down are reported with
their status and left out of the curves, never plotted as numbers.
"""

from __future__ import annotations

import pathlib
import time

import numpy as np

import jaxmpm as jm

from ._methods import METHODS
from ._output import csv_text, save_figure, write_text
from ._runtime import require_float64

DT = 1.0e-5
STEPS = 125  # t = 0.00125, the talk's later time


def sweep(
    method: str, artificial_cells: int, param: str, values, cells: int = 8, ordering: str = "usl"
) -> dict:
    """Error and d(error)/d(param) at each value, in one compiled, vmapped call.

    Args:
        method: the interpolator's label (``METHODS``).
        artificial_cells: layers of artificial cells.
        param: ``"beta"`` or ``"h"``.
        values: the values of ``param``.
        cells: cells of the bar.
        ordering: ``"usl"`` or ``"musl"``.

    Returns:
        ``method``, ``artificial_cells``, ``param``, ``values``, ``error`` and ``derivative`` (NaN
        where the run broke down), ``status`` and ``wall_s``.
    """
    import jax
    import jax.numpy as jnp

    make = METHODS[method]

    def run(p):
        scene = jm.GasExpansion(cells=cells, **{param: p})
        sol = jm.simulate(
            scene,
            make(),
            dt=DT,
            steps=STEPS,
            artificial_cells=artificial_cells,
            throw=False,
            ordering=ordering,
        )
        return jm.errors(scene, sol.state, sol.body)["F_rms_rel"], sol.state.status

    t0 = time.perf_counter()
    (err, status), grad = jax.vmap(jax.value_and_grad(run, has_aux=True))(jnp.asarray(values, dtype=float))
    err, status, grad = (np.asarray(a) for a in (err, status, grad))
    ok = status == 0
    return dict(
        method=method,
        artificial_cells=artificial_cells,
        param=param,
        values=np.asarray(values, dtype=float),
        error=np.where(ok, err, np.nan),
        derivative=np.where(ok, grad, np.nan),
        status=status,
        wall_s=time.perf_counter() - t0,
    )


def run_all(betas, hs, cells: int = 8, ordering: str = "usl") -> list[dict]:
    """Sweep beta and h for every interpolator, with and without artificial cells.

    Args:
        betas: values of beta (at the default h).
        hs: values of h (at the default beta).
        cells: cells of the bar.
        ordering: ``"usl"`` or ``"musl"``.

    Returns:
        The ``sweep`` results.
    """
    out = []
    for method in METHODS:
        for ac in (0, 1):
            out.append(sweep(method, ac, "beta", betas, cells, ordering))
            out.append(sweep(method, ac, "h", hs, cells, ordering))
    return out


def figure(results: list[dict], param: str, path, unit: str, ordering: str = "usl") -> None:
    """The error and its derivative against ``param``, one curve per interpolator, as a PNG.

    Args:
        results: the ``sweep`` results.
        param: ``"beta"`` or ``"h"``.
        path: where to write the PNG.
        unit: the derivative's unit.
        ordering: the ordering the runs used, for the title.
    """
    from ..plotting import figure as new_figure

    fig = new_figure(figsize=(11, 4))
    axes = fig.subplots(1, 2)
    colours = {name: f"C{i}" for i, name in enumerate(METHODS)}  # matplotlib's colour cycle, one each
    for r in results:
        if r["param"] != param:
            continue
        style = dict(color=colours[r["method"]], ls="--" if r["artificial_cells"] else "-", marker="o", ms=3)
        label = r["method"] + (" + AC" if r["artificial_cells"] else "")
        broke = [f"{v:g}" for v, st in zip(r["values"], r["status"]) if st != 0]
        if broke:  # a run that broke down is a gap in the curve (NaN): the legend names it
            label += f" (broke down at {param} = {', '.join(broke)})"
        axes[0].semilogy(r["values"], r["error"], label=label, **style)
        axes[1].plot(r["values"], r["derivative"], label=label, **style)
    axes[0].set_ylabel("RMS relative F error at t = 0.00125 s")
    axes[1].set_ylabel(f"d(error) / d({param})  ({unit})")
    axes[1].axhline(0, color="k", lw=0.6)
    axes[1].set_yscale("symlog", linthresh=1e-6 if param == "beta" else 1e-3)
    for ax in axes:
        ax.set_xlabel(f"{param} ({'1/s' if param == 'beta' else 'm'})")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle(
        f"Sensitivity of the F error to {param}, {ordering.upper()} (jax.grad, vmapped; dashed: with AC)"
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def main(out: str, small: bool = False, ordering: str = "usl") -> list[dict]:
    """Write ``sensitivity[_musl].csv`` and ``sensitivity_{beta,h}[_musl].png`` to ``out``.

    Needs float64 on (``experiments/sensitivity.py`` switches it on).

    Args:
        out: the output directory (created).
        small: fewer values of beta and h, 4 cells instead of 8.
        ordering: ``"usl"`` or ``"musl"``.

    Returns:
        The ``sweep`` results.

    Raises:
        RuntimeError: float64 is off.
        OSError: a file cannot be written (each is written whole: it keeps what it held before).
    """
    require_float64("sensitivity")
    outdir = pathlib.Path(out)
    outdir.mkdir(parents=True, exist_ok=True)
    betas = np.linspace(50.0, 400.0, 4 if small else 15)
    hs = np.linspace(0.05, 0.25, 3 if small else 9)
    results = run_all(betas, hs, cells=4 if small else 8, ordering=ordering)
    tag = "" if ordering == "usl" else f"_{ordering}"
    names = (f"sensitivity{tag}.csv", f"sensitivity_beta{tag}.png", f"sensitivity_h{tag}.png")
    lines = [["method", "artificial_cells", "param", "value", "F_rms_rel", "derivative", "status"]]
    for r in results:
        for v, e, d, s in zip(r["values"], r["error"], r["derivative"], r["status"]):
            lines.append(
                [
                    r["method"],
                    r["artificial_cells"],
                    r["param"],
                    repr(float(v)),
                    repr(float(e)),
                    repr(float(d)),
                    int(s),
                ]
            )
    write_text(outdir / names[0], csv_text(lines, None))
    figure(results, "beta", outdir / names[1], "s", ordering)
    figure(results, "h", outdir / names[2], "1/m", ordering)
    for r in results:
        broke = int(np.sum(r["status"] != 0))
        print(
            f"{r['method']:>6} AC={r['artificial_cells']} {r['param']:>4}: error {np.nanmin(r['error']):.2e}"
            f"..{np.nanmax(r['error']):.2e}, derivative {np.nanmin(r['derivative']):+.2e}.."
            f"{np.nanmax(r['derivative']):+.2e}, {broke} broke down, {r['wall_s']:.1f} s"
        )
    print("wrote " + ", ".join(str(outdir / n) for n in names))
    return results
