"""The low-level API under faults: ``Model`` and ``step`` refuse what ``simulate`` refuses, with the
same messages; options are checked by name; functions that pass keywords on name themselves."""

import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import long_run

DT = 1e-5


def raw(fn):
    """``fn`` without the suite's runtime type checks of its annotations (what a user runs)."""
    return inspect.unwrap(fn)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(artificial_cells=-1), "artificial_cells must be an integer >= 0, got -1"),
        (dict(artificial_cells=1.5), "artificial_cells must be an integer >= 0, got 1.5"),
        (dict(cfl_limit=-1.0), r"cfl_limit must be > 0, got -1.0"),
        (dict(cfl_limit=float("nan")), "cfl_limit must be finite, got nan"),
    ],
)
def test_model_refuses_what_simulate_refuses(kwargs, match):
    scene = jm.GasExpansion(cells=2)
    with pytest.raises(ValueError, match=match):
        jm.Model(scene, jm.SPQ(), jm.FLIP(), **kwargs)
    with pytest.raises(ValueError, match=match):
        jm.simulate(scene, jm.SPQ(), dt=DT, steps=1, **kwargs)


@pytest.mark.parametrize(
    "parts, name",
    [
        (("gas-expansion", jm.MPQ(), jm.FLIP(), None), "scene"),
        ((jm.GasExpansion(cells=2), "mpq", jm.FLIP(), None), "interpolator"),
        ((jm.GasExpansion(cells=2), jm.MPQ(), "flip", None), "transfer"),
        ((jm.GasExpansion(cells=2), jm.MPQ(), jm.FLIP(), "yes"), "viscosity"),
    ],
)
def test_model_refuses_parts_that_are_not_parts(parts, name):
    """Refused by ``Model``'s own check (a ``ValueError``, as a user runs it) or, under the suite's
    jaxtyping runtime checks of the annotation, first by those (a ``TypeError``); either names the
    part. ``simulate`` gives the same ``ValueError``."""
    scene, interpolator, transfer, viscosity = parts
    with pytest.raises((ValueError, TypeError), match=name):
        jm.Model(scene, interpolator, transfer, viscosity=viscosity)
    with pytest.raises(ValueError, match=f"{name} must be"):
        jm.simulate(scene, interpolator, transfer=transfer, viscosity=viscosity, dt=DT, steps=1)


def test_model_takes_numpy_numbers_as_the_python_numbers_they_are():
    scene = jm.GasExpansion(cells=2)
    a = jm.Model(scene, jm.SPQ(), jm.FLIP(), artificial_cells=np.int64(1), cfl_limit=np.float64(0.5))
    b = jm.Model(scene, jm.SPQ(), jm.FLIP(), artificial_cells=1, cfl_limit=0.5)
    assert type(a.artificial_cells) is int and type(a.cfl_limit) is float
    assert a.artificial_cells == 1 and a.cfl_limit == 0.5
    # the same static structure: one compiled program for both
    assert jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)


@pytest.mark.parametrize(
    "dt, match",
    [
        (-1e-5, r"dt must be > 0, got -1e-05"),
        (0.0, r"dt must be > 0, got 0.0"),
        (float("inf"), "dt must be finite, got inf"),
        (jnp.array([DT, DT]), "dt must be one number, got an array of shape \\(2,\\): to step with several"),
    ],
)
def test_step_refuses_a_dt_that_simulate_refuses(dt, match):
    model = jm.Model(jm.GasExpansion(cells=2), jm.SPQ(), jm.FLIP())
    setup = jm.setup(model)
    state = jm.initial_state(model, setup)
    with pytest.raises(ValueError, match=match):
        raw(jm.step)(model, setup, state, dt)


def test_step_takes_a_python_number_as_simulate_does():
    scene = jm.GasExpansion(cells=2)
    model = jm.Model(scene, jm.SPQ(), jm.FLIP())
    setup = jm.setup(model)
    state = jm.initial_state(model, setup)
    by_number = jm.step(model, setup, state, DT)
    by_array = jm.step(model, setup, state, jnp.asarray(DT))
    np.testing.assert_array_equal(by_number.F, by_array.F)
    np.testing.assert_array_equal(by_number.x, by_array.x)
    # and equals simulate's first step: F = 1 + beta dt inside, 1 + (5/8) beta dt in the boundary cells
    sol = jm.simulate(scene, jm.SPQ(), dt=DT, steps=1)
    np.testing.assert_array_equal(by_number.F, sol.state.F)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(contiguous="yes"), "contiguous must be True or False, got 'yes'"),
        (dict(contiguous=1), "contiguous must be True or False, got 1"),
        (dict(max_span=0), "max_span must be an integer >= 1, got 0"),
        (dict(max_span=2.0), "max_span must be an integer >= 1, got 2.0"),
        (dict(max_span=2), "max_span=2 would do nothing for uGIMP"),  # its domains never outgrow a cell
    ],
)
def test_gimp_options_are_checked_by_name(kwargs, match):
    with pytest.raises(ValueError, match=match):
        raw(jm.GIMP)(**kwargs)


def test_gimp_takes_numpy_options_as_the_python_values_they_are():
    g = jm.GIMP(contiguous=np.bool_(True), max_span=np.int64(2))
    assert g.contiguous is True and type(g.max_span) is int and g.max_span == 2
    assert g.name == jm.GIMP(contiguous=True, max_span=2).name


@pytest.mark.parametrize("name", sorted(long_run.SIMULATE_ONLY))
def test_a_long_run_names_the_arguments_of_simulate_it_does_not_take(name):
    value = dict(t_end=1e-4, cfl=0.5, max_steps=10, checkpoint=True, volume_average="domain")[name]
    with pytest.raises(ValueError, match=rf"long_run.run\(\) does not take {name}: "):
        long_run.run(jm.GasExpansion(cells=2), jm.SPQ(), dt=DT, steps=2, **{name: value})


def test_a_long_run_refuses_unknown_keywords_and_missing_steps():
    scene = jm.GasExpansion(cells=2)
    with pytest.raises(
        TypeError, match=r"long_run.run\(\) got an unexpected keyword argument 'stpes'; it takes dt, steps"
    ):
        long_run.run(scene, jm.SPQ(), dt=DT, stpes=2)
    with pytest.raises(ValueError, match="a long run takes fixed steps: give dt .* and steps"):
        long_run.run(scene, jm.SPQ(), dt=DT)
    with pytest.raises(ValueError, match="progress must be None, True or False, got 'yes'"):
        raw(long_run.run_timed)(scene, jm.SPQ(), dt=DT, steps=2, progress="yes")
    with pytest.raises(ValueError, match="throw must be True or False, got 1"):
        raw(long_run.run_timed)(scene, jm.SPQ(), dt=DT, steps=2, throw=1)


def test_simulate_timed_names_itself_for_an_unknown_keyword():
    with pytest.raises(
        TypeError, match=r"simulate_timed\(\) got an unexpected keyword argument 'stpes'; it takes "
    ):
        jm.simulate_timed(jm.GasExpansion(cells=2), jm.SPQ(), dt=DT, stpes=2)


def _parts():
    model = jm.Model(jm.GasExpansion(cells=4), jm.MPQ(), jm.FLIP())
    setup = jm.setup(model)
    return model, setup, jm.initial_state(model, setup)


def test_the_pieces_of_a_run_refuse_what_is_not_a_model():
    model, setup, state = _parts()
    scene = model.scene
    wrap = r"model must be a jm.Model\(scene, interpolator, transfer\), got the scene GasExpansion: wrap it"
    for call in (
        lambda: raw(jm.setup)(scene),
        lambda: raw(jm.initial_state)(scene, setup),
        lambda: raw(jm.step)(scene, setup, state, DT),
        lambda: raw(jm.vtk.write_series)("out", scene, None),
    ):
        with pytest.raises(ValueError, match=wrap):
            call()
    with pytest.raises(ValueError, match=r"got MPQ$"):
        raw(jm.setup)(jm.MPQ())


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(t_new=float("nan")), "t_new must be finite, got nan"),
        (dict(t_new=-1.0), "t_new must be >= 0, got -1.0"),
        (dict(t_new=[1.0, 2.0]), r"t_new must be one number, got an array of shape \(2,\)"),
        (dict(limit="a"), r"limit must be one integer \(a step count\) or None, got 'a'"),
        (dict(limit=2.5), r"limit must be one integer \(a step count\) or None, got 2.5"),
        (dict(active="yes"), "active must be one bool or None, got 'yes'"),
    ],
)
def test_step_refuses_bad_options_by_name(kwargs, match):
    """A NaN or negative ``t_new`` made a state the status called healthy; the others failed inside
    JAX."""
    model, setup, state = _parts()
    with pytest.raises(ValueError, match=match):
        raw(jm.step)(model, setup, state, DT, **kwargs)


def test_step_takes_its_options():
    model, setup, state = _parts()
    new = jm.step(
        model, setup, state, DT, limit=jnp.asarray(3), active=jnp.asarray(True), t_new=jnp.asarray(DT)
    )
    assert int(new.status) == 0 and float(new.t) == DT and int(new.step) == 1
    held = jm.step(model, setup, state, DT, active=jnp.asarray(False))
    assert int(held.step) == 0


def test_write_series_names_what_it_was_given(tmp_path):
    model, _, _ = _parts()
    sol = jm.simulate(
        model.scene,
        jm.MPQ(),
        dt=DT,
        steps=2,
        saveat=jm.SaveAt(every=1, fields=("x", "v", "F", "sigma", "corners")),
    )
    with pytest.raises(ValueError, match=r"solution must be the Solution of a run .*got State$"):
        raw(jm.vtk.write_series)(tmp_path, model, sol.state)
    for out in ("", 3, None):
        with pytest.raises(ValueError, match=r"out_dir must be a folder's name \(a str or os.PathLike\)"):
            raw(jm.vtk.write_series)(out, model, sol)
    assert list(tmp_path.iterdir()) == []  # nothing written before the refusals


def test_a_scene_of_another_float_type_is_refused_by_name():
    """A scene made while float64 was off holds float32 arrays; run after switching float64 on it
    failed inside the step ("cond branches must have equal output types"). It is refused, naming the
    parameter and what to do (shown here with one float32 field put in by hand: the suite runs in
    float64 and does not switch it off)."""
    import equinox as eqx

    scene = jm.GasExpansion(cells=4)
    old = eqx.tree_at(lambda s: s.beta, scene, jnp.asarray(200.0, dtype=jnp.float32))
    match = (
        r"the scene's beta is float32 and this run is float64 \(jax_enable_x64 is on\): make the scene after"
    )
    with pytest.raises(ValueError, match=match):
        jm.simulate(old, jm.MPQ(), dt=DT, steps=1)
    with pytest.raises(ValueError, match=match):
        jm.Model(old, jm.MPQ(), jm.FLIP())
    assert int(jm.simulate(scene, jm.MPQ(), dt=DT, steps=1).state.step) == 1


def test_a_viscosity_of_another_float_type_is_refused_by_name():
    import equinox as eqx

    visc = jm.ArtificialViscosity()
    old = eqx.tree_at(lambda v: v.c_quad, visc, jnp.asarray(1.5, dtype=jnp.float32))
    match = r"the viscosity's c_quad is float32 and this run is float64 \(jax_enable_x64 is on\)"
    with pytest.raises(ValueError, match=match):
        jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), dt=DT, steps=1, viscosity=old)
    with pytest.raises(ValueError, match=match):
        jm.Model(jm.GasExpansion(cells=4), jm.SPQ(), jm.FLIP(), viscosity=old)


def test_a_bool_is_not_a_time_step_and_a_string_not_devices():
    """``dt=True`` ran as 1.0; ``devices="cpu"`` was reported as the letters ('c', 'p', 'u')."""
    scene = jm.GasExpansion(cells=4)
    with pytest.raises(ValueError, match=r"^dt must be one number > 0 \(the time step\), got True$"):
        raw(jm.simulate)(scene, jm.MPQ(), dt=True, steps=1)
    with pytest.raises(ValueError, match=r"devices must be .* got the string 'cpu'$"):
        raw(jm.simulate)(scene, jm.MPQ(), dt=DT, steps=1, devices="cpu")


def test_an_ensemble_refuses_throw_and_bools():
    """An ensemble reads each member's breakdown from its status: ``throw=True`` was dropped silently."""
    scene = jm.GasExpansion(cells=4)
    with pytest.raises(ValueError, match=r"^throw must be False or left out in an ensemble .* got True$"):
        raw(jm.ensemble)(scene, jm.MPQ(), {"beta": [100.0, 200.0]}, dt=DT, steps=1, throw=True)
    with pytest.raises(ValueError, match=r"^vary\['beta'\] must be real numbers, one per member, got bools"):
        raw(jm.ensemble)(scene, jm.MPQ(), {"beta": [True, False]}, dt=DT, steps=1)


def test_a_long_run_under_a_transformation_says_what_to_use():
    """A long run is driven from Python; under jax.grad it raised a ConcretizationTypeError."""

    def final_F(beta):
        scene = jm.GasExpansion(cells=4, beta=beta)
        return long_run.run(scene, jm.MPQ(), dt=DT, steps=2, progress=False).state.F.sum()

    match = r"a long run is driven from Python .* jax.vmap; inside them use jm.simulate"
    with pytest.raises(ValueError, match=match):
        jax.grad(final_F)(200.0)
    assert np.isfinite(float(final_F(200.0)))


def test_a_fit_and_an_ensemble_under_a_transformation_say_what_to_use():
    """Each drives its own compiled calls from Python; under jax.grad or jax.vmap they raised JAX's
    ConcretizationTypeError."""
    ts = np.linspace(0.0, 1e-3, 3)

    def loss(gamma):
        slab = jm.GasSlab(cells=8, h=1 / 8, pad=24, gamma=gamma)
        return jm.calibrate.calibrate(slab, jm.CPDI(), ts, np.ones(3), dt=DT).loss

    with pytest.raises(
        ValueError, match=r"^a fit is driven from Python .* with jm.calibrate.trajectory or jm.simulate"
    ):
        jax.grad(loss)(1.4)

    def status(beta):
        return jm.ensemble(
            jm.GasExpansion(cells=4, beta=beta), jm.MPQ(), {"P0": [3e5, 4e5]}, dt=DT, steps=1
        ).status

    with pytest.raises(ValueError, match=r"^jm.ensemble batches its members itself, in one compiled call"):
        jax.vmap(status)(jnp.array([100.0, 200.0]))

    # the values of vary= or dt traced (the scene made outside) gave JAX's TracerArrayConversionError
    scene = jm.GasExpansion(cells=4)

    def member_values(p0):
        return jm.ensemble(scene, jm.MPQ(), {"P0": p0}, dt=DT, steps=1).status

    def member_dt(dt):
        return jm.ensemble(scene, jm.MPQ(), {"P0": [3e5, 4e5]}, dt=dt, steps=1).status

    for call in (lambda: jax.jit(member_values)(jnp.array([3e5, 4e5])), lambda: jax.jit(member_dt)(DT)):
        with pytest.raises(
            ValueError, match=r"^jm.ensemble batches its members itself, in one compiled call"
        ):
            call()

    def derivative(dt):  # gave a ConcretizationTypeError after compiling the run
        return jm.gradient(scene, jm.MPQ(), ["P0"], dt=dt, steps=2)["P0"]

    with pytest.raises(ValueError, match=r"^jm.gradient returns concrete numbers: call it outside jax.jit"):
        jax.jit(derivative)(DT)


def test_describe_reads_one_status_and_refuses_what_is_none():
    assert jm.status.describe(0) == []
    assert jm.status.describe(np.int32(jm.status.LEFT_GRID)) == [jm.status.QUANTITY[jm.status.LEFT_GRID]]
    both = jm.status.NONFINITE | jm.status.NEGATIVE_ENERGY
    assert len(jm.status.describe(jnp.asarray(both, dtype=jnp.int32))) == 2
    for bad in (None, "8", 1.5, True):
        with pytest.raises(ValueError, match="status must be one run's status, an integer >= 0"):
            raw(jm.status.describe)(bad)  # without the suite's type checks: what a user runs
    with pytest.raises(ValueError, match=r"for an ensemble, describe each member's"):
        raw(jm.status.describe)(np.array([0, 4]))
    for bad in (-1, 1 << 20):
        with pytest.raises(ValueError, match=rf"status must be an integer >= 0 of the bits .*, got {bad}$"):
            jm.status.describe(bad)
