"""The gas slab, its diffrax reference, calibration with optax, ensembles and sharding."""

import json
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import BACKEND_COMPILE, TRACE, float32, monitored

import jaxmpm as jm
from jaxmpm import calibrate as cal
from jaxmpm import reference

pytestmark = pytest.mark.slow

TRUTH = dict(gamma=1.4, P0=3.0e5)
TS = np.linspace(0.0, 12e-3, 61)  # through the first turnaround: gamma and P0 are both identifiable


def _dt(scene):
    return 0.2 * float(scene.h) / float(np.sqrt(float(scene.gamma) * float(scene.P0) / float(scene.rho0)))


SLAB = dict(cells=16, h=1 / 16, pad=96)  # a coarse model keeps the fits to seconds


@pytest.fixture(scope="module")
def synthetic():
    sc = jm.GasSlab(**TRUTH, **SLAB)
    dt = _dt(sc)
    x = np.asarray(cal.trajectory(sc, jm.CPDI(), TS, dt=dt))
    return sc, dt, x


def test_gas_slab_reference_tolerances_follow_the_float_type():
    """In float32 the reference's float64 tolerances (rtol 1e-8, atol 1e-10) lie below what the type
    resolves: the solver shrank its steps (68,791 at 400 cells for 8,210 in float64) and at 1,600 cells
    ran out of ``max_steps``, a message that blamed ``max_steps``. Its defaults are now the type's
    (1e-6 and 1e-8 in float32: 3,360 steps at 400 cells, the end's x_free within 3e-6 of float64's),
    and tolerances below what it resolves are refused, naming float64."""
    ts = np.linspace(0.0, 12e-3, 7)
    with float32():
        ref = reference.gas_slab(jm.GasSlab(), ts, cells=400)
        assert ref.x_free.dtype == jnp.float32 and int(ref.stats["num_steps"]) < 10_000
        for kw, name in ((dict(rtol=1e-8), "rtol"), (dict(atol=1e-10), "atol")):
            with pytest.raises(
                ValueError, match=rf"^{name}=1e-(08|10) is below what float32 resolves .*float64"
            ):
                reference.gas_slab(jm.GasSlab(), ts, cells=400, **kw)
    ref64 = reference.gas_slab(jm.GasSlab(), ts, cells=400)
    assert float(ref.x_free[-1]) == pytest.approx(float(ref64.x_free[-1]), rel=3e-6)
    assert int(ref64.stats["num_steps"]) > 5_000  # float64's own tolerances, 1e-8 and 1e-10


def test_gas_slab_reference_compiles_once_for_new_parameter_values():
    """The reference's solve is compiled once per size (cells, number of times): a slab of other
    constants and another length reuses it, nothing traced or compiled again."""
    ts = [0.0, 1e-3, 2e-3, 3e-3, 4e-3]
    first = reference.gas_slab(jm.GasSlab(), ts, cells=23)
    with monitored(TRACE, BACKEND_COMPILE) as events:
        other = reference.gas_slab(jm.GasSlab(P0=4e5, gamma=1.3, p_atm=0.9e5, rho0=1.2, h=0.05), ts, cells=23)
    assert events == []
    assert np.all(np.asarray(other.x_free)[1:] != np.asarray(first.x_free)[1:])
    assert float(other.X[-1]) == pytest.approx(
        0.5 * (2 * 23 - 1) / 23 * float(jm.GasSlab(h=0.05).length), rel=1e-14
    )


def test_gas_slab_scene_and_its_reference_agree():
    sc = jm.GasSlab()
    assert float(sc.F_eq) == pytest.approx(3.0 ** (1 / 1.4), rel=1e-15)
    with pytest.raises(ValueError, match="P0 must be > p_atm"):
        jm.GasSlab(P0=1e5, p_atm=2e5)
    ts = jnp.linspace(0.0, 12e-3, 25)
    ref = [reference.gas_slab(sc, ts, n) for n in (100, 200, 400)]
    d1 = float(jnp.max(jnp.abs(ref[0].x_free - ref[1].x_free)))
    d2 = float(jnp.max(jnp.abs(ref[1].x_free - ref[2].x_free)))
    # The reference converges (first order: the free surface starts as a jump in pressure)
    assert 0.8 < np.log2(d1 / d2) < 1.3 and d2 < 1e-3
    assert float(ref[-1].x_free[0]) == 1.0
    # MPM (CPDI) converges to it at first order: max |x_R - x_R,ref| 0.041, 0.020, 0.010 m at 16, 32, 64
    # cells (and 0.005 at 128, measured), the slab's free surface being a jump at t = 0
    errs = []
    for n in (16, 32, 64):
        s = jm.GasSlab(cells=n, h=1 / n, pad=6 * n)
        x = np.asarray(cal.trajectory(s, jm.CPDI(), np.asarray(ts), dt=_dt(s)))
        errs.append(np.max(np.abs(x - np.asarray(ref[-1].x_free))))
    orders = np.log2(np.asarray(errs[:-1]) / np.asarray(errs[1:]))
    assert np.all((orders > 0.9) & (orders < 1.1)) and errs[-1] < 0.011, errs
    # F(X, t) at any X: the wall cell stays compressed less than the free end is stretched
    F = ref[-1].F_at(jnp.asarray([0.0, 1.0]))
    assert F.shape == (25, 2) and float(F[5, 1]) > float(F[5, 0])


def test_calibration_recovers_gamma_and_P0_without_noise(synthetic):
    sc, dt, x = synthetic
    start = dict(gamma=1.4 * 1.3, P0=3.0e5 * 0.7)  # 30% off
    fit = cal.calibrate(
        jm.GasSlab(**SLAB), jm.CPDI(), TS, x, fit=("gamma", "P0"), starts=start, dt=dt, progress=False
    )
    for k, v in TRUTH.items():
        assert fit.fitted[k] == pytest.approx(v, rel=1e-8), fit  # measured 8.7e-10 and 8.3e-10
    assert fit.loss < 1e-12 and fit.history.shape[0] == fit.iterations + 1
    assert fit.history[-1, 0] < 1e-6 * fit.history[0, 0]


def test_calibration_with_one_percent_noise_and_several_starts(synthetic):
    sc, dt, x = synthetic
    rng = np.random.default_rng(0)
    noisy = x * (1 + 0.01 * rng.standard_normal(x.size))
    # the third start expands the slab off the grid at once: it is reported, the others go on
    starts = [dict(gamma=1.82, P0=2.1e5), dict(gamma=1.6, P0=3.6e5), dict(gamma=1.1, P0=3.9e5)]
    fit = cal.calibrate(
        jm.GasSlab(**SLAB), jm.CPDI(), TS, noisy, fit=("gamma", "P0"), starts=starts, dt=dt, progress=False
    )
    for k, v in TRUTH.items():
        # measured -2.3e-3 and -5.7e-4, against the fit's own standard errors of 4.9e-3 and 4.7e-3
        assert fit.fitted[k] == pytest.approx(v, rel=6e-3), fit
        assert fit.starts_fitted[k].shape == (3,)
    assert fit.history.shape[1] == 3
    assert list(fit.failed_starts) == [2] and "broke down at step" in fit.failed_starts[2]


def test_adam_keeps_parameters_physical_and_descends(synthetic):
    sc, dt, x = synthetic
    with pytest.warns(cal.CalibrationWarning, match="did not converge in 15 iterations"):
        fit = cal.calibrate(
            jm.GasSlab(**SLAB),
            jm.CPDI(),
            TS,
            x,
            starts=dict(gamma=1.05, P0=1.2e5),  # near the edges of the admissible ranges
            dt=dt,
            method="adam",
            iterations=15,
            learning_rate=0.1,
            progress=False,
        )
    assert fit.fitted["gamma"] > 1.0 and fit.fitted["P0"] > 1.0e5
    assert fit.history[-1, 0] < fit.history[0, 0]
    assert not fit.converged and fit.warning.startswith("the fit did not converge")


def test_adam_steps_back_from_a_point_that_breaks_down_and_goes_on():
    """Adam has no line search: a step that reaches a run that breaks down (here the slab leaving a
    grid of 48 cells) is refused, and the step from the point before is taken again, half as long.
    The start goes on, and no broken run's loss enters the history."""
    slab = dict(p_atm=1.0, rho0=1.0, cells=8, h=1 / 8, pad=48)
    ts = np.linspace(0.0, 4.0, 41)
    dt = 0.2 * (1 / 8) / np.sqrt(1.3 * 4.2)
    x = np.asarray(cal.trajectory(jm.GasSlab(gamma=1.3, P0=4.2, **slab), jm.CPDI(), ts, dt=dt))
    x = x + 0.01 * np.random.default_rng(1).standard_normal(x.size)
    with pytest.warns(cal.CalibrationWarning, match="did not converge in 25 iterations"):
        fit = cal.calibrate(
            jm.GasSlab(**slab),
            jm.CPDI(),
            ts,
            x,
            starts=dict(gamma=1.4, P0=3.8),
            dt=dt,
            method="adam",
            iterations=25,
            progress=False,
        )
    assert fit.failed_starts == {} and fit.iterations == 25
    assert fit.rejected and all(e["broke"] and np.isnan(e["loss"]) for e in fit.rejected)
    assert "particle left the grid" in fit.rejected[0]["why"]
    assert np.all(np.isfinite(fit.history)) and fit.loss < 0.1 * fit.history[0, 0]
    assert np.all(np.isfinite(cal.trajectory(jm.GasSlab(**slab, **fit.fitted), jm.CPDI(), ts, dt=dt)))


def test_calibration_reports_a_broken_trial_and_bad_input(synthetic):
    sc, dt, x = synthetic
    with pytest.raises(
        cal.CalibrationError, match="every start broke down: start 0, at its start: the run at"
    ):
        cal.calibrate(jm.GasSlab(**SLAB), jm.CPDI(), TS, x, dt=20 * dt, iterations=2, progress=False)
    with pytest.raises(
        cal.CalibrationError, match="every start broke down: start 0, iteration 1: the run at"
    ):
        cal.calibrate(
            jm.GasSlab(**SLAB), jm.CPDI(), TS, x, dt=20 * dt, iterations=2, method="adam", progress=False
        )
    with pytest.raises(ValueError, match="method must be"):
        cal.calibrate(jm.GasSlab(**SLAB), jm.CPDI(), TS, x, dt=dt, method="sgd")
    with pytest.raises(ValueError, match="not fitted"):
        cal.calibrate(jm.GasSlab(**SLAB), jm.CPDI(), TS, x, fit=("gamma",), starts=dict(P0=2e5), dt=dt)
    with pytest.raises(ValueError, match="unknown parameter"):
        cal.calibrate(jm.GasSlab(**SLAB), jm.CPDI(), TS, x, fit=("kappa",), dt=dt)


def test_ensemble_of_1024_matches_separate_runs_and_isolates_a_failure():
    sc = jm.GasSlab(cells=8, h=1 / 8, pad=48)
    dt = _dt(sc)
    rng = np.random.default_rng(0)
    gamma, P0 = rng.uniform(1.2, 1.8, 1024), rng.uniform(2e5, 4e5, 1024)
    P0[7] = 5e7  # far too stiff for dt: this member must fail alone
    ens = jm.ensemble(sc, jm.CPDI(), {"gamma": gamma, "P0": P0}, dt=dt, steps=200)
    assert ens.status.shape == (1024,) and int(np.sum(ens.status != 0)) == 1
    (f,) = ens.failures()
    assert f["member"] == 7 and f["step"] == 1 and "stable limit" in f["quantities"][0]
    assert np.all(np.isfinite(np.asarray(ens.solution.state.x)))

    @jax.jit
    def separate(g, p):  # one member's own run, not batched: compiled once, called per member
        sol = jm.simulate(
            jm.GasSlab(cells=8, h=1 / 8, pad=48, gamma=g, P0=p), jm.CPDI(), dt=dt, steps=200, throw=False
        )
        return sol.state.x, sol.state.status

    for i in range(1024):
        x, status = separate(gamma[i], P0[i])
        np.testing.assert_allclose(
            np.asarray(ens.solution.state.x[i]), np.asarray(x), rtol=1e-13, atol=0, err_msg=str(i)
        )
        assert int(status) == int(ens.status[i])


def test_sharded_ensemble_on_four_host_devices_equals_unsharded():
    script = textwrap.dedent(
        """
        import json, jax
        jax.config.update("jax_enable_x64", True)
        import numpy as np, jaxmpm as jm
        sc = jm.GasSlab(cells=8, h=1 / 8, pad=48)
        rng = np.random.default_rng(1)
        vary = {"gamma": rng.uniform(1.2, 1.8, 10), "P0": rng.uniform(2e5, 4e5, 10)}
        vary["P0"][3] = 5e7
        a = jm.ensemble(sc, jm.CPDI(), vary, dt=2e-5, steps=100)
        b = jm.ensemble(sc, jm.CPDI(), vary, dt=2e-5, steps=100, devices=jax.devices()[:1])
        diff = float(np.max(np.abs(np.asarray(a.solution.state.x) - np.asarray(b.solution.state.x))))
        print(json.dumps(dict(n=len(jax.devices()), a=a.devices, b=b.devices, diff=diff,
                              status_a=a.status.tolist(), status_b=b.status.tolist())))
        """
    )
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["n"] == 4 and r["a"] == 4 and r["b"] == 1
    assert r["diff"] == 0.0 and r["status_a"] == r["status_b"] and r["status_a"][3] != 0


def test_ensemble_bad_input():
    sc = jm.GasSlab(cells=8, h=1 / 8, pad=48)
    with pytest.raises(ValueError, match="same length"):
        jm.ensemble(sc, jm.CPDI(), {"gamma": [1.3, 1.4], "P0": [2e5]}, dt=1e-5, steps=2)
    with pytest.raises(ValueError, match="unknown parameter"):
        jm.ensemble(sc, jm.CPDI(), {"kappa": [1.0]}, dt=1e-5, steps=2)
    with pytest.raises(ValueError, match="finite"):
        jm.ensemble(sc, jm.CPDI(), {"gamma": [np.nan]}, dt=1e-5, steps=2)


def test_calibrate_and_ensemble_cli(tmp_path, capsys, synthetic):
    from jaxmpm.cli import main

    sc, dt, x = synthetic
    data = tmp_path / "traj.csv"
    np.savetxt(data, np.c_[TS, x], delimiter=",", header="t,x_free", comments="")
    argv = [
        "calibrate",
        "gas-slab",
        "cells=16",
        "h=0.0625",
        "pad=96",
        "--data",
        str(data),
        "--fit",
        "gamma,P0",
        "--start",
        "gamma=1.82,P0=2.1e5",
    ]
    assert main(argv + ["--dt", repr(dt), "--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"fitted", "loss", "iterations", "wall_s"}
    assert out["fitted"]["gamma"] == pytest.approx(1.4, rel=1e-8)  # measured 8.7e-10
    assert out["fitted"]["P0"] == pytest.approx(3e5, rel=1e-8)  # measured 8.3e-10
    bad = tmp_path / "bad.csv"
    bad.write_text("time,x\n0,1\n")
    assert main(["calibrate", "gas-slab", "--data", str(bad)]) == 2
    assert "t,x_free" in capsys.readouterr().err
    assert main(["calibrate", "vibrating-bar", "--data", str(data)]) == 2
    assert "gas-slab" in capsys.readouterr().err
    ens = [
        "ensemble",
        "gas-slab",
        "cells=8",
        "h=0.125",
        "pad=48",
        "--vary",
        "gamma=1.3:1.5",
        "--vary",
        "P0=2e5:4e5",
    ]
    assert main(ens + ["--members", "5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["members"] == 5 and out["ok"] == 5 and len(out["results"]) == 5
    assert all(1.3 <= r["params"]["gamma"] <= 1.5 and r["x_free"] > 1.0 for r in out["results"])
    assert main(["ensemble", "gas-slab", "--vary", "gamma=2:1", "--members", "3"]) == 2
    assert "LOW <= HIGH" in capsys.readouterr().err


def test_devices_spread_lm_starts_only_and_name_what_is_allowed():
    args = (jm.GasSlab(**SLAB), jm.CPDI(), TS, np.ones_like(TS))
    with pytest.raises(ValueError, match="devices spreads the starts of method='lm' only, got method='adam'"):
        cal.calibrate(*args, dt=1e-5, method="adam", devices=1)
    with pytest.raises(ValueError, match=r"devices must be a count from 1 to \d+"):
        cal.calibrate(*args, dt=1e-5, devices=10**6)


def test_trajectory_of_a_run_that_breaks_down_raises_naming_the_step(synthetic):
    # eagerly, a broken run is an error with its step, particle and quantity (never NaN data);
    # traced, as the fit calls it, it is NaN, which the fit reads as a breakdown
    sc, dt, _ = synthetic
    with pytest.raises(jm.SimulationError, match=r"step \d+.*particle \d+") as info:
        cal.trajectory(sc, jm.CPDI(), TS, dt=20 * dt)
    assert info.value.solution.state.status != 0
    ts = jnp.asarray(TS)  # (a constant of the traced function, as the fit's times are)
    traced = jax.jit(lambda g: cal.trajectory(jm.GasSlab(gamma=g, **SLAB), jm.CPDI(), ts, dt=20 * dt))(1.4)
    assert np.all(np.isnan(np.asarray(traced)))
