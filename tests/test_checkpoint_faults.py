"""Saved runs that are damaged, foreign or inconsistent, and files a run must not overwrite.

Every bad file is refused by ``long_run.load`` and ``long_run.resume`` with a ``ValueError`` of one
line naming the file (a missing file stays a ``FileNotFoundError``), and by ``jaxmpm resume`` with
exit status 2 and one ``jaxmpm: error:`` line, never a traceback. A run never replaces a file it was
not told to, and finds an ``out`` it cannot write before it compiles anything.
"""

import errno
import json
import os
import pathlib
import re

import jax
import numpy as np
import pytest
from helpers import float32

import jaxmpm as jm
from jaxmpm import long_run
from jaxmpm.cli import main

SCENE = jm.GasExpansion(cells=4, beta=300.0)
KW = dict(dt=1e-5, steps=20, chunk=10, artificial_cells=1, progress=False)
SAVEAT = jm.SaveAt(every=5, fields=("x", "F"))


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> pathlib.Path:
    """A complete saved run (MPQ, APIC, with a history): every bad file below is made from it."""
    path = tmp_path_factory.mktemp("good") / "good.npz"
    long_run.run(SCENE, jm.MPQ(), transfer=jm.APIC(), saveat=SAVEAT, out=path, **KW)
    return path


def arrays_of(path) -> dict:
    with np.load(path) as f:
        return {k: f[k] for k in f.files}


def meta_of(path) -> dict:
    with np.load(path) as f:
        return json.loads(str(f["meta"]))


def variant(good, tmp_path, *, meta=None, drop=(), **arrays) -> pathlib.Path:
    """A copy of ``good`` with ``meta`` updated (a key set to ``DROP`` is removed), the arrays ``drop``
    left out and the arrays ``arrays`` (names with ``__`` for ``.``) replaced."""
    data = arrays_of(good)
    m = json.loads(str(data["meta"]))
    for k, v in (meta or {}).items():
        if v is DROP:
            m.pop(k)
        else:
            m[k] = v
    data["meta"] = np.asarray(json.dumps(m))
    for k in drop:
        del data[k]
    data.update({k.replace("__", "."): v for k, v in arrays.items()})
    path = tmp_path / "bad.npz"
    np.savez(path, **data)
    return path


DROP = object()


def assert_refused(path, capsys, *fragments, error=ValueError):
    """``load``, ``resume`` and ``jaxmpm resume`` each refuse ``path`` with one line naming it."""
    before = path.read_bytes() if path.is_file() else None
    with pytest.raises(error) as info:
        long_run.load(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message, message
    for fragment in fragments:
        assert fragment in message, message
    with pytest.raises(error):
        long_run.resume(path, progress=False)
    with pytest.raises(error):
        long_run.resume_timed(path, progress=False)
    capsys.readouterr()
    assert main(["resume", str(path), "--no-progress"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("jaxmpm: error:"), captured.err
    assert str(path) in lines[0] and "Traceback" not in captured.err + captured.out
    if before is not None:
        assert path.read_bytes() == before  # nothing the user saved is touched
    return message


def test_a_healthy_state_that_is_not_finite(good, tmp_path, capsys):
    x = arrays_of(good)["state.x"].copy()
    x[1, 0] = np.nan
    assert_refused(variant(good, tmp_path, state__x=x), capsys, "state.x is not finite, yet its status is 0")


def test_a_healthy_state_with_an_inverted_particle(good, tmp_path, capsys):
    """Every step checks det F > 0; a file whose healthy state has det F <= 0 was edited or damaged."""
    F = arrays_of(good)["state.F"].copy()
    F[2] = -F[2]
    assert_refused(
        variant(good, tmp_path, state__F=F), capsys, "particle 2 has det F = ", "<= 0, yet its status is 0"
    )


def test_a_breakdown_at_a_step_that_does_not_follow_the_kept_state(good, tmp_path, capsys):
    """A broken run keeps its last good state; the step that broke down is the next one. A file whose
    status says breakdown with another failing step (0 here, after 20 good steps) was edited: it was
    reported as a breakdown "at step -1"."""
    status = np.asarray(4, dtype=arrays_of(good)["state.status"].dtype)
    fail = np.asarray(0, dtype=arrays_of(good)["state.fail_step"].dtype)
    path = variant(good, tmp_path, meta={"status": 4}, state__status=status, state__fail_step=fail)
    assert_refused(
        path, capsys, "state.status is 4 (a breakdown) but state.fail_step is 0, not the step after"
    )


@pytest.mark.parametrize(
    "status, particle, fragment",
    [
        (
            4,
            99,
            "state.fail_particle is 99, not one of the run's 8 particles (0 to 7) or -1 (the run itself)",
        ),
        (
            4,
            -7,
            "state.fail_particle is -7, not one of the run's 8 particles (0 to 7) or -1 (the run itself)",
        ),
        (1024 + 4, 3, "state.status is 1028, which holds bits that no check sets (1024)"),
    ],
)
def test_a_breakdown_on_a_particle_the_run_lacks_or_of_unknown_bits(
    good, tmp_path, capsys, status, particle, fragment
):
    """A broken run names the particle that broke down (or -1, the run itself) and known bits only: a
    file naming particle 99 of 8 made `jaxmpm resume` print a traceback."""
    a = arrays_of(good)
    path = variant(
        good,
        tmp_path,
        meta={"status": status},
        state__status=np.asarray(status, dtype=a["state.status"].dtype),
        state__fail_step=np.asarray(21, dtype=a["state.fail_step"].dtype),
        state__fail_particle=np.asarray(particle, dtype=a["state.fail_particle"].dtype),
    )
    assert_refused(path, capsys, fragment, "the file was edited or is damaged")


def test_a_step_past_the_runs_steps(good, tmp_path, capsys):
    assert_refused(variant(good, tmp_path, meta={"steps": 10}), capsys, "step 20 of a run of 10 steps")


def test_the_good_file_loads(good):
    sol, meta = long_run.load(good)
    assert meta["step"] == 20 and int(sol.state.step) == 20 and sol.history["x"].shape[0] == 5


def test_empty_file(tmp_path, capsys):
    path = tmp_path / "empty.npz"
    path.write_bytes(b"")
    assert_refused(path, capsys, "is empty", "not a jaxmpm checkpoint")


def test_truncated_file(good, tmp_path, capsys):
    path = tmp_path / "half.npz"
    data = good.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert_refused(path, capsys, "damaged or truncated")


def test_damaged_member(good, tmp_path, capsys):
    data = bytearray(good.read_bytes())
    i = data.find(b"state.x.npy")  # the member's local header: spoil the bytes after it
    data[i + 200 : i + 260] = b"\x00" * 60
    path = tmp_path / "spoilt.npz"
    path.write_bytes(bytes(data))
    assert_refused(path, capsys, "damaged or truncated")


def test_text_file(tmp_path, capsys):
    path = tmp_path / "notes.npz"
    path.write_text("these are my notes, not a run\n")
    assert_refused(path, capsys, "is not a jaxmpm checkpoint (not a NumPy .npz archive)")


def test_single_array_file(tmp_path, capsys):
    path = tmp_path / "one.npz"
    with open(path, "wb") as f:
        np.save(f, np.arange(3.0))
    assert_refused(path, capsys, "single NumPy array (.npy)")


def test_archive_without_meta(tmp_path, capsys):
    path = tmp_path / "other.npz"
    np.savez(path, a=np.arange(3))
    assert_refused(path, capsys, "without 'meta'")


def test_meta_not_json(good, tmp_path, capsys):
    data = arrays_of(good)
    data["meta"] = np.asarray("{this is not json")
    path = tmp_path / "bad.npz"
    np.savez(path, **data)
    assert_refused(path, capsys, "'meta' is not valid JSON")


def test_meta_not_an_object(good, tmp_path, capsys):
    data = arrays_of(good)
    data["meta"] = np.asarray(json.dumps([1, 2, 3]))
    path = tmp_path / "bad.npz"
    np.savez(path, **data)
    assert_refused(path, capsys, "not a JSON object")


def test_meta_not_a_string(good, tmp_path, capsys):
    data = arrays_of(good)
    data["meta"] = np.arange(4)
    path = tmp_path / "bad.npz"
    np.savez(path, **data)
    assert_refused(path, capsys, "'meta' is not a JSON string")


@pytest.mark.parametrize("key", ["params", "scene", "interpolator", "dt", "steps", "chunk", "saveat", "step"])
def test_meta_lacks_a_key(good, tmp_path, capsys, key):
    path = variant(good, tmp_path, meta={key: DROP})
    assert_refused(path, capsys, f"meta lacks {key}")


def test_another_format(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"format": "something-else"})
    assert_refused(path, capsys, "not a jaxmpm run file", "'something-else'")


def test_newer_format(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"format_version": long_run.FORMAT_VERSION + 1})
    assert_refused(path, capsys, "written by a newer jaxmpm")


def test_a_run_saved_from_more_devices_than_here_resumes_on_as_many(good, tmp_path, capsys):
    """It said "its meta does not describe a run: devices must be a count from 1 to 1", of a good
    file: the file is read (``load``, on one device) and ``resume`` names what it needs."""
    path = variant(good, tmp_path, meta={"devices": 8})
    here = len(jax.devices())
    want = f"{path}: the run was saved from 8 devices and resumes on as many; this process has {here}"
    for resume in (long_run.resume, long_run.resume_timed):
        with pytest.raises(ValueError, match=f"^{re.escape(want)}"):
            resume(path, progress=False)
    capsys.readouterr()
    assert main(["resume", str(path), "--no-progress"]) == 2
    assert capsys.readouterr().err.strip() == f"jaxmpm: error: {want} (jax.devices())"
    _, meta = long_run.load(path)
    assert meta["devices"] == 8


def test_unknown_scene(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"scene": "no-such-scene"})
    assert_refused(path, capsys, "unknown scene 'no-such-scene'", "allowed: ", *jm.SCENES)


def test_unknown_interpolator(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"interpolator": {"name": "nurbs"}})
    assert_refused(path, capsys, "unknown interpolator 'nurbs'", *jm.INTERPOLATORS)


def test_unknown_transfer(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"transfer": "pic-flip-blend"})
    assert_refused(path, capsys, "unknown transfer 'pic-flip-blend'", *jm.TRANSFERS)


def test_params_the_scene_rejects(good, tmp_path, capsys):
    params = dict(meta_of(good)["params"], cells=-1)
    path = variant(good, tmp_path, meta={"params": params})
    assert_refused(path, capsys, "scene gas-expansion rejects the saved parameters", "cells must be")


def test_param_of_the_wrong_type(good, tmp_path, capsys):
    params = dict(meta_of(good)["params"], beta="hot")
    path = variant(good, tmp_path, meta={"params": params})
    assert_refused(
        path, capsys, "the saved parameter beta of scene gas-expansion must be a number, got 'hot'"
    )


def test_unknown_param(good, tmp_path, capsys):
    params = dict(meta_of(good)["params"], colour="red")
    path = variant(good, tmp_path, meta={"params": params})
    assert_refused(path, capsys, "unknown parameter 'colour'", "beta")


def test_interpolator_options_rejected(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"interpolator": {"name": "mpq", "wobble": 3}})
    assert_refused(path, capsys, "interpolator mpq rejects the saved options")


@pytest.mark.parametrize(
    "change, fragment",
    [
        ({"dt": -1.0}, "dt must be > 0"),
        ({"dt": "fast"}, "meta's dt must be a number, got 'fast'"),
        ({"cfl_limit": "high"}, "meta's cfl_limit must be a number or null"),
        ({"chunk": 0}, "chunk must be an integer >= 1"),
        ({"chunk": 7}, "chunk must be a multiple of saveat.every"),
        ({"steps": 2.5}, "steps must be an integer"),
        ({"ordering": "sideways"}, "ordering must be one of"),
        ({"saveat": [5]}, "saveat must be a JSON object"),
        ({"checkpoint_every": 0}, "checkpoint_every must be an integer >= 1"),
    ],
)
def test_meta_values_that_describe_no_run(good, tmp_path, capsys, change, fragment):
    path = variant(good, tmp_path, meta=change)
    assert_refused(path, capsys, fragment)


def test_state_array_missing(good, tmp_path, capsys):
    path = variant(good, tmp_path, drop=["state.x"])
    assert_refused(path, capsys, "state.x is missing", "(8, 1)")


def test_state_array_of_the_wrong_shape(good, tmp_path, capsys):
    path = variant(good, tmp_path, state__F=np.ones((7, 1, 1)))
    assert_refused(path, capsys, "state.F has shape (7, 1, 1), expected (8, 1, 1)")


def test_state_array_of_the_wrong_dtype(good, tmp_path, capsys):
    v = arrays_of(good)["state.v"].astype(np.float32)
    path = variant(good, tmp_path, state__v=v)
    assert_refused(path, capsys, "state.v has dtype float32, expected float64")


def test_a_run_saved_in_float32_is_refused_in_float64_saying_so(tmp_path, capsys):
    """A run saved from Python with float64 off cannot go on in float64 (``jaxmpm resume`` always runs
    in it): the refusal says the run was saved in float32 and how to go on with it."""
    path = tmp_path / "f32.npz"
    with float32():
        long_run.run(jm.GasExpansion(cells=4), jm.MPQ(), dt=1e-5, steps=4, chunk=2, out=path)
        assert long_run.load(path)[0].state.x.dtype == np.float32  # it loads in float32
    assert_refused(
        path,
        capsys,
        "body.X has dtype float32, expected float64",
        "the run was saved in float32: load or resume it in Python with float64 off",
    )


def test_meta_names_another_transfer_than_the_arrays_hold(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"transfer": "flip"})  # FLIP has no C, the file holds one
    assert_refused(path, capsys, "holds state.C", "transfer flip")


def test_meta_names_other_params_than_the_arrays_hold(good, tmp_path, capsys):
    params = dict(meta_of(good)["params"], h=0.25)  # the same particle count, other positions
    path = variant(good, tmp_path, meta={"params": params})
    assert_refused(
        path, capsys, "body.X does not match", "gas-expansion", "another scene or other parameters"
    )


def test_meta_names_another_scene_than_the_arrays_hold(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"scene": "vibrating-bar", "params": {"cells": 4}})
    assert_refused(path, capsys, "body.X", "vibrating-bar")


def test_meta_names_another_particle_count(good, tmp_path, capsys):
    params = dict(meta_of(good)["params"], cells=5)
    path = variant(good, tmp_path, meta={"params": params})
    assert_refused(path, capsys, "body.X has shape (8, 1), expected (10, 1)")


def test_state_step_and_meta_step_differ(good, tmp_path, capsys):
    path = variant(good, tmp_path, meta={"step": 10})
    assert_refused(path, capsys, "state.step is 20 but its meta says step 10")


def test_history_of_the_wrong_length(good, tmp_path, capsys):
    x = arrays_of(good)["history.x"][:3]
    path = variant(good, tmp_path, history__x=x)
    assert_refused(path, capsys, "history.x has shape (3, 8, 1), expected (5, 8, 1)")


def test_history_missing(good, tmp_path, capsys):
    path = variant(good, tmp_path, drop=["history.ts"])
    assert_refused(path, capsys, "history.ts is missing")


def test_a_folder_is_not_a_saved_run(tmp_path, capsys):
    folder = tmp_path / "run.npz"
    folder.mkdir()
    assert_refused(folder, capsys, "is a folder")


def test_missing_file(tmp_path, capsys):
    path = tmp_path / "missing.npz"
    with pytest.raises(FileNotFoundError, match="no saved run"):
        long_run.load(path)
    with pytest.raises(FileNotFoundError, match="no saved run"):
        long_run.resume(path, progress=False)
    assert main(["resume", str(path)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert (
        len(lines) == 1
        and lines[0].startswith("jaxmpm: error: no saved run")
        and "Traceback" not in captured.err
    )
    assert not path.exists()


# --- a run does not overwrite, and finds a bad ``out`` before it compiles anything


@pytest.fixture
def nothing_compiles(monkeypatch):
    """Fail the test if the run gets as far as building its first state (the first compilation)."""

    def fail(*args, **kwargs):
        raise AssertionError("compiled before checking out")

    monkeypatch.setattr(long_run, "_start", fail)
    monkeypatch.setattr(long_run, "_drive", fail)


def test_run_does_not_overwrite_a_checkpoint(good, tmp_path, nothing_compiles):
    path = tmp_path / "run.npz"
    path.write_bytes(good.read_bytes())
    before = path.read_bytes()
    with pytest.raises(ValueError) as info:
        long_run.run(SCENE, jm.SPQ(), out=path, **KW)
    message = str(info.value)
    assert "\n" not in message
    assert (
        f"{path} already exists (a jaxmpm checkpoint of gas-expansion at step 20 of 20, complete)" in message
    )
    assert "overwrite=True" in message and "--overwrite" in message and f"jaxmpm resume {path}" in message
    assert path.read_bytes() == before


def test_run_does_not_overwrite_any_file(tmp_path, nothing_compiles):
    path = tmp_path / "thesis.npz"
    path.write_text("three years of work")
    with pytest.raises(ValueError) as info:
        long_run.run_timed(SCENE, jm.SPQ(), out=path, **KW)
    message = str(info.value)
    assert f"{path} already exists (an existing file" in message and "overwrite=True" in message
    assert "jaxmpm resume" not in message
    assert path.read_text() == "three years of work"


def test_overwrite_replaces_the_file(tmp_path):
    path = tmp_path / "run.npz"
    path.write_text("old")
    sol = long_run.run(SCENE, jm.SPQ(), out=path, overwrite=True, **KW)
    loaded, meta = long_run.load(path)
    assert meta["step"] == 20 and np.array_equal(np.asarray(loaded.state.x), np.asarray(sol.state.x))


def test_out_is_a_folder(tmp_path, nothing_compiles):
    with pytest.raises(ValueError, match="is a folder, not a file"):
        long_run.run(SCENE, jm.SPQ(), out=tmp_path, **KW)


def test_out_ending_with_a_slash_names_a_folder(tmp_path, capsys, nothing_compiles):
    """``o/zz/`` names a folder even where none exists: it is refused, not written as a file ``o/zz``."""
    with pytest.raises(ValueError, match="ends with a slash, which names a folder, not a file"):
        long_run.run(SCENE, jm.SPQ(), out=f"{tmp_path}/zz/", **KW)
    argv = ["run", "gas-expansion", "cells=2", "--interpolator", "mpq", "--dt", "1e-5", "--steps", "2"]
    assert main(argv + ["--out", f"{tmp_path}/zz/"]) == 2
    assert f"--out {tmp_path}/zz/ ends with a slash" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_out_in_a_missing_folder(tmp_path, nothing_compiles):
    out = tmp_path / "no" / "such" / "run.npz"
    with pytest.raises(ValueError, match=r"the folder .*such does not exist"):
        long_run.run(SCENE, jm.SPQ(), out=out, **KW)
    assert not out.parent.exists()


def test_out_in_a_folder_that_cannot_be_written(tmp_path, monkeypatch, nothing_compiles):
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        if os.access(folder, os.W_OK):  # root writes in any folder: the probe file is refused as the
            real = long_run.tempfile.mkstemp  # kernel refuses it to anyone else

            def refused(*args, dir=None, **kwargs):
                if pathlib.Path(dir) == folder:
                    raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(folder))
                return real(*args, dir=dir, **kwargs)

            monkeypatch.setattr(long_run.tempfile, "mkstemp", refused)
        with pytest.raises(ValueError) as refusal:
            long_run.run(SCENE, jm.SPQ(), out=folder / "run.npz", **KW)
        assert str(refusal.value) == (
            f"out={folder / 'run.npz'}: cannot write in the folder {folder} ({os.strerror(errno.EACCES)})"
        )
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o700)


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_out_in_a_folder_no_one_can_write(nothing_compiles):
    with pytest.raises(ValueError, match="cannot write in the folder /proc"):  # not even root
        long_run.run(SCENE, jm.SPQ(), out="/proc/jaxmpm-run.npz", **KW)


def test_resume_rewrites_its_own_file_only(good, tmp_path):
    path = tmp_path / "run.npz"
    path.write_bytes(good.read_bytes())
    other = tmp_path / "other.npz"
    other.write_text("keep me")
    with pytest.raises(ValueError, match="already exists"):
        long_run.resume(path, out=other, progress=False)
    assert other.read_text() == "keep me"
    long_run.resume(path, progress=False)  # its own file: allowed
    long_run.resume(path, out=other, overwrite=True, progress=False)
    assert long_run.load(other)[1]["step"] == 20


def test_a_time_that_is_not_step_times_dt(good, tmp_path, capsys):
    t = arrays_of(good)["state.t"]
    edited = variant(good, tmp_path, state__t=np.asarray(t * (1 + 1e-12), dtype=t.dtype))
    assert_refused(edited, capsys, "state.t is", "but step 20 of dt = 1e-05 is at t = 0.0002")


# --- arrays of another run under the metadata: the checks that need no recomputation of the run

MISMATCH = "the checkpoint's arrays do not match its metadata: "


def number_after(text: str, before: str) -> float:
    """The number that follows ``before`` in ``text``."""
    return float(re.search(re.escape(before) + r"(\S+?),? ", text).group(1))


@pytest.mark.parametrize("param, value", [("P0", 6e5), ("gamma", 1.6), ("p_atm", 5e4)])
def test_meta_names_another_material_than_the_stress_holds(good, tmp_path, capsys, param, value):
    """The saved stress is the material's at the saved F: metadata naming other material parameters
    than those the arrays were made with is refused, naming the first particle whose stress differs
    and both values."""
    params = dict(meta_of(good)["params"], **{param: value})
    path = variant(good, tmp_path, meta={"params": params})
    message = assert_refused(path, capsys)
    saved = arrays_of(good)["state.sigma"][0, 0, 0]
    head = f"{path}: {MISMATCH}state.sigma[0, 0, 0] is {float(saved)!r}, but the material of scene "
    assert message.startswith(head + "gas-expansion with the saved params gives "), message
    J = arrays_of(good)["state.F"][0, 0, 0]
    expected = -(params["P0"] * J ** -params["gamma"] - params["p_atm"])
    assert number_after(message, "with the saved params gives ") == pytest.approx(expected, rel=1e-12)
    assert message.endswith(
        " at the saved F; the meta names another scene, other parameters or another viscosity than the "
        "arrays hold"
    )


@pytest.fixture(scope="module")
def slab(tmp_path_factory) -> pathlib.Path:
    """A complete saved run of a gas slab (P0 = 3e5, CPDI, FLIP, no history)."""
    path = tmp_path_factory.mktemp("slab") / "slab.npz"
    scene = jm.GasSlab(cells=8, h=1 / 8, pad=32)
    long_run.run(scene, jm.CPDI(), dt=5e-6, steps=40, out=path, progress=False)
    return path


def test_arrays_of_a_run_under_the_metadata_of_another(slab, tmp_path, capsys):
    """The arrays of a complete P0 = 3e5 FLIP run under metadata that says P0 = 9e5, PIC, one
    artificial cell and a run of 80 steps, 40 done: refused (by the stress), not continued."""
    meta = meta_of(slab)
    meta["params"]["P0"] = 9e5
    change = dict(params=meta["params"], transfer="pic", artificial_cells=1, steps=80, complete=False)
    path = variant(slab, tmp_path, meta=change)
    message = assert_refused(path, capsys, f"{path}: {MISMATCH}state.sigma[0, 0, 0] is ")
    assert "but the material of scene gas-slab with the saved params gives " in message
    assert long_run.load(slab)[1]["step"] == 40  # the file it was made from loads


def test_a_stress_edited_beyond_round_off(slab, tmp_path, capsys):
    """Round-off is allowed (4096 ulps of the stress's terms); a stress off by more is refused at the
    particle where it is."""
    sigma = arrays_of(slab)["state.sigma"].copy()
    sigma[5, 0, 0] *= 1 + 1e-6
    path = variant(slab, tmp_path, state__sigma=sigma)
    assert_refused(path, capsys, f"{MISMATCH}state.sigma[5, 0, 0] is {float(sigma[5, 0, 0])!r}, but")
    sigma[5, 0, 0] = arrays_of(slab)["state.sigma"][5, 0, 0] * (1 + 1e-14)
    assert long_run.load(variant(slab, tmp_path, state__sigma=sigma))[1]["step"] == 40


TUBE = jm.ShockTube(cells=20, h=0.05)
TUBE_SAVEAT = jm.SaveAt(every=5, fields=("x", "v", "F", "sigma", "e"))


@pytest.fixture(scope="module")
def tube(tmp_path_factory) -> pathlib.Path:
    """A complete saved run of a shock tube (two ideal-gas regions, with energy), with a history."""
    path = tmp_path_factory.mktemp("tube") / "tube.npz"
    long_run.run(TUBE, jm.SPQ(), dt=1e-3, steps=10, saveat=TUBE_SAVEAT, out=path, progress=False)
    return path


def test_meta_names_another_equation_of_state_than_the_stress_holds(tube, tmp_path, capsys):
    """An ideal gas's stress is -(gamma - 1) rho e: the saved stress at the saved F and e under
    another gamma is refused."""
    assert long_run.load(tube)[1]["step"] == 10
    params = dict(meta_of(tube)["params"], gamma=1.6)
    path = variant(tube, tmp_path, meta={"params": params})
    message = assert_refused(path, capsys, f"{path}: {MISMATCH}state.sigma[0, 0, 0] is ")
    data = arrays_of(tube)
    rho = params["rho_l"] / data["state.F"][0, 0, 0]
    expected = -(params["gamma"] - 1) * rho * data["state.e"][0]
    given = number_after(message, "shock-tube with the saved params gives ")
    assert given == pytest.approx(expected, rel=1e-12)
    assert " at the saved F and e; " in message


@pytest.mark.parametrize(
    "param, value, field, saved, initial",
    [("p_l", 2.0, "sigma", -1.0, -2.0), ("u_l", 0.5, "v", 0.0, 0.5)],
)
def test_meta_names_another_initial_state_than_the_history_holds(
    tube, tmp_path, capsys, param, value, field, saved, initial
):
    """The first frame of a history is the run's initial state: scene parameters that only set the
    initial state (the left state's pressure, its velocity) are refused there."""
    params = dict(meta_of(tube)["params"], **{param: value})
    path = variant(tube, tmp_path, meta={"params": params})
    message = assert_refused(path, capsys)
    head = f"{path}: {MISMATCH}history.{field}[0, 0, 0"
    assert message.startswith(head), message
    assert number_after(message, "] (t = 0) is ") == pytest.approx(saved, rel=1e-12)
    assert number_after(message, "with the saved params has ") == pytest.approx(initial, rel=1e-12)
    assert message.endswith(
        " (the first frame of a history is the run's initial state); the meta names another scene or "
        "other parameters than the arrays hold"
    )


def test_history_times_that_are_not_the_saves(tube, tmp_path, capsys):
    ts = arrays_of(tube)["history.ts"].copy()
    ts[1] = 0.004
    path = variant(tube, tmp_path, history__ts=ts)
    assert_refused(
        path,
        capsys,
        f"{path}: {MISMATCH}history.ts[1] is 0.004, but save 1 of one every 5 steps of dt = 0.001 is at "
        "t = 0.005",
    )


@pytest.fixture(scope="module")
def viscous_tube(tmp_path_factory) -> pathlib.Path:
    path = tmp_path_factory.mktemp("viscous") / "tube.npz"
    viscosity = jm.ArtificialViscosity()
    long_run.run(TUBE, jm.SPQ(), dt=1e-3, steps=10, viscosity=viscosity, out=path, progress=False)
    return path


def test_a_viscous_run_under_metadata_without_viscosity(viscous_tube, tmp_path, capsys):
    """The stress of a run with an artificial viscosity holds the viscous pressure of its last step,
    which the file does not: its stress is not checked (it loads), and under metadata without the
    viscosity it is refused where the viscous pressure is not round-off."""
    assert long_run.load(viscous_tube)[1]["viscosity"] == [2.0, 0.2]
    path = variant(viscous_tube, tmp_path, meta={"viscosity": None})
    assert_refused(path, capsys, f"{path}: {MISMATCH}state.sigma[", "shock-tube with the saved params gives ")


# --- a save that fails names the file asked for


def test_a_full_disk_while_saving_names_the_file(tmp_path, monkeypatch):
    """The error of a save that fails is the system's, naming ``out`` (not the temporary file beside
    it, and no second file: ``-> None``); the temporary file is removed."""

    def full(f, **arrays):
        f.write(b"PK\x03\x04 half an archive")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(long_run.np, "savez", full)
    out = tmp_path / "run.npz"
    with pytest.raises(OSError) as info:
        long_run.run(SCENE, jm.SPQ(), out=out, **KW)
    assert str(info.value) == f"[Errno 28] No space left on device: '{out}'"
    assert info.value.filename == str(out) and info.value.filename2 is None
    assert list(tmp_path.iterdir()) == []


def test_a_rename_that_fails_names_the_file(tmp_path, monkeypatch):
    """A rename into place that fails (its error names the temporary file and ``out``) names ``out``
    alone."""
    out = tmp_path / "run.npz"
    real = os.replace

    def replace(src, dst, *args, **kwargs):
        if pathlib.Path(dst) == out:
            raise OSError(errno.EIO, "Input/output error", str(src), str(dst))
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError) as info:
        long_run.run(SCENE, jm.SPQ(), out=out, **KW)
    assert str(info.value) == f"[Errno 5] Input/output error: '{out}'"
    assert list(tmp_path.iterdir()) == []


def test_an_error_without_a_number_keeps_its_message(tmp_path):
    """An ``OSError("message")`` of the writer is raised as it is (a file name would turn its text
    into ``[Errno None] None: ...``)."""
    from jaxmpm._files import write_whole

    def broken(f):
        raise OSError("the device went away")

    with pytest.raises(OSError) as info:
        write_whole(tmp_path / "a.bin", broken)
    assert str(info.value) == "the device went away"
    assert list(tmp_path.iterdir()) == []
