"""How well calibration recovers known constants: the numbers of the calibration page's "Measured" list.

The data come from outside the MPM, the diffrax reference of a gas slab (``jm.reference.gas_slab``, 400
cells) with ``p_atm = rho0 = L = 1``, ``gamma = 1.3``, ``P0 = 4.2``, or from the model itself where a
known truth of the model is the point (noise draws, a grid that just holds the data). The model is
CPDI; the fits are ``jaxmpm.calibrate``'s, the settings those of ``tests/test_calibration_truth.py``,
whose assertions bound the same quantities. Writes ``results.json`` and ``table.md`` to ``--out``
(the calibration page includes the table).

    python experiments/calibration_truth.py --out docs/calibration_truth --overwrite

A file already in ``--out`` is refused, before anything is computed, unless ``--overwrite``.
"""

import argparse
import json
import pathlib
import time
import warnings

import jax
import numpy as np

import jaxmpm as jm
from jaxmpm import calibrate as cal
from jaxmpm.scenes.gas_slab import pad_for
from jaxmpm.studies._output import write_text
from jaxmpm.studies._runtime import machine

FILES = ("results.json", "table.md")
"""The files written to ``--out``."""
UNIT = dict(p_atm=1.0, rho0=1.0)
TRUTH = dict(gamma=1.3, P0=4.2)
START = dict(gamma=1.6, P0=3.0)


def _dt(scene) -> float:
    return 0.2 * float(scene.h) / float(scene.wave_speed)


def _off(fitted: dict, truth: dict) -> dict:
    """Relative error of each fitted constant, in percent."""
    return {k: 100.0 * (fitted[k] - v) / v for k, v in truth.items()}


def reference() -> dict:
    """The reference trajectory to t = 4 (81 samples), its reach and first turnaround."""
    ts = np.linspace(0.0, 4.0, 81)
    ref = jm.reference.gas_slab(jm.GasSlab(**TRUTH, **UNIT), ts, cells=400)
    x = np.asarray(ref.x_free)
    return dict(ts=ts, x=x, x_max=float(x.max()), t_turn=float(ts[np.argmax(x)]))


def window_fit(ref: dict, cells: int, t_end: float) -> dict:
    """A fit of the reference to ``t <= t_end`` with ``cells`` cells, started 23% and 29% off."""
    keep = ref["ts"] <= t_end
    ts, x = ref["ts"][keep], ref["x"][keep]
    model = dict(cells=cells, h=1.0 / cells, **UNIT)
    scene = jm.GasSlab(**model, pad=pad_for(jm.GasSlab(**model), 1.25 * x.max()))
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cal.CalibrationWarning)  # kept in Fit.warning
        fit = cal.calibrate(scene, jm.CPDI(), ts, x, starts=START, dt=_dt(jm.GasSlab(**START, **model)))
    wall = time.perf_counter() - t0
    return dict(
        cells=cells,
        t_end=t_end,
        fitted=fit.fitted,
        off_percent=_off(fit.fitted, TRUTH),
        std=fit.std,
        correlation=float(fit.correlation[0, 1]),
        warning=fit.warning,
        converged=bool(fit.converged),
        iterations=int(fit.iterations),
        wall_s=wall,
    )


def noise_draws(draws: int = 64, sigma: float = 0.02) -> dict:
    """``draws`` data sets of the model's own trajectory to 12 ms (8 cells) plus noise of ``sigma``,
    fitted in one vmap-ed batch: how often the one-standard-error interval holds the truth, and the
    mean reported standard error against the spread of the fitted values."""
    ts = np.linspace(0.0, 12e-3, 61)
    slab = dict(cells=8, h=1 / 8, pad=48)
    truth = jm.GasSlab(gamma=1.4, P0=3e5, **slab)
    dt = _dt(truth)
    x = np.asarray(cal.trajectory(truth, jm.CPDI(), ts, dt=dt))
    X = x + sigma * np.random.default_rng(1).standard_normal((draws, x.size))
    fits = cal.calibrate_each(jm.GasSlab(**slab), jm.CPDI(), ts, X, start=dict(gamma=1.45, P0=2.9e5), dt=dt)
    out = dict(draws=draws, sigma=sigma, converged=sum(bool(f.converged) for f in fits))
    for k, v in dict(gamma=1.4, P0=3e5).items():
        values = np.array([f.fitted[k] for f in fits])
        std = np.array([f.std[k] for f in fits])
        out[k] = dict(
            coverage=float(np.mean(np.abs(values - v) <= std)),
            std_over_spread=float(np.mean(std) / np.std(values, ddof=1)),
        )
    out["binomial_sd"] = float(np.sqrt(0.68 * 0.32 / draws))
    out["sigma_fitted"] = float(np.mean([f.sigma for f in fits]))
    return out


def tight_grid() -> dict:
    """A grid that just holds the data (pad 54: to x = 4.375, data to 4.06): trial runs that leave it
    are rejected, and the fit still reaches the truth (the model's own trajectory, no noise)."""
    ts = np.linspace(0.0, 12e-3, 61)
    truth = jm.GasSlab(gamma=1.4, P0=3e5, cells=16, h=1 / 16, pad=96)
    dt = _dt(truth)
    x = np.asarray(cal.trajectory(truth, jm.CPDI(), ts, dt=dt))
    fit = cal.calibrate(
        jm.GasSlab(cells=16, h=1 / 16, pad=54), jm.CPDI(), ts, x, starts=dict(gamma=2.0, P0=1.3e5), dt=dt
    )
    return dict(
        rejected_broken=sum(bool(e["broke"]) for e in fit.rejected),
        off_relative=max(abs(fit.fitted[k] - v) / v for k, v in dict(gamma=1.4, P0=3e5).items()),
        converged=bool(fit.converged),
    )


def information() -> dict:
    """The expected correlation of gamma and P0 (Fisher information at the truth) for windows of 3 and
    12 ms, the default slab (CPDI, 16 cells)."""
    ts = np.linspace(0.0, 12e-3, 61)
    sc = jm.GasSlab(gamma=1.4, P0=3e5, cells=16, h=1 / 16, pad=96)
    info = cal.information(sc, jm.CPDI(), ts, dt=_dt(sc), noise=0.01)
    return {f"{t * 1e3:g} ms": float(info.correlation(t_end=t)[0, 1]) for t in (3e-3, 12e-3)}


def profile(ref: dict) -> dict:
    """The loss 5% along the weakest direction from the fit, over the fitted loss, for the windows to
    t = 1 and t = 4 (CPDI, 16 cells); ``None`` where a run along it broke down."""
    model = dict(cells=16, h=1 / 16, **UNIT)
    dt = _dt(jm.GasSlab(**START, **model))
    rises = {}
    for t_end in (1.0, 4.0):
        keep = ref["ts"] <= t_end
        ts, x = ref["ts"][keep], ref["x"][keep]
        scene = jm.GasSlab(**model, pad=pad_for(jm.GasSlab(**model), 1.6 * x.max()))
        fit = cal.calibrate(
            scene, jm.CPDI(), ts, x, starts=TRUTH, dt=dt, max_correlation=1.0, max_relative_std=10.0
        )
        prof = cal.profile(scene, jm.CPDI(), ts, x, fit, [-0.05, 0.0, 0.05], dt=dt)
        ends = prof["ok"][[0, 2]].all()  # a point whose run broke down has no loss: no rise
        rises[f"t <= {t_end:g}"] = float(min(prof["loss"][0], prof["loss"][2]) / fit.loss) if ends else None
    return rises


def _g(x: float, fmt: str = ".4g") -> str:
    return format(x, fmt)


def markdown(r: dict) -> str:
    """The table of the results."""
    ref = r["reference"]
    lines = [
        f"Reference: the slab reaches x = {ref['x_max']:.3g} and first turns back at t = "
        f"{ref['t_turn']:.3g}.",
        "",
        "| data | cells | gamma (off) | P0 (off) | std gamma, P0 | correlation | warning | iterations |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for f in r["windows"]:
        off = f["off_percent"]
        warn = "-" if f["warning"] is None else f["warning"].split(":")[0]  # its first clause
        lines.append(
            f"| reference to t = {f['t_end']:g} | {f['cells']} | "
            f"{_g(f['fitted']['gamma'])} ({off['gamma']:+.2f}%) "
            f"| {_g(f['fitted']['P0'])} ({off['P0']:+.2f}%) | {_g(f['std']['gamma'], '.2g')}, "
            f"{_g(f['std']['P0'], '.2g')} | {f['correlation']:.5f} | {warn} | {f['iterations']} |"
        )
    n = r["noise_draws"]
    lines += [
        "",
        f"{n['draws']} noise draws of {n['sigma'] * 100:g} cm on the model's own trajectory to 12 ms "
        f"(8 cells), "
        f"one vmap-ed batch ({n['converged']} converged): the one-standard-error intervals hold the truth "
        f"in {100 * n['gamma']['coverage']:.1f}% (gamma) and {100 * n['P0']['coverage']:.1f}% (P0) of the "
        f"draws (68% expected, binomial spread {100 * n['binomial_sd']:.1f}%); the mean reported standard "
        f"error over the spread of the fitted values is {n['gamma']['std_over_spread']:.3f} (gamma) and "
        f"{n['P0']['std_over_spread']:.3f} (P0); the fitted noise level {n['sigma_fitted']:.4g}.",
        "",
        f"A grid that just holds the data: {r['tight_grid']['rejected_broken']} trial runs that broke down "
        f"were rejected, and the fit reached the truth to {r['tight_grid']['off_relative']:.1e} "
        f"(converged: {r['tight_grid']['converged']}).",
        "",
        "Expected correlation of gamma and P0 (Fisher information at the truth, CPDI, 16 cells): "
        + ", ".join(f"{v:.4f} for a window of {k}" for k, v in r["information"].items())
        + ".",
        "",
        "The loss 5% along the weakest direction over the fitted loss (CPDI, 16 cells): "
        + ", ".join(
            f"{'-' if v is None else format(v, '.3f')} with data to {k}" for k, v in r["profile"].items()
        )
        + ".",
        "",
        f"Machine: {r['machine']}; total {r['wall_s']:.0f} s.",
        "",
    ]
    return "\n".join(lines)


def measure() -> dict:
    """Every measurement, in float64 (``main`` switches it on).

    Returns:
        The results (``results.json``).
    """
    t0 = time.perf_counter()
    ref = reference()
    result = dict(
        reference=dict(x_max=ref["x_max"], t_turn=ref["t_turn"]),
        windows=[window_fit(ref, cells, t_end) for t_end in (4.0, 1.0) for cells in (16, 64)],
        noise_draws=noise_draws(),
        tight_grid=tight_grid(),
        information=information(),
        profile=profile(ref),
        machine=machine(),
    )
    result["wall_s"] = time.perf_counter() - t0
    return result


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", required=True, help="folder for results.json and table.md")
    parser.add_argument("--overwrite", action="store_true", help="replace results.json and table.md there")
    args = parser.parse_args(argv)
    path = pathlib.Path(args.out)
    if path.exists() and not path.is_dir():
        parser.error(f"--out {args.out} is a file, not a folder")
    for name in FILES:
        if (path / name).is_dir():
            parser.error(f"--out {args.out}: {name} is a folder, where this script writes a file")
        if (path / name).exists() and not args.overwrite:
            parser.error(f"--out {args.out} already holds {name}; pass --overwrite to replace it")
    jax.config.update("jax_enable_x64", True)
    result = measure()
    path.mkdir(parents=True, exist_ok=True)
    write_text(path / "results.json", json.dumps(result, indent=1, allow_nan=False) + "\n")
    write_text(path / "table.md", markdown(result))
    return result


if __name__ == "__main__":
    main()
