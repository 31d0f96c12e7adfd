"""A hand-computed step, and the artificial-cell extrapolation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm.boundaries import artificial_layer


def test_hand_computed_spq_step():
    """Two-particle elastic bar, wall at 0, free end: every number below worked out by hand.

    X = (0.5, 1.5), h = 1, m = V0 = 1, E = 1, F = (1.2, 1.0) so sigma = (0.2, 0), v = 0, dt = 0.1.
    Nodes 0, 1, 2 at x = 0, 1, 2 (indices 2, 3, 4 with pad = 2).
    masses (0.5, 1.0, 0.5); f_int = -(sigma V dphi) = (0.24, -0.24, 0); node 0 is the wall;
    a_1 = -0.24, v_1 = -0.024; FLIP: v_p = 0.1 * 0.5 * (-0.24) = -0.012 for both particles;
    x_p = X + 0.1 * 0.5 * (-0.024) = X - 0.0012; grad v = (-0.024, +0.024);
    F = (1.2 * (1 - 0.0024), 1.0 * (1 + 0.0024)) = (1.19712, 1.0024).
    """
    scene = jm.VibratingBar(E=1.0, rho0=1.0, h=1.0, cells=2, ppc=1, pad=2, v0=0.0)
    model = jm.Model(scene, jm.SPQ(), jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    F0 = jnp.array([1.2, 1.0])[:, None, None]
    state = jm.State(
        t=state.t,
        step=state.step,
        x=state.x,
        v=jnp.zeros((2, 1)),
        F=F0,
        sigma=F0 - 1.0,
        C=None,
        corners=None,
        x_traction=None,
        status=state.status,
        fail_step=state.fail_step,
        fail_particle=state.fail_particle,
    )
    new = jax.jit(jm.step)(model, s, state, jnp.asarray(0.1))  # one program, not op by op
    np.testing.assert_allclose(new.v[:, 0], [-0.012, -0.012], rtol=1e-14)
    np.testing.assert_allclose(new.x[:, 0], [0.5 - 0.0012, 1.5 - 0.0012], rtol=1e-15)
    np.testing.assert_allclose(new.F[:, 0, 0], [1.19712, 1.0024], rtol=1e-15)
    np.testing.assert_allclose(new.sigma[:, 0, 0], [0.19712, 0.0024], rtol=1e-13)
    assert int(new.step) == 1 and float(new.t) == pytest.approx(0.1, rel=1e-15)


@pytest.mark.parametrize("ppc", [1, 2, 3])
@pytest.mark.parametrize("layers", [1, 2, 3])
def test_artificial_layer_extrapolates_linear_fields_exactly(ppc, layers):
    cells = 4
    layer = artificial_layer(cells, ppc, layers, (True, True))
    X = (np.arange(cells * ppc) + 0.5) / ppc
    X_art = np.concatenate(
        [-(np.arange(layers * ppc)[::-1] + 0.5) / ppc, cells + (np.arange(layers * ppc) + 0.5) / ppc]
    )
    field = jnp.asarray(3.0 - 2.5 * X)[:, None]
    np.testing.assert_allclose(layer.extrapolate(field)[:, 0], 3.0 - 2.5 * X_art, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(layer.mean(jnp.full((cells * ppc, 1), 1.7))[:, 0], 1.7, rtol=1e-15)


def test_artificial_layer_only_on_free_sides():
    assert artificial_layer(4, 2, 1, (False, False)) is None
    assert artificial_layer(4, 2, 0, (True, True)) is None
    left_only = artificial_layer(4, 2, 1, (True, False))
    assert left_only.src.shape == (2, 2) and int(left_only.src.max()) == 1


def test_artificial_cells_need_two_particles():
    with pytest.raises(ValueError, match="at least 2 real particles"):
        jm.simulate(jm.GasExpansion(cells=1, ppc=1), jm.SPQ(), dt=1e-5, steps=1, artificial_cells=1)


def test_artificial_cells_need_padding():
    """Refused by the Model, before the run is traced (it was raised from inside the run's tracing)."""
    with pytest.raises(ValueError, match="pad must be > artificial_cells"):
        jm.simulate(jm.GasExpansion(pad=2), jm.SPQ(), dt=1e-5, steps=1, artificial_cells=2)
    with pytest.raises(ValueError, match="pad must be > artificial_cells"):
        jm.Model(jm.GasExpansion(pad=2), jm.SPQ(), jm.FLIP(), artificial_cells=2)


def test_wall_holds_node_velocity():
    scene = jm.VibratingBar()
    assert scene.left == "wall" and scene.right == "free"
    # the wall node (index pad) and every node beyond it are held at v = 0, the next one is free
    walls = np.asarray(jm.setup(jm.Model(scene, jm.SPQ(), jm.FLIP())).walls)[:, 0]
    assert walls[: scene.pad + 1].all() and not walls[scene.pad + 1 :].any()
    sol = jm.simulate(scene, jm.SPQ(), dt=1e-4, steps=50)
    # The particle nearest the wall moves only through the node next to it, never through the wall node.
    err = jm.errors(scene, sol.state, sol.body)
    # measured 9.03e-7 (1.80e-5 with the wall node left free, 1.46e-5 with the hold left out of the step)
    assert float(err["x_max_abs"]) < 2e-6
