"""The 1D grid's scatter and gather: each run of consecutive stencil nodes moved as one window
(``Grid.scatter(..., base)``) and the single-node form both give the sums of the values added one at
a time in order, bit for bit, drop what falls off either end of the grid and read zero there."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm._step import _particle_corners

N_NODES = 12


def _plain_grid():
    from jaxmpm.grid import Grid

    return Grid(x_min=jnp.zeros(1), h=jnp.asarray(0.5), n_nodes=N_NODES)


def _runs(rng, n, g, width):
    """``n`` particles of ``g`` runs of ``width`` nodes each, crowded on a few nodes (so the order
    of the sums shows) and reaching past both ends of the grid."""
    base = rng.integers(-width - 1, N_NODES + 1, size=(n, g))
    base[:4] = -width  # wholly off the low end
    base[4:8] = -1  # one node off the low end
    base[8:12] = N_NODES - 1  # reaches one node past the high end
    idx = base[:, :, None] + np.arange(width)[None, None, :]
    return base.astype(np.int32), idx.reshape(n, g * width).astype(np.int32)


def _sequential_sum(idx, values):
    """The documented result: values added one at a time, in flat order, off-grid ones dropped."""
    out = np.zeros((N_NODES,) + values.shape[2:], dtype=values.dtype)
    for p in range(idx.shape[0]):
        for k in range(idx.shape[1]):
            i = int(idx[p, k])
            if 0 <= i < N_NODES:
                out[i] = out[i] + values[p, k]
    return out


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("g, width", [(1, 2), (2, 2), (1, 3)])
@pytest.mark.parametrize("tail", [(), (1,), (2,)])
def test_scatters_are_the_sequential_sum_bit_for_bit(dtype, g, width, tail):
    rng = np.random.default_rng(3)
    base, idx = _runs(rng, 200, g, width)
    values = rng.normal(size=(200, g * width) + tail).astype(dtype)
    grid = _plain_grid()
    windowed = jax.jit(lambda i, v, b: grid.scatter(i, v, b))(
        jnp.asarray(idx), jnp.asarray(values), jnp.asarray(base)
    )
    expected = _sequential_sum(idx, values)
    assert windowed.dtype == dtype and windowed.shape == expected.shape
    assert np.asarray(windowed).tobytes() == expected.tobytes()
    single = jax.jit(lambda i, v: grid.scatter(i, v))(jnp.asarray(idx), jnp.asarray(values))
    assert np.asarray(single).tobytes() == expected.tobytes()


@pytest.mark.parametrize("g, width", [(1, 2), (2, 2), (1, 3)])
@pytest.mark.parametrize("tail", [(), (2,)])
def test_gathers_read_the_nodes_and_zero_off_the_grid(g, width, tail):
    rng = np.random.default_rng(4)
    base, idx = _runs(rng, 100, g, width)
    field = rng.normal(size=(N_NODES,) + tail)
    grid = _plain_grid()
    got = np.asarray(
        jax.jit(lambda i, f, b: grid.gather(i, f, b))(jnp.asarray(idx), jnp.asarray(field), jnp.asarray(base))
    )
    inside = (idx >= 0) & (idx < N_NODES)
    expected = np.where(
        inside.reshape(inside.shape + (1,) * len(tail)), field[np.clip(idx, 0, N_NODES - 1)], 0.0
    )
    assert got.shape == expected.shape
    assert got.tobytes() == expected.tobytes()
    single = np.asarray(jax.jit(lambda i, f: grid.gather(i, f))(jnp.asarray(idx), jnp.asarray(field)))
    assert single.tobytes() == expected.tobytes()


@pytest.mark.slow
def test_windowed_scatter_and_gather_differentiate_as_the_single_node_forms():
    rng = np.random.default_rng(5)
    base, idx = _runs(rng, 50, 1, 2)
    base, idx = jnp.asarray(base), jnp.asarray(idx)
    values = jnp.asarray(rng.normal(size=idx.shape))
    field = jnp.asarray(rng.normal(size=N_NODES))
    grid = _plain_grid()

    def loss(v, f, windowed):
        b = base if windowed else None
        nodal = grid.scatter(idx, v, b)
        return jnp.sum(jnp.sin(nodal) * f) + jnp.sum(grid.gather(idx, f * nodal, b) ** 2)

    for a, b in zip(
        jax.grad(loss, (0, 1))(values, field, True), jax.grad(loss, (0, 1))(values, field, False)
    ):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["spq", "mpq", "cpdi", "cpdi2"])
def test_1d_stencils_name_their_runs_of_consecutive_nodes(name):
    scene = jm.GasExpansion(cells=5, ppc=3, pad=3)
    model = jm.Model(scene, jm.INTERPOLATORS[name](), jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    x = state.x + 0.01 * jnp.sin(jnp.arange(s.body.n, dtype=state.x.dtype))[:, None]
    st = model.interpolator.stencil(s.grid, s.body.r0, x, state.F, _particle_corners(state, s.body))
    for idx, base in ((st.idx, st.base), (st.gidx, st.gbase)):
        assert base is not None
        n, g = base.shape
        runs = np.asarray(idx).reshape(n, g, -1)
        np.testing.assert_array_equal(runs, np.asarray(base)[:, :, None] + np.arange(runs.shape[2]))


@pytest.mark.slow
def test_stencils_without_runs_have_no_base():
    scene = jm.GasExpansion(cells=3, ppc=2, pad=3, dim=2)
    model = jm.Model(scene, jm.SPQ(), jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    st = model.interpolator.stencil(s.grid, s.body.r0, state.x, state.F, None)
    assert st.base is None and st.gbase is None  # 2D: single-node updates
    gimp = jm.GasExpansion(cells=3, ppc=2, pad=3)
    model = jm.Model(gimp, jm.GIMP(), jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    st = model.interpolator.stencil(s.grid, s.body.r0, state.x, state.F, None)
    assert st.base is None  # GIMP keeps the single-node form
