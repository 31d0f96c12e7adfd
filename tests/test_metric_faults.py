"""The metrics and the VTK writers under faults: the state of a run that broke down is measured only
when asked, a scene that is not one is named, and files already there are replaced only when asked."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raw

import jaxmpm as jm
from jaxmpm.cli import main

DT = 1e-5


@pytest.fixture(scope="module")
def runs():
    scene = jm.GasExpansion(cells=2, ppc=1)
    broken = jm.simulate(scene, jm.MPQ(), dt=1e-3, steps=3, throw=False)  # dt beyond the stable limit
    ok = jm.simulate(scene, jm.MPQ(), dt=DT, steps=2)
    assert broken.failure() is not None and int(broken.state.step) == 0 and ok.failure() is None
    return scene, broken, ok


def test_diagnostics_separation_and_density_refuse_a_run_that_broke_down(runs):
    scene, broken, ok = runs
    st, body = broken.state, broken.body
    calls = {
        "diagnostics": lambda **kw: jm.diagnostics(scene, st, body, **kw),
        "separation": lambda **kw: jm.separation(st, body, **kw),
        "density": lambda **kw: jm.density(st, body, **kw),
    }
    for name, call in calls.items():
        with pytest.raises(
            ValueError,
            match=rf"{name}\(\) measures a finished run, and this state is of a run that broke down at "
            r"step 1 \(time step beyond the stable limit.*the last good one, at step 0 \(t = 0\).*"
            r"Pass allow_broken=True",
        ):
            call()
    # Asked for, the last good state (the initial one) is measured.
    d = jm.diagnostics(scene, st, body, allow_broken=True)
    assert float(d["mass"]) == float(jnp.sum(body.m))
    assert float(d["energy_kinetic"]) == pytest.approx(
        0.5 * float(jnp.sum(body.m * st.v[:, 0] ** 2)), rel=1e-14
    )
    np.testing.assert_array_equal(jm.separation(st, body, allow_broken=True), np.zeros(body.n - 1))
    np.testing.assert_array_equal(
        jm.density(st, body, allow_broken=True), np.asarray(body.m / (body.V0 * st.F[:, 0, 0]))
    )
    # A healthy run is measured as before.
    np.testing.assert_array_equal(
        jm.density(ok.state, ok.body), np.asarray(ok.body.m / (ok.body.V0 * ok.state.F[:, 0, 0]))
    )
    assert float(jm.diagnostics(scene, ok.state, ok.body)["energy_kinetic"]) > 0.0
    assert jm.separation(ok.state, ok.body).shape == (ok.body.n - 1,)


def test_a_traced_status_is_passed_through(runs):
    """Under jit the status cannot be read: it is checked beside the measures, as for errors."""
    scene, broken, _ = runs
    st, body = broken.state, broken.body
    rho = jax.jit(jm.density)(st, body)
    np.testing.assert_array_equal(rho, jm.density(st, body, allow_broken=True))
    sep = jax.jit(jm.separation)(st, body)
    np.testing.assert_array_equal(sep, jm.separation(st, body, allow_broken=True))
    mass = eqx.filter_jit(lambda s: jm.diagnostics(scene, s, body)["mass"])(st)
    assert float(mass) == float(jnp.sum(body.m))


def test_allow_broken_is_a_bool(runs):
    scene, broken, _ = runs
    with pytest.raises(ValueError, match="allow_broken must be True or False, got 'yes'"):
        raw(jm.diagnostics)(scene, broken.state, broken.body, allow_broken="yes")
    with pytest.raises(ValueError, match="allow_broken must be True or False, got 1"):
        raw(jm.density)(broken.state, broken.body, allow_broken=1)


def test_euler_errors_of_a_broken_run_measure_its_density_when_asked():
    """``euler_errors(..., allow_broken=True)`` measures the density too (it calls ``density``)."""
    scene = jm.ShockTube(cells=4)
    ok = jm.simulate(scene, jm.SPQ(), dt=1e-4, steps=2, viscosity=jm.ArtificialViscosity())
    broken = eqx.tree_at(
        lambda s: (s.status, s.fail_step), ok.state, (jnp.full_like(ok.state.status, 8), ok.state.step + 1)
    )
    with pytest.raises(ValueError, match=r"euler_errors\(\) measures a finished run.*broke down at step 3"):
        jm.euler_errors(scene, broken, ok.body)
    err = jm.euler_errors(scene, broken, ok.body, allow_broken=True)
    assert err == jm.euler_errors(scene, ok.state, ok.body)


def test_a_broken_run_of_regions_is_reported_with_its_breakdown(capsys):
    """The command line's report of a broken run measures its last good state and says it broke down."""
    argv = ["run", "shock-tube", "cells=4", "--interpolator", "spq", "--dt", "1e-2", "--steps", "3", "--json"]
    assert main(argv) == 3
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["status"] != 0 and out["failure"]["step"] == 1
    assert len(out["particles"]["rho"]) == 8 and out["diagnostics"]["mass"] > 0
    assert "broke down at step 1" in captured.err


SCENE_CALLS = {
    "errors": lambda f, s, sol: f(s, sol.state, sol.body),
    "pressure_error": lambda f, s, sol: f(s, sol.state, sol.body),
    "euler_errors": lambda f, s, sol: f(s, sol.state, sol.body),
    "diagnostics": lambda f, s, sol: f(s, sol.state, sol.body),
    "exact_fields": lambda f, s, sol: f(s, sol.body, sol.state.t),
    "smooth_mask": lambda f, s, sol: f(s, sol.body, sol.state.t),
    "available_errors": lambda f, s, sol: f(s),
}


@pytest.mark.parametrize("name", list(SCENE_CALLS))
@pytest.mark.parametrize("scene, shown", [(None, "None"), ("gas-expansion", "'gas-expansion'")])
def test_a_scene_that_is_not_one_is_named(runs, name, scene, shown):
    _, _, ok = runs
    fn, call = getattr(jm.metrics, name), SCENE_CALLS[name]
    # under the suite's runtime type checks a TypeError naming scene may come first
    with pytest.raises((ValueError, TypeError), match="scene"):
        call(fn, scene, ok)
    # as a user runs it
    with pytest.raises(
        ValueError,
        match=rf"scene must be a jaxmpm scene \(an AbstractScene, such as jm.GasExpansion\(\)\), got {shown}",
    ):
        call(raw(fn), scene, ok)


def test_write_particles_and_write_grid_keep_a_file_already_there(tmp_path):
    mine = tmp_path / "p.vtk"
    mine.write_text("MINE")
    x = np.zeros((2, 1))
    with pytest.raises(FileExistsError, match=rf"{mine} already exists: pass overwrite=True to replace it"):
        jm.vtk.write_particles(mine, x)
    assert mine.read_text() == "MINE"
    assert jm.vtk.write_particles(mine, x, overwrite=True) == mine
    assert mine.read_bytes().startswith(b"# vtk DataFile")
    grid = jm.GasExpansion(cells=2).grid()
    fields = {"mass": np.zeros(grid.n_nodes)}
    theirs = tmp_path / "g.vtk"
    theirs.write_text("MINE")
    with pytest.raises(FileExistsError, match=rf"{theirs} already exists: pass overwrite=True"):
        jm.vtk.write_grid(theirs, grid, fields)
    assert theirs.read_text() == "MINE"
    jm.vtk.write_grid(theirs, grid, fields, overwrite=True)
    assert theirs.read_bytes().startswith(b"# vtk DataFile")
    new = jm.vtk.write_grid(tmp_path / "new.vtk", grid, fields)  # a new file needs nothing
    assert new.read_bytes().startswith(b"# vtk DataFile")
    with pytest.raises(ValueError, match="overwrite must be True or False, got 'yes'"):
        raw(jm.vtk.write_particles)(tmp_path / "q.vtk", x, overwrite="yes")
    assert not (tmp_path / "q.vtk").exists()


def test_write_series_keeps_the_files_already_there(tmp_path):
    scene = jm.GasExpansion(cells=2, ppc=1)
    sol = jm.simulate(
        scene, jm.SPQ(), dt=DT, steps=2, saveat=jm.SaveAt(every=1, fields=("x", "v", "F", "sigma"))
    )
    model = jm.Model(scene, jm.SPQ(), jm.FLIP())
    frames = tmp_path / "frames"
    paths = jm.vtk.write_series(frames, model, sol)
    written = {p.name: p.read_bytes() for p in paths}
    with pytest.raises(
        FileExistsError, match=rf"{frames / 'particles_00000.vtk'} already exists: pass overwrite=True"
    ):
        jm.vtk.write_series(frames, model, sol)
    assert {p.name: p.read_bytes() for p in frames.iterdir()} == written
    # one file of the series already there: refused before anything is written
    other = tmp_path / "other"
    other.mkdir()
    (other / "grid.pvd").write_text("MINE")
    with pytest.raises(FileExistsError, match=rf"{other / 'grid.pvd'} already exists"):
        jm.vtk.write_series(other, model, sol)
    assert [p.name for p in other.iterdir()] == ["grid.pvd"] and (other / "grid.pvd").read_text() == "MINE"
    again = jm.vtk.write_series(frames, model, sol, overwrite=True)
    assert [p.name for p in again] == [p.name for p in paths]
    assert {p.name: p.read_bytes() for p in frames.iterdir()} == written


def test_a_state_that_is_not_finite_has_no_zero_error(runs):
    """A NaN in a state the status calls healthy (written there by hand, or by a manufactured solution
    that is not finite) gives NaN errors, never 0: a zero error would read as an exact result."""
    scene, _, ok = runs
    nan_F = eqx.tree_at(lambda s: s.F, ok.state, ok.state.F.at[0].set(jnp.nan))
    err = jm.errors(scene, nan_F, ok.body)
    for key in ("F_max_rel", "F_rms_rel"):
        assert np.isnan(float(err[key])), (key, err[key])
    assert np.isnan(np.asarray(jm.separation(nan_F, ok.body))).any()
    assert float(jm.errors(scene, ok.state, ok.body)["F_max_rel"]) >= 0.0  # finite where the state is
    # the derivative of an error that is exactly 0 stays 0 (no NaN from sqrt at 0)
    start = jm.simulate(scene, jm.MPQ(), dt=DT, steps=0)
    assert (
        float(
            jax.grad(
                lambda F: jm.errors(scene, eqx.tree_at(lambda s: s.F, start.state, F), start.body)[
                    "F_rms_rel"
                ]
            )(start.state.F).sum()
        )
        == 0.0
    )


def test_exact_fields_refuse_a_time_that_is_not_one(runs):
    """A NaN time gave NaN fields, a negative one an F of -199; both are refused by name."""
    scene, _, ok = runs
    for t, match in (
        (float("nan"), "t must be finite, got nan"),
        (-1.0, r"t must be >= 0, got -1.0"),
        ([0.0, 1.0], r"t must be one number"),
    ):
        with pytest.raises(ValueError, match=match):
            raw(jm.metrics.exact_fields)(scene, ok.body, t)
    assert jm.metrics.exact_fields(scene, ok.body, DT)["F"].shape == ok.state.F.shape


def test_the_slab_references_f_is_read_inside_the_slab_only():
    ref = jm.reference.gas_slab(jm.GasSlab(cells=8, h=1 / 8, pad=24), [0.0, 1e-3], cells=8)
    assert ref.F_at(np.array([0.0, 0.5, 1.0])).shape == (2, 3)
    with pytest.raises(ValueError, match=r"X must lie in the slab, 0 <= X <= 1, got values from 5 to 5"):
        raw(type(ref).F_at)(ref, 5.0)
    with pytest.raises(ValueError, match="X must be finite, got nan"):
        raw(type(ref).F_at)(ref, float("nan"))
