"""ParaView output (written for every dimension): the files hold
exactly the run's values, the grid fields are the step's own particle-to-grid transfer, and a run
that breaks down still leaves its good frames."""

import errno
import inspect
import os
import pathlib
import re

import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm.cli import main


def read_legacy(path):
    """A small reader of the legacy binary VTK files jaxmpm writes: header keywords and arrays."""
    data = path.read_bytes()
    out, pos = {"fields": {}}, 0

    def line():
        nonlocal pos
        end = data.index(b"\n", pos)
        text = data[pos:end].decode()
        pos = end + 1
        return text

    def array(count, dtype):
        nonlocal pos
        a = np.frombuffer(data, dtype=dtype, count=count, offset=pos)
        pos += a.nbytes + 1  # and the newline after it
        return a

    assert line().startswith("# vtk DataFile")
    out["title"], out["format"], out["dataset"] = line(), line(), line().split()[1]
    n_point = None
    while pos < len(data):
        words = line().split()
        if not words:
            continue
        key = words[0]
        if key == "POINTS":
            n = int(words[1])
            out["points"] = array(3 * n, ">f8").reshape(n, 3)
        elif key == "CELLS":
            out["cells"] = array(int(words[2]), ">i4").reshape(int(words[1]), -1)
        elif key == "CELL_TYPES":
            out["cell_types"] = array(int(words[1]), ">i4")
        elif key in ("DIMENSIONS", "ORIGIN", "SPACING"):
            out[key.lower()] = [float(w) for w in words[1:]]
        elif key == "POINT_DATA":
            n_point = int(words[1])
        elif key == "SCALARS":
            assert line() == "LOOKUP_TABLE default"
            out["fields"][words[1]] = array(n_point, ">f8")
        elif key == "VECTORS":
            out["fields"][words[1]] = array(3 * n_point, ">f8").reshape(n_point, 3)
        elif key == "TENSORS":
            out["fields"][words[1]] = array(9 * n_point, ">f8").reshape(n_point, 3, 3)
        else:
            raise AssertionError(f"unexpected section {key}")
    return out


def test_particle_file_holds_the_values_exactly(tmp_path):
    x = np.array([[0.1], [0.3], [0.7]])
    F = np.array([[[1.5]], [[0.5]], [[2.0]]])
    path = jm.vtk.write_particles(tmp_path / "p.vtk", x, {"J": F[:, 0, 0], "F": jm.vtk._pad_tensors(F, True)})
    got = read_legacy(path)
    assert got["format"] == "BINARY" and got["dataset"] == "UNSTRUCTURED_GRID"
    np.testing.assert_array_equal(got["points"][:, 0], x[:, 0])
    np.testing.assert_array_equal(got["points"][:, 1:], 0.0)
    np.testing.assert_array_equal(got["cells"], [[1, 0], [1, 1], [1, 2]])
    np.testing.assert_array_equal(got["cell_types"], [1, 1, 1])
    np.testing.assert_array_equal(got["fields"]["J"], F[:, 0, 0])
    expected = np.tile(np.eye(3), (3, 1, 1))
    expected[:, 0, 0] = F[:, 0, 0]
    np.testing.assert_array_equal(got["fields"]["F"], expected)
    with pytest.raises(ValueError, match="'bad'"):
        jm.vtk.write_particles(tmp_path / "q.vtk", x, {"bad": np.zeros((3, 2))})


def test_series_matches_the_run_and_the_step_transfer(tmp_path):
    scene = jm.GasExpansion(cells=4, pad=6)
    saveat = jm.SaveAt(every=5, fields=("x", "v", "F", "sigma", "corners"))
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-5, steps=20, artificial_cells=1, saveat=saveat)
    model = jm.Model(scene, jm.MPQ(), jm.FLIP(), artificial_cells=1)
    paths = jm.vtk.write_series(tmp_path, model, sol)
    assert len(paths) == 2 * 5 + 2
    pvd = (tmp_path / "particles.pvd").read_text()
    times = [float(t) for t in re.findall(r'timestep="([^"]+)"', pvd)]
    np.testing.assert_allclose(times, np.asarray(sol.ts), rtol=0, atol=0)
    last = read_legacy(tmp_path / "particles_00004.vtk")
    np.testing.assert_array_equal(last["points"][:, 0], np.asarray(sol.state.x[:, 0]))
    np.testing.assert_array_equal(last["fields"]["F"][:, 0, 0], np.asarray(sol.state.F[:, 0, 0]))
    np.testing.assert_array_equal(last["fields"]["sigma"][:, 0, 0], np.asarray(sol.state.sigma[:, 0, 0]))
    np.testing.assert_array_equal(last["fields"]["X"][:, 0], np.asarray(sol.body.X[:, 0]))
    grid = read_legacy(tmp_path / "grid_00004.vtk")
    g = scene.grid()
    assert grid["dataset"] == "STRUCTURED_POINTS" and grid["dimensions"] == [g.n_nodes, 1, 1]
    assert grid["origin"][0] == float(g.x_min[0]) and grid["spacing"][0] == float(g.h)
    mass, vel = grid["fields"]["mass"], grid["fields"]["velocity"][:, 0]
    m = np.asarray(sol.body.m)
    assert mass.sum() == pytest.approx(m.sum(), rel=1e-14)  # partition of unity: all of the body
    # the nodal velocity is sum(phi m v) / sum(phi m) with MPQ's centre weights (linear hats)
    s = (np.asarray(sol.state.x[:, 0]) - float(g.x_min[0])) / float(g.h)
    base = np.floor(s).astype(int)
    w1 = s - base
    mom = np.zeros(g.n_nodes)
    mas = np.zeros(g.n_nodes)
    v = np.asarray(sol.state.v[:, 0])
    for k, w in ((0, 1 - w1), (1, w1)):
        np.add.at(mas, base + k, w * m)
        np.add.at(mom, base + k, w * m * v)
    np.testing.assert_allclose(mass, mas, rtol=1e-14, atol=0)
    on = mas > 0
    np.testing.assert_allclose(vel[on], mom[on] / mas[on], rtol=1e-13)
    np.testing.assert_array_equal(vel[~on], 0.0)


def test_a_broken_run_keeps_its_good_frames(tmp_path):
    scene = jm.VibratingBar(v0=-30.0)
    saveat = jm.SaveAt(every=70, fields=("x", "v", "F", "sigma", "corners"))
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-4, steps=2000, cfl_limit=None, saveat=saveat, throw=False)
    assert int(sol.status) != 0
    model = jm.Model(scene, jm.MPQ(), jm.FLIP(), cfl_limit=None)
    paths = jm.vtk.write_series(tmp_path, model, sol, allow_broken=True)  # its good frames, marked
    frames = (len(paths) - 2) // 2
    last_good = int(sol.state.step)
    assert last_good % 70 != 0  # so the last good state falls between saves: the extra frame
    assert frames == last_good // 70 + 2 < 2000 // 70 + 1
    saved = read_legacy(tmp_path / f"particles_{frames - 2:05d}.vtk")
    F_saved = np.asarray(sol.history["F"][frames - 2][:, 0, 0])
    np.testing.assert_array_equal(saved["fields"]["F"][:, 0, 0], F_saved)
    final = read_legacy(tmp_path / f"particles_{frames - 1:05d}.vtk")
    np.testing.assert_array_equal(final["fields"]["F"][:, 0, 0], np.asarray(sol.state.F[:, 0, 0]))
    assert np.all(np.asarray(sol.state.F) > 0)
    pvd = (tmp_path / "particles.pvd").read_text()
    assert f'timestep="{float(sol.state.t)!r}"' in pvd


def test_a_run_to_an_end_time_writes_each_time_once(tmp_path):
    scene = jm.GasExpansion(cells=4, pad=6)
    saveat = jm.SaveAt(every=10, fields=("x", "v", "F", "sigma"))
    sol = jm.simulate(scene, jm.CPDI(), t_end=2e-4, cfl=0.5, max_steps=400, saveat=saveat)
    assert int(sol.state.step) < 300  # so several saves come after t_end and repeat the final state
    jm.vtk.write_series(tmp_path, jm.Model(scene, jm.CPDI(), jm.FLIP()), sol)
    times = [float(t) for t in re.findall(r'timestep="([^"]+)"', (tmp_path / "grid.pvd").read_text())]
    assert times == sorted(set(times)) and times[0] == 0.0 and times[-1] == float(sol.state.t) == 2e-4
    last = read_legacy(tmp_path / f"particles_{len(times) - 1:05d}.vtk")
    np.testing.assert_array_equal(last["fields"]["F"][:, 0, 0], np.asarray(sol.state.F[:, 0, 0]))


def test_write_series_needs_the_fields(tmp_path):
    scene = jm.GasExpansion(cells=4, pad=6)
    sol = jm.simulate(scene, jm.SPQ(), dt=1e-5, steps=4)
    with pytest.raises(ValueError, match="history"):
        jm.vtk.write_series(tmp_path, jm.Model(scene, jm.SPQ(), jm.FLIP()), sol)
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-5, steps=4, saveat=jm.SaveAt(every=2))
    with pytest.raises(ValueError, match="corners"):
        jm.vtk.write_series(tmp_path, jm.Model(scene, jm.MPQ(), jm.FLIP()), sol)


def test_cli_run_vtk(tmp_path, capsys):
    import json

    out = tmp_path / "vtk"
    argv = ["run", "gas-expansion", "--interpolator", "cpdi", "--dt", "1e-5", "--steps", "20"]
    assert main([*argv, "--vtk", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["vtk"] == {"dir": str(out), "frames": 11, "every": 2}
    assert len(list(out.glob("particles_*.vtk"))) == 11 and (out / "grid.pvd").exists()
    assert main([*argv, "--vtk-every", "3"]) == 2
    assert "--vtk-every needs --vtk" in capsys.readouterr().err
    assert main([*argv, "--vtk", str(out), "--out", str(tmp_path / "r.npz")]) == 2
    assert "--vtk" in capsys.readouterr().err


def test_cli_breakdown_still_writes_frames(tmp_path, capsys):
    out = tmp_path / "vtk"
    argv = ["run", "vibrating-bar", "v0=-30", "--interpolator", "mpq", "--dt", "1e-4", "--steps", "2000"]
    assert main([*argv, "--cfl-limit", "none", "--vtk", str(out), "--vtk-every", "50"]) == 3
    assert "F <= 0" in capsys.readouterr().err
    frames = sorted(out.glob("particles_*.vtk"))
    assert 1 < len(frames) < 41
    F = read_legacy(frames[-1])["fields"]["J"]
    assert np.all(np.isfinite(F)) and np.all(F > 0)
    assert F.shape[0] == read_legacy(frames[0])["points"].shape[0]


def _series(beta: float, steps: int):
    scene = jm.GasExpansion(beta=beta, cells=2, ppc=1)
    saveat = jm.SaveAt(every=1, fields=("x", "v", "F", "sigma"))
    sol = jm.simulate(scene, jm.SPQ(), dt=1e-5, steps=steps, saveat=saveat)
    return jm.Model(scene, jm.SPQ(), jm.FLIP()), sol


def _files(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir()}


@pytest.mark.parametrize("failure", [KeyboardInterrupt, OSError])
def test_overwrite_replaces_a_series_whole_or_not_at_all(tmp_path, monkeypatch, failure):
    """A Ctrl-C or an OSError at any rename of ``write_series(..., overwrite=True)`` (the temporary
    files' and the renames over the series already there) leaves every file of the folder as it was,
    byte for byte, with no temporary file; without one, the new series replaces the old one, and the
    files of other names (frames of an earlier, longer series; the user's) are left as they are."""
    folder = tmp_path / "frames"
    jm.vtk.write_series(folder, *_series(200.0, 2))  # 3 frames
    (folder / "particles_00009.vtk").write_text("frame 9 of an earlier, longer series")
    (folder / "grid_00009.vtk").write_text("its grid")
    (folder / "notes.txt").write_text("mine")
    before = _files(folder)
    model, sol = _series(100.0, 3)  # 4 frames: the fourth under a name not there before
    jm.vtk.write_series(tmp_path / "fresh", model, sol)
    expected = _files(tmp_path / "fresh")

    real = os.replace
    renames, fail_at = [0], [None]

    def replace(src, dst, *args, **kwargs):
        if tmp_path in pathlib.Path(dst).parents:
            renames[0] += 1
            if renames[0] == fail_at[0]:
                raise failure() if failure is KeyboardInterrupt else OSError(errno.EIO, "I/O error")
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace)
    jm.vtk.write_series(tmp_path / "count", model, sol)  # a new folder: only the temporary files' renames
    written = renames[0]
    assert written == 10
    for k in range(1, 3 * written):  # every rename: the temporary files', the old files', the new files'
        renames[0], fail_at[0] = 0, k
        try:
            jm.vtk.write_series(folder, model, sol, overwrite=True)
        except failure:
            pass
        else:
            assert k > renames[0], f"rename {k} of {renames[0]} did not fail"
            break
        assert _files(folder) == before, f"failed at rename {k}"
    else:
        raise AssertionError("every rename failed")
    assert renames[0] == 2 * written + 8  # each file renamed into place, and each old one aside
    after = _files(folder)
    assert after == {**before, **expected}
    assert sorted(set(after) - set(expected)) == ["grid_00009.vtk", "notes.txt", "particles_00009.vtk"]


def test_a_new_series_interrupted_at_any_rename_leaves_nothing(tmp_path, monkeypatch):
    """Into a folder it makes, ``write_series`` interrupted at any rename (the temporary files' or the
    hard links into place) removes every file it wrote and the folder."""
    model, sol = _series(100.0, 3)
    folder = tmp_path / "frames"
    real_replace, real_link = os.replace, os.link
    calls, fail_at = [0], [None]

    def failing(real):
        def rename(src, dst, *args, **kwargs):
            if tmp_path in pathlib.Path(dst).parents:
                calls[0] += 1
                if calls[0] == fail_at[0]:
                    raise KeyboardInterrupt
            return real(src, dst, *args, **kwargs)

        return rename

    monkeypatch.setattr(os, "replace", failing(real_replace))
    monkeypatch.setattr(os, "link", failing(real_link))
    for k in range(1, 21):  # 10 files: each renamed from its temporary file, then linked into place
        calls[0], fail_at[0] = 0, k
        with pytest.raises(KeyboardInterrupt):
            jm.vtk.write_series(folder, model, sol)
        assert not folder.exists() and list(tmp_path.iterdir()) == [], f"interrupted at rename {k}"
    calls[0], fail_at[0] = 0, None
    jm.vtk.write_series(folder, model, sol)
    assert calls[0] == 20 and len(list(folder.iterdir())) == 10


def test_nodal_fields_check_that_the_state_and_setup_are_of_the_model():
    scene = jm.GasExpansion(cells=4)
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-5, steps=2)
    model = jm.Model(scene, jm.MPQ(), jm.FLIP())
    for args, match in (
        ((model, sol.body), r"state must be a State of model"),
        (
            (jm.Model(jm.GasExpansion(cells=6), jm.MPQ(), jm.FLIP()), sol.state),
            "state does not belong to model",
        ),
        ((model, sol.state, "x"), r"setup must be the Setup of model, jm.setup\(model\), got 'x'"),
        ((scene, sol.state), r"model must be a jm.Model\(scene, interpolator, transfer\), got the scene"),
    ):
        with pytest.raises(ValueError, match=match):
            inspect.unwrap(jm.vtk.nodal_fields)(*args)  # without the suite's type checks: what a user runs
    assert float(np.sum(jm.vtk.nodal_fields(model, sol.state)["mass"])) == pytest.approx(
        float(jnp.sum(sol.body.m))
    )
