"""Gradients: against fourth-order central differences in float64, across modes and transformations.

Generic points: parameter values at which no query point sits on a node during the run (see
``jaxmpm.sensitivity`` for what the derivative means at a kink, and the pinned kink-dense case below).
"""

import functools
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import INTERPOLATORS, TRANSFERS, raw

import jaxmpm as jm
from jaxmpm.cli import main

pytestmark = pytest.mark.slow

GAS = jm.GasExpansion(beta=173.0, h=0.11, P0=1.9e5, gamma=1.37, p_atm=0.93e5, rho0=1.07, cells=4)
BAR = jm.VibratingBar(E=97.0, v0=0.13, h=0.061, rho0=1.03, cells=6)
RTOL = 1e-6
FD_REL = 1e-4  # relative step of the difference quotient
EPS = float(jnp.finfo(jnp.float64).eps)
# vmap, jit and checkpointing change the order of floating-point reductions, and reverse mode through
# tens of steps of an error that cancels F - F_exact ~ 1e-4 amplifies that: agreement is to ~1e3 ulps.
REORDER_RTOL = 1e-10


def fd5(f, values, name, rel=FD_REL):
    """Fourth-order central difference of ``f`` in ``values[name]`` (truncation O(step^4))."""
    d = rel * abs(float(values[name]))
    ev = lambda k: float(f({**values, name: values[name] + k * d}))
    return (8 * (ev(1) - ev(-1)) - (ev(2) - ev(-2))) / (12 * d)


@functools.cache
def gas_gradient(name, transfer):
    """The reverse-mode gradient of GAS's error in every continuous parameter (25 steps, no artificial
    cells), computed once: the finite-difference check and the forward/reverse comparison both use it."""
    return jm.gradient(
        GAS,
        INTERPOLATORS[name],
        jm.continuous_parameters(GAS),
        dt=0.93e-5,
        steps=25,
        mode="reverse",
        transfer=TRANSFERS[transfer],
    )


def assert_matches_finite_differences(scene, interpolator, *, dt, steps, g=None, **kw):
    """``g``: the reverse-mode gradient in every continuous parameter, when it was computed already."""
    names = jm.continuous_parameters(scene)
    if g is None:
        g = jm.gradient(scene, interpolator, names, dt=dt, steps=steps, **kw)
    f = jax.jit(jm.sensitivity.objective(scene, interpolator, names, dt=dt, steps=steps, **kw))
    values = {n: jnp.asarray(dt if n == "dt" else float(getattr(scene, n))) for n in names}
    f0 = float(f(values))
    assert f0 > 1e-6  # an error large enough for a difference quotient to resolve
    for n in names:
        fd = fd5(f, values, n)
        # The difference quotient cannot resolve less than its own round-off: the objective is an
        # error of F ~ 1, so it carries absolute round-off of order eps, and the quotient ~eps / step.
        # Below that floor (100 times it) a derivative is compared with zero. This covers identically
        # zero derivatives: MPQ and CPDI do not see a uniform pressure offset at all, because their
        # domain forces telescope onto the boundary corners, where the traction cancels them.
        floor = 100 * EPS / (FD_REL * abs(float(values[n])))
        assert abs(float(g[n]) - fd) <= RTOL * abs(fd) + floor, (n, float(g[n]), fd)


@pytest.mark.parametrize("transfer", list(TRANSFERS.values()), ids=list(TRANSFERS))
@pytest.mark.parametrize("name", list(INTERPOLATORS), ids=list(INTERPOLATORS))
def test_gas_gradients_match_finite_differences(name, transfer):
    if name == "cpgimp" and transfer.name == "apic":
        pytest.skip(
            "kink-dense: APIC makes node 0 exactly still, cpGIMP's edge then sits on it (pinned below)"
        )
    assert_matches_finite_differences(
        GAS, INTERPOLATORS[name], dt=0.93e-5, steps=25, transfer=transfer, g=gas_gradient(name, transfer.name)
    )


@pytest.mark.parametrize("name", [n for n in INTERPOLATORS if n != "cpgimp"])
def test_gas_gradients_with_artificial_cells(name):
    assert_matches_finite_differences(GAS, INTERPOLATORS[name], dt=0.93e-5, steps=25, artificial_cells=1)


def test_bar_gradients_match_finite_differences(interpolator):
    assert_matches_finite_differences(BAR, interpolator, dt=1.1e-4, steps=40)


def test_kink_dense_case_is_pinned():
    """cpGIMP with artificial cells: the left domain edge stays on node 0 (v = 0 there), and round-off
    moves it across the node's kink back and forth. The error is then rough in beta at the 1e-4 scale:
    difference quotients disagree in sign. MPQ with artificial cells is smooth at the same point."""

    def slopes(interp):
        f = jax.jit(jm.sensitivity.objective(GAS, interp, ["beta"], dt=0.93e-5, steps=25, artificial_cells=1))
        b = 173.0 + np.linspace(-1e-3, 1e-3, 9)
        vals = np.array([float(f({"beta": jnp.asarray(x)})) for x in b])
        return np.diff(vals) / np.diff(b)

    rough = slopes(jm.GIMP(contiguous=True))
    smooth = slopes(jm.MPQ())
    assert np.ptp(smooth) < 1e-5 * np.max(np.abs(smooth))
    assert np.ptp(rough) > 0.5 * np.max(np.abs(rough))


@pytest.mark.parametrize("name", list(INTERPOLATORS))
def test_forward_and_reverse_modes_agree(name):
    interpolator = INTERPOLATORS[name]
    names = ("beta", "h", "dt")
    kw = dict(dt=0.93e-5, steps=25, artificial_cells=0)
    # reverse mode in every continuous parameter (beta, h and dt among them), from the same compiled
    # run as the finite-difference check of this interpolator with FLIP (the default transfer)
    rev = gas_gradient(name, "flip")
    fwd = jm.gradient(GAS, interpolator, names, mode="forward", **kw)
    f = jm.sensitivity.objective(GAS, interpolator, names, **kw)
    values = {n: jnp.asarray(0.93e-5 if n == "dt" else float(getattr(GAS, n))) for n in names}
    tangent = {n: jnp.asarray(t) for n, t in zip(names, (0.3, -2.0, 1e-7))}
    _, jvp = jax.jvp(f, (values,), (tangent,))
    for n in names:
        np.testing.assert_allclose(fwd[n], rev[n], rtol=REORDER_RTOL)
    np.testing.assert_allclose(jvp, sum(rev[n] * tangent[n] for n in names), rtol=REORDER_RTOL)


def test_vmap_of_grad_equals_loop_of_grad():
    def loss(beta):
        scene = jm.GasExpansion(beta=beta, h=0.11, cells=4)
        sol = jm.simulate(scene, jm.MPQ(), dt=0.93e-5, steps=20, artificial_cells=1)
        return jm.errors(scene, sol.state, sol.body)["F_rms_rel"]

    betas = jnp.array([97.0, 173.0, 311.0])
    batched = jax.vmap(jax.grad(loss))(betas)
    looped = jnp.stack([jax.grad(loss)(b) for b in betas])
    np.testing.assert_allclose(batched, looped, rtol=REORDER_RTOL)


def test_grad_under_jit_equals_without():
    f = jm.sensitivity.objective(GAS, jm.CPDI(), ["beta", "P0"], dt=0.93e-5, steps=20)
    values = {"beta": jnp.asarray(173.0), "P0": jnp.asarray(1.9e5)}
    plain = jax.grad(f)(values)
    jitted = jax.jit(jax.grad(f))(values)
    for n in values:
        np.testing.assert_allclose(jitted[n], plain[n], rtol=REORDER_RTOL)


@pytest.mark.parametrize("block", [True, 7])
def test_checkpointing_gives_the_same_gradient(block):
    kw = dict(dt=0.93e-5, steps=50, artificial_cells=1)
    names = ("beta", "h", "gamma")
    plain = jm.gradient(GAS, jm.MPQ(), names, **kw)
    ckpt = jm.gradient(GAS, jm.MPQ(), names, checkpoint=block, **kw)
    for n in names:
        np.testing.assert_allclose(ckpt[n], plain[n], rtol=REORDER_RTOL)
    a = jm.simulate(GAS, jm.MPQ(), checkpoint=block, **kw)
    b = jm.simulate(GAS, jm.MPQ(), **kw)
    np.testing.assert_allclose(a.state.F, b.state.F, rtol=16 * EPS)


@pytest.mark.slow
@pytest.mark.parametrize("every", [1, 5, 40])
def test_checkpointing_bounds_memory_with_a_history_saved_often(every):
    """With a history saved every k steps, k at most the checkpoint block, checkpointed reverse mode
    still stores states at block ends only (groups of save intervals): its compiled gradient needs a
    fraction of the memory of the plain one, and gives the plain one's gradient and history."""
    steps = 800  # checkpoint=True: blocks of ceil(sqrt(800 / 8)) = 10 steps

    def f(beta, checkpoint):
        scene = jm.GasExpansion(beta=beta, cells=16, h=1 / 16, pad=4)
        sol = jm.simulate(
            scene,
            jm.MPQ(),
            dt=1e-6,
            steps=steps,
            checkpoint=checkpoint,
            saveat=jm.SaveAt(every=every, fields=("x",)),
        )
        return jnp.sum(sol.state.F) + 1e-3 * jnp.sum(sol.history["x"][-3:]), sol.history["x"]

    def temp_bytes(checkpoint):
        grad = jax.jit(jax.grad(lambda b: f(b, checkpoint)[0]))
        return grad.lower(200.0).compile().memory_analysis().temp_size_in_bytes

    plain, checkpointed = temp_bytes(False), temp_bytes(True)
    assert checkpointed < plain / 4, (plain, checkpointed)
    (value, history), (value0, history0) = f(200.0, True), f(200.0, False)
    np.testing.assert_array_equal(np.asarray(history), np.asarray(history0))
    assert history.shape[0] == steps // every + 1 and float(value) == float(value0)
    g, g0 = jax.grad(lambda b: f(b, True)[0])(200.0), jax.grad(lambda b: f(b, False)[0])(200.0)
    np.testing.assert_allclose(float(g), float(g0), rtol=REORDER_RTOL)


def test_one_sided_derivative_on_a_node():
    """A point exactly on node j uses the cell to its right: dS_j/dx = -1/h, dS_{j+1}/dx = +1/h."""
    from jaxmpm.interpolators._transfer import point_stencil

    grid = jm.Grid(x_min=jnp.array([0.0]), h=jnp.asarray(0.5), n_nodes=6)
    jac = jax.jacfwd(lambda y: point_stencil(grid, y)[1])(jnp.asarray(1.0))  # node 2, exactly
    np.testing.assert_allclose(jac, [-2.0, 2.0])
    idx = point_stencil(grid, jnp.asarray(1.0))[0]
    assert idx.tolist() == [2, 3]


def test_zero_error_has_zero_gradient_not_nan():
    """APIC's first step is exact, so F_rms_rel = 0 there; its derivative must be 0, not NaN."""
    g = jm.gradient(jm.GasExpansion(cells=3), jm.SPQ(), ["beta", "h"], dt=1e-5, steps=1, transfer=jm.APIC())
    assert all(float(v) == 0.0 for v in g.values()), g


def test_objective_takes_plain_numbers_for_every_parameter():
    """Values as Python floats (or ints) give what 0-d float64 arrays give, the grid spacing too; a
    value that is not a number, or a missing name, is a ValueError naming it."""
    names = ["beta", "h", "dt"]
    f = jm.sensitivity.objective(jm.GasExpansion(cells=4), jm.MPQ(), names, dt=1e-5, steps=5)
    arrays = f({"beta": jnp.asarray(200.0), "h": jnp.asarray(0.125), "dt": jnp.asarray(1e-5)})
    assert float(arrays) > 1e-6
    assert float(f({"beta": 200, "h": 0.125, "dt": 1e-5})) == float(arrays)
    with pytest.raises(ValueError, match=r"values\['h'\] must be a real number, got 'a'"):
        raw(f)({"beta": 200.0, "h": "a", "dt": 1e-5})  # without the suite's type checks: what a user runs
    with pytest.raises(ValueError, match=r"values must hold a value for each of beta, h, dt; missing: h"):
        f({"beta": 200.0, "dt": 1e-5})


def test_objective_checks_the_values_as_the_scene_does_and_refuses_other_names():
    """Values the scene itself refuses (h <= 0, rho0 < 0, beta NaN) are refused by name before the
    run, as GasExpansion(h=-0.125) is; a name the function was not made for is refused, not ignored."""
    f = jm.sensitivity.objective(
        jm.GasExpansion(cells=4), jm.MPQ(), ["beta", "h", "rho0", "dt"], dt=1e-5, steps=2
    )
    good = dict(beta=200.0, h=0.125, rho0=1.0, dt=1e-5)
    for bad, match in (
        (dict(h=-0.125), "h must be > 0, got -0.125"),
        (dict(rho0=-1.0), "rho0 must be > 0, got -1"),
        (dict(beta=float("nan")), "beta must be finite, got nan"),
        (dict(dt=0.0), "dt must be > 0, got 0"),
    ):
        with pytest.raises(ValueError, match=match):
            f({**good, **bad})
    with pytest.raises(ValueError, match=r"values names 'gama', which is not one of beta, h, rho0, dt"):
        f({**good, "gama": 1.1})
    # under jax.grad the values are traced: the scene's checks let tracers pass, and the run goes on
    g = jax.grad(f)(good)
    assert set(g) == set(good) and all(np.isfinite(float(v)) for v in g.values())


def test_bad_gradient_names():
    with pytest.raises(ValueError, match="cells is structural"):
        jm.gradient(GAS, jm.SPQ(), ["cells"], dt=1e-5, steps=2)
    with pytest.raises(ValueError, match="unknown parameter 'E'"):
        jm.gradient(GAS, jm.SPQ(), ["E"], dt=1e-5, steps=2)


def test_cli_grad(capsys):
    argv = [
        "run",
        "gas-expansion",
        "beta=173",
        "h=0.11",
        "P0=1.9e5",
        "gamma=1.37",
        "p_atm=0.93e5",
        "rho0=1.07",
        "cells=4",
        "--interpolator",
        "cpdi",
        "--dt",
        "0.93e-5",
        "--steps",
        "25",
        "--grad",
        "beta,h,dt",
        "--json",
    ]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["grad"]) == {"beta", "h", "dt"}
    f = jax.jit(jm.sensitivity.objective(GAS, jm.CPDI(), ["beta", "h", "dt"], dt=0.93e-5, steps=25))
    values = {"beta": jnp.asarray(173.0), "h": jnp.asarray(0.11), "dt": jnp.asarray(0.93e-5)}
    for n in ("beta", "h", "dt"):
        assert out["grad"][n] == pytest.approx(fd5(f, values, n), rel=RTOL)
    assert (
        main(
            ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1", "--grad", "ppc"]
        )
        == 2
    )
    assert "ppc is structural" in capsys.readouterr().err


def test_cli_grad_of_a_run_that_broke_down_is_null(capsys):
    """A run that breaks down has no derivative: with --grad --json each is null, and grad_s too."""
    argv = ["run", "gas-expansion", "cells=4", "--interpolator", "spq", "--dt", "1e-3", "--steps", "10"]
    assert main(argv + ["--grad", "beta,h", "--json"]) == 3
    out = json.loads(capsys.readouterr().out)
    assert out["status"] != 0 and out["grad"] == {"beta": None, "h": None} and out["grad_s"] is None
