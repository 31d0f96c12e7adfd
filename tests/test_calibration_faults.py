"""Calibration's faults: bad input to the gas slab's reference and to the fits refused by name before
anything is traced, a fit the data pull against the bound of a constant's range kept inside it and
reported, and an unidentifiable fit's warning saying what is true (never "nan")."""

import warnings

import numpy as np
import pytest
from helpers import float32, raw

import jaxmpm as jm
from jaxmpm import calibrate as cal
from jaxmpm import reference

SLAB = dict(cells=8, h=1 / 8, pad=96)  # a coarse model: each fit below takes seconds
TS = np.linspace(0.0, 6e-3, 31)
DT = 0.2 * (1 / 8) / np.sqrt(1.4 * 4e5)
X = np.linspace(1.0, 2.0, TS.size)  # data of the right shape; the checks below refuse before any run


# -- reference.gas_slab ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "ts, match",
    [
        ([-1e-3, 1e-3], r"ts must start at >= 0, got ts\[0\]=-0.001"),
        ([], r"ts must be a non-empty 1-d sequence of times, got shape \(0,\)"),
        ([2e-3, 1e-3], r"ts must be non-decreasing, got ts\[0\]=0.002, ts\[1\]=0.001"),
        ([0.0, float("nan")], "ts must be finite"),
        ([[0.0, 1e-3]], r"ts must be a non-empty 1-d sequence of times, got shape \(1, 2\)"),
        (1e-3, r"ts must be a non-empty 1-d sequence of times, got shape \(\)"),
        ("abc", "ts must be a real number, got 'abc'"),
    ],
)
def test_gas_slab_reference_refuses_bad_times_by_name(ts, match):
    with pytest.raises(ValueError, match=match):
        reference.gas_slab(jm.GasSlab(**SLAB), ts, cells=8)


def test_gas_slab_reference_refuses_a_scene_that_is_not_a_gas_slab():
    with pytest.raises(ValueError, match=r"scene must be a GasSlab \(jm.GasSlab\(...\)\), got GasExpansion"):
        reference.gas_slab(jm.GasExpansion(), [0.0, 1e-3], cells=8)
    with pytest.raises(ValueError, match="max_steps must be an integer >= 1, got 0"):
        reference.gas_slab(jm.GasSlab(**SLAB), [0.0, 1e-3], cells=8, max_steps=0)


@pytest.mark.slow
def test_gas_slab_reference_takes_a_repeated_time():
    """diffrax reports a repeated time twice: the times need only be non-decreasing."""
    sol = reference.gas_slab(jm.GasSlab(**SLAB), [0.0, 1e-3, 1e-3], cells=8)
    x = np.asarray(sol.x_free)
    assert x[0] == 1.0 and x[1] == x[2] > 1.0


# -- calibrate, calibrate_each, information, profile, trajectory -----------------------------------------


INTERP_STR = (
    r"interpolator must be a jaxmpm interpolator such as jm.CPDI\(\) \(INTERPOLATORS: spq, gimp, cpgimp, "
    r"cpdi, mpq, cpdi2\), got 'mpq': pass jm.MPQ\(\)"
)


GURNEY = dict(cells=20, pad=60, explosive="gamma-law")


def _uncertainty(f, sc, fitted=None, **kw):
    """``uncertainty`` of a fit of gamma and P0 from three residuals (a well-posed Jacobian)."""
    J = np.array([[1.0, 0.2], [0.3, 1.0], [0.5, 0.5]])
    fitted = dict(gamma=1.4, P0=3e5) if fitted is None else fitted
    return f(sc, ("gamma", "P0"), fitted, [0.1, -0.1, 0.05], J_theta=J, **kw)


def _fit():
    return cal.Fit(
        fitted={"gamma": 1.4, "P0": 3e5},
        loss=0.0,
        iterations=0,
        history=np.zeros((1, 1)),
        starts_fitted={},
        wall_s=0.0,
        weakest={"gamma": 0.6, "P0": 0.8},
    )


@pytest.mark.parametrize(
    "name, call, match",
    [
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, starts=[], dt=DT),
            r"starts must be a dict or a non-empty list of dicts of start values .*got an empty list",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, starts=[1.4], dt=DT),
            r"starts\[0\] must be a dict of start values \(name to number\), got 1.4",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, starts=[dict(gamma="a")], dt=DT),
            r"starts\[0\]\['gamma'\] must be a real number, got 'a'",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), [], [], dt=DT),
            r"t_data and x_data must be 1D arrays of the same length \(>= 2\), got shapes \(0,\) and \(0,\)",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, [], dt=DT),
            r"t_data and x_data must be 1D arrays .* got shapes \(31,\) and \(0,\)",
        ),
        ("calibrate", lambda f, sc: f(sc, "mpq", TS, X, dt=DT), INTERP_STR),
        (
            "calibrate",
            lambda f, sc: f("gas-slab", jm.CPDI(), TS, X, dt=DT),
            r"scene must be a jaxmpm scene such as jm.GasSlab\(\), got 'gas-slab'",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, fit="gamma", dt=DT),
            r"fit must be a sequence of parameter names such as \('gamma', 'P0'\), got 'gamma'",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, fit=(), dt=DT),
            "fit must name at least one constant; fittable: P0, gamma, p_atm, rho0",
        ),
        ("calibrate", lambda f, sc: f(sc, jm.CPDI(), TS, X, tol=float("nan"), dt=DT), "tol must be finite"),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, progress="no", dt=DT),
            "progress must be True or False",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, fit=("P0", "p_atm"), starts=dict(P0=5e4), dt=DT),
            r"start 0 \(P0=50000, p_atm=100000\): GasSlab refuses it: P0 must be > p_atm",
        ),
        (
            "calibrate_each",
            lambda f, sc: f(sc, jm.CPDI(), TS, np.zeros((0, TS.size)), dt=DT),
            r"x_sets must be 2D \(data sets, times\) with at least one data set, got shape \(0, 31\)",
        ),
        ("calibrate_each", lambda f, sc: f(sc, "mpq", TS, X[None], dt=DT), INTERP_STR),
        (
            "calibrate_each",
            lambda f, sc: f(sc, jm.CPDI(), [], np.zeros((1, 0)), dt=DT),
            r"t_data and x_sets\[0\] must be 1D arrays .* got shapes \(0,\) and \(0,\)",
        ),
        (
            "calibrate_each",
            lambda f, sc: f(sc, jm.CPDI(), TS, X[None], start=[], dt=DT),
            r"start must be a dict of start values \(name to number\) or None, got \[\]",
        ),
        (
            "information",
            lambda f, sc: f(sc, jm.CPDI(), [], dt=DT),
            r"ts must be a non-empty 1D array of times from >= 0, increasing, got \[\]",
        ),
        ("information", lambda f, sc: f(sc, "mpq", TS, dt=DT), INTERP_STR),
        ("trajectory", lambda f, sc: f(sc, jm.CPDI(), [], dt=DT), "ts must hold at least one time"),
        ("trajectory", lambda f, sc: f(sc, "mpq", TS, dt=DT), INTERP_STR),
        (
            "profile",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, _fit(), [], dt=DT),
            "alphas must hold at least one",
        ),
        ("profile", lambda f, sc: f(sc, "mpq", TS, X, _fit(), [0.0], dt=DT), INTERP_STR),
        (
            "profile",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, {"gamma": 1.4}, [0.0], dt=DT),
            "fit must be the Fit that calibrate returned",
        ),
        (
            "calibrate",
            lambda f, sc: f(jm.GasExpansion(), jm.CPDI(), TS, X, fit=("beta",), dt=DT),
            r"scene must be a jm.GasSlab \(observed: its free surface\) or a jm.GurneySlab .* GasExpansion",
        ),
        (
            "trajectory",
            lambda f, sc: f(jm.AxisAligned(cells=4), jm.CPDI(), TS, dt=DT),
            r"scene must be a jm.GasSlab .* got AxisAligned",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, noise=[0.1, 0.2], dt=DT),
            r"noise must be one number, got an array of shape \(2,\)",
        ),
        (
            "information",
            lambda f, sc: f(sc, jm.CPDI(), TS, noise=[0.1], dt=DT),
            r"noise must be one number, got an array of shape \(1,\)",
        ),
        (
            "profile",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, _fit(), [0.0], dt=DT, direction={"gama": 1.0}),
            r"direction names 'gama', which the fit did not fit; fitted: gamma, P0",
        ),
        (
            "profile",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, _fit(), [0.0], dt=DT, direction=[1.0, 0.0]),
            r"direction must be a dict from the fitted names \(gamma, P0\)",
        ),
        (
            "profile",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, _fit(), [0.0], dt=DT, direction={"gamma": 0.0}),
            "direction must have a component that is not zero",
        ),
        ("fittable", lambda f, sc: f("gas-slab"), "scene must be a jaxmpm scene or scene class"),
        *[
            (
                "uncertainty",
                lambda f, sc, kw=kw: _uncertainty(f, sc, **kw),
                match,
            )
            for kw, match in (
                (dict(noise=0.0), r"noise must be > 0, got 0\.0"),
                (dict(noise=-1.0), r"noise must be > 0, got -1\.0"),
                (dict(noise=float("nan")), "noise must be finite"),
                (dict(noise=[0.1, 0.2]), r"noise must be one number, got an array of shape \(2,\)"),
            )
        ],
        (
            "uncertainty",
            lambda f, sc: _uncertainty(f, sc, dict(gamma=1.0, P0=3e5)),
            r"fitted\['gamma'\] must be finite and > 1 \(its bound\), got 1\.0",
        ),
        (
            "uncertainty",
            lambda f, sc: _uncertainty(f, sc, dict(gamma=1.4, P0=np.inf)),
            r"fitted\['P0'\] must be finite and > 100000 \(its bound\), got inf",
        ),
        (
            "profile",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, _fit(), [0.1, -5.0], dt=DT),
            r"alphas\[1\] = -5\.0 takes gamma to 0\.0697019, at or below its bound 1: take smaller steps",
        ),
        (
            "calibrate",
            lambda f, sc: f(jm.GurneySlab(**GURNEY), jm.CPDI(), TS, np.zeros(TS.size), fit=("D",), dt=DT),
            r"x_data must hold a nonzero plate speed \(the loss is scaled by the largest one\), got all",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, learning_rate=0.1, dt=DT),
            r"learning_rate is Adam's step, and method='lm' takes none",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, method="lbfgs", learning_rate=0.1, dt=DT),
            r"learning_rate is Adam's step, and method='lbfgs' takes none",
        ),
        (
            "calibrate",
            lambda f, sc: f(sc, jm.CPDI(), TS, X, method="adam", learning_rate=-0.1, dt=DT),
            r"learning_rate must be > 0, got -0.1",
        ),
        (
            "uncertainty",
            lambda f, sc: f(sc, (), {}, [1.0], J_theta=np.zeros((1, 0))),
            "names must name at least one fitted parameter",
        ),
    ],
)
def test_calibration_refuses_bad_input_by_name_before_any_run(name, call, match):
    fn = getattr(cal, name)
    # as a user runs it: the function's own check
    with pytest.raises(ValueError, match=match):
        call(raw(fn), jm.GasSlab(**SLAB))
    # under the suite's runtime type checks of the annotations a TypeError may come first
    with pytest.raises((ValueError, TypeError)):
        call(fn, jm.GasSlab(**SLAB))


# -- a fit pulled against a bound ------------------------------------------------------------------------


@pytest.mark.slow
def test_a_fit_pulled_to_gamma_1_stays_inside_and_says_it_ran_into_the_edge():
    """Data that expand further than any gamma > 1 allows at the model's P0 pull gamma to 1: the step
    to gamma = 1 + exp(-51), which is 1.0 in float64, is a trial the scene refuses, rejected as a
    broken run would be; the fit ends inside the range and its warning names the edge."""
    truth = jm.GasSlab(gamma=1.05, P0=4e5, **SLAB)
    x = np.asarray(cal.trajectory(truth, jm.CPDI(), TS, dt=DT))
    model = jm.GasSlab(gamma=1.4, P0=3e5, **SLAB)
    with pytest.warns(
        cal.CalibrationWarning, match="the fit ran into the edge of the allowed range: gamma = 1"
    ):
        fit = cal.calibrate(model, jm.CPDI(), TS, x, fit=("gamma",), dt=DT, iterations=30, progress=False)
    assert fit.fitted["gamma"] > 1.0
    jm.GasSlab(**{**model.parameter_values(), **fit.fitted})  # a scene the fit's answer makes
    assert "(must be > 1; gamma - 1 fell from 0.4 to" in fit.warning
    assert "check the data and the constants not fitted (P0, p_atm, rho0)" in fit.warning
    refused = [e for e in fit.rejected if e["broke"] and "why" in e]
    assert refused and "where GasSlab has no run: gamma must be > 1" in refused[0]["why"]


@pytest.mark.slow
@pytest.mark.parametrize("start", [3.0, 1.05, 1.000001])
def test_a_fit_pulled_to_the_edge_says_so_from_any_start(start):
    """The same data and model from starts far from the bound, near it and a millionth from it: each
    fit ends inside the range with the edge's warning, not an error about runs that break down (no run
    broke down: the trials at the bound are values the scene refuses) nor a warning about noise."""
    kw = dict(p_atm=1.0, rho0=1.0, h=1 / 8, cells=8, pad=64)
    ts, dt = np.linspace(0.0, 3.0, 16), 0.2 * (1 / 8) / np.sqrt(1.3 * 4.2)
    x = np.asarray(cal.trajectory(jm.GasSlab(P0=4.2, gamma=1.3, **kw), jm.CPDI(), ts, dt=dt))
    model = jm.GasSlab(P0=2.0, **kw)  # too little P0: the data want gamma below 1
    with pytest.warns(cal.CalibrationWarning, match="the fit ran into the edge of the allowed range: gamma"):
        fit = cal.calibrate(model, jm.CPDI(), ts, x, fit=("gamma",), starts=dict(gamma=start), dt=dt)
    assert 1.0 < fit.fitted["gamma"] < 1.0 + 1e-6, fit.fitted
    assert "breaks down" not in fit.warning and "noise" not in fit.warning, fit.warning
    assert not any(e.get("failure") for e in fit.rejected)  # refused values, no run that broke down


@pytest.mark.slow
def test_a_fit_inside_the_range_does_not_warn_of_the_edge():
    x = np.asarray(cal.trajectory(jm.GasSlab(gamma=1.3, **SLAB), jm.CPDI(), TS, dt=DT))
    with warnings.catch_warnings():
        warnings.simplefilter("error", cal.CalibrationWarning)
        fit = cal.calibrate(jm.GasSlab(**SLAB), jm.CPDI(), TS, x, fit=("gamma",), dt=DT, progress=False)
    assert fit.fitted["gamma"] == pytest.approx(1.3, rel=1e-6) and fit.warning is None


# -- a fit held back by runs that break down -------------------------------------------------------------


def _behind_the_stable_limit():
    """Data of a slab whose gamma = 1.4, P0 = 3e5 need a CFL number of 0.377 at the step ``dt``; the
    model runs with ``cfl_limit=0.35``, so the way from the start (gamma 1.3, P0 2.6e5) to the data
    ends in runs that break down (the step beyond the stable limit), from about gamma 1.30."""
    slab = dict(cells=8, h=1 / 8, pad=48)
    truth = jm.GasSlab(gamma=1.4, P0=3e5, **slab)
    dt = 0.2 * float(truth.h) / float(truth.wave_speed)
    x = np.asarray(cal.trajectory(truth, jm.CPDI(), TS, dt=dt))
    return jm.GasSlab(**slab), x, dt, dict(starts=dict(gamma=1.3, P0=2.6e5), cfl_limit=0.35, progress=False)


@pytest.mark.slow
def test_levenberg_marquardt_held_back_by_breakdowns_says_so():
    """Levenberg-Marquardt's damping, raised by the trials that broke down, shortens its steps until
    one that is accepted gains almost nothing: that is not convergence while Gauss-Newton still
    predicts nearly the whole loss away (99.97% here). The fit cannot reach its best point, and says
    so (it returned converged=True, loss 0.0246, with no word of the breakdowns)."""
    model, x, dt, kw = _behind_the_stable_limit()
    with pytest.raises(cal.CalibrationError, match="the fit cannot reach its best point"):
        cal.calibrate(model, jm.CPDI(), TS, x, dt=dt, iterations=100, **kw)


@pytest.mark.slow
def test_adam_goes_back_from_a_breakdown_without_counting_earlier_ones():
    """Adam halves a step whose point broke down and goes back; an accepted step lets the step grow
    again, and only 20 halvings in a row from one point give the start up. Here the 20 halvings came
    over 54 iterations from 17 points, each followed by steps that lowered the loss: the start was
    reported as broken down ('every start broke down', at a point whose run is fine)."""
    model, x, dt, kw = _behind_the_stable_limit()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cal.CalibrationWarning)
        try:
            fit = cal.calibrate(model, jm.CPDI(), TS, x, dt=dt, method="adam", iterations=60, **kw)
        except cal.CalibrationError as e:
            assert "every start broke down" not in str(e), str(e)
            assert "the fit cannot reach its best point" in str(e), str(e)
            return
    assert not fit.failed_starts
    assert fit.loss < 0.0482  # the start's loss; every point the fit stood on ran
    jm.simulate(jm.GasSlab(**{**model.parameter_values(), **fit.fitted}), jm.CPDI(), dt=dt, steps=1)


# -- an unidentifiable fit -------------------------------------------------------------------------------


@pytest.mark.slow
def test_an_unidentifiable_fit_says_which_standard_errors_are_infinite_never_nan():
    """Scaling P0, p_atm and rho0 together leaves the slab's motion unchanged: J^T J is singular."""
    sc = jm.GasSlab(**SLAB)
    x = np.asarray(cal.trajectory(sc, jm.CPDI(), TS, dt=DT))
    x = x + 0.01 * np.random.default_rng(0).standard_normal(x.size)
    with pytest.warns(cal.CalibrationWarning) as record:
        fit = cal.calibrate(
            sc, jm.CPDI(), TS, x, fit=("P0", "p_atm", "rho0"), dt=DT, iterations=5, progress=False
        )
    message = str(record[-1].message)
    assert "nan" not in message.lower() and message == fit.warning
    assert message.startswith(
        "the data do not determine the constants: the standard errors of P0, p_atm and rho0 are infinite "
        "(J^T J is singular"
    )
    assert "so the correlations of P0, p_atm and rho0 are undefined" in message
    assert all(np.isinf(v) for v in fit.std.values())


def test_identifiability_names_the_constant_whose_standard_error_is_infinite():
    sc = jm.GasSlab(**SLAB)
    J = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])  # proportional columns: singular
    u = cal.uncertainty(sc, ("gamma", "P0"), {"gamma": 1.4, "P0": 3e5}, [0.1, -0.1, 0.0], J_theta=J)
    text = cal.identifiability(sc, u, TS[:3])
    assert "nan" not in text.lower()
    assert "the standard errors of gamma and P0 are infinite" in text
    assert "the correlations of gamma and P0 are undefined" in text


def test_a_singular_fit_gives_the_determined_constant_its_standard_error():
    """P0 and p_atm enter only through one combination (equal columns of d r / d theta): J^T J is
    singular, but gamma's unit vector is orthogonal to its null space, so the data determine gamma,
    with the standard error of the model reduced to (gamma, that combination), on n - 2 degrees of
    freedom."""
    sc = jm.GasSlab(**SLAB)
    rng = np.random.default_rng(3)
    a, b = rng.standard_normal(12), rng.standard_normal(12)
    J = np.stack([a, b, b], axis=1)
    r = 0.1 * rng.standard_normal(12)
    names = ("gamma", "P0", "p_atm")
    fitted = {"gamma": 1.4, "P0": 3e5, "p_atm": 1e5}
    u = cal.uncertainty(sc, names, fitted, r, J_theta=J)
    Jr = np.stack([a, b], axis=1)  # the reduced model: theta_gamma and theta_P0 + theta_p_atm
    sigma = np.sqrt(r @ r / (12 - 2))
    var = sigma**2 * np.linalg.inv(Jr.T @ Jr)[0, 0]
    assert u["sigma"] == pytest.approx(sigma, rel=1e-13)
    assert u["std"]["gamma"] == pytest.approx((1.4 - 1.0) * np.sqrt(var), rel=1e-9)
    assert u["covariance_theta"][0, 0] == pytest.approx(var, rel=1e-9)
    assert np.isinf(u["std"]["P0"]) and np.isinf(u["std"]["p_atm"])
    corr = np.asarray(u["correlation"])
    assert corr[0, 0] == pytest.approx(1.0, rel=1e-12)
    assert np.isnan(corr[0, 1:]).all() and np.isnan(corr[1:, :]).all()
    text = cal.identifiability(sc, u, TS[:12])
    assert "the standard errors of P0 and p_atm are infinite" in text


def test_zero_residuals_give_a_correlation_not_nan():
    """With residuals exactly zero (sigma = 0) the standard errors are zero and the correlation, which
    does not depend on sigma, is still defined."""
    sc = jm.GasSlab(**SLAB)
    J = np.array([[1.0, 2.0], [2.0, 4.1], [3.0, 6.0]])
    u = cal.uncertainty(sc, ("gamma", "P0"), {"gamma": 1.4, "P0": 3e5}, np.zeros(3), J_theta=J)
    corr = np.asarray(u["correlation"])
    assert np.all(np.isfinite(corr)) and corr[0, 0] == pytest.approx(1.0) and abs(corr[0, 1]) > 0.99
    text = cal.identifiability(sc, u, TS[:3])
    assert text is not None and "nan" not in text.lower() and "gamma and P0 are correlated 0.99" in text


def test_information_correlation_of_a_plan_that_determines_nothing_is_refused():
    info = cal.Information(
        names=("P0", "p_atm"),
        values={"P0": 3e5, "p_atm": 1e5},
        ts=TS[:3],
        jacobian=np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]]),
        noise=0.01,
    )
    assert all(np.isinf(v) for v in info.std().values())
    with pytest.raises(ValueError, match="this plan does not determine P0 and p_atm: the Fisher information"):
        info.correlation()


def test_a_singular_plan_gives_the_determined_constant_its_standard_error():
    """P0 and p_atm enter a plan through one combination (proportional columns): gamma is still
    determined, with the Cramer-Rao bound of the plan reduced to gamma and that combination."""
    rng = np.random.default_rng(4)
    a, b = rng.standard_normal(10), rng.standard_normal(10)
    info = cal.Information(
        names=("gamma", "P0", "p_atm"),
        values={"gamma": 1.4, "P0": 3e5, "p_atm": 1e5},
        ts=np.linspace(0.0, 1e-3, 10),
        jacobian=np.stack([a, b, 3.0 * b], axis=1),
        noise=0.01,
    )
    std = info.std()
    Jr = np.stack([a, b], axis=1)
    assert std["gamma"] == pytest.approx(0.01 * np.sqrt(np.linalg.inv(Jr.T @ Jr)[0, 0]), rel=1e-9)
    assert np.isinf(std["P0"]) and np.isinf(std["p_atm"])


def test_a_singular_fit_in_float32_is_singular_to_float32s_precision():
    """The Jacobian of a float32 run carries its round-off (1e-7 relative a step, more over a run):
    proportional columns are then 1e-6 apart, not exactly equal, and the float64 cut (squared
    singular values 1e-14 of the largest) called them independent, P0 and p_atm determined to +-1e8.
    The cut follows the precision of the scene's float type."""
    rng = np.random.default_rng(6)
    a, b = rng.standard_normal(12), rng.standard_normal(12)
    J = np.stack([a, b, 3.0 * b * (1.0 + 1e-6 * rng.standard_normal(12))], axis=1)
    r = 0.1 * rng.standard_normal(12)
    names, fitted = ("gamma", "P0", "p_atm"), {"gamma": 1.4, "P0": 3e5, "p_atm": 1e5}
    with float32():
        sc = jm.GasSlab(**SLAB)
        u = cal.uncertainty(sc, names, fitted, r, J_theta=J.astype(np.float32))
    assert np.isfinite(u["std"]["gamma"]) and np.isinf(u["std"]["P0"]) and np.isinf(u["std"]["p_atm"])
    u64 = cal.uncertainty(jm.GasSlab(**SLAB), names, fitted, r, J_theta=J)  # float64 resolves 1e-6
    assert all(np.isfinite(v) for v in u64["std"].values())
    info = cal.Information(
        names=names,
        values=fitted,
        ts=TS[:12],
        jacobian=J,
        noise=0.01,
        precision=float(np.finfo(np.float32).eps),
    )
    std = info.std()
    assert np.isfinite(std["gamma"]) and np.isinf(std["P0"]) and np.isinf(std["p_atm"])


@pytest.mark.slow
def test_a_plan_computed_in_float32_says_what_it_cannot_determine():
    """The gas slab's P0, p_atm and rho0 enter only through two combinations: in float64 a plan of the
    four constants determines gamma alone (the others' standard errors infinite); in float32 it called
    all four undetermined (gamma's component along the null space 6.7e-6, over the float64 cut 1e-6)."""
    ts = np.linspace(0.0, 12e-3, 61)
    dt = 0.2 * (1 / 16) / np.sqrt(1.4 * 3e5)
    with float32():
        sc = jm.GasSlab(cells=16, h=1 / 16, pad=96)
        info = cal.information(sc, jm.CPDI(), ts, fit=("gamma", "P0", "p_atm", "rho0"), dt=dt, noise=0.01)
    std = info.std()
    assert std["gamma"] == pytest.approx(0.0159, rel=0.5)  # 0.0159 in float64
    assert all(np.isinf(std[k]) for k in ("P0", "p_atm", "rho0"))


def test_a_plan_in_any_units_has_the_same_correlation():
    """Whether a plan determines its constants does not depend on their units: a regular plan whose
    Jacobian columns differ in scale by 1e8 (a pressure in Pa beside an exponent) has the
    correlation of the same plan in scaled units, and standard errors that scale with the units.
    (The test on the unscaled information, ratio of eigenvalues 1e-16 here, called it singular.)"""
    rng = np.random.default_rng(5)
    A = rng.standard_normal((12, 3))  # a regular plan, condition ~ 3
    units = np.array([1.0, 1e-8, 1e-7])  # d x / d P0 per Pa, d x / d p_atm per Pa

    def plan(J):
        return cal.Information(
            names=("gamma", "P0", "p_atm"),
            values={"gamma": 1.4, "P0": 3e5, "p_atm": 1e5},
            ts=np.linspace(0.0, 1e-3, 12),
            jacobian=J,
            noise=0.01,
        )

    scaled, si = plan(A), plan(A * units)
    np.testing.assert_allclose(si.correlation(), scaled.correlation(), rtol=1e-10, atol=1e-12)
    std_scaled, std_si = scaled.std(), si.std()
    for k, u in zip(("gamma", "P0", "p_atm"), units):
        assert std_si[k] == pytest.approx(std_scaled[k] / u, rel=1e-10)


def test_a_plan_refuses_a_window_before_its_first_time():
    """``Information.std`` of a window that holds no observation is refused, not a silent inf."""
    info = cal.Information(
        names=("gamma",),
        values={"gamma": 1.4},
        ts=np.array([1e-3, 2e-3]),
        jacobian=np.ones((2, 1)),
        noise=0.1,
    )
    assert np.isfinite(info.std()["gamma"])
    with pytest.raises(ValueError, match=r"t_end must be at or after the plan's first time, 0.001, got -1.0"):
        raw(cal.Information.std)(info, t_end=-1.0)
    with pytest.raises(ValueError, match="t_end must be a real number, got 'a'"):
        raw(cal.Information.fisher)(info, t_end="a")
    with pytest.raises(ValueError, match=r"noise must be one number, got an array of shape \(2,\)"):
        raw(cal.Information.fisher)(info, noise=[1.0, 2.0])


# -- what a fit reports -----------------------------------------------------------------------------------


@pytest.mark.slow
def test_lbfgs_below_tol_is_converged_without_a_warning():
    """Noise-free data: L-BFGS stops with a loss far below ``tol`` (by its rule of no further
    improvement), which is a converged fit, not one that ran out of iterations."""
    kw = dict(p_atm=1.0, rho0=1.0, h=1 / 8, cells=8, pad=64)
    ts, dt = np.linspace(0.0, 3.0, 16), 0.2 * (1 / 8) / np.sqrt(1.3 * 4.2)
    scene = jm.GasSlab(P0=4.2, gamma=1.3, **kw)
    x = np.asarray(cal.trajectory(scene, jm.CPDI(), ts, dt=dt))
    with warnings.catch_warnings():
        warnings.simplefilter("error", cal.CalibrationWarning)
        fit = cal.calibrate(
            scene, jm.CPDI(), ts, x, starts=dict(gamma=1.6, P0=3.0), dt=dt, method="lbfgs", iterations=40
        )
    assert fit.loss <= 1e-14 and fit.converged and fit.warning is None, (fit.loss, fit.warning)
    assert fit.fitted["gamma"] == pytest.approx(1.3, rel=1e-6)


@pytest.mark.parametrize("fn", ["calibrate", "calibrate_each", "information", "profile"])
def test_an_unknown_keyword_names_the_function_called_and_lists_only_what_it_takes(fn):
    data = dict(calibrate=(X,), calibrate_each=(X[None],), information=(), profile=(X, _fit(), [0.0]))[fn]

    def call(**kw):
        return getattr(cal, fn)(jm.GasSlab(**SLAB), jm.CPDI(), TS, *data, dt=DT, **kw)

    with pytest.raises(TypeError, match=rf"^{fn}\(\) got an unexpected keyword argument 'stepz'; it takes "):
        call(stepz=3)
    try:
        call(stepz=3)
    except TypeError as e:
        takes = set(str(e).split("it takes ")[1].split(", "))
    assert "transfer" in takes and not {"steps", "saveat", "throw", "t_end", "cfl", "max_steps"} & takes
    with pytest.raises(ValueError, match=rf"^{fn}\(\) does not take steps: "):
        call(steps=3)


def test_draws_of_P0_and_p_atm_fitted_together_keep_P0_above_p_atm():
    """Both fitted: their offsets are 0, and a Gaussian wide enough puts some draws at P0 <= p_atm,
    which the scene refuses; those are drawn again, and the draw is still seeded."""
    fitted, offs = dict(P0=1.2e5, p_atm=1.0e5), dict(P0=0.0, p_atm=0.0)
    C = np.diag([0.1**2, 0.1**2])  # ln P0 and ln p_atm each +-10%: about 10% of plain draws out of order
    rng = np.random.default_rng(0)
    plain = fitted["P0"] * np.exp(0.1 * rng.standard_normal(4000)) <= fitted["p_atm"] * np.exp(
        0.1 * rng.standard_normal(4000)
    )
    assert plain.mean() > 0.05  # the Gaussian itself does put members out of order
    d = cal.draw(fitted, offs, ("P0", "p_atm"), C, 4000, seed=1)
    assert np.all(d["P0"] > d["p_atm"]) and d["P0"].shape == (4000,)
    again = cal.draw(fitted, offs, ("P0", "p_atm"), C, 4000, seed=1)
    assert np.array_equal(d["P0"], again["P0"]) and np.array_equal(d["p_atm"], again["p_atm"])
    # one constant of the pair alone: nothing to order, the plain Gaussian draw
    one = cal.draw(dict(P0=1.2e5), dict(P0=1.0e5), ("P0",), np.eye(1) * 0.01, 5, seed=1)
    expect = 1.0e5 + np.exp(np.log(2e4) + 0.1 * np.random.default_rng(1).standard_normal(5))
    np.testing.assert_allclose(one["P0"], expect, rtol=1e-12)
    with pytest.raises(ValueError, match="fewer than one draw in a thousand has P0 > p_atm"):
        cal.draw(dict(P0=1.0e5, p_atm=1.2e6), offs, ("P0", "p_atm"), np.diag([1e-4, 1e-4]), 10, seed=0)
