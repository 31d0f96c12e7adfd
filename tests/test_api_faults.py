"""The Python API's faults: bad input refused by name before tracing, broken runs never read as
finished (errors, derivatives, histories, batches), and an initial state checked as every step is."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import float32

import jaxmpm as jm
from jaxmpm import status as st_bits
from jaxmpm.studies.talk import state_at

DT = 1e-5


def broken_scene():
    """A gas squeezed so hard that its first step inverts every particle."""
    return jm.GasExpansion(beta=-2e5, cells=4)


@pytest.mark.slow
def test_a_derivative_through_a_run_that_breaks_down_raises_the_breakdown():
    """Under jax.grad the status is concrete and the state is not: the error names the step, the
    particle and the quantities, and says the state is traced."""
    with pytest.raises(
        jm.SimulationError, match=r"broke down at step 1 \(t = 1e-05\): particle 0 \(at step 0\)"
    ):
        jm.gradient(broken_scene(), jm.SPQ(), ["beta"], dt=DT, steps=3)
    with pytest.raises(jm.SimulationError, match="traced by a transformation"):
        jax.grad(
            lambda b: jm.simulate(jm.GasExpansion(beta=b, cells=4), jm.SPQ(), dt=DT, steps=3).state.F.sum()
        )(-2e5)


def test_errors_refuse_the_state_of_a_run_that_broke_down():
    sc = broken_scene()
    sol = jm.simulate(sc, jm.MPQ(), dt=DT, steps=20, artificial_cells=1, throw=False)
    assert int(sol.status) != 0 and int(sol.state.step) == 0
    with pytest.raises(
        ValueError, match=r"errors\(\) measures a finished run.*broke down at step 1.*at step 0"
    ):
        jm.errors(sc, sol.state, sol.body)
    # Asked for, the last good state (the initial one, exact) is measured.
    assert float(jm.errors(sc, sol.state, sol.body, allow_broken=True)["F_rms_rel"]) == 0.0
    # A healthy run is measured as before.
    healthy = jm.GasExpansion(cells=4)
    ok = jm.simulate(healthy, jm.MPQ(), dt=DT, steps=1, artificial_cells=1)  # exact: F = 1 + beta dt
    assert float(jm.errors(healthy, ok.state, ok.body)["F_rms_rel"]) < 1e-12


def test_errors_under_vmap_are_returned_beside_the_status():
    def one(beta):
        sc = jm.GasExpansion(beta=beta, cells=4)
        sol = jm.simulate(sc, jm.SPQ(), dt=DT, steps=3, throw=False)
        return sol.status, jm.errors(sc, sol.state, sol.body)["F_max_rel"]

    status, err = jax.vmap(one)(jnp.array([200.0, -2e5]))
    assert int(status[0]) == 0 and int(status[1]) != 0
    assert np.all(np.isfinite(np.asarray(err)))


def test_euler_errors_refuse_the_state_of_a_run_that_broke_down():
    sc = jm.ShockTube(cells=20)
    sol = jm.simulate(sc, jm.SPQ(), dt=1.0, steps=2, throw=False)  # far beyond the stable step
    assert int(sol.status) & st_bits.CFL
    with pytest.raises(ValueError, match=r"euler_errors\(\) measures a finished run"):
        jm.euler_errors(sc, sol.state, sol.body)


def test_saves_after_a_breakdown_carry_the_time_of_the_state_they_repeat():
    save = jm.SaveAt(every=5, fields=("x",))
    sol = jm.simulate(jm.GasExpansion(cells=4, pad=2), jm.MPQ(), dt=1e-4, steps=40, saveat=save, throw=False)
    kept = int(sol.state.step)
    assert int(sol.status) != 0 and 0 < kept < 40
    ts = np.asarray(sol.ts)
    frames = np.arange(ts.size) * 5
    np.testing.assert_array_equal(ts[frames <= kept], frames[frames <= kept] * 1e-4)
    np.testing.assert_array_equal(ts[frames > kept], float(sol.state.t))
    x = np.asarray(sol.history["x"])
    np.testing.assert_array_equal(
        x[frames > kept], np.broadcast_to(np.asarray(sol.state.x), x[frames > kept].shape)
    )
    # A healthy run's times are its saved steps times dt, bit for bit: each saved state's own t.
    ok = jm.simulate(jm.GasExpansion(cells=4), jm.MPQ(), dt=1e-5, steps=40, saveat=save)
    np.testing.assert_array_equal(np.asarray(ok.ts), (np.arange(9) * 5) * 1e-5)


def test_failure_of_a_batch_names_how_to_read_one_member():
    run = lambda b: jm.simulate(jm.GasExpansion(beta=b, cells=4), jm.SPQ(), dt=DT, steps=3, throw=False)
    sols = jax.vmap(run)(jnp.array([200.0, -2e5]))
    with pytest.raises(ValueError, match=r"batch of shape \(2,\) \(jax.vmap\).*a\[i\]"):
        sols.failure()
    assert jax.tree.map(lambda a: a[0], sols).failure() is None
    assert jax.tree.map(lambda a: a[1], sols).failure()["step"] == 1


def test_numpy_integers_are_taken_as_the_integers_they_are():
    sc = jm.GasExpansion(cells=4)
    a = jm.simulate(
        sc, jm.SPQ(), dt=DT, steps=np.int64(4), artificial_cells=np.int32(1), checkpoint=np.int64(2)
    )
    b = jm.simulate(sc, jm.SPQ(), dt=DT, steps=4, artificial_cells=1, checkpoint=2)
    np.testing.assert_array_equal(np.asarray(a.state.F), np.asarray(b.state.F))
    c = jm.simulate(sc, jm.SPQ(), t_end=1e-4, max_steps=np.int64(40))
    assert int(c.status) == 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(dt=[DT], steps=2), r"dt must be one number, got an array of shape \(1,\)"),
        (dict(dt=np.array([DT, 2 * DT]), steps=2), r"dt must be one number, got an array of shape \(2,\)"),
        (dict(dt="1e-5", steps=2), "dt must be a real number, got '1e-5'"),
        (dict(t_end=jnp.array([1e-4, 2e-4]), max_steps=10), "t_end must be one number"),
        (dict(t_end=1e-4, cfl=[0.5], max_steps=10), "cfl must be one number"),
        (dict(dt=DT, steps=2, cfl_limit=np.ones(2)), "cfl_limit must be one number"),
        (dict(dt=DT, steps=2, saveat=3), r"saveat must be None or a jaxmpm.SaveAt .*got 3"),
    ],
)
def test_run_arguments_of_the_wrong_shape_or_type_are_refused_by_name(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), **kwargs)


def test_a_scene_parameter_with_a_shape_is_refused_outside_vmap_and_runs_under_it():
    # (the suite's runtime type checks refuse such a scene at construction already; tree_at does not)
    sc = eqx.tree_at(lambda s: s.beta, jm.GasExpansion(cells=4), jnp.array([100.0, 200.0]))
    with pytest.raises(ValueError, match=r"GasExpansion.beta must be one number.*jax.vmap.*jaxmpm.ensemble"):
        jm.simulate(sc, jm.SPQ(), dt=DT, steps=2)
    run = lambda b: jm.simulate(jm.GasExpansion(beta=b, cells=4), jm.SPQ(), dt=DT, steps=2).state.F
    assert jax.vmap(run)(sc.beta).shape[0] == 2


def test_dim_must_be_an_integer():
    # (the suite's runtime type checks refuse dim=2.0 at the call already; the scene's own check is
    # what a user without them meets)
    sc = jm.GasExpansion(dim=2, cells=2, pad=3)
    object.__setattr__(sc, "dim", 2.0)
    with pytest.raises(ValueError, match="dim must be 1, 2 or 3, got 2.0"):
        jm.scenes.AbstractScene.__check_init__(sc)
    object.__setattr__(sc, "dim", np.int64(2))
    jm.scenes.AbstractScene.__check_init__(sc)


@pytest.mark.parametrize(
    "dt, ts, match",
    [
        (0.0, [0.0, 1e-4], "dt must be > 0, got 0.0"),
        (float("nan"), [0.0, 1e-4], "dt must be finite"),
        (1e-5, [-1.0, 1e-4], "ts must be >= 0"),
    ],
)
def test_calibration_trajectory_checks_dt_and_times_first(dt, ts, match):
    with pytest.raises(ValueError, match=match):
        jm.calibrate.trajectory(jm.GasSlab(cells=4, pad=40), jm.MPQ(), ts, dt=dt)


@pytest.mark.parametrize(
    "vary, kwargs, match",
    [
        ({"dt": [DT, -DT]}, dict(dt=DT, steps=5), r"vary\['dt'\] must be > 0, got -1e-05 \(member 1\)"),
        ({"dt": [DT, 0.0]}, dict(dt=DT, steps=5), r"vary\['dt'\] must be > 0, got 0 \(member 1\)"),
        (
            {"gamma": [1.4, 0.5]},
            dict(dt=DT, steps=5),
            r"vary\['gamma'\] holds 0.5, which GasExpansion refuses: gamma",
        ),
        (
            {"P0": [2e5, 0.0]},
            dict(dt=DT, steps=5),
            r"vary\['P0'\] holds 0, which GasExpansion refuses: P0 must be > 0",
        ),
        ({"cfl": [0.5, -0.5]}, dict(t_end=1e-4, cfl=0.5, max_steps=20), r"vary\['cfl'\] must be > 0"),
    ],
)
def test_ensemble_values_outside_what_a_parameter_allows_are_refused(vary, kwargs, match):
    with pytest.raises(ValueError, match=match):
        jm.ensemble(jm.GasExpansion(cells=4), jm.SPQ(), vary=vary, **kwargs)


def inverted_scene():
    """A manufactured field that starts with F = -1: the initial state is not a body."""
    return jm.Manufactured(displacement_fn=lambda s, X, t: -2.0 * X + 0.0 * t, ends="traction", cells=4)


@pytest.mark.parametrize("steps", [0, 1, 5])
def test_an_initial_state_that_is_not_a_body_fails_at_step_0(steps):
    sc = inverted_scene()
    sol = jm.simulate(sc, jm.SPQ(), dt=1e-3, steps=steps, throw=False)
    assert int(sol.status) == st_bits.NONFINITE | st_bits.NONPOSITIVE_F  # sigma is NaN at F = -1
    assert int(sol.state.fail_step) == 0 and int(sol.state.fail_particle) == 0 and int(sol.state.step) == 0
    with pytest.raises(
        jm.SimulationError, match=r"the initial state is not valid: particle 0 .*F = -1 at step 0"
    ) as e:
        jm.simulate(sc, jm.SPQ(), dt=1e-3, steps=steps)
    assert "No step was taken" in str(e.value)
    np.testing.assert_array_equal(np.asarray(e.value.solution.state.F[:, 0, 0]), -1.0)


def test_a_healthy_initial_state_is_unchanged_by_its_check():
    sol = jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), dt=DT, steps=0)
    assert int(sol.status) == 0 and int(sol.state.fail_step) == -1 and int(sol.state.fail_particle) == -1


def test_the_talk_reads_the_frames_before_a_breakdown_as_healthy():
    sol = jm.simulate(
        jm.GasExpansion(cells=4, pad=2), jm.MPQ(), dt=1e-4, steps=40, saveat=jm.SaveAt(every=1), throw=False
    )
    failed_at = int(sol.state.fail_step)
    assert failed_at > 2
    before = state_at(sol, failed_at - 1)
    assert int(before.status) == 0 and int(before.fail_step) == -1
    assert float(jm.errors(jm.GasExpansion(cells=4, pad=2), before, sol.body)["F_max_rel"]) >= 0.0
    assert int(state_at(sol, failed_at).status) == int(sol.status)


@pytest.mark.slow
@pytest.mark.parametrize(
    "dt, steps, bit",
    [(1e-3, 3, st_bits.CFL), (1e-5, 3000, st_bits.LEFT_GRID)],
    ids=["time-step", "left-grid"],
)
def test_a_run_that_broke_down_by_its_step_or_the_grid_has_a_finite_derivative(dt, steps, bit):
    def run(b):
        return jm.simulate(jm.GasExpansion(beta=b, cells=2, pad=2), jm.SPQ(), dt=dt, steps=steps, throw=False)

    assert int(run(200.0).status) == bit
    assert np.isfinite(float(jax.grad(lambda b: jnp.sum(run(b).state.x))(200.0)))


@pytest.mark.slow
@pytest.mark.parametrize("name, dim", [("spq", 1), ("mpq", 1), ("cpdi", 2)])
def test_the_derivative_of_a_run_broken_by_a_non_finite_step_is_that_of_its_last_good_state(name, dim):
    """A compression that inverts the particles at step 6: the discarded step is NaN, and the
    derivatives of the kept state (reverse, forward, and reverse under vmap beside a healthy member)
    are those of the healthy run that stops at step 5, not NaN."""

    def run(b, steps):
        sc = jm.GasExpansion(beta=b, cells=4, dim=dim, pad=4)
        return jm.simulate(sc, jm.INTERPOLATORS[name](), dt=DT, steps=steps, cfl_limit=None, throw=False)

    def f(b, steps):
        return jnp.sum(run(b, steps).state.x ** 2)

    b = -2e4  # J = (1 + b t)^dim reaches 0 at t = 5e-5, step 5
    broken = run(b, 12)
    assert int(broken.state.fail_step) == 6 and int(broken.status) & st_bits.NONFINITE
    assert int(run(b, 5).status) == 0
    last_good = float(jax.grad(f)(b, 5))
    assert np.isfinite(last_good) and last_good != 0.0
    assert float(jax.grad(f)(b, 12)) == last_good
    assert float(jax.jacfwd(f)(b, 12)) == float(jax.jacfwd(f)(b, 5))
    both = jax.vmap(jax.grad(f), (0, None))(jnp.array([b, 200.0]), 12)
    # (the batched program may sum in another order: equal to a few ulps)
    np.testing.assert_allclose(np.asarray(both), [last_good, float(jax.grad(f)(200.0, 12))], rtol=1e-14)


def _sum_of_positions(dt):
    """The sum of the final positions of a small SPQ run of 3 steps of ``dt`` (1e-3 is beyond the
    stable limit at step 1; 1e-6 runs healthy)."""
    return jnp.sum(jm.simulate(jm.GasExpansion(cells=2, pad=2), jm.SPQ(), dt=dt, steps=3).state.x)


@pytest.mark.slow
def test_a_jitted_derivative_of_a_run_that_broke_down_raises():
    """``jax.jit(jax.grad(f))`` of a sum of positions uses none of the solution's values, only its
    derivative: the breakdown is raised all the same (with ``throw=True``), in forward mode too, and a
    healthy run's jitted derivative is the unjitted one."""

    f = _sum_of_positions
    for derivative in (jax.grad(f), jax.jacfwd(f)):
        with pytest.raises(Exception, match="jaxmpm: the run broke down: a step failed one of its checks"):
            jax.block_until_ready(jax.jit(derivative)(1e-3))  # dt beyond the stable limit at step 1
    assert float(jax.jit(jax.grad(f))(1e-6)) == float(jax.grad(f)(1e-6)) != 0.0


def test_a_run_that_broke_down_under_grad_in_dt_names_the_step_in_steps_of_dt():
    """Outside a jit, ``jax.grad`` in ``dt`` traces the time step but not the status: the breakdown is
    raised as a ``SimulationError`` naming the step, its time in steps of ``dt``, the particle and
    the quantity."""

    f = _sum_of_positions
    with pytest.raises(
        jm.SimulationError,
        match=r"^jaxmpm: the run broke down at step 1 \(t = 1 dt\): particle 0 \(at step 0\): time step "
        r"beyond the stable limit .*The state is traced by a transformation",
    ):
        jax.grad(f)(1e-3)
    assert float(jax.grad(f)(1e-6)) != 0.0


def test_saveat_fields_is_a_tuple_of_names_and_throw_a_bool():
    # (the suite's runtime type checks refuse fields="x" at the call already; this is the check a
    # user without them meets)
    save = jm.SaveAt(every=1)
    object.__setattr__(save, "fields", "x")
    with pytest.raises(ValueError, match="SaveAt.fields must be a tuple of names .*got 'x'"):
        save.__check_init__()
    with pytest.raises(ValueError, match="throw must be True or False, got 'no'"):
        jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), dt=DT, steps=1, throw="no")


def test_metrics_refuse_a_state_and_a_body_of_different_runs():
    small, large = jm.GasExpansion(cells=4), jm.GasExpansion(cells=6)
    a = jm.simulate(small, jm.SPQ(), dt=DT, steps=1)
    b = jm.simulate(large, jm.SPQ(), dt=DT, steps=1)
    for call in (
        lambda: jm.errors(small, a.state, b.body),
        lambda: jm.diagnostics(small, a.state, b.body),
        lambda: jm.separation(a.state, b.body),
    ):
        with pytest.raises(ValueError, match="the state has 8 particles and the body 12"):
            call()
    with pytest.raises(
        ValueError, match=r"where must be one bool per particle, shape \(8,\), got bool of shape \(3,\)"
    ):
        jm.errors(small, a.state, a.body, where=jnp.ones(3, dtype=bool))
    assert float(jm.errors(small, a.state, a.body, where=jnp.ones(8, dtype=bool))["F_max_rel"]) >= 0.0


def test_a_courant_number_above_the_stability_limit_is_refused_before_the_run():
    """Every full step of a run to t_end at cfl > cfl_limit would fail its own check."""
    sc = jm.GasExpansion(cells=4)
    with pytest.raises(ValueError, match=r"cfl = 1.5 is above cfl_limit = 1: every full step would fail"):
        jm.simulate(sc, jm.SPQ(), t_end=1e-4, cfl=1.5, max_steps=10)
    with pytest.raises(ValueError, match=r"cfl = 0.8 is above cfl_limit = 0.5"):
        jm.simulate(sc, jm.SPQ(), t_end=1e-4, cfl=0.8, cfl_limit=0.5, max_steps=10)
    # at the limit it runs, and without the check any Courant number is the user's to choose
    assert int(jm.simulate(sc, jm.SPQ(), t_end=1e-4, cfl=1.0, max_steps=40).status) == 0
    sol = jm.simulate(sc, jm.SPQ(), t_end=1e-4, cfl=1.5, cfl_limit=None, max_steps=40)
    assert int(sol.status) == 0 and float(sol.state.t) == 1e-4


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(gamma=-1.0), "gamma must be > 1.0, got -1.0"),
        (dict(P0=0.0), "P0 must be > 0"),
        (dict(p_atm=-1.0), "p_atm must be >= 0"),
        (dict(model="gas", mu=-1.0), "mu must be > 0"),
        (dict(model="gas", lam=-1.0), "lam must be >= 0"),
    ],
)
def test_the_constants_of_the_model_not_in_use_are_checked_too(kwargs, match):
    """A bad constant is refused, not ignored because the other model would have used it."""
    with pytest.raises(ValueError, match=match):
        jm.Manufactured(**kwargs)


def test_a_run_breaking_inside_the_users_jit_raises_and_says_how_to_see_the_failure():
    """Under jax.jit the status is not known until the compiled run has finished: the error is a
    runtime error of JAX's, whose message says how to read the step and particle."""
    run = jax.jit(lambda b: jm.simulate(jm.GasExpansion(beta=b, cells=4), jm.SPQ(), dt=DT, steps=3).state.F)
    with pytest.raises(RuntimeError, match="Inside a jit the step, particle and quantity cannot be named"):
        jax.block_until_ready(run(-2e5))
    assert np.isfinite(np.asarray(run(200.0))).all()  # a healthy run under the same jit


def test_a_gradient_with_respect_to_dt_checks_dt_first():
    scene = jm.GasExpansion(cells=2, ppc=1)
    for dt, match in ((-1e-5, "dt must be > 0"), (0.0, "dt must be > 0"), (np.nan, "dt must be finite")):
        with pytest.raises(ValueError, match=match):
            jm.gradient(scene, jm.MPQ(), ["dt"], dt=dt, steps=2)
    with pytest.raises(ValueError, match="dt must be one number"):
        jm.gradient(scene, jm.MPQ(), ["dt"], dt=[1e-5, 2e-5], steps=2)


def test_an_ensemble_checks_each_members_values_together():
    slab = jm.GasSlab(cells=4, pad=40)
    vary = {"P0": [3e5, 1.5e5], "p_atm": [1e5, 2e5]}  # each value alone is allowed; member 1 has P0 < p_atm
    match = r"member 1 of vary \(P0=150000, p_atm=200000\) is refused by GasSlab"
    with pytest.raises(ValueError, match=match):
        jm.ensemble(slab, jm.CPDI(), vary=vary, dt=1e-6, steps=3)


@pytest.mark.slow
def test_the_metrics_refuse_what_they_cannot_measure():
    scene = jm.GasExpansion(cells=2, ppc=1)
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-5, steps=2)
    with pytest.raises(ValueError, match="the state is 1D and the scene gas-expansion is 2D"):
        jm.errors(jm.GasExpansion(cells=2, ppc=1, dim=2), sol.state, sol.body)
    with pytest.raises(ValueError, match="where selects no particle"):
        jm.errors(scene, sol.state, sol.body, where=jnp.zeros(sol.body.n, bool))
    with pytest.raises(ValueError, match="where must be one bool per particle"):
        jm.metrics.pressure_error(scene, sol.state, sol.body, where=jnp.ones(sol.body.n + 1, bool))
    broken = jm.simulate(scene, jm.MPQ(), dt=1e-3, steps=3, throw=False)
    assert broken.failure() is not None
    with pytest.raises(ValueError, match="pressure_error\\(\\) measures a finished run"):
        jm.metrics.pressure_error(scene, broken.state, broken.body)
    last_good = jm.metrics.pressure_error(scene, broken.state, broken.body, allow_broken=True)
    assert int(broken.state.step) == 0 and float(last_good) == 0.0  # the initial state, exact
    ens = jm.ensemble(scene, jm.MPQ(), vary={"beta": [100.0, 200.0]}, dt=1e-5, steps=2)
    with pytest.raises(ValueError, match="errors\\(\\) measures one run, and this state holds a batch"):
        jm.errors(scene, ens.solution.state, ens.solution.body)


@pytest.mark.parametrize(
    "devices, match", [([], "devices"), (0, "devices must be a count from 1"), ("cpu", "devices")]
)
def test_an_ensemble_checks_its_devices_as_simulate_does(devices, match):
    with pytest.raises(ValueError, match=match):
        jm.ensemble(
            jm.GasExpansion(cells=2), jm.SPQ(), vary={"beta": [1.0, 2.0]}, dt=1e-5, steps=2, devices=devices
        )


def test_an_ensemble_takes_a_device_count():
    ens = jm.ensemble(
        jm.GasExpansion(cells=2), jm.SPQ(), vary={"beta": [1.0, 2.0]}, dt=1e-5, steps=2, devices=1
    )
    assert ens.devices == 1 and list(np.asarray(ens.status)) == [0, 0]


def test_write_series_checks_the_model_and_the_solution_before_writing(tmp_path):
    scene = jm.GasExpansion(cells=2, ppc=1)
    saveat = jm.SaveAt(every=1, fields=("x", "v", "F", "sigma"))
    sol = jm.simulate(scene, jm.SPQ(), dt=1e-5, steps=2, saveat=saveat)
    other = jm.Model(jm.GasExpansion(cells=3, ppc=1), jm.SPQ(), jm.FLIP())
    with pytest.raises(ValueError, match="the model is not the solution's run: its body has 3 particles"):
        jm.vtk.write_series(tmp_path / "frames", other, sol)
    assert not (tmp_path / "frames").exists()
    a_file = tmp_path / "a_file"
    a_file.write_text("MINE")
    with pytest.raises(ValueError, match="is a file, not a folder"):
        jm.vtk.write_series(a_file, jm.Model(scene, jm.SPQ(), jm.FLIP()), sol)
    with pytest.raises(ValueError, match=rf"out_dir {a_file}/sub: {a_file} is a file .*, not a folder"):
        jm.vtk.write_series(a_file / "sub", jm.Model(scene, jm.SPQ(), jm.FLIP()), sol)
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    for overwrite in (False, True):
        with pytest.raises(ValueError, match=r"out_dir .*dangling is a link to nothing \(.*nowhere\)"):
            jm.vtk.write_series(
                tmp_path / "dangling", jm.Model(scene, jm.SPQ(), jm.FLIP()), sol, overwrite=overwrite
            )
    assert a_file.read_text() == "MINE" and not (tmp_path / "nowhere").exists()
    paths = jm.vtk.write_series(tmp_path / "frames", jm.Model(scene, jm.SPQ(), jm.FLIP()), sol)
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == sorted(p.name for p in paths)


@pytest.mark.parametrize(
    "kw, name",
    [(dict(dt=1e-50, steps=3), "dt"), (dict(t_end=1e-50, max_steps=3), "t_end")],
)
def test_a_time_that_rounds_to_zero_in_the_runs_float_type_is_refused(kw, name):
    """In float32 dt = 1e-50 became 0: the run took 3 steps of nothing (t = 0, status 0). Refused
    before anything is traced, naming the value given and the float type."""
    with float32():
        scene = jm.GasExpansion(cells=4)
        with pytest.raises(ValueError, match=rf"^{name}=1e-50 rounds to 0 in float32, the run's float type"):
            jm.simulate(scene, jm.MPQ(), **kw)
    sol = jm.simulate(jm.GasExpansion(cells=4), jm.MPQ(), **kw)  # float64 holds it
    assert sol.failure() is None and float(sol.state.t) > 0.0
