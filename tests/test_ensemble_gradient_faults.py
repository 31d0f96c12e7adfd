"""Ensembles and derivatives under faults: an ensemble's members checked each as a whole, a member's
scene when run settings vary too, a derivative of a run that broke down refused alike in both modes,
a parameter named twice refused by name, and an objective whose broken members cannot pass as
finished under ``jax.vmap``."""

import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import status as st_bits

DT = 1e-5
RUN = dict(dt=DT, steps=3, artificial_cells=1)
HEALTHY_BETA = 200.0
BROKEN_BETA = -2e5  # squeezed so hard that the first step inverts every particle
BROKEN_STATUS = st_bits.NONFINITE | st_bits.NONPOSITIVE_F | st_bits.CFL
QUANTITIES = " and ".join(st_bits.describe(BROKEN_STATUS))


def first_line(error: Exception) -> str:
    """The error's message without the note JAX adds to an error raised under a transformation."""
    return str(error).split("\n")[0]


def gas(beta=HEALTHY_BETA):
    return jm.GasExpansion(beta=beta, cells=4)


def test_the_broken_scene_breaks_down_at_step_1_with_its_status():
    sol = jm.simulate(gas(BROKEN_BETA), jm.MPQ(), throw=False, **RUN)
    assert (int(sol.status), int(sol.state.fail_step), int(sol.state.step)) == (BROKEN_STATUS, 1, 0)


# ensemble: each member's values checked together ----------------------------------------------------


def test_an_ensemble_refuses_a_member_by_index_with_its_values_not_an_extreme_against_the_base():
    """P0 and p_atm vary together: the largest p_atm (4e5) is above the base scene's P0 (3e5) but
    below its own member's, and member 1 (P0 = 3e5 < p_atm = 4e5) is the one the scene refuses."""
    slab = jm.GasSlab(cells=4, h=0.25, pad=8)
    match = (
        r"^member 1 of vary \(P0=300000, p_atm=400000\) is refused by GasSlab: P0 must be > p_atm "
        r"\(the slab expands\), got P0=300000.0, p_atm=400000.0$"
    )
    with pytest.raises(ValueError, match=match):
        jm.ensemble(slab, jm.CPDI(), {"P0": [6e5, 3e5], "p_atm": [1e5, 4e5]}, dt=1e-6, steps=2)
    # one value a member's own other value makes invalid, whichever parameter holds the extreme
    match = r"^member 0 of vary \(P0=200000, p_atm=250000\) is refused by GasSlab: P0 must be > p_atm"
    with pytest.raises(ValueError, match=match):
        jm.ensemble(slab, jm.CPDI(), {"P0": [2e5, 9e5], "p_atm": [2.5e5, 1e5]}, dt=1e-6, steps=2)


def test_an_ensemble_of_one_varied_parameter_names_the_member_of_a_refused_value():
    match = (
        r"^vary\['gamma'\] holds 0.5, which GasExpansion refuses: gamma must be > 1.0, got 0.5 \(member 2\)$"
    )
    with pytest.raises(ValueError, match=match):
        jm.ensemble(gas(), jm.MPQ(), {"gamma": [1.4, 1.3, 0.5, 1.2]}, **RUN)


@pytest.mark.slow
def test_an_ensemble_whose_every_member_is_valid_runs_though_an_extreme_is_invalid_with_the_base():
    slab = jm.GasSlab(cells=4, h=0.25, pad=8)  # P0 = 3e5, p_atm = 1e5
    vary = {"P0": [6e5, 8e5], "p_atm": [1e5, 4e5]}  # every member has P0 > p_atm
    ens = jm.ensemble(slab, jm.CPDI(), vary, dt=1e-6, steps=2)
    assert ens.status.tolist() == [0, 0]
    assert {k: v.tolist() for k, v in ens.params.items()} == vary
    own = ens.member_scene(slab, 1)
    assert own.parameter_values() == {**slab.parameter_values(), "P0": 8e5, "p_atm": 4e5}


# Ensemble.member_scene with run settings varied ----------------------------------------------------


def test_an_ensemble_names_a_keyword_it_does_not_take():
    # Python named the inner function: "prepare() got an unexpected keyword argument 'stepz'"
    sc = jm.GasExpansion(cells=4)
    with pytest.raises(
        TypeError, match=r"^ensemble\(\) got an unexpected keyword argument 'stepz'; it takes "
    ):
        jm.ensemble(sc, jm.CPDI(), vary={"beta": [100.0, 200.0]}, dt=DT, stepz=3)


@pytest.mark.slow
def test_member_scene_leaves_out_the_varied_run_settings():
    """``dt`` is a run setting, not a scene parameter: member i's scene holds its scene values, and its
    errors are those of the run of its own dt alone."""
    scene = gas()
    ens = jm.ensemble(scene, jm.MPQ(), {"dt": [DT, 2 * DT], "beta": [150.0, 250.0]}, **RUN)
    own = ens.member_scene(scene, 1)
    assert own.parameter_values() == {**scene.parameter_values(), "beta": 250.0}
    assert float(ens.params["dt"][1]) == 2 * DT
    sol = ens.member(1)
    got = jm.errors(own, sol.state, sol.body)["F_max_rel"]
    alone = jm.simulate(gas(250.0), jm.MPQ(), **{**RUN, "dt": 2 * DT})
    want = jm.errors(gas(250.0), alone.state, alone.body)["F_max_rel"]
    np.testing.assert_allclose(float(got), float(want), rtol=1e-9)
    assert float(got) > 0.0
    # only run settings varied: the member's scene is the base scene's values
    only_dt = jm.ensemble(scene, jm.MPQ(), {"dt": [DT, 2 * DT]}, **RUN)
    assert only_dt.member_scene(scene, 1).parameter_values() == scene.parameter_values()


# gradient: a run that broke down, in both modes ----------------------------------------------------


def _gradient_refusal(mode, error):
    with pytest.raises(ValueError) as info:
        jm.gradient(gas(BROKEN_BETA), jm.MPQ(), ["beta"], throw=False, mode=mode, error=error, **RUN)
    return str(info.value)


@pytest.mark.slow
@pytest.mark.parametrize("error", ["F_rms_rel", lambda scene, sol: jnp.sum(sol.state.x)])
def test_a_gradient_of_a_run_that_broke_down_is_refused_alike_in_both_modes(error):
    """With ``throw=False`` the run's status says it broke down: its derivative (that of the last good
    state, here the initial one) is not returned as the run's, whichever the mode or the error."""
    want = (
        f"gradient() differentiates a finished run, and this state is of a run that broke down at step "
        f"1 ({QUANTITIES}): its state is the last good one, at step 0 (t = 0), not the run's end. A "
        f"smaller dt or fewer steps run to the end; jm.sensitivity.objective(..., with_status=True) "
        f"gives the error of the last good state and its status, for jax.grad(..., has_aux=True)."
    )
    assert _gradient_refusal("reverse", error) == want
    assert _gradient_refusal("forward", error) == want


@pytest.mark.slow
@pytest.mark.parametrize("transform", [jax.grad, jax.jacfwd])
def test_errors_of_a_broken_run_under_a_derivative_are_refused_not_a_tracer_error(transform):
    """Under ``jax.jacfwd`` (as under ``jax.grad``) the status is concrete and the time may be traced:
    the refusal names what it can read."""

    def f(beta):
        scene = gas(beta)
        sol = jm.simulate(scene, jm.MPQ(), throw=False, **RUN)
        return jm.errors(scene, sol.state, sol.body)["F_rms_rel"]

    want = (
        f"errors() measures a finished run, and this state is of a run that broke down at step 1 "
        f"({QUANTITIES}): its state is the last good one, at step 0{{}}, not the run's end. Pass "
        f"allow_broken=True to measure that state anyway."
    )
    with pytest.raises(ValueError) as info:
        transform(f)(BROKEN_BETA)
    # the time is concrete under jax.grad, traced under jax.jacfwd
    t = " (t = 0)" if transform is jax.grad else ""
    assert first_line(info.value) == want.format(t)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["reverse", "forward"])
def test_a_healthy_gradient_is_that_of_the_objective(mode):
    """``gradient`` is exactly ``jax.grad`` (or ``jax.jacfwd``) of ``objective``, with or without
    ``throw``."""
    names = ["beta", "P0", "dt"]
    values = {"beta": jnp.asarray(HEALTHY_BETA), "P0": gas().P0, "dt": jnp.asarray(DT)}
    for kw in ({}, {"throw": False}):
        f = jm.sensitivity.objective(gas(), jm.MPQ(), names, **RUN, **kw)
        want = (jax.grad if mode == "reverse" else jax.jacfwd)(f)(values)
        got = jm.gradient(gas(), jm.MPQ(), names, mode=mode, **RUN, **kw)
        assert {k: float(v) for k, v in got.items()} == {k: float(v) for k, v in want.items()}


# names: each once -----------------------------------------------------------------------------------


def test_a_parameter_named_twice_is_refused_by_name():
    match = r"^names must name each parameter once, got \['beta', 'P0', 'beta'\]: 'beta' twice$"
    with pytest.raises(ValueError, match=match):
        jm.gradient(gas(), jm.MPQ(), ["beta", "P0", "beta"], **RUN)
    with pytest.raises(ValueError, match=match):
        jm.sensitivity.objective(gas(), jm.MPQ(), ["beta", "P0", "beta"], **RUN)
    with pytest.raises(
        ValueError, match=r"^names must name each parameter once, got \('dt', 'dt'\): 'dt' twice$"
    ):
        jm.gradient(gas(), jm.MPQ(), ("dt", "dt"), **RUN)


# objective: a broken member under jax.vmap ---------------------------------------------------------


@pytest.mark.slow
def test_the_objective_with_status_gives_each_members_status_beside_its_error():
    """``with_status=True``: ``(error, status)``; a member that broke down has its nonzero status and
    the error of its last good state (here the initial one, exact: 0), NaN-free, with that state's
    derivatives (``jax.grad(..., has_aux=True)``)."""
    plain = jm.sensitivity.objective(gas(), jm.MPQ(), ["beta"], throw=False, **RUN)
    f = jm.sensitivity.objective(gas(), jm.MPQ(), ["beta"], throw=False, with_status=True, **RUN)
    betas = jnp.array([HEALTHY_BETA, BROKEN_BETA])
    value, status = jax.vmap(lambda b: f({"beta": b}))(betas)
    assert status.tolist() == [0, BROKEN_STATUS]
    healthy = float(plain({"beta": jnp.asarray(HEALTHY_BETA)}))
    assert healthy > 0.0
    np.testing.assert_allclose(np.asarray(value), [healthy, 0.0], rtol=1e-12, atol=0.0)
    grad, status = jax.vmap(jax.grad(lambda b: f({"beta": b}), has_aux=True))(betas)
    assert status.tolist() == [0, BROKEN_STATUS]
    healthy_grad = float(jax.grad(lambda b: plain({"beta": b}))(HEALTHY_BETA))
    np.testing.assert_allclose(np.asarray(grad), [healthy_grad, 0.0], rtol=1e-12, atol=0.0)
    # concrete: the same pair
    value, status = f({"beta": jnp.asarray(BROKEN_BETA)})
    assert (float(value), int(status)) == (0.0, BROKEN_STATUS)


@pytest.mark.slow
def test_the_plain_objective_of_a_broken_run_is_refused_or_nan_never_a_finished_runs_error():
    """Without ``with_status`` a concrete status that says the run broke down is refused; a traced one
    (``jax.vmap``, ``jax.jit``) gives NaN, value and derivative, for that member only."""
    f = jm.sensitivity.objective(gas(), jm.MPQ(), ["beta"], throw=False, **RUN)
    healthy = float(f({"beta": jnp.asarray(HEALTHY_BETA)}))
    healthy_grad = float(jax.grad(lambda b: f({"beta": b}))(HEALTHY_BETA))
    betas = jnp.array([HEALTHY_BETA, BROKEN_BETA])
    value = np.asarray(jax.vmap(lambda b: f({"beta": b}))(betas))
    np.testing.assert_allclose(value[0], healthy, rtol=1e-12, atol=0.0)
    assert np.isnan(value[1])
    grad = np.asarray(jax.vmap(jax.grad(lambda b: f({"beta": b})))(betas))
    np.testing.assert_allclose(grad[0], healthy_grad, rtol=1e-12, atol=0.0)
    assert np.isnan(grad[1])
    assert np.isnan(float(jax.jit(f)({"beta": jnp.asarray(BROKEN_BETA)})))
    want = (
        f"objective() measures a finished run, and this state is of a run that broke down at step 1 "
        f"({QUANTITIES}): its state is the last good one, at step 0{{}}, not the run's end. "
        f"Pass with_status=True to get the error of that state beside its status."
    )
    # the time is concrete but under jax.jacfwd
    for transform, t in ((lambda g: g, " (t = 0)"), (jax.grad, " (t = 0)"), (jax.jacfwd, "")):
        with pytest.raises(ValueError) as info:
            transform(lambda b: f({"beta": b}))(jnp.asarray(BROKEN_BETA))
        assert first_line(info.value) == want.format(t)
    want = want.format(" (t = 0)")
    callable_error = jm.sensitivity.objective(
        gas(), jm.MPQ(), ["beta"], throw=False, error=lambda scene, sol: jnp.sum(sol.state.x), **RUN
    )
    with pytest.raises(ValueError) as info:
        callable_error({"beta": jnp.asarray(BROKEN_BETA)})
    assert str(info.value) == want
    assert np.isnan(float(jax.vmap(lambda b: callable_error({"beta": b}))(betas)[1]))


def test_objective_refuses_a_with_status_that_is_not_a_bool():
    objective = inspect.unwrap(jm.sensitivity.objective)  # past the suite's jaxtyping check, to its own
    with pytest.raises(ValueError, match=r"^with_status must be True or False, got 'yes'$"):
        objective(gas(), jm.MPQ(), ["beta"], with_status="yes", **RUN)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["reverse", "forward"])
def test_a_gradient_of_an_error_that_is_not_finite_is_refused(mode):
    # a constant NaN has derivative 0: without the check, the gradient would be {"beta": 0.0}
    nan = lambda scene, sol: jnp.asarray(jnp.nan)  # noqa: E731
    with pytest.raises(ValueError, match=r"^gradient\(\) differentiates a finite error, and the error of"):
        jm.gradient(gas(), jm.MPQ(), ["beta"], error=nan, mode=mode, **RUN)


def test_an_ensemble_of_a_scene_of_bodies_checks_its_members_on_that_scene():
    """A ``Bodies`` scene holds its parts beside its parameters: each member's values are checked on
    the scene itself (its parts kept), and a refused one is named with its member."""
    from jaxmpm.geometry import Box

    part = jm.Region(Box(0.0, 1.0), jm.NeoHookean(lam=1.0, mu=1.0), rho0=1.0, velocity=0.1)
    scene = jm.Bodies(parts=(part,), cells=4, h=0.25, pad=4)
    ens = jm.ensemble(scene, jm.CPDI(), {"h": [0.25, 0.3]}, dt=1e-3, steps=2)
    assert list(ens.status) == [0, 0]
    one = jm.simulate(jm.Bodies(parts=(part,), cells=4, h=0.3, pad=4), jm.CPDI(), dt=1e-3, steps=2)
    np.testing.assert_allclose(np.asarray(ens.solution.state.x[1]), np.asarray(one.state.x), rtol=1e-14)
    with pytest.raises(ValueError, match=r"^vary\['h'\] holds -0.1, which Bodies refuses: h must be > 0"):
        jm.ensemble(scene, jm.CPDI(), {"h": [0.25, -0.1]}, dt=1e-3, steps=2)
