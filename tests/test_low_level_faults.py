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
