"""Calibration that tells the truth: uncertainty, identifiability, broken trial runs, experiment design.

The data of the identifiability tests come from outside the MPM: the diffrax reference
(``jm.reference.gas_slab``, 400 cells) of a slab with ``p_atm = rho0 = L = 1`` at ``gamma = 1.3``,
``P0 = 4.2``, which expands to 6.75 times its length and first turns back at ``t = 3.35``. The model
is CPDI at 16 cells.
"""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import calibration_case, usage

import jaxmpm as jm
from jaxmpm import calibrate as cal
from jaxmpm.cli import main
from jaxmpm.scenes.gas_slab import pad_for

pytestmark = pytest.mark.slow

UNIT = dict(p_atm=1.0, rho0=1.0)
TRUTH = dict(gamma=1.3, P0=4.2)
START = dict(gamma=1.6, P0=3.0)
MODEL = dict(cells=16, h=1 / 16, **UNIT)


def _dt(scene):
    return 0.2 * float(scene.h) / float(scene.wave_speed)


@pytest.fixture(scope="module")
def reference():
    """The reference trajectory to t = 4 (past the first turnaround, 81 samples)."""
    ts = np.linspace(0.0, 4.0, 81)
    ref = jm.reference.gas_slab(jm.GasSlab(**TRUTH, **UNIT), ts, cells=400)
    return ts, np.asarray(ref.x_free)


def _csv(path, t, x):
    np.savetxt(path, np.c_[t, x], delimiter=",", header="t,x_free", comments="")
    return str(path)


def test_the_slab_bounds_its_reach_and_estimates_its_turnaround(reference):
    ts, x = reference
    slab = jm.GasSlab(**TRUTH, **UNIT)
    # W(F_max) = W(1) with W(F) = P0 F^(1-gamma)/(gamma-1) + p_atm F
    F = slab.max_reach()
    W = lambda F: 4.2 * F ** (1 - 1.3) / 0.3 + F  # noqa: E731
    assert W(F) == pytest.approx(W(1.0), rel=1e-12) and F > float(slab.F_eq)
    assert x.max() < F < 1.1 * x.max()  # 6.75 < 7.28: a bound, and a close one
    assert slab.max_reach(0.1) == pytest.approx(1 + 2 * np.sqrt(1.3 * 4.2) * 0.1 / 0.3, rel=1e-12)
    # the uniform-stretch estimate is about 10% before the reference's first turnaround (t = 3.35)
    assert 0.85 < slab.turnaround_estimate() / ts[np.argmax(x)] < 0.95
    assert pad_for(jm.GasSlab(cells=16, h=1 / 16), 2.0) == 16 + 4


def test_the_long_window_recovers_the_constants_with_no_warning(reference):
    ts, x = reference
    scene = jm.GasSlab(**MODEL)
    scene = jm.GasSlab(**MODEL, pad=pad_for(scene, 1.25 * x.max()))
    fit = cal.calibrate(scene, jm.CPDI(), ts, x, starts=START, dt=_dt(jm.GasSlab(**START, **MODEL)))
    assert fit.warning is None and fit.converged and fit.method == "lm"
    for k, v in TRUTH.items():  # measured -3.1e-3 and 3.2e-3, standard errors 1.7e-3 and 1.9e-3 relative
        assert fit.fitted[k] == pytest.approx(v, rel=6e-3), fit.fitted
        assert 0 < fit.std[k] < 4e-3 * v
    corr = fit.correlation
    assert corr.shape == (2, 2) and np.allclose(np.diag(corr), 1) and abs(corr[0, 1]) < 0.99
    assert np.allclose(corr, corr.T) and np.isfinite(fit.condition) and fit.condition > 1
    # the covariances in the fit's variables and the physical ones: C_phys = D C_theta D
    D = np.array([fit.fitted[k] - fit.offsets[k] for k in fit.names])
    np.testing.assert_allclose(fit.covariance, fit.covariance_theta * np.outer(D, D), rtol=1e-12)
    np.testing.assert_allclose(np.sqrt(np.diag(fit.covariance)), [fit.std[k] for k in fit.names], rtol=1e-12)
    # sigma from the residuals: sqrt(sum r^2 / (n - p))
    assert fit.sigma == pytest.approx(np.sqrt(np.sum(fit.residuals**2) / (ts.size - 2)), rel=1e-12)
    assert fit.loss == pytest.approx(np.mean((fit.residuals / 1.0) ** 2), rel=1e-12)


def test_the_short_window_warns_that_the_data_cannot_separate_gamma_and_P0(reference):
    ts, x = reference
    short = ts <= 1.0  # the free surface still moves at nearly constant speed
    scene = jm.GasSlab(**MODEL, pad=pad_for(jm.GasSlab(**MODEL), 1.25 * x[short].max()))
    with pytest.warns(cal.CalibrationWarning) as record:
        fit = cal.calibrate(
            scene, jm.CPDI(), ts[short], x[short], starts=START, dt=_dt(jm.GasSlab(**START, **MODEL))
        )
    assert str(record[0].message) == fit.warning
    assert abs(fit.correlation[0, 1]) > 0.99
    assert "gamma and P0 are correlated" in fit.warning
    assert "before the free surface's first turnaround" in fit.warning and "observe past it" in fit.warning
    # the weakest direction: gamma and P0 up together (the early speed fixes a combination of both)
    assert fit.weakest["gamma"] * fit.weakest["P0"] > 0
    # the thresholds are settable: with a looser bound on the correlation and the relative errors, no
    # warning (unless the fit did not converge)
    fit2 = cal.calibrate(
        scene,
        jm.CPDI(),
        ts[short],
        x[short],
        starts=fit.fitted,
        dt=_dt(jm.GasSlab(**START, **MODEL)),
        max_correlation=1.0,
        max_relative_std=10.0,
    )
    assert fit2.warning is None and fit2.converged


def test_lm_backs_off_trial_runs_that_break_down_and_never_uses_their_loss():
    # A grid that just holds the data (pad 54: to x = 4.375 for data to 4.06): from this start, trial
    # steps overshoot into slabs that leave the grid.
    ts = np.linspace(0.0, 12e-3, 61)
    truth = jm.GasSlab(gamma=1.4, P0=3e5, cells=16, h=1 / 16, pad=96)
    dt = _dt(truth)
    x = np.asarray(cal.trajectory(truth, jm.CPDI(), ts, dt=dt))
    fit = cal.calibrate(
        jm.GasSlab(cells=16, h=1 / 16, pad=54), jm.CPDI(), ts, x, starts=dict(gamma=2.0, P0=1.3e5), dt=dt
    )
    broke = [e for e in fit.rejected if e["broke"]]
    assert len(broke) >= 3, fit.rejected
    assert all(np.isnan(e["loss"]) for e in broke)
    whys = [e["why"] for e in broke if "why" in e]
    assert whys and all("broke down at step" in w and ", particle " in w for w in whys)
    assert any("particle left the grid" in w for w in whys)
    h = fit.history[:, 0]
    assert np.all(np.isfinite(h)) and np.all(np.diff(h) <= 0)  # only accepted, finite losses
    for e in broke:  # no broken trial's values became the fit's
        assert all(abs(e["values"][k] - fit.fitted[k]) > 1e-6 * fit.fitted[k] for k in fit.fitted)
    assert fit.converged and fit.warning is None
    assert fit.fitted["gamma"] == pytest.approx(1.4, rel=1e-6)
    assert fit.fitted["P0"] == pytest.approx(3e5, rel=1e-6)


def test_noise_draws_cover_the_truth_and_the_errors_match_the_spread():
    """64 synthetic data sets (the model's own trajectory plus Gaussian noise of 2 cm) fitted in one
    vmap-ed batch: the one-standard-error intervals hold the truth in about 68% of the draws. With 64
    draws the binomial standard deviation of that fraction is sqrt(0.68 0.32 / 64) = 0.058; the test
    allows 3 of them (0.51 to 0.86). The reported standard errors equal the spread of the fitted values
    within 30% (the spread's own sampling error is 9%)."""
    ts = np.linspace(0.0, 12e-3, 61)
    slab = dict(cells=8, h=1 / 8, pad=48)  # the model's own data: the coarsest model serves
    truth = jm.GasSlab(gamma=1.4, P0=3e5, **slab)
    dt = _dt(truth)
    x = np.asarray(cal.trajectory(truth, jm.CPDI(), ts, dt=dt))
    sigma = 0.02
    X = x + sigma * np.random.default_rng(1).standard_normal((64, x.size))
    fits = cal.calibrate_each(jm.GasSlab(**slab), jm.CPDI(), ts, X, start=dict(gamma=1.45, P0=2.9e5), dt=dt)
    assert all(f.converged and f.warning is None for f in fits)
    # each data set's iterations and history are its own, as a fit of that set alone gives them
    iterations = np.array([f.iterations for f in fits])
    assert iterations.min() < iterations.max()
    assert all(f.history.shape == (f.iterations + 1, 1) and f.history[-1, 0] == f.loss for f in fits)
    b = int(np.argmin(iterations))
    alone = cal.calibrate(jm.GasSlab(**slab), jm.CPDI(), ts, X[b], starts=dict(gamma=1.45, P0=2.9e5), dt=dt)
    assert alone.iterations == fits[b].iterations  # the fitted values: to round-off (batch of 64 or 1)
    assert alone.fitted == pytest.approx(fits[b].fitted, rel=1e-12)
    for k, v in dict(gamma=1.4, P0=3e5).items():
        values = np.array([f.fitted[k] for f in fits])
        std = np.array([f.std[k] for f in fits])
        cover = np.mean(np.abs(values - v) <= std)
        assert 0.68 - 3 * 0.058 <= cover <= 0.68 + 3 * 0.058, (k, cover)
        ratio = np.mean(std) / np.std(values, ddof=1)
        assert 0.7 < ratio < 1.3, (k, ratio)
    # the estimated noise level is the true one
    assert np.mean([f.sigma for f in fits]) == pytest.approx(sigma, rel=0.05)
    # the Fisher information at the truth predicts the same standard errors before any data exist
    info = cal.information(truth, jm.CPDI(), ts, dt=dt, noise=sigma)
    for k in ("gamma", "P0"):
        assert info.std()[k] == pytest.approx(np.mean([f.std[k] for f in fits]), rel=0.05)


def test_information_is_the_jacobian_of_the_trajectory_and_shrinks_with_the_window():
    ts = np.linspace(0.0, 12e-3, 61)
    sc = jm.GasSlab(gamma=1.4, P0=3e5, cells=16, h=1 / 16, pad=96)
    dt = _dt(sc)
    info = cal.information(sc, jm.CPDI(), ts, dt=dt, noise=0.01)
    # forward mode (information) against reverse mode: the same derivative to round-off
    names = ("gamma", "P0")

    def x_of(p):
        return cal.trajectory(
            jm.GasSlab(**{**sc.parameter_values(), **dict(zip(names, p))}), jm.CPDI(), ts, dt=dt
        )

    J_rev = np.asarray(jax.jacrev(x_of)(jnp.asarray([1.4, 3e5])))
    for j in range(2):  # per column: the columns' units differ (m per unit gamma, m per Pa)
        scale = np.max(np.abs(J_rev[:, j]))
        np.testing.assert_allclose(info.jacobian[:, j], J_rev[:, j], rtol=1e-9, atol=1e-12 * scale)
    # and central differences, to the accuracy they have: the MPM trajectory is only piecewise smooth
    # (particles crossing cells), so differences over a step agree to about 2e-4
    for j, (k, step) in enumerate((("gamma", 1e-5), ("P0", 1.0))):
        up = cal.trajectory(
            jm.GasSlab(**{**sc.parameter_values(), k: getattr(sc, k) + step}), jm.CPDI(), ts, dt=dt
        )
        dn = cal.trajectory(
            jm.GasSlab(**{**sc.parameter_values(), k: getattr(sc, k) - step}), jm.CPDI(), ts, dt=dt
        )
        fd = (np.asarray(up) - np.asarray(dn)) / (2 * step)
        np.testing.assert_allclose(info.jacobian[:, j], fd, rtol=1e-3, atol=1e-9 * np.max(np.abs(fd)))
    np.testing.assert_allclose(info.fisher(), info.jacobian.T @ info.jacobian / 0.01**2, rtol=1e-14)
    ends = [3e-3, 6e-3, 9e-3, 12e-3]
    stds = [info.std(t_end=t)["gamma"] for t in ends]
    assert all(a > b for a, b in zip(stds, stds[1:]))  # a longer window determines gamma better
    assert abs(info.correlation(t_end=3e-3)[0, 1]) > 0.99 > abs(info.correlation()[0, 1])
    # fewer samples and more noise: the standard errors scale as noise / sqrt(samples), nearly
    assert info.std(noise=0.02)["P0"] == pytest.approx(2 * info.std()["P0"], rel=1e-12)
    assert info.std(samples=16)["P0"] / info.std()["P0"] == pytest.approx(np.sqrt(61 / 16), rel=0.15)
    with pytest.raises(ValueError, match="noise"):
        cal.information(sc, jm.CPDI(), ts, dt=dt, noise=-1.0)


def test_profile_is_a_valley_for_a_short_window_and_a_bowl_for_a_long_one(reference):
    ts, x = reference
    dt = _dt(jm.GasSlab(**START, **MODEL))
    rises = {}
    for name, keep in (("short", ts <= 1.0), ("long", ts <= 4.0)):
        scene = jm.GasSlab(**MODEL, pad=pad_for(jm.GasSlab(**MODEL), 1.6 * x[keep].max()))
        fit = cal.calibrate(
            scene,
            jm.CPDI(),
            ts[keep],
            x[keep],
            starts=TRUTH,
            dt=dt,
            max_correlation=1.0,
            max_relative_std=10.0,
        )
        prof = cal.profile(scene, jm.CPDI(), ts[keep], x[keep], fit, [-0.05, 0.0, 0.05], dt=dt)
        assert prof["ok"].all() and prof["loss"][1] == pytest.approx(fit.loss, rel=1e-10)
        assert prof["gamma"][1] == pytest.approx(fit.fitted["gamma"], rel=1e-14)
        rises[name] = min(prof["loss"][0], prof["loss"][2]) / fit.loss
    # 5% along the weakest direction: the short window's loss rises by under 5% (a valley; 1.6%
    # measured), the long one's several times over (a bowl; 5.7 times measured)
    assert 1.0 <= rises["short"] < 1.05 and rises["long"] > 3.0, rises


def test_fit_sample_draws_admissible_constants_from_the_fitted_gaussian(reference):
    ts, x = reference
    scene = jm.GasSlab(**MODEL, pad=pad_for(jm.GasSlab(**MODEL), 1.25 * x.max()))
    fit = cal.calibrate(scene, jm.CPDI(), ts, x, starts=TRUTH, dt=_dt(jm.GasSlab(**START, **MODEL)))
    draws = fit.sample(20000, seed=3)
    assert draws["gamma"].min() > 1.0 and draws["P0"].min() > 1.0
    theta = np.stack([np.log(draws[k] - fit.offsets[k]) for k in fit.names], axis=1)
    np.testing.assert_allclose(np.cov(theta.T), fit.covariance_theta, rtol=0.05)
    assert np.mean(draws["gamma"]) == pytest.approx(fit.fitted["gamma"], abs=3 * fit.std["gamma"] / 100)
    with pytest.raises(ValueError, match="members"):
        fit.sample(0)


# -- the command line ----------------------------------------------------------------------------------


def test_cli_sizes_the_grid_for_the_data_and_recovers_the_constants(reference, tmp_path, capsys):
    ts, x = reference
    data = _csv(tmp_path / "traj.csv", ts, x)
    # 32 cells: the default pad (192 cells of 1/32) ends the grid at x = 7, too near the data's 6.75
    argv = ["calibrate", "gas-slab", "p_atm=1", "rho0=1", "cells=32", "h=0.03125", "--data", data]
    argv += ["--fit", "gamma,P0", "--start", "gamma=1.6,P0=3.0", "--json", "--no-progress"]
    assert main(argv) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert cap.err == ""
    assert out["pad"] == pad_for(jm.GasSlab(cells=32, h=1 / 32), 1.25 * x.max()) > 192
    assert out["warning"] is None and out["converged"] and out["method"] == "lm"
    for k, v in TRUTH.items():  # measured -1.5e-3 and 1.7e-3, standard errors 8.0e-4 and 8.8e-4 relative
        assert out["fitted"][k] == pytest.approx(v, rel=4e-3)
        assert 0 < out["std"][k] < 2e-3 * v
    assert abs(out["correlation"]["gamma"]["P0"]) < 0.99
    assert out["correlation"]["P0"]["P0"] == pytest.approx(1.0, rel=1e-14)
    assert out["condition"] > 1 and out["sigma"] > 0 and out["noise"] is None
    assert set(out) >= {"fitted", "loss", "iterations", "wall_s", "covariance", "covariance_theta", "offsets"}
    # the scene's other parameters, as the fit ran them: what a rerun needs
    assert out["fixed"] == {"p_atm": 1.0, "h": 0.03125, "rho0": 1.0, "cells": 32, "ppc": 2, "pad": out["pad"]}
    # with the grid of the default pad, the data are out of reach: refused before any run, naming pad
    assert main(argv[:6] + ["pad=96"] + argv[6:]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the grid ends at x = 4" in err[0] and f"use pad >= {out['pad']}" in err[0]
    # the fit's Gaussian drives an ensemble
    fit_json = tmp_path / "fit.json"
    fit_json.write_text(json.dumps(out))
    ens = ["ensemble", "gas-slab", "p_atm=1", "rho0=1", "cells=32", "h=0.03125", "--from-fit", str(fit_json)]
    assert main(ens + ["--members", "8", "--json"]) == 0
    e = json.loads(capsys.readouterr().out)
    assert e["ok"] == 8 and e["from_fit"] == ["gamma", "P0"] and e["pad"] > 192
    gammas = np.array([r["params"]["gamma"] for r in e["results"]])
    assert np.all(np.abs(gammas - out["fitted"]["gamma"]) < 6 * out["std"]["gamma"]) and np.ptp(gammas) > 0


def test_cli_short_window_warns_in_one_line_and_exits_0(reference, tmp_path, capsys):
    ts, x = reference
    data = _csv(tmp_path / "short.csv", ts[ts <= 1.0], x[ts <= 1.0])
    argv = ["calibrate", "gas-slab", "p_atm=1", "rho0=1", "cells=16", "h=0.0625", "--data", data]
    assert main(argv + ["--start", "gamma=1.6,P0=3.0", "--json", "--no-progress"]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0] == f"jaxmpm: warning: {out['warning']}"
    assert "correlated" in lines[0] and "turnaround" in lines[0]
    assert abs(out["correlation"]["gamma"]["P0"]) > 0.99


def test_cli_blocked_fit_exits_3_naming_the_breakdown_and_pad(tmp_path, capsys):
    ts = np.linspace(0.0, 12e-3, 61)
    x = np.asarray(jm.reference.gas_slab(jm.GasSlab(), ts, cells=400).x_free)
    data = _csv(tmp_path / "traj.csv", ts, x)
    dt = 0.2 * 0.0625 / float(np.sqrt(1.4 * 3e5))
    argv = [
        "calibrate",
        "gas-slab",
        "cells=16",
        "h=0.0625",
        "pad=52",
        "--interpolator",
        "gimp",
        "--dt",
        repr(dt),
    ]
    assert main(argv + ["--data", data, "--start", "gamma=1.82,P0=2.1e5", "--no-progress"]) == 3
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1, cap.err
    assert "every step toward a lower loss is a run that breaks down" in lines[0]
    assert "particle left the grid" in lines[0] and "raise pad (now 52)" in lines[0]


def test_cli_blocked_fit_with_json_prints_why_and_an_ensemble_refuses_it(tmp_path, capsys):
    """With ``--json`` a fit without an answer still prints one object (``fitted`` null, ``error`` the
    stderr line's reason), and ``ensemble --from-fit`` refuses that file by saying so."""
    ts = np.linspace(0.0, 12e-3, 61)
    x = np.asarray(jm.reference.gas_slab(jm.GasSlab(), ts, cells=400).x_free)
    data = _csv(tmp_path / "traj.csv", ts, x)
    dt = 0.2 * 0.0625 / float(np.sqrt(1.4 * 3e5))
    argv = ["calibrate", "gas-slab", "cells=16", "h=0.0625", "pad=52", "--interpolator", "gimp"]
    argv += ["--dt", repr(dt), "--data", data, "--start", "gamma=1.82,P0=2.1e5", "--no-progress", "--json"]
    assert main(argv) == 3
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert out["fitted"] is None and cap.err == f"jaxmpm: {out['error']}\n"
    assert "every step toward a lower loss is a run that breaks down" in out["error"]
    assert out["starts"] == [{"gamma": 1.82, "P0": 2.1e5}] and out["pad"] == 52 and out["dt"] == dt
    assert out["fixed"] == {"p_atm": 1e5, "h": 0.0625, "rho0": 1.0, "cells": 16, "ppc": 2, "pad": 52}
    fit = tmp_path / "fit.json"
    fit.write_text(cap.out)
    assert main(["ensemble", "gas-slab", "--from-fit", str(fit), "--members", "4"]) == 2
    err = capsys.readouterr().err
    assert err == f"jaxmpm: error: --from-fit: {fit} is a fit that has no answer: {out['error']}\n"


def test_cli_reports_the_loss_history_and_iterations_of_the_best_start(tmp_path, capsys):
    """The start that breaks down comes first: the reported history and iteration count are those of
    the best start, as a fit from that start alone gives them, not start 0's."""
    scene, t, data, starts, dt = calibration_case()
    starts = starts[::-1]
    path = _csv(tmp_path / "traj.csv", t, data)
    argv = ["calibrate", "gas-slab", "cells=16", "h=0.0625", "pad=96", "--data", path, "--dt", repr(dt)]
    for s in starts:
        argv += ["--start", ",".join(f"{k}={v!r}" for k, v in s.items())]
    assert main(argv + ["--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    best = out["best_start"]
    assert list(out["failed_starts"]) == ["0"] and best != 0
    history = out["loss_history"]
    assert len(history) == out["iterations"] + 1 and history[-1] == out["loss"]
    alone = jm.calibrate.calibrate(
        scene, jm.CPDI(), t, data, fit=("gamma", "P0"), starts=starts[best], dt=dt, progress=False
    )
    assert out["iterations"] == alone.iterations
    np.testing.assert_allclose(history, alone.history[:, 0], rtol=1e-9)


def test_cli_several_starts_report_the_best_and_the_one_that_broke_down(tmp_path, capsys):
    scene, t, data, starts, dt = calibration_case()
    path = _csv(tmp_path / "traj.csv", t, data)
    argv = ["calibrate", "gas-slab", "cells=16", "h=0.0625", "pad=96", "--data", path, "--dt", repr(dt)]
    for s in starts:
        argv += ["--start", ",".join(f"{k}={v!r}" for k, v in s.items())]
    assert main(argv + ["--devices", "1", "--json", "--no-progress"]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    # the start that broke down is named on stderr too (text and JSON alike), not only in the JSON
    assert (
        cap.err.startswith("jaxmpm: note: start 3 stopped and is not in the fit: ")
        and "broke down at step" in cap.err
    )
    assert out["starts"] == starts and len(out["starts_fitted"]) == 4
    assert list(out["failed_starts"]) == ["3"] and "broke down at step" in out["failed_starts"]["3"]
    assert out["starts_fitted"][3] is None and out["best_start"] != 3
    assert out["start"] == starts[out["best_start"]]
    assert out["fitted"] == out["starts_fitted"][out["best_start"]]
    # the loss history is the best start's: one entry per iteration it took and its start, ending
    # at the reported loss
    assert len(out["loss_history"]) == out["iterations"] + 1 and out["loss_history"][-1] == out["loss"]
    assert all(v is not None for v in out["loss_history"])
    assert out["fitted"]["gamma"] == pytest.approx(1.4, rel=6e-3)  # measured -2.3e-3
    assert out["fitted"]["P0"] == pytest.approx(3e5, rel=6e-3)  # measured -5.7e-4
    usage(
        capsys, argv + ["--method", "adam", "--devices", "1"], "--devices spreads the starts of --method lm"
    )
    usage(capsys, argv[:-2] + ["--start", "gamma=1.5,rho0=2"], "--start: rho0 is not fitted")


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--noise", "-1"], "--noise must be"),
        (["--noise", "nan"], "--noise must be"),
        (["--noise", "0"], "--noise must be"),
        (["--noise", "inf"], "--noise must be"),
        (["--max-correlation", "1.5"], "--max-correlation must be"),
        (["--max-correlation", "nan"], "--max-correlation must be"),
        (["--max-relative-std", "-0.1"], "--max-relative-std must be"),
    ],
)
def test_cli_bad_noise_and_thresholds_are_one_line(tmp_path, capsys, extra, match):
    data = _csv(tmp_path / "traj.csv", [0.0, 1e-3], [1.0, 1.5])
    usage(capsys, ["calibrate", "gas-slab", "--data", data, *extra], match)


@pytest.mark.parametrize(
    "content, match",
    [
        (None, "cannot read"),
        ("not json", "is not JSON"),
        ('{"fitted": {"gamma": 1.4}}', "is not the output of `jaxmpm calibrate --json`"),
        (
            '{"scene": "vibrating-bar", "fitted": {}, "covariance_theta": {}, "offsets": {}}',
            "is a fit of 'vibrating-bar'",
        ),
        (
            '{"fitted": {"gamma": 1.4}, "covariance_theta": {"gamma": {"gamma": null}}, '
            '"offsets": {"gamma": 1}}',
            "has no finite covariance",
        ),
        (
            '{"fitted": {"gamma": 1.4}, "covariance_theta": {"gamma": {"gamma": -1}}, '
            '"offsets": {"gamma": 1}}',
            "not symmetric positive semi-definite",
        ),
        ('{"fitted": {"cells": 4}, "covariance_theta": {}, "offsets": {}}', "'cells' is not a continuous"),
    ],
)
def test_cli_ensemble_from_fit_faults_are_one_line(tmp_path, capsys, content, match):
    path = tmp_path / "fit.json"
    if content is not None:
        path.write_text(content)
    usage(capsys, ["ensemble", "gas-slab", "--from-fit", str(path), "--members", "2"], match)


def test_cli_ensemble_needs_vary_or_from_fit(capsys):
    usage(
        capsys, ["ensemble", "gas-slab", "--members", "2"], "--vary NAME=LOW:HIGH (repeatable), or --from-fit"
    )


def test_cli_ensemble_grid_sizing_names_a_bad_corner_of_the_ranges(capsys):
    argv = ["ensemble", "gas-slab", "--vary", "P0=5e4:2e5", "--dt", "1e-5", "--steps", "2", "--members", "2"]
    usage(capsys, argv, "--vary: P0 must be > p_atm")


FIT_MPQ_VISCOUS = {
    "scene": "gas-slab",
    "interpolator": "mpq",
    "method": "lm",
    "dt": 2e-5,
    "pad": 48,
    "viscosity": [2.0, 0.2],
    "fixed": {"p_atm": 100000.0, "rho0": 1.0, "h": 0.125, "cells": 8, "ppc": 2},
    "fitted": {"gamma": 1.4, "P0": 300000.0},
    "offsets": {"gamma": 1.0, "P0": 100000.0},
    "covariance_theta": {"gamma": {"gamma": 1e-14, "P0": 0.0}, "P0": {"gamma": 0.0, "P0": 1e-14}},
}


@pytest.mark.slow
def test_cli_ensemble_from_fit_runs_the_fits_model(tmp_path, capsys):
    """The members of --from-fit run the model the constants were fitted in: the fit's interpolator and
    artificial viscosity (a member equals that model's own run), and another one is refused."""
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(FIT_MPQ_VISCOUS))
    argv = [
        "ensemble",
        "gas-slab",
        "--from-fit",
        str(path),
        "--members",
        "1",
        "--dt",
        "2e-5",
        "--steps",
        "50",
    ]
    assert main([*argv, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["interpolator"] == "mpq" and out["viscosity"] == [2.0, 0.2]
    (member,) = out["results"]
    params = {**FIT_MPQ_VISCOUS["fixed"], **member["params"], "pad": out["pad"]}
    sol = jm.simulate(
        jm.GasSlab(**params),
        jm.MPQ(),
        dt=2e-5,
        steps=50,
        viscosity=jm.ArtificialViscosity(c_quad=2.0, c_lin=0.2),
    )
    expected = jm.scenes.gas_slab.free_surface(sol.state.x, sol.state.F, sol.state.corners, sol.body)
    assert member["x_free"] == pytest.approx(float(expected), rel=1e-12)
    for extra, match in (
        (["--interpolator", "cpdi"], "--interpolator cpdi: the fit ran with mpq"),
        (["--viscosity", "1,0.1"], "--viscosity 1,0.1: the fit ran with the artificial viscosity 2.0,0.2"),
        (["--transfer", "apic"], "--transfer apic: the fit ran with flip"),
        (["--artificial-cells", "1"], "--artificial-cells 1: the fit ran without artificial cells"),
    ):
        usage(capsys, [*argv, *extra], match)
    plain = {**FIT_MPQ_VISCOUS, "viscosity": None}
    path.write_text(json.dumps(plain))
    usage(capsys, [*argv, "--viscosity"], "--viscosity 2.0,0.2: the fit ran without artificial viscosity")
    assert main([*argv, "--interpolator", "mpq", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["viscosity"] is None
