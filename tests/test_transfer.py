"""Particle-to-grid and grid-to-particle conserve mass and momentum, for every interpolator and transfer."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm.geometry import Box


def setup_bar(interpolator, transfer, beta=150.0):
    scene = jm.GasExpansion(cells=5, ppc=3, beta=beta)
    model = jm.Model(scene, interpolator, transfer)
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    # Perturb the state away from the manufactured solution so nothing is trivially symmetric.
    rng = np.random.default_rng(1)
    n = s.body.n
    x = state.x + jnp.asarray(rng.uniform(-0.01, 0.01, (n, 1)))
    if isinstance(interpolator, jm.CPDI2):  # its centre is always its corners' mean
        x = s.body.particle_corners(state.corners).mean(axis=1)
    state = jm.State(
        t=state.t,
        step=state.step,
        x=x,
        v=state.v + jnp.asarray(rng.normal(0, 5.0, (n, 1))),
        F=state.F * jnp.asarray(rng.uniform(0.9, 1.1, (n, 1, 1))),
        sigma=state.sigma,
        C=None if state.C is None else state.C + jnp.asarray(rng.normal(0, 10.0, (n, 1, 1))),
        corners=state.corners,
        x_traction=state.x_traction,
        status=state.status,
        fail_step=state.fail_step,
        fail_particle=state.fail_particle,
    )
    return model, s, state


def test_p2g_conserves_mass_and_momentum(interpolator, transfer):
    model, s, state = setup_bar(interpolator, transfer)
    g, body = s.grid, s.body
    corners = None if state.corners is None else state.corners[body.corner_ids]
    st = interpolator.stencil(g, body.r0, state.x, state.F, corners)
    mass = g.scatter(st.idx, st.w * body.m[:, None])
    momentum = g.scatter(st.idx, transfer.momentum(g, st, state.x, state.v, state.C, body.m))
    np.testing.assert_allclose(jnp.sum(mass), jnp.sum(body.m), rtol=1e-14)
    np.testing.assert_allclose(jnp.sum(momentum), jnp.sum(body.m * state.v[:, 0]), rtol=1e-13)


def test_g2p_conserves_momentum(interpolator):
    """PIC/APIC velocity from a grid field carries exactly the grid momentum sum_i m_i v_i."""
    model, s, state = setup_bar(interpolator, jm.PIC())
    g, body = s.grid, s.body
    corners = None if state.corners is None else state.corners[body.corner_ids]
    st = interpolator.stencil(g, body.r0, state.x, state.F, corners)
    mass = g.scatter(st.idx, st.w * body.m[:, None])
    v_grid = jnp.asarray(np.random.default_rng(2).normal(0, 3.0, (g.n_nodes, 1)))
    for transfer in (jm.PIC(), jm.APIC()):
        v_p, _ = transfer.update(g, st, state.v, jnp.zeros_like(v_grid), v_grid, jnp.asarray(1e-5))
        np.testing.assert_allclose(jnp.sum(body.m * v_p[:, 0]), jnp.sum(mass * v_grid[:, 0]), rtol=1e-13)


def test_step_conserves_mass_and_momentum(interpolator, transfer):
    """Equal and opposite tractions, internal forces summing to zero: momentum is constant over a run."""
    scene = jm.GasExpansion(beta=200.0)
    sol0 = jm.simulate(scene, interpolator, dt=1e-5, steps=0, transfer=transfer)
    sol = jm.simulate(scene, interpolator, dt=1e-5, steps=60, transfer=transfer, cfl_limit=None)
    d0 = jm.diagnostics(scene, sol0.state, sol0.body)
    d1 = jm.diagnostics(scene, sol.state, sol.body)
    np.testing.assert_allclose(d1["mass"], d0["mass"], rtol=1e-15)
    np.testing.assert_allclose(d1["momentum"], d0["momentum"], rtol=1e-12)


@pytest.mark.slow
def test_apic_with_cpdi_gains_energy_at_a_free_surface_into_near_vacuum_flip_and_mpq_do_not():
    """The 1D slab of the blast study at 100:1 (16 cells, CPDI) to 0.3 of two sound transits: the exact
    motion keeps kinetic plus stored energy at its initial 0. Measured: FLIP -3.6% of the kinetic energy,
    the outermost particle 1.66 times as fast as the one inside it; APIC +61%, nearly all in the
    outermost particle (7.7 times as fast), which the documentation states as a limitation. It is APIC
    with CPDI's weights: with MPQ's (hats at the centre) APIC gains none (-0.12%, ratio 1.16)."""
    from jaxmpm.studies import blast

    slab, disk = blast.make_slab(100.0, 16)
    t_end = 0.3 * blast.TRANSITS * float(disk.transit_time)
    out = {}
    for interp, name in (("cpdi", "flip"), ("cpdi", "apic"), ("mpq", "apic")):
        sol = jm.simulate(
            slab,
            jm.INTERPOLATORS[interp](),
            transfer=jm.TRANSFERS[name](),
            t_end=t_end,
            cfl=blast.CFL,
            max_steps=2000,
        )
        d = jm.metrics.diagnostics(slab, sol.state, sol.body)
        v = np.asarray(sol.state.v)[:, 0]
        out[interp, name] = (float(d["energy"]) / float(d["energy_kinetic"]), v[-1] / v[-2])
    assert abs(out["cpdi", "flip"][0]) < 0.05 and out["cpdi", "flip"][1] < 2.0  # -0.036, 1.66
    assert out["cpdi", "apic"][0] > 0.4 and out["cpdi", "apic"][1] > 5.0  # +0.61, 7.7
    assert abs(out["mpq", "apic"][0]) < 0.05 and out["mpq", "apic"][1] < 2.0  # -0.0012, 1.16


def _two_blocks():
    """Two elastic blocks of different stiffness, density and velocity, in contact and free (1D): a
    motion far from linear, on which nothing external acts."""
    soft, stiff = jm.NeoHookean(lam=1e3, mu=1e3), jm.NeoHookean(lam=4e3, mu=2e3)
    parts = (
        jm.Region(Box(0.0, 3.0), soft, 1000.0, velocity=0.3),
        jm.Region(Box(3.0, 6.0), stiff, 3000.0, velocity=-0.2),
    )
    return jm.Bodies(parts=parts, cells=6, h=0.25, ppc=2, pad=3, dim=1)


def test_artificial_cells_keep_momentum_with_flip_but_not_with_pic_or_apic():
    """The artificial particles add momentum to the nodal velocity and no force. FLIP's particle update
    divides the force by the real mass, so the body's momentum stays what it was (-225) to round-off.
    PIC and APIC give the particles the nodal velocity itself, which holds the artificial particles'
    momentum, and the body's momentum changes (measured over 30 steps: PIC
    -237.67, APIC -228.97; the documentation's known limitations)."""
    scene = _two_blocks()
    p = {}
    for transfer in (jm.FLIP(), jm.PIC(), jm.APIC()):
        sol = jm.simulate(scene, jm.SPQ(), dt=0.01, steps=30, transfer=transfer, artificial_cells=1)
        assert sol.failure() is None
        p[transfer.name] = float(jm.diagnostics(scene, sol.state, sol.body)["momentum"])
    np.testing.assert_allclose(p["flip"], -225.0, rtol=1e-14)
    assert p["pic"] < -235.0 and p["apic"] < -227.0, p  # -237.67, -228.97
