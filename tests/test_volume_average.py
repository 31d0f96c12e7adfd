"""Volume-averaged kinematics (J-bar): the averages are what their definitions say, a uniform J is left
alone, and a run without them is the run it always was."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm._step import _volume_averaged as volume_averaged
from jaxmpm._util import det

_volume_averaged = jax.jit(volume_averaged, static_argnums=0)


def _stencil_and_F(interpolator, seed=0):
    scene = jm.Blast(cells=4, ppc=2, pad=2)
    model = jm.Model(scene, interpolator, jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    rng = np.random.default_rng(seed)
    n = s.body.n
    F = jnp.asarray(np.eye(2) + 0.1 * rng.standard_normal((n, 2, 2)))
    x = state.x + 0.2 * float(scene.h) * jnp.asarray(rng.uniform(-1.0, 1.0, (n, 2)))
    stencil = interpolator.stencil(s.grid, s.body.r0, x, state.F, None)
    return s, stencil, x, F


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["cell", "node"])
def test_volume_average_is_the_defined_average(kind):
    """cell: J_bar is the V0-weighted mean of J over the particles whose centre lies in the cell; node:
    J projected to the nodes with the weights and back. F_bar = (J_bar / J)^(1/2) F: det F_bar = J_bar,
    and F_bar / J_bar^(1/2) = F / J^(1/2) (the isochoric part is kept)."""
    s, stencil, x, F = _stencil_and_F(jm.SPQ())
    F_bar = np.asarray(_volume_averaged(kind, s.grid, s.body, stencil, x, F))
    J, V0 = np.asarray(det(F)), np.asarray(s.body.V0)
    if kind == "cell":
        cell = np.floor((np.asarray(x) - np.asarray(s.grid.x_min)) / float(s.grid.h)).astype(int)
        key = cell[:, 0] * 1000 + cell[:, 1]
        expected = np.array([np.sum((V0 * J)[key == k]) / np.sum(V0[key == k]) for k in key])
    else:
        idx, w = np.asarray(stencil.idx), np.asarray(stencil.w)
        vol = np.zeros(s.grid.n_nodes)
        ref = np.zeros(s.grid.n_nodes)
        np.add.at(vol, idx, w * (V0 * J)[:, None])
        np.add.at(ref, idx, w * V0[:, None])
        J_i = np.where(ref > 0, vol / np.where(ref > 0, ref, 1.0), 0.0)
        expected = np.sum(w * J_i[idx], axis=1)
    np.testing.assert_allclose(np.linalg.det(F_bar), expected, rtol=1e-13)
    np.testing.assert_allclose(
        F_bar / np.sqrt(expected)[:, None, None], np.asarray(F) / np.sqrt(J)[:, None, None], rtol=1e-13
    )
    assert not np.allclose(expected, J)  # the average did something


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["cell", "node"])
@pytest.mark.parametrize("interpolator", [jm.SPQ(), jm.CPDI()], ids=["spq", "cpdi"])
def test_a_uniform_J_is_its_own_average(kind, interpolator):
    s, stencil, x, F = _stencil_and_F(interpolator, seed=1)
    rot = jnp.array([[0.8, -0.6], [0.6, 0.8]])
    F_u = jnp.broadcast_to(1.3 * rot, F.shape)
    np.testing.assert_allclose(_volume_averaged(kind, s.grid, s.body, stencil, x, F_u), F_u, rtol=1e-14)


@pytest.mark.slow
def test_volume_average_is_refused_by_name_and_changes_a_blast():
    with pytest.raises(ValueError, match="volume_average must be None or one of 'cell', 'node', got 'nodal'"):
        jm.simulate(jm.Blast(cells=4), jm.CPDI(), dt=1e-5, steps=1, volume_average="nodal")
    scene = jm.Blast(cells=4, ppc=2)
    dt = 0.25 * float(scene.h) / 374.0
    plain = jm.simulate(scene, jm.CPDI(), dt=dt, steps=5)
    measured = {"cell": 1.31e-4, "node": 7.20e-3}  # the largest move of a particle, in h
    for kind in ("cell", "node"):
        avg = jm.simulate(scene, jm.CPDI(), dt=dt, steps=5, volume_average=kind)
        assert int(avg.state.status) == 0
        gap = float(jnp.max(jnp.abs(avg.state.x - plain.state.x))) / float(scene.h)
        assert 0.5 * measured[kind] < gap < 2.0 * measured[kind], (kind, gap)
    g = jax.grad(
        lambda P0: jm.simulate(
            jm.Blast(cells=4, ppc=2, P0=P0), jm.CPDI(), dt=dt, steps=5, volume_average="node"
        ).state.x[-1, 0]
    )(1.5e5)
    assert np.isfinite(float(g)) and float(g) > 0.0


def test_volume_average_is_refused_for_regions_of_different_materials():
    """A gas disk in copper with J-bar broke down at once (the copper took the gas's volume change);
    regions of one material (a shock tube's two gas states) are taken."""
    from jaxmpm.geometry import Ball, Box

    gas, cu = jm.IdealGas(gamma=1.4), jm.MieGruneisen(**jm.MIE_GRUNEISEN["copper"])
    disk = jm.Region(Ball((6.0, 6.0), 3.3), gas, rho0=100.0, energy=2.5e6, velocity=(0.0, 0.0))
    rest = jm.Region(Box((0, 0), (12, 12)) - Ball((6.0, 6.0), 3.3), cu, rho0=8930.0)
    scene = jm.Bodies(parts=(disk, rest), cells=12, h=1e-3, pad=4, dim=2)
    for kind in ("cell", "node"):
        with pytest.raises(
            ValueError,
            match=r"^volume_average averages J over the particles of a cell or node, whatever their region, "
            r"and region 1 of Bodies is of another material \(MieGruneisen\) than region 0 \(IdealGas\)",
        ):
            jm.simulate(scene, jm.CPDI(), dt=1e-8, steps=1, volume_average=kind)
    tube = jm.ShockTube(cells=8)
    sol = jm.simulate(tube, jm.CPDI(), dt=1e-4, steps=1, volume_average="cell")
    assert sol.failure() is None


def test_regions_whose_material_constants_are_traced_are_one_material_only_as_one_object():
    """Under jax.grad the constants cannot be compared: two gases of traced gamma are refused unless
    they are the same material object, which runs and has a derivative."""
    from jaxmpm.geometry import Box

    def run(gamma, shared):
        left = jm.IdealGas(gamma=gamma)
        right = left if shared else jm.IdealGas(gamma=5 / 3)
        parts = (
            jm.Region(Box(0.0, 5.5), left, rho0=1.0, energy=2.5),
            jm.Region(Box(5.51, 10.0), right, rho0=0.125, energy=2.0),
        )
        sc = jm.Bodies(parts=parts, cells=10, h=0.1, ppc=2, pad=4, left="wall", right="wall")
        return jnp.sum(jm.simulate(sc, jm.CPDI(), dt=1e-3, steps=5, volume_average="cell").state.x)

    with pytest.raises(ValueError, match="region 1 of Bodies is of another material"):
        run(1.4, shared=False)
    with pytest.raises(
        ValueError, match="region 1 of Bodies has traced constants .* give every region the same"
    ):
        jax.grad(run)(1.4, False)
    assert np.isfinite(float(jax.grad(run)(1.4, True)))
