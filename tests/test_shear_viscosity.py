"""The shear artificial viscosity ``2 mu dev(D)``, ``mu = c_shear rho c h``: its value on known
rates of deformation and on uniform expansion, its power, where it acts, and off by default."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm

DT, H, RHO, C = 1e-3, 0.1, 2.0, 300.0


@pytest.mark.slow
def test_simple_shear_and_a_uniform_expansion():
    visc = jm.ArtificialViscosity(c_shear=0.5)
    g = 4.0  # shear rate: F_new = F_old + dt L with L = [[0, g], [0, 0]]
    F_old = jnp.eye(2)[None]
    F_new = (jnp.eye(2) + DT * jnp.array([[0.0, g], [0.0, 0.0]]))[None]
    s, power = visc.shear_stress(
        F_old, F_new, jnp.asarray(DT), jnp.array([RHO]), jnp.array([C]), jnp.asarray(H)
    )
    mu = 0.5 * RHO * C * H
    # D = sym(L) = [[0, g/2], [g/2, 0]], traceless: s = 2 mu D, s : D / rho = 4 mu (g/2)^2 / rho
    np.testing.assert_allclose(np.asarray(s[0]), [[0.0, mu * g], [mu * g, 0.0]], rtol=1e-12)
    np.testing.assert_allclose(float(power[0]), 2.0 * mu * g**2 / 2.0 / RHO, rtol=1e-12)
    # a uniform expansion has no deviatoric rate: no shear stress, no heat
    F_exp = jnp.eye(3)[None] * 1.01
    s, power = visc.shear_stress(
        jnp.eye(3)[None], F_exp, jnp.asarray(DT), jnp.array([RHO]), jnp.array([C]), jnp.asarray(H)
    )
    assert float(jnp.max(jnp.abs(s))) <= 1e-9 * mu and abs(float(power[0])) <= 1e-9


def test_off_by_default_and_checked():
    assert jm.ArtificialViscosity().c_shear is None
    with pytest.raises(ValueError, match="c_shear"):
        jm.ArtificialViscosity(c_shear=-1.0)


@pytest.mark.slow
def test_it_acts_where_the_flow_shears():
    """The 2D gas expansion is uniform but for its boundary cells: a shear viscosity moves its
    particles by 2.1e-4 h in 20 steps; a disk charge's radial flow has a deviatoric rate everywhere,
    and the same viscosity moves its particles by 0.26 h in half a transit."""
    bulk0 = jm.ArtificialViscosity(c_quad=0.0, c_lin=0.0)
    sc = jm.GasExpansion(cells=6, pad=4, dim=2)
    kw = dict(dt=1e-5, steps=20, artificial_cells=1)
    a = jm.simulate(sc, jm.MPQ(), viscosity=bulk0, **kw)
    b = jm.simulate(sc, jm.MPQ(), viscosity=jm.ArtificialViscosity(c_quad=0.0, c_lin=0.0, c_shear=0.5), **kw)
    gap = float(jnp.max(jnp.abs(a.state.x - b.state.x))) / float(sc.h)
    assert 1e-4 < gap < 4e-4, gap  # measured 2.06e-4 (h)
    disk = jm.BlastDisk(cells=8, pad=20)
    kw = dict(t_end=0.5 * float(disk.transit_time), cfl=0.3, max_steps=2000)
    a = jm.simulate(disk, jm.CPDI(), viscosity=bulk0, **kw)
    b = jm.simulate(
        disk, jm.CPDI(), viscosity=jm.ArtificialViscosity(c_quad=0.0, c_lin=0.0, c_shear=0.3), **kw
    )
    gap = float(jnp.max(jnp.abs(a.state.x - b.state.x))) / float(disk.h)
    assert 0.2 < gap < 0.5, gap  # measured 0.261 (h)


@pytest.mark.slow
def test_in_1d_the_shear_viscosity_adds_nothing():
    """In 1D the rate of deformation is all volumetric (``dev(D) = 0``): a shock tube with an energy
    equation runs bit for bit as with the bulk viscosity alone, its energies included."""
    sc = jm.ShockTube(cells=64)
    kw = dict(t_end=0.05, cfl=0.3, max_steps=2000)
    base = jm.simulate(sc, jm.CPDI(), viscosity=jm.ArtificialViscosity(), **kw)
    with_shear = jm.simulate(sc, jm.CPDI(), viscosity=jm.ArtificialViscosity(c_shear=0.3), **kw)
    assert int(base.state.step) > 10
    np.testing.assert_array_equal(np.asarray(with_shear.state.e), np.asarray(base.state.e))
    np.testing.assert_array_equal(np.asarray(with_shear.state.x), np.asarray(base.state.x))


@pytest.mark.slow
def test_command_line_and_saved_runs_carry_the_shear_coefficient(tmp_path, capsys):
    import json

    from jaxmpm.cli import main

    argv = ["run", "blast-disk", "cells=4", "pad=8", "--interpolator", "cpdi", "--dt", "1e-5", "--steps", "4"]
    assert main([*argv, "--viscosity", "2,0.2,0.5", "--json", "--out", str(tmp_path / "r.npz")]) == 0
    assert json.loads(capsys.readouterr().out)["viscosity"] == [2.0, 0.2, 0.5]
    sol, meta = jm.long_run.load(tmp_path / "r.npz")
    assert meta["viscosity"] == [2.0, 0.2, 0.5]
    again = jm.simulate(
        jm.BlastDisk(cells=4, pad=8),
        jm.CPDI(),
        dt=1e-5,
        steps=4,
        viscosity=jm.ArtificialViscosity(2, 0.2, 0.5),
    )
    np.testing.assert_array_equal(np.asarray(sol.state.x), np.asarray(again.state.x))
    assert main([*argv, "--viscosity", "2,0.2,0.5,1"]) == 2
    assert "QUAD,LIN,SHEAR" in capsys.readouterr().err
