"""The metrics under faults, continued: an ensemble's batch, the state of a run that broke down and a
time past the one the exact solution holds until are refused; the ranges of the smoothness measures'
settings and the common mistakes in their arguments are named."""

import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raw

import jaxmpm as jm
from jaxmpm import metrics
from jaxmpm.ensemble import Ensemble
from jaxmpm.particles import parallelogram_corners

C0 = np.zeros(1)  # the centre of the radial measures, in 1D


@pytest.fixture(scope="module")
def runs():
    scene = jm.GasExpansion(cells=2, ppc=1)
    broken = jm.simulate(scene, jm.MPQ(), dt=1e-3, steps=3, throw=False)  # dt beyond the stable limit
    ok = jm.simulate(scene, jm.MPQ(), dt=1e-5, steps=2)
    assert broken.failure() is not None and int(broken.state.step) == 0 and ok.failure() is None
    return scene, broken, ok


def healed(state):
    """``state`` with the status of a healthy run (what ``allow_broken=True`` must measure alike)."""
    return eqx.tree_at(
        lambda s: (s.status, s.fail_step),
        state,
        (jnp.zeros_like(state.status), jnp.full_like(state.fail_step, -1)),
    )


def stacked(*trees):
    """An ensemble's batch: the members stacked along a leading axis."""
    return jax.tree.map(lambda *a: jnp.stack(a), *trees)


# an ensemble's batch -------------------------------------------------------------------------------


def test_a_batch_with_a_broken_member_is_refused_by_every_state_measure(runs):
    scene, broken, ok = runs
    state, body = stacked(ok.state, broken.state), stacked(ok.body, broken.body)
    calls = {
        "diagnostics": lambda: jm.diagnostics(scene, state, body),
        "density": lambda: jm.density(state, body),
        "separation": lambda: jm.separation(state, body),
        "pressure": lambda: jm.pressure(state),
        "domain_corners": lambda: jm.domain_corners(state, body),
        "radial_velocity": lambda: metrics.radial_velocity(state, body, C0),
        "spurious_rotation": lambda: metrics.spurious_rotation(state, body),
    }
    for name, call in calls.items():
        with pytest.raises(
            ValueError,
            match=rf"^{name}\(\) measures one run, and this state holds a batch \(x of shape \(2, 2, 1\)\): "
            r"measure each member whose status is 0 \(Ensemble.member\(i\), with its scene "
            r"Ensemble.member_scene\(scene, i\)\); under jax.vmap the status is not read, so leave out "
            r"the members that broke down first$",
        ):
            call()
    # mapped over the members (traced, the status is not read: the broken member is measured at its
    # last good state, which is why the message says to leave such members out first)
    rho = jax.vmap(jm.density)(state, body)
    np.testing.assert_array_equal(rho[0], jm.density(ok.state, ok.body))
    np.testing.assert_array_equal(rho[1], jm.density(broken.state, broken.body, allow_broken=True))


@pytest.mark.parametrize("t", [-1.0, np.nan])
def test_a_state_whose_time_is_negative_or_nan_is_refused(runs, t):
    """A state written by hand at t = -1 was measured against the exact solution at -1 (finite,
    meaningless errors), and at t = NaN every exact error was None, as for a scene without one."""
    scene, _, ok = runs
    state = eqx.tree_at(lambda s: s.t, ok.state, jnp.asarray(t, dtype=ok.state.t.dtype))
    for name, call in {
        "errors": lambda: jm.errors(scene, state, ok.body),
        "pressure_error": lambda: metrics.pressure_error(scene, state, ok.body),
        "separation": lambda: jm.separation(state, ok.body),
    }.items():
        with pytest.raises(
            ValueError, match=rf"^{name}\(\) measures a state of a run, whose time t is finite"
        ):
            call()
    with pytest.raises(ValueError, match=r"^t must be a finite number, got nan$"):
        metrics.exact_holds(scene, np.nan)


def test_a_batched_body_is_refused(runs):
    _, _, ok = runs
    with pytest.raises(
        ValueError, match=r"^body must be one run's Body, and this one holds a batch \(X of shape"
    ):
        jm.density(ok.state, stacked(ok.body, ok.body))


# the state of a run that broke down ----------------------------------------------------------------


STATE_MEASURES = {
    "pressure": lambda st, body, **kw: jm.pressure(st, **kw),
    "domain_corners": lambda st, body, **kw: jm.domain_corners(st, body, **kw),
    "implied_corners": lambda st, body, **kw: metrics.implied_corners(st, body, **kw),
    "rotation_angle": lambda st, body, **kw: metrics.rotation_angle(st, **kw),
    "spurious_rotation": lambda st, body, **kw: metrics.spurious_rotation(st, body, **kw),
    "radial_velocity": lambda st, body, **kw: metrics.radial_velocity(st, body, C0, **kw),
    "angular_spread": lambda st, body, **kw: metrics.angular_spread(st, body, C0, 2, **kw),
}


@pytest.mark.parametrize("name", list(STATE_MEASURES) + ["vorticity"])
def test_the_state_measures_refuse_a_run_that_broke_down(runs, name):
    _, broken, _ = runs
    st, body = broken.state, broken.body
    call = STATE_MEASURES.get(name, lambda st, body, **kw: metrics.vorticity(st, **kw))
    with pytest.raises(
        ValueError,
        match=rf"^{name}\(\) measures a finished run, and this state is of a run that broke down at step 1 "
        r"\(time step beyond the stable limit.*the last good one, at step 0 \(t = 0\).*"
        r"Pass allow_broken=True to measure that state anyway.$",
    ):
        call(st, body)
    if name != "vorticity":  # (an MPQ run with FLIP carries no C to measure)
        # asked for, the last good state is measured as that of a healthy run
        got = call(st, body, allow_broken=True)
        want = call(healed(st), body)
        jax.tree.map(np.testing.assert_array_equal, got, want)


def test_the_domains_and_pressure_of_a_broken_run_are_measured_when_asked(runs):
    """As the blast study and the command line's report measure a run that broke down, beside its
    status."""
    _, broken, _ = runs
    st, body = broken.state, broken.body
    corners = jm.domain_corners(st, body, allow_broken=True)
    assert int(metrics.folded_domains(corners, body)) == 0
    np.testing.assert_array_equal(jm.pressure(st, allow_broken=True), -np.asarray(st.sigma[:, 0, 0]))


def test_a_healthy_run_is_measured_as_before(runs):
    _, _, ok = runs
    st, body = ok.state, ok.body
    np.testing.assert_array_equal(jm.pressure(st), -np.asarray(st.sigma[:, 0, 0]))
    np.testing.assert_array_equal(
        jm.domain_corners(st, body), body.particle_corners(st.corners)
    )  # MPQ tracks its corners
    np.testing.assert_array_equal(
        metrics.implied_corners(st, body), parallelogram_corners(body.r0, st.x, st.F)
    )


# the body's particle count -------------------------------------------------------------------------


def test_density_checks_the_bodys_particle_count(runs):
    _, _, ok = runs
    other = jm.GasExpansion(cells=1, ppc=1, rho0=7.0).body()
    with pytest.raises(ValueError, match=r"^the state has 2 particles and the body 1$"):
        jm.density(ok.state, other)


# a time past the one the exact solution holds until ------------------------------------------------


@pytest.fixture(scope="module")
def vacuum():
    scene = jm.VacuumExpansion(cells=4, ppc=1, pad=40)
    sol = jm.simulate(scene, jm.CPDI(), dt=1e-3, steps=1)
    return scene, sol


def test_past_t_valid_there_is_no_exact_solution_to_measure_against(vacuum):
    """Past the time a scene's exact solution holds, its errors against it are None (as for a scene
    with none), exact_fields is None, and pressure_error, a number against it, is refused."""
    scene, sol = vacuum
    t_valid = float(scene.t_valid)
    assert t_valid == pytest.approx(0.105644, abs=5e-7)  # to the digits the message prints
    late = eqx.tree_at(lambda s: s.t, sol.state, jnp.asarray(3.0 * t_valid))
    body = sol.body
    assert not metrics.exact_holds(scene, 3.0 * t_valid)
    err = jm.errors(scene, late, body)
    assert all(err[k] is None for k in metrics.EXACT_ERRORS)
    assert np.isfinite(float(err["separation_max"]))  # not against the exact solution: measured
    assert metrics.exact_fields(scene, body, 3.0 * t_valid) is None
    past = r"the exact solution of vacuum-expansion, which holds up to t_valid = 0.105644, and "
    with pytest.raises(
        ValueError, match=rf"^pressure_error\(\) compares with {past}the state's time t = 0.3169"
    ):
        metrics.pressure_error(scene, late, body)
    # up to t_valid itself, measured
    assert metrics.exact_holds(scene, t_valid)
    at = eqx.tree_at(lambda s: s.t, sol.state, jnp.asarray(t_valid))
    assert np.isfinite(float(jm.errors(scene, at, body)["F_max_rel"]))
    assert metrics.exact_fields(scene, body, jnp.asarray(t_valid)) is not None
    # traced, the time cannot be read: measured
    x_rms = eqx.filter_jit(lambda s: jm.errors(scene, s, body)["x_rms_abs"])(late)
    assert np.isfinite(float(x_rms))
    # a scene without t_valid holds at any time; one with no exact solution at none
    assert metrics.exact_holds(jm.GasExpansion(), 1e9)
    assert not metrics.exact_holds(jm.GasSlab(), 0.0)


@pytest.mark.slow
def test_a_shock_tubes_euler_errors_hold_up_to_t_valid():
    """The shock tube's exact solution (``solution``, of the Euler equations) holds until a wave
    reaches an end of the tube: euler_errors are measured up to t_valid and None past it."""
    scene = jm.ShockTube(cells=20)
    model = jm.Model(scene, jm.CPDI(), jm.FLIP())
    setup = jm.setup(model)
    state, body = jm.initial_state(model, setup), setup.body
    t_valid = float(scene.t_valid)
    assert metrics.exact_holds(scene, t_valid) and not metrics.exact_holds(scene, 1.01 * t_valid)
    at = eqx.tree_at(lambda s: s.t, state, jnp.asarray(t_valid))
    err = metrics.euler_errors(scene, at, body)
    assert sorted(err) == ["e_L1", "p_L1", "rho_L1", "u_L1"] and all(
        np.isfinite(float(v)) for v in err.values()
    )
    late = eqx.tree_at(lambda s: s.t, state, jnp.asarray(1.01 * t_valid))
    assert metrics.euler_errors(scene, late, body) is None


# the smoothness measures' settings -----------------------------------------------------------------


@pytest.mark.parametrize(
    "threshold, message",
    [
        (
            -1.0,
            r"threshold must be >= 0 and < 1 \(the smallest \|m_k\| counted, relative to the largest\), "
            r"got -1.0",
        ),
        (5.0, r"threshold must be >= 0 and < 1 .*, got 5.0"),
        (1.0, r"threshold must be >= 0 and < 1 .*, got 1.0"),
        (float("nan"), r"threshold must be finite, got nan"),
    ],
)
def test_angular_spread_takes_a_threshold_in_0_1(runs, threshold, message):
    _, _, ok = runs
    with pytest.raises(ValueError, match=f"^{message}$"):
        metrics.angular_spread(ok.state, ok.body, C0, 2, threshold=threshold)


def test_angular_spread_counts_every_moving_bin_at_threshold_0(runs):
    _, _, ok = runs
    out = metrics.angular_spread(ok.state, ok.body, C0, 2, threshold=0.0)
    assert np.all(np.asarray(out["counted"]))


@pytest.mark.parametrize("iterations", [-1, 0])
def test_polar_rotation_takes_at_least_one_iteration(iterations):
    F = jnp.array([[[2.0, 1.0], [0.0, 1.0]]])
    with pytest.raises(ValueError, match=rf"^iterations must be an integer >= 1, got {iterations}$"):
        metrics.polar_rotation(F, iterations=iterations)


@pytest.mark.parametrize("shape", [(4, 2), (2,), (4, 2, 3), (4, 4, 4)])
def test_polar_rotation_takes_a_stack_of_square_matrices_of_1_to_3_rows(shape):
    with pytest.raises(
        ValueError,
        match=r"^F must be deformation gradients, shape \(n, dim, dim\) with dim 1, 2 or 3, got shape "
        + re.escape(str(shape)),
    ):
        raw(metrics.polar_rotation)(jnp.ones(shape))  # without the suite's type checks: what a user runs


def test_polar_rotation_takes_a_numpy_integer():
    F = jnp.array([[[2.0, 1.0], [0.0, 1.0]]])
    np.testing.assert_array_equal(raw(metrics.polar_rotation)(F, np.int64(8)), metrics.polar_rotation(F))


# common mistakes -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["errors", "diagnostics"])
def test_a_solution_for_the_state_is_named(runs, name):
    scene, _, ok = runs
    fn = getattr(jm, name)
    # under the suite's runtime type checks a TypeError naming state may come first
    with pytest.raises((ValueError, TypeError), match="state"):
        fn(scene, ok, ok.body)
    with pytest.raises(
        ValueError,
        match=r"^state must be a jaxmpm State, got a Solution: pass solution.state and solution.body$",
    ):
        raw(fn)(scene, ok, ok.body)
    with pytest.raises(
        ValueError,
        match=r"^body must be a jaxmpm Body, got a Solution: pass solution.state and solution.body$",
    ):
        raw(fn)(scene, ok.state, ok)


def test_none_for_the_state_or_the_body_is_named(runs):
    scene, _, ok = runs
    with pytest.raises(
        ValueError,
        match=r"^body must be the run's reference configuration, a jaxmpm Body \(solution.body\), got None$",
    ):
        raw(jm.errors)(scene, ok.state, None)
    with pytest.raises(ValueError, match=r"^state must be a jaxmpm State \(solution.state\), got None$"):
        raw(jm.diagnostics)(scene, None, ok.body)
    with pytest.raises(ValueError, match=r"^state must be a jaxmpm State \(solution.state\), got None$"):
        raw(jm.density)(None, ok.body)


def test_an_ensemble_for_the_state_is_named(runs):
    scene, _, ok = runs
    ens = Ensemble(params={}, solution=stacked(ok, ok), status=np.zeros(2, int), devices=1)
    with pytest.raises(
        ValueError, match=r"^state must be a jaxmpm State, got an Ensemble: measure each member"
    ):
        raw(jm.errors)(scene, ens, ok.body)


def test_where_as_a_list_of_bools_is_taken(runs):
    scene, _, ok = runs
    st, body = ok.state, ok.body
    want = jm.errors(scene, st, body, where=jnp.array([True, False]))
    got = raw(jm.errors)(scene, st, body, where=[True, False])
    assert got.keys() == want.keys()
    for k in want:
        if want[k] is None:
            assert got[k] is None
        else:
            assert float(got[k]) == float(want[k]), k
    p_want = metrics.pressure_error(scene, st, body, where=jnp.array([True, True]))
    assert float(raw(metrics.pressure_error)(scene, st, body, where=[True] * 2)) == float(p_want)
    with pytest.raises(
        ValueError, match=r"^where must be one bool per particle, shape \(2,\), got int64 of shape \(2,\)$"
    ):
        raw(jm.errors)(scene, st, body, where=[1, 0])


def test_allow_broken_takes_a_numpy_bool(runs):
    scene, broken, ok = runs
    want = jm.errors(scene, ok.state, ok.body)
    got = raw(jm.errors)(scene, ok.state, ok.body, allow_broken=np.bool_(False))
    assert float(got["F_max_rel"]) == float(want["F_max_rel"])
    with pytest.raises(ValueError, match=r"errors\(\) measures a finished run"):
        raw(jm.errors)(scene, broken.state, broken.body, allow_broken=np.bool_(False))
    rho = raw(jm.density)(broken.state, broken.body, allow_broken=np.bool_(True))
    np.testing.assert_array_equal(rho, jm.density(broken.state, broken.body, allow_broken=True))


def test_radial_bin_takes_a_numpy_integer(runs):
    _, _, ok = runs
    np.testing.assert_array_equal(
        raw(metrics.radial_bin)(ok.body, C0, np.int64(4)), metrics.radial_bin(ok.body, C0, 4)
    )
    out = raw(metrics.angular_spread)(ok.state, ok.body, C0, np.int64(2))
    np.testing.assert_array_equal(out["max"], metrics.angular_spread(ok.state, ok.body, C0, 2)["max"])


def test_corners_of_the_wrong_shape_are_named(runs):
    _, _, ok = runs
    body = ok.body
    message = (
        r"^corners must be the 2\^dim corners of each particle, shape \(n, 2\^dim, dim\) = \(2, 2, 1\) "
        r"\(domain_corners\(state, body\)\), got shape \(2, 2\)$"
    )
    for fn in (metrics.corner_jacobians, metrics.folded_domains, jm.corner_gap):
        # under the suite's runtime type checks a TypeError naming corners may come first
        with pytest.raises((ValueError, TypeError), match="corners"):
            fn(jnp.zeros((2, 2)), body)
    for fn in (metrics.corner_jacobians, jm.corner_gap):
        with pytest.raises(ValueError, match=message):
            raw(fn)(jnp.zeros((2, 2)), body)


@pytest.mark.parametrize("name", ["errors", "diagnostics"])
def test_a_scene_that_seeds_other_particles_than_the_body_is_refused(name):
    """Measured against another scene (here twice the cells), a run's errors would compare it with the
    wrong exact solution: the particle counts tell them apart."""
    sol = jm.simulate(jm.VibratingBar(cells=4), jm.MPQ(), dt=1e-4, steps=2)
    fn = getattr(jm, name)
    with pytest.raises(
        ValueError, match=rf"{name}\(\): the body has 8 particles, and vibrating-bar seeds 16"
    ):
        fn(jm.VibratingBar(cells=8), sol.state, sol.body)
    fn(jm.VibratingBar(cells=4), sol.state, sol.body)
    disk = jm.BlastDisk(cells=8)
    run = jm.simulate(disk, jm.MPQ(), dt=1e-6, steps=1)
    with pytest.raises(ValueError, match=r"the body has \d+ particles, and blast-disk seeds \d+"):
        fn(jm.BlastDisk(cells=10), run.state, run.body)
