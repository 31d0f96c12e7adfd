"""Shape functions: partition of unity, linear completeness, gradients, GIMP averages."""

import jax
import jax.numpy as jnp
import numpy as np

import jaxmpm as jm
from jaxmpm.shapes import hat, hat_integral

# GIMP's weight h (Phi(b) - Phi(a)) / (2 l) differences two O(1) antiderivative values and scales the
# result by h / (2 l) (<= 4 for these particles): a few tens of ulps of round-off, not more.
EPS = float(jnp.finfo(jnp.float64).eps)
TOL = 64 * EPS


def grid():
    return jm.Grid(x_min=jnp.array([-1.0]), h=jnp.asarray(0.25), n_nodes=41)


def random_particles(n=64, seed=0):
    rng = np.random.default_rng(seed)
    x = jnp.asarray(rng.uniform(1.0, 7.0, size=(n, 1)))
    F = jnp.asarray(rng.uniform(0.6, 1.8, size=(n, 1, 1)))
    r0 = jnp.full((n, 1), 0.0625)
    corners = jnp.stack([x - F[:, :, 0] * r0, x + F[:, :, 0] * r0], axis=1)  # (n, 2, 1)
    return r0, x, F, corners


@jax.jit  # one program per interpolator, not op by op
def nodal_sums(interpolator):
    g = grid()
    r0, x, F, corners = random_particles()
    st = interpolator.stencil(g, r0, x, F, corners)
    nodes = g.nodes()[:, 0]
    return (
        st,
        x,
        jnp.sum(st.w, axis=1),
        jnp.sum(st.w * nodes[st.idx], axis=1),
        jnp.sum(st.dw[..., 0], axis=1),
        jnp.sum(st.dw[..., 0] * (nodes[st.gidx] - x), axis=1),  # sum dphi (x_i - x_p): well conditioned
    )


def test_partition_of_unity(interpolator):
    _, _, w_sum, _, _, _ = nodal_sums(interpolator)
    np.testing.assert_allclose(w_sum, 1.0, rtol=0, atol=TOL)


def test_linear_completeness(interpolator):
    _, x, _, w_x, _, _ = nodal_sums(interpolator)
    np.testing.assert_allclose(w_x, x[:, 0], rtol=TOL, atol=0)


def test_gradients_sum_to_zero_and_reproduce_slope(interpolator):
    _, _, _, _, dw_sum, dw_x = nodal_sums(interpolator)
    np.testing.assert_allclose(dw_sum, 0.0, rtol=0, atol=TOL / 0.0625)
    np.testing.assert_allclose(dw_x, 1.0, rtol=TOL, atol=0)


def test_weights_are_nonnegative(interpolator):
    st, *_ = nodal_sums(interpolator)
    assert float(jnp.min(st.w)) >= 0.0


def test_gimp_dphi_is_derivative_of_phi():
    """GIMP's dphi equals d(phi)/d(x_p) (Bardenhagen & Kober 2004)."""
    g = grid()
    r0, x, F, _ = random_particles(8, seed=3)
    gimp = jm.GIMP()

    def w_of(xp):
        return gimp.stencil(g, r0[:1], xp[None, None], F[:1], None).w[0]

    jac_of = jax.jit(jax.jacfwd(w_of))  # one program each, not op by op
    dw_of = jax.jit(lambda xp: gimp.stencil(g, r0[:1], xp[None, None], F[:1], None).dw[0, :, 0])
    for xp in np.asarray(x[:, 0]):
        np.testing.assert_allclose(jac_of(jnp.asarray(xp)), dw_of(jnp.asarray(xp)), rtol=1e-12, atol=1e-12)


def test_hat_integral_is_the_hats_antiderivative():
    """The integral of the hat from -1 to xi, in closed form: 0, (1 + xi)^2 / 2, 1 - (1 - xi)^2 / 2, 1."""
    xi = np.linspace(-1.5, 1.5, 301)
    expected = np.where(xi < 0, 0.5 * (1 + xi) ** 2, 1 - 0.5 * (1 - xi) ** 2)
    expected = np.where(xi <= -1, 0.0, np.where(xi >= 1, 1.0, expected))
    np.testing.assert_allclose(hat_integral(jnp.asarray(xi)), expected, rtol=0, atol=1e-15)
    assert np.allclose(np.diff(expected) / np.diff(xi), hat(0.5 * (xi[1:] + xi[:-1])), atol=1e-2)


def test_gimp_reduces_to_spq_inside_a_cell():
    """A domain inside one cell averages a linear function: GIMP weights equal SPQ's there."""
    g = grid()
    x = jnp.array([[1.1], [2.3]])  # domains [x - 0.05, x + 0.05] stay within one cell of 0.25
    r0 = jnp.full((2, 1), 0.05)
    F = jnp.ones((2, 1, 1))

    @jax.jit  # one program each, not op by op
    def dense(interpolator):
        st = interpolator.stencil(g, r0, x, F, None)
        return jnp.zeros((2, g.n_nodes)).at[jnp.arange(2)[:, None], st.idx].add(st.w)

    np.testing.assert_allclose(dense(jm.GIMP()), dense(jm.SPQ()), atol=1e-15)
