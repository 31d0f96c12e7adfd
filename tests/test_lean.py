"""A scene carries only what it needs: the compiled step holds nothing else.

Optional physics (traction, body force, artificial cells) and optional state (the tracked corners of
MPQ and CPDI2, APIC's affine matrices) are decided by Python structure while tracing, so a step
without them has none of their operations and none of their arrays in its jaxpr.
"""

from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import pytest
from helpers import INTERPOLATORS
from jaxtyping import Array, Float

import jaxmpm as jm

CELLS, PPC = 7, 3  # 21 particles, 22 corners, 28 grid nodes: shapes no other array of the step has


class Gas(jm.AbstractScene):
    """A 1D gas bar whose traction and body force are whatever the test gives it."""

    name: ClassVar[str] = "lean-gas"
    description: ClassVar[str] = "a gas bar with optional traction and body force"
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "free"
    right: ClassVar[str] = "free"
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None
    regions: ClassVar[None] = None

    traction: Callable | None = eqx.field(static=True, default=None)
    body_force: Callable | None = eqx.field(static=True, default=None)
    h: Float[Array, ""] = eqx.field(converter=jnp.asarray, default=0.125)
    rho0: Float[Array, ""] = eqx.field(converter=jnp.asarray, default=1.0)
    cells: int = eqx.field(static=True, default=CELLS)
    ppc: int = eqx.field(static=True, default=PPC)
    pad: int = eqx.field(static=True, default=10)

    def material(self):
        return jm.AdiabaticGas(P0=2.0e5, gamma=1.4, p_atm=1.0e5)

    def initial_velocity(self, X):
        return 200.0 * X


def traction(t):
    return -jnp.ones((1,)), jnp.ones((1,))


def gravity(X, t):
    return -9.81 * jnp.ones_like(X)


def step_jaxpr(scene, interpolator=None, transfer=None, artificial_cells=0):
    model = jm.Model(scene, interpolator or jm.SPQ(), transfer or jm.FLIP(), artificial_cells)
    setup = jm.setup(model)
    state = jm.initial_state(model, setup)
    return state, jax.make_jaxpr(lambda st: jm.step(model, setup, st, jnp.asarray(1e-5)))(state).jaxpr


def equations(jaxpr):
    """Every equation of a jaxpr, those of its sub-jaxprs (jit, cond, scan, custom rules) included."""
    for eqn in jaxpr.eqns:
        yield eqn
        for param in eqn.params.values():
            for sub in param if isinstance(param, (tuple, list)) else (param,):
                inner = getattr(sub, "jaxpr", sub)
                if isinstance(inner, jax.extend.core.Jaxpr):
                    yield from equations(inner)


def shapes(jaxpr) -> list[tuple[int, ...]]:
    """The shape of every array the step reads, makes or returns."""
    out = [v.aval.shape for v in (*jaxpr.invars, *jaxpr.outvars) if hasattr(v.aval, "shape")]
    for eqn in equations(jaxpr):
        out += [v.aval.shape for v in eqn.outvars if hasattr(v.aval, "shape")]
    return out


def primitives(jaxpr) -> list[str]:
    return [eqn.primitive.name for eqn in equations(jaxpr)]


@pytest.mark.slow
def test_step_holds_only_declared_physics():
    base = primitives(step_jaxpr(Gas())[1])
    with_traction = primitives(step_jaxpr(Gas(traction=traction))[1])
    with_body_force = primitives(step_jaxpr(Gas(body_force=gravity))[1])
    with_cells = primitives(step_jaxpr(Gas(), artificial_cells=1)[1])
    assert len(base) < min(len(with_traction), len(with_body_force), len(with_cells))
    assert with_traction.count("scatter-add") == base.count("scatter-add") + 1  # the traction's one scatter
    assert with_body_force.count("scatter-add") == base.count("scatter-add") + 1  # the body force's
    assert with_cells.count("scatter-add") == base.count("scatter-add") + 2  # artificial mass, momentum
    both = primitives(step_jaxpr(Gas(body_force=gravity), artificial_cells=1)[1])
    assert len(both) > len(with_body_force)


@pytest.mark.parametrize("name", list(INTERPOLATORS))
def test_corners_are_in_the_step_only_where_tracked(name):
    """Only the interpolators that track the shared corners of the particle domains (MPQ, CPDI2) have
    them: an (n + 1, 1) array that no other interpolator's step reads, makes or returns, and that their
    step carries from input to output."""
    state, jaxpr = step_jaxpr(Gas(), INTERPOLATORS[name])
    n_corners = CELLS * PPC + 1
    corner_arrays = [s for s in shapes(jaxpr) if s == (n_corners, 1)]
    assert INTERPOLATORS[name].tracks_corners == (name in ("mpq", "cpdi2"))
    if INTERPOLATORS[name].tracks_corners:
        assert state.corners.shape == (n_corners, 1)
        in_shapes = [v.aval.shape for v in jaxpr.invars]
        out_shapes = [v.aval.shape for v in jaxpr.outvars]
        assert in_shapes.count((n_corners, 1)) == 1 and out_shapes.count((n_corners, 1)) == 1
    else:
        assert state.corners is None
        assert corner_arrays == []


@pytest.mark.parametrize("name", ["flip", "pic", "apic"])
def test_affine_matrices_are_in_the_step_only_for_apic(name):
    """APIC carries an affine matrix C per particle, an (n, 1, 1) state array beside F and sigma;
    FLIP and PIC read and return only F and sigma of that shape."""
    state, jaxpr = step_jaxpr(Gas(), transfer=jm.TRANSFERS[name]())
    n = CELLS * PPC
    matrices_in = [v.aval.shape for v in jaxpr.invars].count((n, 1, 1))
    matrices_out = [v.aval.shape for v in jaxpr.outvars].count((n, 1, 1))
    expected = 3 if name == "apic" else 2  # F, sigma (and C)
    assert (state.C is not None) == (name == "apic")
    assert matrices_in == expected and matrices_out == expected


@pytest.mark.slow
def test_a_two_material_step_holds_both_models_and_nothing_else():
    """A body of a gas region and a neo-Hookean region: the step holds the gas's power of ``J`` and the
    solid's logarithm, as many of each as the one-material steps, and no energy equation."""
    from jaxmpm.geometry import Box

    gas, solid = jm.AdiabaticGas(P0=2.0, gamma=1.4, p_atm=1.0), jm.NeoHookean(lam=2.0, mu=1.0)
    one = lambda m: jm.Bodies(parts=(jm.Region(Box(0.0, 10.0), m, 1.0),), cells=10, h=0.1)  # noqa: E731
    two = jm.Bodies(
        parts=(jm.Region(Box(0.0, 5.0), gas, 1.0), jm.Region(Box(5.0, 10.0) - Box(0.0, 5.0), solid, 2.0)),
        cells=10,
        h=0.1,
    )
    g, s = primitives(step_jaxpr(one(gas), jm.CPDI())[1]), primitives(step_jaxpr(one(solid), jm.CPDI())[1])
    state, jaxpr = step_jaxpr(two, jm.CPDI())
    both = primitives(jaxpr)
    assert "pow" in g and "log" not in g  # the gas: J^-gamma, no logarithm
    assert "log" in s and "pow" not in s  # the neo-Hookean solid: ln J, no power
    assert both.count("pow") == g.count("pow") and both.count("log") == s.count("log")
    assert state.e is None and state.internal is None


@pytest.mark.slow
@pytest.mark.parametrize("ordering", ["usl", "musl"])
def test_2d_step_copies_what_the_particles_read_once_and_1d_does_not(ordering, monkeypatch):
    """In 2D and 3D the step writes the stencil's node indices and the nodal acceleration and velocity
    with one exact copy each (a ``scatter``, which XLA's CPU backend does not fuse into the gathers
    that read them; MUSL's re-projected velocity too), so the nodal arithmetic runs once a node, not
    once a read. In 1D there is no copy. Counted against the same step with the copies taken out."""
    import jaxmpm._step

    def scatters(scene):
        model = jm.Model(scene, jm.SPQ(), jm.FLIP(), ordering=ordering)
        setup = jm.setup(model)
        state = jm.initial_state(model, setup)
        # the step as traced now (jm.step's compiled program is cached across the monkeypatch)
        jaxpr = jax.make_jaxpr(lambda st: jaxmpm._step.take_step(model, setup, st, jnp.asarray(1e-6)))(
            state
        ).jaxpr
        return primitives(jaxpr).count("scatter")

    scenes = (jm.GasExpansion(cells=4), jm.GasExpansion(dim=2, cells=4), jm.GasExpansion(dim=3, cells=2))
    with_copies = [scatters(scene) for scene in scenes]
    monkeypatch.setattr(jaxmpm._step, "_materialised", lambda dim, fields: fields)
    without = [scatters(scene) for scene in scenes]
    per_run = 4 if ordering == "musl" else 3
    assert [a - b for a, b in zip(with_copies, without)] == [0, per_run, per_run]


def test_the_copy_is_exact():
    """The copy keeps every bit: signed zeros, infinities, NaN, integers."""
    from jaxmpm._step import _materialised

    a = jnp.asarray([[0.0, -0.0], [jnp.inf, -jnp.inf], [jnp.nan, 1e-310], [1.0 / 3.0, -2.5]])
    i = jnp.asarray([[3, 0], [7, 1], [2, 2], [0, 9]], dtype=jnp.int32)
    same, ints = _materialised(2, (a, i))
    assert same.tobytes() == a.tobytes() and ints.tobytes() == i.tobytes()
    assert _materialised(1, (a, i)) == (a, i)  # 1D: the arrays themselves
