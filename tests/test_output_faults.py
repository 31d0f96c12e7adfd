"""The writers of ParaView files and figures under faults: a ParaView series is written only for the
model of its own run, and a run that broke down only when asked (marked so); figures keep a file
already there and are written whole; bad positions, grids, fields and folders are refused by name
before anything is written."""

import inspect
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import plotting
from jaxmpm.cli import main

DT = 1e-5


def raw(fn):
    """``fn`` without the suite's runtime type checks of its annotations (what a user runs)."""
    return inspect.unwrap(fn)


def _files(folder):
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


# ---------------------------------------------------------------- write_series: the model and the run

SCENE = jm.GasExpansion(cells=4, ppc=1, pad=2)
SAVE = jm.SaveAt(every=2)


@pytest.fixture(scope="module")
def cpdi_run():
    return jm.simulate(SCENE, jm.CPDI(), dt=DT, steps=4, saveat=SAVE)


@pytest.mark.parametrize(
    "scene, message",
    [
        (jm.GasExpansion(cells=4, ppc=1, pad=2, beta=-1e4), "its initial v differs from the solution's"),
        (jm.GasExpansion(cells=4, ppc=1, pad=2, P0=9e9), "its initial sigma differs from the solution's"),
        (jm.GasExpansion(cells=4, ppc=1, pad=2, rho0=3.0), "the body it seeds differs in m"),
        (jm.GasExpansion(cells=4, ppc=1, pad=2, h=0.5), "the body it seeds differs in X"),
    ],
    ids=["beta", "P0", "rho0", "h"],
)
def test_write_series_refuses_a_model_with_other_scene_parameters(tmp_path, cpdi_run, scene, message):
    with pytest.raises(ValueError, match=f"the model is not the solution's run: {message}"):
        jm.vtk.write_series(tmp_path / "frames", jm.Model(scene, jm.CPDI(), jm.FLIP()), cpdi_run)
    assert not (tmp_path / "frames").exists()


def test_write_series_refuses_a_model_that_carries_other_state(tmp_path, cpdi_run):
    mpq = jm.Model(SCENE, jm.MPQ(), jm.FLIP())
    with pytest.raises(
        ValueError,
        match="the model is not the solution's run: its interpolator MPQ carries corners, and the "
        "solution's run did not",
    ):
        jm.vtk.write_series(tmp_path / "frames", mpq, cpdi_run)
    apic = jm.Model(SCENE, jm.CPDI(), jm.APIC())
    with pytest.raises(
        ValueError,
        match="the model is not the solution's run: its transfer APIC carries C, and the solution's run "
        "did not",
    ):
        jm.vtk.write_series(tmp_path / "frames", apic, cpdi_run)
    sol = jm.simulate(
        SCENE, jm.MPQ(), dt=DT, steps=2, saveat=jm.SaveAt(every=1, fields=("x", "v", "F", "sigma", "corners"))
    )
    with pytest.raises(
        ValueError, match="its interpolator CPDI does not carry corners, and the solution's run did"
    ):
        jm.vtk.write_series(tmp_path / "frames", jm.Model(SCENE, jm.CPDI(), jm.FLIP()), sol)
    assert not (tmp_path / "frames").exists()
    # the model of the run itself is written
    paths = jm.vtk.write_series(tmp_path / "frames", jm.Model(SCENE, jm.CPDI(), jm.FLIP()), cpdi_run)
    assert _files(tmp_path / "frames") == sorted(p.name for p in paths)


@pytest.fixture(scope="module")
def broken_run():
    sol = jm.simulate(SCENE, jm.SPQ(), dt=2e-4, steps=20, throw=False, saveat=SAVE)
    assert sol.failure() is not None
    return sol


def test_write_series_refuses_a_broken_run_unless_allow_broken(tmp_path, broken_run):
    model = jm.Model(SCENE, jm.SPQ(), jm.FLIP())
    failure = broken_run.failure()
    step, quantities = failure["step"], " and ".join(failure["quantities"])
    with pytest.raises(
        ValueError,
        match=rf"write_series writes a finished run, and this one broke down at step {step} "
        rf"\({re.escape(quantities)}\): its state is the last good one, at step {int(broken_run.state.step)} "
        r".*Pass allow_broken=True",
    ):
        jm.vtk.write_series(tmp_path / "frames", model, broken_run)
    assert not (tmp_path / "frames").exists()
    with pytest.raises(ValueError, match="allow_broken must be True or False, got 'yes'"):
        raw(jm.vtk.write_series)(tmp_path / "frames", model, broken_run, allow_broken="yes")
    assert not (tmp_path / "frames").exists()


def test_a_broken_run_written_with_allow_broken_is_marked_in_the_collections(tmp_path, broken_run):
    model = jm.Model(SCENE, jm.SPQ(), jm.FLIP())
    failure = broken_run.failure()
    paths = jm.vtk.write_series(tmp_path, model, broken_run, allow_broken=True)
    frames = (len(paths) - 2) // 2
    last_good = int(broken_run.state.step)
    assert last_good % 2 == 1  # so the last good state falls between saves: the extra frame
    assert frames == last_good // 2 + 2  # the saves up to it, then the last good state
    last = (tmp_path / f"particles_{frames - 1:05d}.vtk").read_bytes()
    assert jm.vtk._pad_vectors(np.asarray(broken_run.state.x)).astype(">f8").tobytes() in last
    for kind in ("particles", "grid"):
        text = (tmp_path / f"{kind}.pvd").read_text()
        comment = re.search(r"<!-- (.*) -->", text).group(1)
        assert comment.startswith(
            f"jaxmpm: the run broke down at step {failure['step']} ({' and '.join(failure['quantities'])}; "
            f"first at particle {failure['particle']}): the last frame is its last good state, step "
            f"{int(broken_run.state.step)}, t = {float(broken_run.state.t)!r}"
        )
        sets = ET.fromstring(text).find("Collection").findall("DataSet")  # still valid XML
        assert [d.get("file") for d in sets] == [f"{kind}_{i:05d}.vtk" for i in range(frames)]


def test_a_breakdown_of_the_run_itself_names_no_particle(tmp_path):
    """A run that ran out of steps (max_steps) failed as a whole: the collection says so, not
    "particle -1"."""
    scene = jm.ShockTube(cells=21, ppc=1)
    sol = jm.simulate(
        scene,
        jm.SPQ(),
        t_end=0.2,
        max_steps=40,
        throw=False,
        saveat=jm.SaveAt(every=10, fields=("x", "v", "F", "sigma", "e")),
    )
    assert sol.failure()["particle"] == -1
    jm.vtk.write_series(tmp_path, jm.Model(scene, jm.SPQ(), jm.FLIP()), sol, allow_broken=True)
    comment = re.search(r"<!-- (.*) -->", (tmp_path / "particles.pvd").read_text()).group(1)
    assert (
        "(max_steps steps were taken before t_end was reached (raise max_steps); the run itself)" in comment
    )
    assert "particle" not in comment


def test_a_finished_run_has_no_breakdown_mark(tmp_path, cpdi_run):
    jm.vtk.write_series(tmp_path, jm.Model(SCENE, jm.CPDI(), jm.FLIP()), cpdi_run, allow_broken=True)
    for kind in ("particles", "grid"):
        text = (tmp_path / f"{kind}.pvd").read_text()
        assert "<!--" not in text
        assert text.startswith('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n')


def test_the_cli_writes_a_broken_runs_good_frames_marked(tmp_path, capsys):
    out = tmp_path / "vtk"
    argv = ["run", "gas-expansion", "cells=4", "ppc=1", "pad=2", "--interpolator", "spq", "--dt", "2e-4"]
    assert main([*argv, "--steps", "20", "--vtk", str(out), "--vtk-every", "2"]) == 3
    assert "step" in capsys.readouterr().err  # the CLI reports the breakdown itself
    assert len(list(out.glob("particles_*.vtk"))) >= 1
    assert "<!-- jaxmpm: the run broke down at step" in (out / "particles.pvd").read_text()
    assert "<!-- jaxmpm: the run broke down at step" in (out / "grid.pvd").read_text()


# ---------------------------------------------------------------- figures

ONE_PANEL = {("r", "c"): [("l", np.arange(3.0), np.arange(3.0), {})]}
ONE_SERIES = {"a": [("x", np.arange(3.0), np.arange(1.0, 4.0))]}


def _draw(fn, path, **kwargs):
    data = ONE_PANEL if inspect.unwrap(fn) is inspect.unwrap(plotting.profile_grid) else ONE_SERIES
    return fn(data, ylabel="y", title="t", path=path, **kwargs)


@pytest.mark.parametrize(
    "fn", [plotting.profile_grid, plotting.time_series], ids=["profile_grid", "time_series"]
)
def test_figures_keep_a_file_already_there_unless_overwrite(tmp_path, fn):
    mine = tmp_path / "mine.png"
    mine.write_text("the user's own file\n")
    with pytest.raises(FileExistsError, match=rf"{mine} already exists: pass overwrite=True to replace it"):
        _draw(fn, mine)
    assert mine.read_text() == "the user's own file\n" and _files(tmp_path) == ["mine.png"]
    assert _draw(fn, mine, overwrite=True) == mine
    assert mine.read_bytes().startswith(b"\x89PNG\r\n\x1a\n") and _files(tmp_path) == ["mine.png"]
    with pytest.raises(ValueError, match="overwrite must be True or False, got 'yes'"):
        _draw(raw(fn), tmp_path / "new.png", overwrite="yes")
    assert _files(tmp_path) == ["mine.png"]


@pytest.mark.parametrize(
    "fn", [plotting.profile_grid, plotting.time_series], ids=["profile_grid", "time_series"]
)
def test_figures_write_the_format_of_the_suffix(tmp_path, fn):
    assert _draw(fn, tmp_path / "f.PDF").read_bytes().startswith(b"%PDF")
    assert _draw(fn, tmp_path / "f.svg").read_text().lstrip().startswith("<?xml")
    # without a suffix, as Figure.savefig does: PNG, and .png appended
    assert _draw(fn, str(tmp_path / "plain")) == tmp_path / "plain.png"
    assert (tmp_path / "plain.png").read_bytes().startswith(b"\x89PNG")
    assert _files(tmp_path) == ["f.PDF", "f.svg", "plain.png"]  # no temporary file left


@pytest.mark.parametrize(
    "fn", [plotting.profile_grid, plotting.time_series], ids=["profile_grid", "time_series"]
)
def test_figures_refuse_a_bad_path_before_drawing(tmp_path, fn):
    with pytest.raises(
        ValueError, match=r"path must end in a figure format matplotlib writes \(.*png.*\), got "
    ):
        _draw(fn, tmp_path / "notes.txt")
    with pytest.raises(
        FileNotFoundError, match=rf"No such folder to write f.png in: '{tmp_path / 'nope'}'"
    ) as e:
        _draw(fn, tmp_path / "nope" / "f.png")
    assert ".tmp" not in str(e.value)
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(ValueError, match=rf"path {tmp_path / 'dir.png'} is a folder, not a file"):
        _draw(fn, tmp_path / "dir.png", overwrite=True)
    with pytest.raises(ValueError, match="path must be a file name"):
        _draw(raw(fn), None)
    assert _files(tmp_path) == ["dir.png"]


def test_figures_refuse_empty_input_by_name(tmp_path):
    with pytest.raises(ValueError, match=r"panels must be a non-empty dict \{\(row_label, col_label\)"):
        plotting.profile_grid({}, ylabel="y", title="t", path=tmp_path / "e.png")
    with pytest.raises(ValueError, match=r"series must be a non-empty dict \{panel"):
        plotting.time_series({}, ylabel="y", title="t", path=tmp_path / "e.png")
    assert _files(tmp_path) == []


# ---------------------------------------------------------------- write_particles and write_grid

GRID_2D = jm.GasExpansion(cells=2, ppc=1, pad=1, dim=2).grid()  # 5 x 5 nodes
SHAPE = r"x must be the positions, an array of shape \(n, dim\) with dim 1, 2 or 3, got "


@pytest.mark.parametrize(
    "x, message",
    [
        (np.zeros(5), SHAPE + r"shape \(5,\)"),
        (None, SHAPE + "None"),
        (np.zeros((5, 4)), SHAPE + r"shape \(5, 4\)"),
        ([["a"]], SHAPE + r"\[\['a'\]\]"),
    ],
    ids=["flat", "None", "4 components", "strings"],
)
def test_write_particles_refuses_positions_of_the_wrong_shape(tmp_path, x, message):
    with pytest.raises(ValueError, match=message):
        raw(jm.vtk.write_particles)(tmp_path / "p.vtk", x)
    with pytest.raises((ValueError, TypeError), match="x"):
        jm.vtk.write_particles(tmp_path / "p.vtk", x)
    assert _files(tmp_path) == []


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"my field": np.zeros(2)}, r"fields: the name 'my field' cannot be written in legacy VTK"),
        ({"tab\tname": np.zeros(2)}, r"fields: the name 'tab\\tname' cannot be written in legacy VTK"),
        ({"a%20b": np.zeros(2)}, r"fields: the name 'a%20b' cannot be written in legacy VTK"),
        ({"": np.zeros(2)}, r"fields: the name '' cannot be written in legacy VTK"),
        ({3: np.zeros(2)}, r"fields: the name 3 cannot be written in legacy VTK"),
        ({"a": None}, r"field 'a' must be an array of real numbers, got None"),
        ({"a": np.zeros(3)}, r"field 'a' has 3 values, expected one for each of the 2 particles"),
        ({"a": 1.0}, r"field 'a' is one number, expected one value for each of the 2 particles"),
        ({"a": np.zeros((2, 2))}, r"field 'a': shape \(2, 2\) is not \(n,\), \(n, 3\) or \(n, 9\)"),
        (["a"], r"fields must be a dict of names to arrays, got \['a'\]"),
    ],
    ids=["space", "tab", "percent", "empty", "int", "None", "length", "scalar", "shape", "list"],
)
def test_write_particles_refuses_fields_legacy_vtk_cannot_hold(tmp_path, fields, message):
    with pytest.raises(ValueError, match=message):
        raw(jm.vtk.write_particles)(tmp_path / "p.vtk", np.zeros((2, 1)), fields)
    assert _files(tmp_path) == []


def test_a_field_name_says_what_is_allowed(tmp_path):
    with pytest.raises(
        ValueError,
        match=r"a name is one word of printable ASCII \(letters, digits, punctuation other than '%'\)",
    ):
        jm.vtk.write_particles(tmp_path / "p.vtk", np.zeros((2, 1)), {"my field": np.zeros(2)})


def test_write_grid_refuses_a_bad_grid_or_fields(tmp_path):
    ok = {"m": np.zeros(GRID_2D.n_nodes)}
    with pytest.raises(ValueError, match="field 'm' has 3 values, expected one for each of the 25 nodes"):
        jm.vtk.write_grid(tmp_path / "g.vtk", GRID_2D, {"m": np.zeros(3)})
    with pytest.raises(
        ValueError, match=r"grid must be a jm.Grid of 1, 2 or 3 dimensions \(scene.grid\(\)\), got None"
    ):
        raw(jm.vtk.write_grid)(tmp_path / "g.vtk", None, ok)
    with pytest.raises(ValueError, match="fields must be a dict of names to arrays, got None"):
        raw(jm.vtk.write_grid)(tmp_path / "g.vtk", GRID_2D, None)
    with pytest.raises((ValueError, TypeError), match="fields"):
        jm.vtk.write_grid(tmp_path / "g.vtk", GRID_2D, None)
    with pytest.raises(ValueError, match="fields: the name 'node mass' cannot be written in legacy VTK"):
        jm.vtk.write_grid(tmp_path / "g.vtk", GRID_2D, {"node mass": np.zeros(GRID_2D.n_nodes)})
    assert _files(tmp_path) == []
    assert jm.vtk.write_grid(tmp_path / "g.vtk", GRID_2D, ok) == tmp_path / "g.vtk"


@pytest.mark.parametrize("write", ["particles", "grid"])
def test_vtk_writers_name_the_folder_they_cannot_write_in(tmp_path, write):
    def call(path, **kw):
        if write == "particles":
            return jm.vtk.write_particles(path, np.zeros((2, 1)), **kw)
        return jm.vtk.write_grid(path, GRID_2D, {"m": np.zeros(GRID_2D.n_nodes)}, **kw)

    missing = tmp_path / "no_such_dir"
    with pytest.raises(FileNotFoundError, match=rf"No such folder to write p.vtk in: '{missing}'") as e:
        call(missing / "p.vtk")
    assert ".tmp" not in str(e.value)
    a_file = tmp_path / "a_file"
    a_file.write_text("MINE")
    with pytest.raises(NotADirectoryError, match=rf"Not a folder, cannot write p.vtk in it: '{a_file}'"):
        call(a_file / "p.vtk")
    with pytest.raises(ValueError, match=rf"path {tmp_path} is a folder, not a file"):
        call(tmp_path, overwrite=True)
    with pytest.raises(ValueError, match=r"path must be a file name \(a str or os.PathLike\), got None"):
        if write == "particles":
            raw(jm.vtk.write_particles)(None, np.zeros((2, 1)))
        else:
            raw(jm.vtk.write_grid)(None, GRID_2D, {})
    assert _files(tmp_path) == ["a_file"] and a_file.read_text() == "MINE"


def test_valid_files_are_unchanged(tmp_path):
    """A valid call writes exactly the bytes it wrote before the checks were added."""
    p = jm.vtk.write_particles(tmp_path / "p.vtk", np.array([[0.5], [1.5]]), {"a": np.array([1.0, 2.0])})
    expected = (
        b"# vtk DataFile Version 3.0\njaxmpm particles\nBINARY\nDATASET UNSTRUCTURED_GRID\n"
        b"POINTS 2 double\n"
        + np.array([[0.5, 0, 0], [1.5, 0, 0]], dtype=">f8").tobytes()
        + b"\nCELLS 2 4\n"
        + np.array([[1, 0], [1, 1]], dtype=">i4").tobytes()
        + b"\nCELL_TYPES 2\n"
        + np.ones(2, dtype=">i4").tobytes()
        + b"\nPOINT_DATA 2\nSCALARS a double 1\nLOOKUP_TABLE default\n"
        + np.array([1.0, 2.0], dtype=">f8").tobytes()
        + b"\n"
    )
    assert p.read_bytes() == expected


@pytest.mark.slow
def test_a_study_rerun_replaces_its_own_figures(tmp_path, capsys):
    """The talk's study draws with ``jaxmpm.plotting``: run again into its own folder, it replaces
    the figures it wrote (the folder is its own: ``.jaxmpm-study`` names it)."""
    (tmp_path / ".jaxmpm-study").write_text("talk\n")
    old = tmp_path / "separation.png"
    old.write_bytes(b"the previous run's figure")
    assert main(["study", "talk", "--out", str(tmp_path), "--small"]) == 0
    assert old.read_bytes().startswith(b"\x89PNG") and (tmp_path / "F_t0.0001.png").exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_a_folder_under_a_frames_name_is_refused_before_the_run(tmp_path, capsys):
    """--vtk with --overwrite where a frame's name is a folder: refused before the run, one line (it
    was a traceback after the run, and a run that broke down lost its breakdown message)."""
    out = tmp_path / "vtk"
    out.mkdir()
    (out / "particles_00002.vtk").mkdir()
    argv = ["run", "gas-expansion", "cells=4", "ppc=1", "pad=2", "--interpolator", "spq", "--dt", "1e-5"]
    assert main([*argv, "--steps", "4", "--vtk", str(out), "--vtk-every", "2", "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith(f"jaxmpm: error: --vtk {out}: particles_00002.vtk is a folder")
        and "Traceback" not in err
    )
    assert _files(out) == ["particles_00002.vtk"]


def test_a_folder_under_a_study_files_name_is_refused_before_the_study(tmp_path, capsys):
    (tmp_path / ".jaxmpm-study").write_text("talk\n")
    (tmp_path / "results.csv").mkdir()
    assert main(["study", "talk", "--out", str(tmp_path), "--small"]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith(f"jaxmpm: error: --out {tmp_path}: results.csv is a folder") and "Traceback" not in err
    )
    assert _files(tmp_path) == [".jaxmpm-study", "results.csv"]


def test_a_whole_write_onto_a_folder_leaves_no_temporary_file(tmp_path):
    """``write_whole`` whose rename fails (a folder at the path) removes its temporary file and names
    the path, not the temporary file."""
    from jaxmpm._files import write_whole

    (tmp_path / "a.csv").mkdir()
    with pytest.raises(OSError) as info:
        write_whole(tmp_path / "a.csv", lambda f: f.write(b"x"))
    assert info.value.filename == str(tmp_path / "a.csv")
    assert _files(tmp_path) == ["a.csv"]
