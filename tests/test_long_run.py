"""Long runs: chunks, checkpoints that survive a crash, bit-for-bit resume, saved outputs."""

import json

import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import long_run

SCENE = jm.GasExpansion(cells=4, beta=300.0)
KW = dict(dt=1e-5, steps=95, chunk=10, artificial_cells=1, progress=False)
FIELDS = ("t", "step", "x", "v", "F", "sigma", "C", "corners", "x_traction", "status")


def assert_states_identical(a, b):
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y), err_msg=name)


@pytest.mark.slow
def test_chunked_equals_one_scan(interpolator, transfer):
    chunked = long_run.run(SCENE, interpolator, transfer=transfer, **KW)
    whole = jm.simulate(SCENE, interpolator, dt=1e-5, steps=95, artificial_cells=1, transfer=transfer)
    assert int(chunked.state.step) == 95
    for name in ("x", "v", "F", "sigma"):
        np.testing.assert_allclose(
            getattr(chunked.state, name), getattr(whole.state, name), rtol=1e-13, atol=1e-13
        )


def test_resume_equals_uninterrupted_bit_for_bit(tmp_path):
    saveat = jm.SaveAt(every=5, fields=("x", "F"))
    full = long_run.run(SCENE, jm.MPQ(), transfer=jm.APIC(), saveat=saveat, **KW)
    path = tmp_path / "run.npz"
    long_run.run(
        SCENE,
        jm.MPQ(),
        transfer=jm.APIC(),
        saveat=saveat,
        out=path,
        checkpoint_every=3,
        **(KW | dict(steps=40)),
    )  # stopped after step 40, as if interrupted
    _, meta = long_run.load(path)
    assert meta["step"] == 40 and meta["complete"]  # complete for its own target of 40 steps
    # Continue it to the full 95 steps: rewrite the target, as a user extending a run would.
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    meta["steps"] = 95
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(path, **arrays)
    resumed = long_run.resume(path, progress=False)
    assert_states_identical(resumed.state, full.state)
    for name in ("x", "F"):
        np.testing.assert_array_equal(np.asarray(resumed.history[name]), np.asarray(full.history[name]))
    np.testing.assert_array_equal(np.asarray(resumed.ts), np.asarray(full.ts))
    _, meta = long_run.load(path)
    assert meta["complete"] and meta["step"] == 95


def test_crash_during_checkpoint_write_resumes_from_previous(tmp_path, monkeypatch):
    path = tmp_path / "run.npz"
    full = long_run.run(SCENE, jm.MPQ(), **KW)
    real_write = long_run._write_npz
    calls = {"n": 0}

    def crashing_write(p, arrays):
        calls["n"] += 1
        if calls["n"] == 3:  # die in the middle of the third checkpoint: half a temporary file
            with open(p.with_name(p.name + ".tmp"), "wb") as f:
                f.write(b"PK\x03\x04 half a zip archive")
            raise KeyboardInterrupt("killed while writing")
        real_write(p, arrays)

    monkeypatch.setattr(long_run, "_write_npz", crashing_write)
    with pytest.raises(KeyboardInterrupt):
        long_run.run(SCENE, jm.MPQ(), out=path, checkpoint_every=2, **KW)
    monkeypatch.setattr(long_run, "_write_npz", real_write)
    _, meta = long_run.load(path)  # the previous checkpoint, intact
    assert meta["step"] == 40
    resumed = long_run.resume(path, progress=False)
    assert_states_identical(resumed.state, full.state)


def test_breakdown_keeps_and_saves_the_state_before_it(tmp_path):
    path = tmp_path / "broken.npz"
    scene = jm.VibratingBar(v0=-30.0)
    with pytest.raises(jm.SimulationError, match=f"saved in {path}") as info:
        long_run.run(scene, jm.MPQ(), dt=1e-4, steps=2000, chunk=64, cfl_limit=None, out=path, progress=False)
    k = info.value.solution.failure()["step"]
    sol, meta = long_run.load(path)
    assert meta["failure"]["step"] == k and meta["step"] == k - 1 and not meta["complete"]
    before = jm.simulate(scene, jm.MPQ(), dt=1e-4, steps=k - 1, cfl_limit=None)
    assert_states_identical(sol.state, dataclass_with_status(before.state, sol.state))
    with pytest.raises(jm.SimulationError):
        long_run.resume(path, progress=False)  # a broken run is not continued


def dataclass_with_status(state, like):
    """``state`` with the status fields of ``like`` (the uninterrupted run never saw the failure)."""
    import dataclasses

    return dataclasses.replace(
        state, status=like.status, fail_step=like.fail_step, fail_particle=like.fail_particle
    )


def test_file_opens_without_jaxmpm(tmp_path):
    path = tmp_path / "run.npz"
    long_run.run(SCENE, jm.CPDI(), saveat=jm.SaveAt(every=5, fields=("F",)), out=path, **KW)
    with np.load(path, allow_pickle=False) as f:
        meta = json.loads(str(f["meta"]))
        assert meta["format"] == "jaxmpm-run" and meta["scene"] == "gas-expansion"
        assert meta["params"]["beta"] == 300.0 and meta["interpolator"]["name"] == "cpdi"
        assert meta["jaxmpm_version"] == jm.__version__
        assert f["state.F"].shape == (8, 1, 1) and f["history.F"].shape == (20, 8, 1, 1)
        np.testing.assert_allclose(f["history.ts"], np.arange(20) * 5e-5, rtol=1e-12)
        assert int(f["state.step"]) == 95 and not f["body.boundary"][3]


def test_bad_arguments():
    with pytest.raises(ValueError, match="chunk must be a multiple of saveat.every"):
        long_run.run(SCENE, jm.SPQ(), dt=1e-5, steps=10, chunk=7, saveat=jm.SaveAt(every=2), progress=False)
    with pytest.raises(ValueError, match="checkpoint_every needs out"):
        long_run.run(SCENE, jm.SPQ(), dt=1e-5, steps=10, checkpoint_every=1, progress=False)
    with pytest.raises(ValueError, match="chunk must be an integer >= 1"):
        long_run.run(SCENE, jm.SPQ(), dt=1e-5, steps=10, chunk=0, progress=False)


def test_cli_out_and_resume(tmp_path, capsys):
    from jaxmpm.cli import main

    path = tmp_path / "cli.npz"
    argv = [
        "run",
        "gas-expansion",
        "cells=4",
        "--interpolator",
        "mpq",
        "--artificial-cells",
        "1",
        "--dt",
        "1e-5",
        "--steps",
        "95",
        "--chunk",
        "10",
        "--out",
        str(path),
        "--checkpoint-every",
        "2",
        "--no-progress",
        "--json",
    ]
    assert main(argv) == 0
    ran = json.loads(capsys.readouterr().out)
    assert ran["out"] == str(path) and ran["t"] == pytest.approx(95e-5) and ran["compile_s"] > 0
    assert main(["resume", str(path), "--json", "--no-progress"]) == 0  # already complete: nothing to do
    resumed = json.loads(capsys.readouterr().out)
    assert resumed["particles"] == ran["particles"]
    assert main(["resume", str(tmp_path / "missing.npz")]) == 2
    assert "no saved run" in capsys.readouterr().err
    assert (
        main(
            [
                "run",
                "gas-expansion",
                "--interpolator",
                "spq",
                "--dt",
                "1e-5",
                "--steps",
                "5",
                "--checkpoint-every",
                "2",
            ]
        )
        == 2
    )
    assert "--checkpoint-every needs --out" in capsys.readouterr().err


def test_cli_breakdown_says_where_it_saved(tmp_path, capsys):
    from jaxmpm.cli import main

    path = tmp_path / "broken.npz"
    argv = [
        "run",
        "vibrating-bar",
        "v0=-30",
        "--interpolator",
        "mpq",
        "--dt",
        "1e-4",
        "--steps",
        "2000",
        "--cfl-limit",
        "none",
        "--chunk",
        "64",
        "--out",
        str(path),
        "--no-progress",
    ]
    assert main(argv) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "F <= 0" in err[0] and f"saved in {path}" in err[0]
    assert long_run.load(path)[1]["failure"]["quantities"]
