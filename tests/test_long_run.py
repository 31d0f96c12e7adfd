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
    with pytest.raises(ValueError, match="overwrite=True needs out=FILE"):  # (it would replace nothing)
        long_run.run(SCENE, jm.SPQ(), dt=1e-5, steps=10, overwrite=True, progress=False)
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


# --- Ctrl-C: stop at once, save the last finished chunk, resume bit for bit


def interrupt_at(monkeypatch, k):
    """Raise ``KeyboardInterrupt`` in the ``k``-th wait for a chunk, once that chunk is computed (its
    result is discarded, as a Ctrl-C's would be)."""
    real = long_run.wait
    calls = {"n": 0}

    def wait(tree):
        calls["n"] += 1
        result = real(tree)
        if calls["n"] == k:
            raise KeyboardInterrupt
        return result

    monkeypatch.setattr(long_run, "wait", wait)
    return calls


def count_writes(monkeypatch):
    real = long_run._write_npz
    steps = []

    def write(path, arrays):
        steps.append(int(arrays["state.step"]))
        real(path, arrays)

    monkeypatch.setattr(long_run, "_write_npz", write)
    return steps


def test_interrupt_saves_the_last_chunk_and_resumes_bit_for_bit(tmp_path, monkeypatch):
    saveat = jm.SaveAt(every=5, fields=("x", "F"))
    full = long_run.run(SCENE, jm.MPQ(), transfer=jm.APIC(), saveat=saveat, **KW)
    path = tmp_path / "run.npz"
    bars = []
    real_bar = long_run._progress_bar

    def bar(*args):
        b = real_bar(*args)
        bars.append(b)
        real_close = b.close
        b.close = lambda: (bars.append("closed"), real_close())
        return b

    monkeypatch.setattr(long_run, "_progress_bar", bar)
    interrupt_at(monkeypatch, 4)  # chunks 1-3 finish (step 30); the 4th is discarded
    with pytest.raises(long_run.Interrupted) as info:
        long_run.run(SCENE, jm.MPQ(), transfer=jm.APIC(), saveat=saveat, out=path, **KW)
    e = info.value
    assert isinstance(e, KeyboardInterrupt)
    assert e.step == 30 and e.saved_in == path and int(e.solution.state.step) == 30
    assert str(e) == f"interrupted at step 30 of 95; saved in {path} (continue with `jaxmpm resume {path}`)"
    assert e.solution.history["x"].shape[0] == 7  # steps 0, 5, ..., 30
    np.testing.assert_array_equal(np.asarray(e.solution.history["F"]), np.asarray(full.history["F"][:7]))
    assert bars[-1] == "closed"
    monkeypatch.undo()
    sol, meta = long_run.load(path)
    assert meta["step"] == 30 and not meta["complete"]
    assert_states_identical(sol.state, e.solution.state)
    resumed = long_run.resume(path, progress=False)
    assert_states_identical(resumed.state, full.state)
    for name in ("x", "F"):
        np.testing.assert_array_equal(np.asarray(resumed.history[name]), np.asarray(full.history[name]))
    np.testing.assert_array_equal(np.asarray(resumed.ts), np.asarray(full.ts))
    assert long_run.load(path)[1]["complete"]


def test_interrupt_right_after_a_checkpoint_saves_once(tmp_path, monkeypatch):
    path = tmp_path / "run.npz"
    writes = count_writes(monkeypatch)
    interrupt_at(monkeypatch, 4)
    with pytest.raises(long_run.Interrupted) as info:
        long_run.run(SCENE, jm.MPQ(), out=path, checkpoint_every=3, **KW)
    assert info.value.step == 30 and writes == [30]  # the checkpoint of step 30 is the file already
    monkeypatch.undo()
    writes = count_writes(monkeypatch)
    interrupt_at(monkeypatch, 2)  # resumed from 30: chunk to 40 finishes, the next is discarded
    with pytest.raises(long_run.Interrupted) as info:
        long_run.resume(path, progress=False)
    assert info.value.step == 40 and writes == [40] and long_run.load(path)[1]["step"] == 40


def test_interrupt_before_the_first_chunk_leaves_the_saved_file_as_it_was(tmp_path, monkeypatch):
    """With overwrite=True, a Ctrl-C before the new run has finished a chunk writes nothing: the file
    still holds the run that was there (it was replaced by the new run's step 0)."""
    path = tmp_path / "run.npz"
    long_run.run(SCENE, jm.SPQ(), out=path, **KW)
    before = path.read_bytes()
    writes = count_writes(monkeypatch)
    interrupt_at(monkeypatch, 1)
    with pytest.raises(long_run.Interrupted) as info:
        long_run.run(SCENE, jm.MPQ(), out=path, overwrite=True, **KW)
    e = info.value
    assert writes == [] and path.read_bytes() == before and e.saved_in is None and e.step == 0
    kept = f"nothing saved ({path} is as it was)"
    assert str(e) == f"interrupted at step 0 of 95, before its first chunk finished: {kept}"


def test_a_file_another_run_made_at_out_meanwhile_is_not_replaced(tmp_path, monkeypatch, capsys):
    """out is checked before the run and written at its end: a file another process made there in
    between (two runs given the same out) is kept, and this run says it was not saved."""
    import os

    from jaxmpm.cli import main

    path = tmp_path / "run.npz"
    real = long_run.wait

    def wait(tree):  # the other run's file appears while this one computes
        if not path.exists():
            path.write_text("THE OTHER RUN")
        return real(tree)

    monkeypatch.setattr(long_run, "wait", wait)
    with pytest.raises(FileExistsError, match=r"appeared while the run computed .* this run is not saved"):
        long_run.run(SCENE, jm.SPQ(), out=path, **KW)
    assert path.read_text() == "THE OTHER RUN" and os.listdir(tmp_path) == ["run.npz"]
    path.unlink()
    argv = ["run", "vibrating-bar", "cells=8", "--interpolator", "mpq", "--dt", "1e-4", "--steps", "30"]
    assert main([*argv, "--chunk", "10", "--out", str(path), "--no-progress"]) == 74
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"jaxmpm: error: cannot write --out {path}: ")
    assert "appeared while the run computed" in err[0] and path.read_text() == "THE OTHER RUN"
    path.unlink()
    monkeypatch.undo()
    long_run.run(SCENE, jm.SPQ(), out=path, checkpoint_every=2, **KW)  # its own checkpoints: replaced
    assert long_run.load(path)[1]["complete"]


def test_interrupt_without_out(monkeypatch):
    interrupt_at(monkeypatch, 2)
    with pytest.raises(long_run.Interrupted) as info:
        long_run.run(SCENE, jm.SPQ(), **KW)
    e = info.value
    assert str(e) == "interrupted at step 10 of 95" and e.saved_in is None and e.step == 10
    assert int(e.solution.state.step) == 10


def test_cli_sigterm_saves_the_last_chunk_like_ctrl_c_and_exits_143(tmp_path, monkeypatch, capsys):
    """SIGTERM (kill, a cluster's scheduler) stops a run as Ctrl-C does: the chunk in flight is
    discarded, the last finished one saved whole (no temporary file left), one line, status 143."""
    import os
    import signal

    from jaxmpm.cli import main

    real = long_run.wait
    calls = {"n": 0}

    def wait(tree):  # SIGTERM to this process while the third chunk computes
        calls["n"] += 1
        if calls["n"] == 3:
            os.kill(os.getpid(), signal.SIGTERM)
        return real(tree)

    monkeypatch.setattr(long_run, "wait", wait)
    path = tmp_path / "run.npz"
    argv = [
        "run",
        "vibrating-bar",
        "cells=8",
        "--interpolator",
        "mpq",
        "--dt",
        "1e-4",
        "--steps",
        "95",
        "--chunk",
        "10",
    ]
    assert main([*argv, "--out", str(path), "--no-progress"]) == 143
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"jaxmpm: terminated (SIGTERM): interrupted at step 20 of 95; saved in {path} "
        f"(continue with `jaxmpm resume {path}`)"
    ]
    assert long_run.load(path)[1]["step"] == 20 and sorted(os.listdir(tmp_path)) == ["run.npz"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the caller's handler, back
    calls["n"] = 0  # resumed from 20: SIGTERM in its third chunk, saved at 40
    assert main(["resume", str(path), "--no-progress"]) == 143
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"jaxmpm: terminated (SIGTERM): interrupted at step 40 of 95; saved in {path} "
        f"(continue with `jaxmpm resume {path}`)"
    ]
    assert long_run.load(path)[1]["step"] == 40


def test_cli_resume_interrupted_exits_130_and_continues(tmp_path, monkeypatch, capsys):
    from jaxmpm.cli import main

    full = long_run.run(SCENE, jm.MPQ(), **KW)
    path = tmp_path / "run.npz"
    interrupt_at(monkeypatch, 2)
    with pytest.raises(long_run.Interrupted):
        long_run.run(SCENE, jm.MPQ(), out=path, **KW)
    interrupt_at(monkeypatch, 2)  # from step 10: the chunk to 20 finishes, the next is discarded
    assert main(["resume", str(path), "--no-progress"]) == 130
    captured = capsys.readouterr()
    assert captured.err.strip().splitlines() == [
        f"jaxmpm: interrupted at step 20 of 95; saved in {path} (continue with `jaxmpm resume {path}`)"
    ]
    assert "Traceback" not in captured.out + captured.err
    monkeypatch.undo()
    resumed = long_run.resume(path, progress=False)
    assert_states_identical(resumed.state, full.state)


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler (``KeyboardInterrupt``, as in a user's process) for the test, and
    what was there back after it: pytest-xdist's workers ignore SIGINT (the controller takes
    Ctrl-C). Handlers are set in the main thread, where the workers run their tests. The cyclic
    garbage collector is paused meanwhile: an interrupt that lands in one of its callbacks (XLA's
    runs there) is reported as unraisable and lost, and each of these tests times one signal."""
    import gc
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers can only be set in the main thread")
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)
        if collecting:
            gc.enable()


@pytest.mark.usefixtures("python_sigint")
def test_a_real_ctrl_c_stops_the_run_at_once(tmp_path, monkeypatch):
    import os
    import signal
    import threading
    import time

    path = tmp_path / "run.npz"
    real = long_run.wait
    calls = {"n": 0, "sent": None}

    def wait(tree):
        calls["n"] += 1
        if calls["n"] == 3:
            calls["sent"] = time.perf_counter() + 0.05
            threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
            real(tree)
            time.sleep(5)  # the signal arrives while the chunk runs or, at the latest, here
        return real(tree)

    monkeypatch.setattr(long_run, "wait", wait)
    with pytest.raises(long_run.Interrupted) as info:
        long_run.run(SCENE, jm.MPQ(), out=path, **KW)
    assert time.perf_counter() - calls["sent"] < 1.0
    assert info.value.step == 20 and long_run.load(path)[1]["step"] == 20


@pytest.mark.usefixtures("python_sigint")
def test_waiting_for_a_chunk_sees_ctrl_c_while_it_runs():
    import os
    import signal
    import threading
    import time

    import jax
    import jax.numpy as jnp

    @jax.jit
    def slow(x):
        return jax.lax.fori_loop(0, 300, lambda i, c: jnp.sin(c) * 0.999 + 1e-3, x)

    x = jnp.ones(100_000)
    slow(x).block_until_ready()  # compiled
    t0 = time.perf_counter()
    slow(x).block_until_ready()
    if time.perf_counter() - t0 < 0.3:
        pytest.skip("the computation is too quick here to interrupt it while it runs")
    y = slow(x)
    if y.is_ready():
        pytest.skip("this backend ran the computation before returning (no asynchronous dispatch)")
    threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
    sent = time.perf_counter() + 0.05
    try:
        with pytest.raises(KeyboardInterrupt):
            try:
                long_run.wait(y)
            finally:
                seen, running = time.perf_counter(), not y.is_ready()
            time.sleep(5)  # the signal came after the computation: fail below, not in another test
    finally:
        y.block_until_ready()
    assert running, "the wait saw Ctrl-C only once the computation had finished"
    assert seen - sent < 0.25


@pytest.mark.usefixtures("python_sigint")
def test_ctrl_c_is_held_back_while_a_chunk_is_recorded():
    import os
    import signal
    import time

    with long_run._DeferInterrupt() as held:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    assert held.pending
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.slow
def test_a_chunk_longer_than_the_run_is_cut_to_it(tmp_path):
    """A chunk is never longer than the run (a masked chunk still computes every step of it)."""
    scene = jm.GasExpansion(cells=4)
    out = tmp_path / "run.npz"
    sol = long_run.run(scene, jm.SPQ(), dt=1e-5, steps=10, chunk=10**7, out=out, progress=False)
    assert long_run.load(out)[1]["chunk"] == 10
    ref = jm.simulate(scene, jm.SPQ(), dt=1e-5, steps=10)
    assert np.array_equal(sol.state.F, ref.state.F)
    saveat = jm.SaveAt(every=4, fields=("x",))
    long_run.run(
        scene, jm.SPQ(), dt=1e-5, steps=10, chunk=400, saveat=saveat, out=out, overwrite=True, progress=False
    )
    assert long_run.load(out)[1]["chunk"] == 12  # a multiple of every, covering the 10 steps
    long_run.run(
        scene, jm.SPQ(), dt=1e-5, steps=0, chunk=400, saveat=saveat, out=out, overwrite=True, progress=False
    )
    sol, meta = long_run.load(out)  # a run of no steps: its chunk is still a multiple of every
    assert meta["chunk"] == 4 and meta["complete"] and sol.history["x"].shape[0] == 1


@pytest.mark.slow
def test_a_scene_of_parts_runs_in_chunks_when_nothing_is_saved(tmp_path):
    """A ``jm.Bodies`` scene is made of Python objects that a file cannot record: saved, it is refused;
    run without ``out``, it runs in chunks as ``simulate`` runs it."""
    from jaxmpm.geometry import Box

    part = jm.Region(Box(0.0, 4.0), jm.LinearElastic(E=100.0), 1.0, 0.5)
    scene = jm.Bodies(parts=(part,), cells=10, ppc=1, h=0.1, pad=3)
    sol = long_run.run(scene, jm.CPDI(), dt=1e-3, steps=20, chunk=5, progress=False)
    ref = jm.simulate(scene, jm.CPDI(), dt=1e-3, steps=20)
    assert np.asarray(sol.state.x).tobytes() == np.asarray(ref.state.x).tobytes()
    with pytest.raises(ValueError, match="a saved run records the scene by its parameters"):
        long_run.run(scene, jm.CPDI(), dt=1e-3, steps=20, chunk=5, progress=False, out=tmp_path / "a.npz")


def test_a_checkpoint_resumed_through_a_link_goes_on_in_the_file_it_names(tmp_path):
    """A link to a checkpoint stays a link: resuming through it continues the file it points to (a
    file written to a link's name otherwise replaces the link, never what it points to)."""
    scene = jm.GasExpansion(cells=4)
    (tmp_path / "data").mkdir()
    target = tmp_path / "data" / "run.npz"
    link = tmp_path / "link.npz"
    long_run.run(scene, jm.SPQ(), dt=1e-5, steps=10, chunk=5, out=target, progress=False)
    with np.load(target) as f:  # as if stopped at step 10 of 20
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["meta"]))
    arrays["meta"] = np.asarray(json.dumps(dict(meta, steps=20, complete=False)))
    np.savez(target, **arrays)
    link.symlink_to(target)
    long_run.resume(link, progress=False)
    assert link.is_symlink() and long_run.load(target)[1]["step"] == 20
