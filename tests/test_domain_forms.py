"""The domain form ``dphi_ip = sum_c S_i(x_c) g_c`` of CPDI, CPDI2 and MPQ in 2D and 3D, evaluated
through its factors (per corner, and for tracked corners per shared corner), equals the per-entry
contraction with ``dphi`` to round-off; in 1D the stencil has no factors."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm._util import contract
from jaxmpm.interpolators._transfer import gradient_forces, gradient_outer, shared_corner_forces

RTOL = 1e-13  # relative to the largest entry: only the order of the sums differs


def distorted(interpolator, dim, seed=0):
    """A gas-expansion body in 2D/3D, corners and F moved at random, with a random stress."""
    scene = jm.GasExpansion(cells=3, ppc=2, dim=dim, pad=3)
    model = jm.Model(scene, interpolator, jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    body, grid = s.body, s.grid
    rng = np.random.default_rng(seed)
    n, h = body.n, float(jnp.min(grid.h))
    F = state.F + jnp.asarray(rng.uniform(-0.15, 0.15, (n, dim, dim)))
    x = state.x + jnp.asarray(rng.uniform(-0.1 * h, 0.1 * h, (n, dim)))
    corners = state.corners
    if corners is not None:
        corners = corners + jnp.asarray(rng.uniform(-0.1 * h, 0.1 * h, corners.shape))
        x = body.particle_corners(corners).mean(axis=1)
    a = rng.normal(0.0, 1e5, (n, dim, dim))
    sigma = jnp.asarray(a + np.swapaxes(a, 1, 2))
    V = body.V0 * jnp.linalg.det(F)
    return grid, body, stencil(interpolator, grid, body, x, F, corners), sigma, V, corners


@jax.jit  # one program, not op by op
def stencil(interpolator, grid, body, x, F, corners):
    particle_corners = None if corners is None else body.particle_corners(corners)
    return interpolator.stencil(grid, body.r0, x, F, particle_corners)


def assert_close(actual, expected):
    scale = float(jnp.max(jnp.abs(expected)))
    assert scale > 0
    np.testing.assert_allclose(actual, expected, rtol=0, atol=RTOL * scale)


@functools.partial(jax.jit, static_argnames="tracks_corners")  # one program a case, not op by op
def factored_and_per_entry(grid, body, st, sigma, V, corners, tracks_corners):
    """Each form through the factors beside the per-entry contraction with ``dphi`` it must equal."""
    n, c, k = st.S_c.shape
    dim = grid.dim
    assert c == 2**dim and st.g_c.shape == (n, c, dim)  # (the shapes are known while tracing)
    per_entry = grid.scatter(st.gidx, contract("nab,nkb->nka", sigma, st.dw) * V[:, None, None])
    values = grid.gather(st.gidx, jnp.asarray(np.random.default_rng(3).normal(0, 1.0, (grid.n_nodes, dim))))
    out = dict(
        # the factors reproduce dphi entry by entry
        dphi=((st.S_c[..., None] * st.g_c[:, :, None, :]).reshape(st.dw.shape), st.dw),
        forces=(grid.scatter(st.gidx, gradient_forces(st, sigma, V)), per_entry),
        outer=(gradient_outer(st, values), contract("nka,nkb->nab", values, st.dw)),
    )
    if tracks_corners:  # shared corners: Q_c gathered per corner, then the corner's hat stencil
        out["shared"] = (shared_corner_forces(grid, st, sigma, V, corners, body.corner_ids), per_entry)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("interpolator", [jm.CPDI(), jm.CPDI2(), jm.MPQ()], ids=["cpdi", "cpdi2", "mpq"])
def test_factored_forces_and_gradient_equal_the_contraction_with_dphi(interpolator, dim):
    forms = factored_and_per_entry(*distorted(interpolator, dim), interpolator.tracks_corners)
    assert set(forms) == {"dphi", "forces", "outer"} | ({"shared"} if interpolator.tracks_corners else set())
    for actual, expected in forms.values():
        assert_close(actual, expected)


@pytest.mark.parametrize("interpolator", [jm.CPDI(), jm.CPDI2(), jm.MPQ()], ids=["cpdi", "cpdi2", "mpq"])
def test_1d_stencil_has_no_factors(interpolator):
    scene = jm.GasExpansion(cells=3, ppc=2)
    model = jm.Model(scene, interpolator, jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    corners = None if state.corners is None else s.body.particle_corners(state.corners)
    st = interpolator.stencil(s.grid, s.body.r0, state.x, state.F, corners)
    assert st.S_c is None and st.g_c is None
