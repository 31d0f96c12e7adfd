"""The drivers' faults: ``Ensemble.member`` out of range, a setup or state of another run given to
``step`` or ``initial_state``, ``simulate`` options that the run does not use (``cfl`` and
``max_steps`` with fixed steps, an empty ``SaveAt.fields``), ``vary`` naming what the run does not
use, ``gradient``'s bad ``error``, ``names`` and ``scene``, and messages that name what was given
wrong (a scene class, ``checkpoint=None``, ``vary`` of strings or as a list, ``trajectory``'s own
keywords). Every one is refused by name before anything is traced."""

import inspect

import jax
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import calibrate as cal

DT = 1e-5


def small(cells: int = 2, pad: int = 2) -> jm.GasExpansion:
    return jm.GasExpansion(cells=cells, ppc=1, pad=pad)


# Ensemble.member ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def three():
    return jm.ensemble(small(), jm.SPQ(), {"beta": [100.0, 200.0, 300.0]}, dt=DT, steps=2)


@pytest.mark.parametrize("i", [3, 7, -4, -7])
def test_member_refuses_an_index_out_of_range(three, i):
    with pytest.raises(ValueError, match=rf"i must be a member's index.*0 to 2.*-3 to -1.*got {i}$"):
        three.member(i)


@pytest.mark.parametrize("i", [True, 1.0, "1", None])
def test_member_refuses_an_index_that_is_not_an_integer(three, i):
    with pytest.raises(ValueError, match="i must be a member's index, an integer from 0 to 2"):
        inspect.unwrap(type(three).member)(three, i)


def test_member_counts_a_negative_index_from_the_end(three):
    for i, j in ((-1, 2), (-3, 0), (np.int64(1), 1)):
        a, b = three.member(i), inspect.unwrap(type(three).member)(three, j)
        assert np.array_equal(a.state.v, b.state.v)
    assert not np.array_equal(three.member(0).state.v, three.member(2).state.v)


# step and initial_state with another run's setup or state ------------------------------------------


@pytest.fixture(scope="module")
def runs():
    out = {}
    for name, model in {
        "m": jm.Model(small(), jm.SPQ(), jm.FLIP()),
        "more": jm.Model(small(cells=3), jm.SPQ(), jm.FLIP()),
        "mpq_apic": jm.Model(small(), jm.MPQ(), jm.APIC()),
        "wider": jm.Model(small(pad=3), jm.SPQ(), jm.FLIP()),
    }.items():
        s = jm.setup(model)
        out[name] = (model, s, jm.initial_state(model, s))
    return out


def test_step_refuses_a_state_of_another_model(runs):
    m2, s2, _ = runs["more"]
    state = runs["m"][2]
    with pytest.raises(
        ValueError,
        match=r"state does not belong to model \(3 particles in 1D, 8 grid nodes\): state.x has shape "
        r"\(2, 1\), should be \(3, 1\); start from jm.initial_state\(model, setup\)",
    ):
        jm.step(m2, s2, state, DT)


def test_step_takes_a_dt_array_of_another_float_dtype_as_simulate_does(runs):
    # a float32 dt array in a float64 run failed deep in lax.cond (branch output types differ)
    m, s, state = runs["m"]
    ref = jm.step(m, s, state, float(np.float32(DT)))  # the same value in float64
    for dt in (jax.numpy.asarray(DT, dtype=np.float32), np.float32(DT)):
        got = jm.step(m, s, state, dt)
        assert got.t.dtype == np.float64 and got.t == ref.t and np.array_equal(got.x, ref.x)


def test_step_refuses_a_setup_of_another_model(runs):
    m, _, state = runs["m"]
    _, s2, state2 = runs["more"]
    match = (
        r"setup does not belong to model \(2 particles in 1D, 7 grid nodes\): setup.body.X has shape "
        r"\(3, 1\), should be \(2, 1\); make it with jm.setup\(model\)"
    )
    with pytest.raises(ValueError, match=match):
        jm.step(m, s2, state, DT)
    with pytest.raises(ValueError, match=match):
        jm.step(m, s2, state2, DT)


def test_step_refuses_a_setup_of_another_grid(runs):
    m, _, state = runs["m"]
    wider = runs["wider"][1]
    with pytest.raises(ValueError, match=r"setup does not belong.*setup.grid has 9 nodes.*should have 7"):
        jm.step(m, wider, state, DT)


def test_step_names_an_optional_field_the_state_lacks_or_should_not_have(runs):
    m, s, state = runs["m"]
    m3, s3, state3 = runs["mpq_apic"]
    with pytest.raises(
        ValueError, match=r"state does not belong.*state.C is None, should have shape \(2, 1, 1\)"
    ):
        jm.step(m3, s3, state, DT)
    with pytest.raises(
        ValueError, match=r"state does not belong.*state.C has shape \(2, 1, 1\), should be None"
    ):
        jm.step(m, s, state3, DT)


def test_step_refuses_what_is_not_a_setup_or_a_state(runs):
    m, s, state = runs["m"]
    step = inspect.unwrap(jm.step)
    with pytest.raises(ValueError, match=r"setup must be the Setup of model, jm.setup\(model\), got 'x'"):
        step(m, "x", state, DT)
    with pytest.raises(ValueError, match=r"state must be a State of model.*got None"):
        step(m, s, None, DT)


def test_initial_state_refuses_a_setup_of_another_model(runs):
    m = runs["m"][0]
    with pytest.raises(
        ValueError, match=r"setup does not belong to model \(2 particles.*setup.body.X has shape"
    ):
        jm.initial_state(m, runs["more"][1])


def test_step_of_its_own_setup_and_state_runs_as_before(runs):
    """The check passes a model's own objects, also traced (jit, vmap), and changes nothing."""
    m, s, state = runs["m"]
    a = jm.step(m, s, state, DT)
    b = jax.jit(lambda st: jm.step(m, s, st, DT))(state)
    c = jax.vmap(lambda st: jm.step(m, s, st, DT))(jax.tree.map(lambda x: x[None], state))
    assert int(a.step) == 1 and int(a.status) == 0
    assert np.array_equal(a.x, b.x) and np.array_equal(a.x, c.x[0])


# simulate: options the run does not use ------------------------------------------------------------


def test_simulate_refuses_max_steps_with_fixed_steps():
    with pytest.raises(
        ValueError, match=r"max_steps \(got 2\) is the bound of a run to an end time.*leave max_steps out"
    ):
        jm.simulate(small(), jm.SPQ(), dt=DT, steps=4, max_steps=2)


@pytest.mark.parametrize("cfl", [0.01, 0.5])
def test_simulate_refuses_cfl_with_fixed_steps(cfl):
    with pytest.raises(
        ValueError, match=r"cfl \(got .*\) sets the step of a run to an end time.*leave cfl out"
    ):
        jm.simulate(small(), jm.SPQ(), dt=DT, steps=4, cfl=cfl)


def test_simulate_to_an_end_time_takes_cfl_by_default_or_given():
    sc = small()
    a = jm.simulate(sc, jm.SPQ(), t_end=3e-5, max_steps=50)
    b = jm.simulate(sc, jm.SPQ(), t_end=3e-5, cfl=0.5, max_steps=50)
    assert float(a.state.t) == pytest.approx(3e-5) and np.array_equal(a.state.x, b.state.x)


def test_saveat_of_no_field_the_run_has_is_refused():
    """SaveAt(fields=("C",)) on a FLIP run would keep an empty history: refused, naming the fields."""
    with pytest.raises(ValueError, match=r"SaveAt\(fields=\('C',\)\) names no field this run has"):
        jm.simulate(
            jm.GasExpansion(cells=2), jm.SPQ(), dt=1e-5, steps=2, saveat=jm.SaveAt(every=1, fields=("C",))
        )
    sol = jm.simulate(
        jm.GasExpansion(cells=2), jm.SPQ(), dt=1e-5, steps=2, saveat=jm.SaveAt(every=1, fields=("x", "C"))
    )
    assert list(sol.history) == ["x"] and sol.history["x"].shape == (3, 4, 1)


def test_saveat_refuses_an_empty_tuple_of_fields():
    with pytest.raises(ValueError, match=r"SaveAt.fields must name at least one field among \('x', 'v'"):
        jm.SaveAt(every=1, fields=())


# ensemble: vary naming what the run does not use, and vary of the wrong kind -----------------------


@pytest.mark.parametrize("name, given", [("cfl", {"cfl": 0.5}), ("t_end", {})])
def test_ensemble_refuses_varying_an_end_time_option_of_a_fixed_step_run(name, given):
    with pytest.raises(
        ValueError, match=rf"vary names '{name}', which belongs to a run to an end time.*vary 'dt'"
    ):
        jm.ensemble(small(), jm.SPQ(), {name: [0.3, 0.4]}, dt=DT, steps=2, **given)


def test_ensemble_refuses_varying_dt_of_a_run_to_an_end_time():
    with pytest.raises(
        ValueError, match=r"vary names 'dt', which belongs to a run of fixed steps.*vary 't_end' or 'cfl'"
    ):
        jm.ensemble(small(), jm.SPQ(), {"dt": [1e-5, 2e-5]}, t_end=1e-4, max_steps=10)


def test_ensemble_refuses_a_cfl_above_the_limit_as_simulate_does():
    """simulate refuses cfl > cfl_limit before the run; an ensemble refuses a member's the same way,
    naming the member, rather than run it into a breakdown at its first step."""
    with pytest.raises(ValueError, match=r"vary\['cfl'\] is above cfl_limit = 1: 2 \(member 1\)"):
        jm.ensemble(small(), jm.SPQ(), {"cfl": [0.5, 2.0]}, t_end=1e-4, cfl=0.5, max_steps=10)
    with pytest.raises(ValueError, match=r"vary\['cfl'\] is above cfl_limit = 0.4: 0.5 \(member 0\)"):
        jm.ensemble(small(), jm.SPQ(), {"cfl": [0.5, 0.3]}, t_end=1e-4, cfl=0.3, max_steps=10, cfl_limit=0.4)
    ens = jm.ensemble(
        small(), jm.SPQ(), {"cfl": [0.5, 2.0]}, t_end=1e-4, cfl=0.5, max_steps=10, cfl_limit=None
    )
    assert ens.status.shape == (2,)


def test_ensemble_names_vary_of_values_that_are_not_numbers():
    with pytest.raises(
        ValueError, match=r"vary\['beta'\] must be a 1D sequence of real numbers, one per member, got \['a'\]"
    ):
        jm.ensemble(small(), jm.SPQ(), {"beta": ["a"]}, dt=DT, steps=1)


def test_ensemble_says_vary_must_be_a_dict():
    with pytest.raises(
        ValueError, match=r"vary must be a dict of parameter name to values, one per member.*got list"
    ):
        inspect.unwrap(jm.ensemble)(small(), jm.SPQ(), [("beta", [1.0])], dt=DT, steps=1)
    with pytest.raises((ValueError, TypeError), match="vary"):
        jm.ensemble(small(), jm.SPQ(), [("beta", [1.0])], dt=DT, steps=1)


# gradient, objective, continuous_parameters ----------------------------------------------------------


# objective's own checks (gradient calls it; the suite's jaxtyping checks may refuse a wrongly typed
# argument of gradient first, by the parameter's name)
objective = inspect.unwrap(jm.sensitivity.objective)


@pytest.mark.parametrize("error", [3, None])
def test_gradient_refuses_an_error_that_is_neither_a_name_nor_a_function(error):
    match = r"error must be one of the finite errors of gas-expansion \(.*F_rms_rel.*\) or a function"
    with pytest.raises(ValueError, match=match):
        objective(small(), jm.SPQ(), ["beta"], dt=DT, steps=2, error=error)
    with pytest.raises((ValueError, TypeError), match="error"):
        jm.gradient(small(), jm.SPQ(), ["beta"], dt=DT, steps=2, error=error)


def test_gradient_refuses_names_that_are_not_a_sequence():
    match = r"names must be a sequence of parameter names such as \['beta'\], got None"
    with pytest.raises(ValueError, match=match):
        objective(small(), jm.SPQ(), None, dt=DT, steps=2)
    with pytest.raises((ValueError, TypeError), match="names"):
        jm.gradient(small(), jm.SPQ(), None, dt=DT, steps=2)


def test_gradient_refuses_names_given_as_a_generator():
    # a generator is used up by the checks: the gradient then named no parameter and returned {}
    match = r"names must be a sequence of parameter names such as \['beta'\], got a generator"
    with pytest.raises(ValueError, match=match):
        objective(small(), jm.SPQ(), (n for n in ["beta"]), dt=DT, steps=2)
    with pytest.raises((ValueError, TypeError), match="names"):
        jm.gradient(small(), jm.SPQ(), (n for n in ["beta"]), dt=DT, steps=2)


def test_gradient_tells_a_registry_name_how_to_make_the_scene():
    match = (
        r"scene must be a jaxmpm scene object, got the name 'gas-expansion': "
        r"jm.SCENES\['gas-expansion'\]\(\) makes that scene"
    )
    with pytest.raises(ValueError, match=match):
        objective("gas-expansion", jm.SPQ(), ["beta"], dt=DT, steps=2)
    with pytest.raises((ValueError, TypeError), match="scene"):
        jm.gradient("gas-expansion", jm.SPQ(), ["beta"], dt=DT, steps=2)


@pytest.mark.parametrize("scene", [None, "gas-expansion", 3])
def test_continuous_parameters_refuses_what_is_not_a_scene(scene):
    with pytest.raises((ValueError, TypeError), match="scene must be a jaxmpm scene or scene class"):
        inspect.unwrap(jm.continuous_parameters)(scene)
    if scene == "gas-expansion":
        with pytest.raises(ValueError, match=r"jm.SCENES\['gas-expansion'\]\(\) makes that scene"):
            inspect.unwrap(jm.continuous_parameters)(scene)


def test_continuous_parameters_takes_a_scene_or_its_class():
    assert jm.continuous_parameters(jm.GasExpansion) == jm.continuous_parameters(small())


@pytest.mark.parametrize("name", list(jm.SCENES))
def test_continuous_parameters_are_the_names_a_gradient_takes(name):
    """Every name ``continuous_parameters`` gives is one ``gradient`` takes: the static float
    parameters (the shock tube's ``x0``, the Gurney scenes' ``split``) are left out."""
    scene = jm.SCENES[name]()
    names = jm.continuous_parameters(scene)
    jm.sensitivity.check_names(scene, names)  # raises for a name gradient refuses
    static = jm.sensitivity.static_parameters(scene)
    assert not set(static) & set(names)
    floats = [k for k, v in type(scene).parameters().items() if isinstance(v, float)]
    assert sorted(names) == sorted([k for k in floats if k not in static] + ["dt"])


def test_static_parameters_are_left_out_of_the_continuous_ones():
    assert "x0" not in jm.continuous_parameters(jm.ShockTube)
    assert jm.sensitivity.static_parameters(jm.ShockTube) == ("x0",)
    assert "split" not in jm.continuous_parameters(jm.GurneySlab())
    with pytest.raises(ValueError, match="x0 is static in shock-tube"):
        jm.sensitivity.check_names(jm.ShockTube(), ["x0"])


# messages that name what was given wrong -------------------------------------------------------------


def test_simulate_tells_a_scene_class_to_call_it():
    match = r"scene must be a jaxmpm scene object, got the class GasExpansion: call it, jm.GasExpansion\(\)"
    with pytest.raises(ValueError, match=match):
        jm.simulate(jm.GasExpansion, jm.SPQ(), dt=DT, steps=1)


def test_simulate_tells_an_interpolator_or_transfer_class_to_call_it():
    with pytest.raises(ValueError, match=r"interpolator must be.*it is the class, call it: jm.SPQ\(\)"):
        jm.simulate(small(), jm.SPQ, dt=DT, steps=1)
    with pytest.raises(ValueError, match=r"transfer must be.*it is the class, call it: jm.APIC\(\)"):
        jm.simulate(small(), jm.SPQ(), dt=DT, steps=1, transfer=jm.APIC)


def test_simulate_tells_a_transfer_name_the_object_to_pass():
    with pytest.raises(ValueError, match=r"transfer must be.*got 'flip': pass jm.FLIP\(\)$"):
        jm.simulate(small(), jm.SPQ(), dt=DT, steps=1, transfer="flip")
    with pytest.raises(ValueError, match=r"got 'nope'$"):  # not a registry name: no hint
        jm.simulate(small(), jm.SPQ(), dt=DT, steps=1, transfer="nope")


@pytest.mark.parametrize("checkpoint", [None, 0, 1.5, "yes", np.True_])
def test_simulate_says_what_checkpoint_allows(checkpoint):
    with pytest.raises(
        ValueError, match=r"checkpoint must be True \(.*\), False \(no checkpointing\) or an integer >= 1"
    ):
        jm.simulate(small(), jm.SPQ(), dt=DT, steps=1, checkpoint=checkpoint)


@pytest.mark.parametrize(
    "keyword, value, why",
    [
        ("throw", False, "trajectory raises SimulationError"),
        ("steps", 3, "trajectory sets it from ts and dt"),
        ("saveat", jm.SaveAt(every=1), "trajectory saves every step"),
        ("t_end", 1e-4, "trajectory runs fixed steps of dt"),
    ],
)
def test_trajectory_names_the_keywords_it_sets_itself(keyword, value, why):
    with pytest.raises(ValueError, match=rf"trajectory\(\) does not take {keyword}: {why}"):
        cal.trajectory(
            jm.GasSlab(cells=4, ppc=1, pad=16), jm.CPDI(), [0.0, 1e-4], dt=1e-5, **{keyword: value}
        )


def test_trajectory_refuses_a_keyword_simulate_does_not_take():
    with pytest.raises(
        TypeError, match=r"trajectory\(\) got an unexpected keyword argument 'nope'; it takes"
    ):
        cal.trajectory(jm.GasSlab(cells=4, ppc=1, pad=16), jm.CPDI(), [0.0, 1e-4], dt=1e-5, nope=1)
