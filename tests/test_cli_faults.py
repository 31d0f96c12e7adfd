"""The command line under faults: a broken run stops computing, Ctrl-C stops a run at once with one
line, output piped into a reader that leaves, runs too large for memory, and folders that cannot be
written or already hold another run's files."""

import json
import os
import re
import signal
import subprocess
import sys
import time

import jax
import pytest
from helpers import usage

import jaxmpm.cli.run as cli_run
from jaxmpm import long_run
from jaxmpm.cli import main

# leaves the grid at step 636 with dt = 1e-5: the right face's traction point first (its particle at 638)
BREAKS = ["run", "gas-expansion", "--interpolator", "spq"]


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def count_chunks(monkeypatch, module) -> list:
    calls = []
    real = module.wait

    def counted(tree):
        calls.append(1)
        return real(tree)

    monkeypatch.setattr(module, "wait", counted)
    return calls


def test_a_broken_run_with_a_huge_step_count_stops_computing(capsys, monkeypatch):
    chunks = count_chunks(monkeypatch, long_run)
    assert main(BREAKS + ["--dt", "1e-5", "--steps", "1000000000", "--json"]) == 3
    captured = capsys.readouterr()
    line = one_line(captured.err)
    assert line.startswith("jaxmpm: the run broke down at step 636") and "left the grid" in line
    # the run went in chunks and stopped after the one that broke down (one chunk holds ~36,000 steps)
    assert len(chunks) == 1
    out = json.loads(captured.out)  # --json still reports: the last good state, status and failure
    assert out["status"] == 4 and out["failure"]["step"] == 636 and out["failure"]["particle"] == 15
    assert out["t"] == pytest.approx(635e-5, rel=1e-12) and out["steps"] == 1000000000
    assert out["wall_s"] is None and len(out["particles"]["x"]) == 16


def test_a_broken_run_to_an_end_time_stops_computing(capsys, monkeypatch):
    chunks = count_chunks(monkeypatch, cli_run)
    argv = BREAKS + ["--t-end", "0.01", "--cfl", "0.5", "--max-steps", "1000000000", "--json"]
    assert main(argv) == 3
    captured = capsys.readouterr()
    assert one_line(captured.err).startswith("jaxmpm: the run broke down at step 4 (after t = ")
    assert len(chunks) == 1
    out = json.loads(captured.out)
    assert out["steps_taken"] == 3 and out["failure"]["step"] == 4 and out["t_end"] == 0.01


@pytest.mark.slow
def test_a_chunked_run_equals_one_scan(capsys, monkeypatch):
    """A run too long for one chunk (a wide grid makes each step slow) equals ``simulate`` bit for bit."""
    import numpy as np

    import jaxmpm as jm

    argv = [
        "run",
        "gas-expansion",
        "pad=20000",
        "beta=20",
        "--interpolator",
        "mpq",
        "--artificial-cells",
        "1",
    ]
    chunks = count_chunks(monkeypatch, cli_run)  # the chunks of the run to --t-end
    assert main(argv + ["--t-end", "0.02", "--cfl", "0.5", "--max-steps", "100000", "--json"]) == 0
    to_end = json.loads(capsys.readouterr().out)
    assert len(chunks) >= 2  # the chunk is ~90 steps here: both runs take more than one (2 measured)
    chunks = count_chunks(monkeypatch, long_run)  # the chunks of the run to --steps (run_timed's)
    assert main(argv + ["--dt", "1e-4", "--steps", "200", "--json"]) == 0
    fixed = json.loads(capsys.readouterr().out)
    assert len(chunks) >= 2  # 3 measured (200 steps)
    scene = jm.GasExpansion(pad=20000, beta=20.0)
    a = jm.simulate(scene, jm.MPQ(), t_end=0.02, cfl=0.5, max_steps=100000, artificial_cells=1)
    b = jm.simulate(scene, jm.MPQ(), dt=1e-4, steps=200, artificial_cells=1)
    assert to_end["steps_taken"] == int(a.state.step) > 100
    for out, sol in ((to_end, a), (fixed, b)):
        np.testing.assert_array_equal(out["particles"]["x"], np.asarray(sol.state.x[:, 0]))
        np.testing.assert_array_equal(out["particles"]["F"], np.asarray(sol.state.F[:, 0, 0]))


def _cli(*args: str, **kwargs) -> subprocess.Popen:
    env = dict(os.environ, JAXMPM_PROGRESS="0")
    return subprocess.Popen(
        [sys.executable, "-m", "jaxmpm.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        **kwargs,
    )


@pytest.mark.slow
def test_ctrl_c_stops_a_plain_run_within_a_second():
    # A wide grid (each step ~3 ms, chunks of ~70 steps) and runs that would take days: one to a step
    # count, one to an end time, started together (one wait for both to be past start-up and
    # compilation).
    timings = [
        ["--dt", "1e-7", "--steps", "1000000000"],
        ["--t-end", "100", "--cfl", "0.05", "--max-steps", "1000000000"],
    ]
    common = [
        "run",
        "gas-expansion",
        "pad=20000",
        "beta=1",
        "--interpolator",
        "mpq",
        "--artificial-cells",
        "1",
    ]
    procs = [_cli(*common, *timing) for timing in timings]
    try:
        time.sleep(12)  # past start-up and compilation
        for p in procs:
            assert p.poll() is None, p.communicate()
        for timing, p in zip(timings, procs):
            t0 = time.perf_counter()
            p.send_signal(signal.SIGINT)
            out, err = p.communicate(timeout=60)
            waited = time.perf_counter() - t0
            assert p.returncode == 130, (timing, err)
            assert one_line(err).startswith("jaxmpm: interrupted at step "), timing
            assert waited < 1.5, (timing, waited)
    finally:  # a run that did not stop must not go on computing after the test
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.communicate()


def test_a_ctrl_c_that_python_ignored_is_raised_at_the_next_poll():
    """Python ignores a KeyboardInterrupt raised inside a garbage-collector callback (JAX registers
    one); the command line's latch remembers the Ctrl-C, and the next poll of a running chunk raises
    it, so the run stops instead of going on computing."""
    import jax.numpy as jnp

    from jaxmpm.long_run import InterruptLatch, wait

    previous = signal.getsignal(signal.SIGINT)
    try:
        latch = InterruptLatch.install()
        assert wait({"a": jnp.ones(3)})["a"].shape == (3,)  # nothing pressed: it waits and returns
        try:
            latch(signal.SIGINT, None)  # as if the signal arrived
        except KeyboardInterrupt:
            pass  # ... and the exception was lost where it was raised
        with pytest.raises(KeyboardInterrupt):
            wait({"a": jnp.ones(3)})
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_ctrl_c_that_python_ignored_prints_nothing():
    """A Ctrl-C that lands in a callback Python cannot raise from (here a weakref's) would print
    ``Exception ignored in ...`` and a traceback through ``sys.unraisablehook``. Once the latch saw
    it, it is not printed (the next poll raises it); any other ignored exception, and an interrupt no
    latch saw, still reach the hook there was."""
    import weakref

    from jaxmpm.long_run import InterruptLatch

    class Target:
        pass

    def lose(exc):
        """Raise ``exc`` where Python ignores it: in the callback of a weakref whose target dies."""

        def callback(_):
            raise exc

        target = Target()
        ref = weakref.ref(target, callback)
        del target
        return ref

    reported = []
    record = lambda unraisable: reported.append(type(unraisable.exc_value))
    previous, previous_hook = signal.getsignal(signal.SIGINT), sys.unraisablehook
    sys.unraisablehook = record
    try:
        latch = InterruptLatch.install()
        lose(KeyboardInterrupt())  # no Ctrl-C seen yet: not the latch's, reported
        try:
            latch(signal.SIGINT, None)  # the Ctrl-C arrives ...
        except KeyboardInterrupt:
            lose(KeyboardInterrupt())  # ... and is raised in a callback: lost, not reported
        lose(RuntimeError("another fault"))
        InterruptLatch.install()  # installed again: the hook is wrapped once
        assert sys.unraisablehook.previous is record
        lose(RuntimeError("another fault"))
        assert reported == [KeyboardInterrupt, RuntimeError, RuntimeError]
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = previous_hook


@pytest.mark.slow
def test_output_into_a_closed_pipe_is_quiet():
    reader = subprocess.Popen(["head", "-1"], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL)
    env = dict(os.environ)
    p = subprocess.run(
        [sys.executable, "-m", "jaxmpm.cli", "scenes"],
        stdout=reader.stdin,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    reader.stdin.close()
    reader.wait()
    assert p.stderr == "" and p.returncode in (0, 141)


@pytest.mark.slow
def test_output_with_standard_output_closed_is_one_line_and_status_74():
    """``jaxmpm scenes >&-``: the process has no standard output (Python's ``sys.stdout`` is None);
    what the command writes there cannot be written, said in one line, no traceback."""
    p = subprocess.run(
        ["bash", "-c", 'exec "$0" -m jaxmpm.cli scenes >&-', sys.executable],
        stderr=subprocess.PIPE,
        text=True,
    )
    assert p.returncode == 74 and p.stderr == "jaxmpm: error: cannot write standard output: it is closed\n"


@pytest.mark.parametrize(
    "params",
    [["cells=1000000000"], ["dim=2", "cells=20000"], ["dim=3", "cells=200"]],
    ids=["1d", "2d", "3d"],
)
def test_a_run_too_large_for_memory_is_refused_before_anything_is_built(capsys, params):
    assert (
        main(["run", "gas-expansion", *params, "--interpolator", "mpq", "--dt", "1e-9", "--steps", "1"]) == 2
    )
    line = one_line(capsys.readouterr().err)
    assert line.startswith("jaxmpm: error: the run (") and "particles" in line and "needs about" in line
    assert "reduce cells, ppc or pad" in line


def test_a_step_count_beyond_the_counter_is_refused(capsys):
    assert main(BREAKS + ["--dt", "1e-5", "--steps", "10000000000"]) == 2
    assert "steps must be <= 2147483647" in one_line(capsys.readouterr().err)


def test_vtk_and_study_folders_are_checked_first(capsys, tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("mine")
    small = ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--steps", "2"]
    assert main(small + ["--vtk", str(a_file)]) == 2
    assert "is a file, not a folder" in one_line(capsys.readouterr().err)
    assert main(small + ["--vtk", str(a_file / "below")]) == 2
    assert "cannot write there" in one_line(capsys.readouterr().err)
    assert main(["study", "talk", "--small", "--out", str(a_file / "below")]) == 2
    assert "--out" in one_line(capsys.readouterr().err)
    assert a_file.read_text() == "mine"
    frames = tmp_path / "frames"
    assert main(small + ["--vtk", str(frames)]) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in frames.iterdir()}
    assert main(small + ["--vtk", str(frames)]) == 2  # another run's frames are not replaced
    assert "already holds ParaView files" in one_line(capsys.readouterr().err)
    assert {p.name: p.read_bytes() for p in frames.iterdir()} == before
    assert main(small + ["--vtk", str(frames), "--overwrite"]) == 0


def test_a_run_refused_after_its_vtk_folder_was_made_leaves_no_folder(capsys, tmp_path):
    """``--devices`` beyond the devices there is refused once the ``--vtk`` folder is made: the command
    removes the folder it made (still empty), and leaves a folder that was there before."""
    small = ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--steps", "2"]
    too_many = ["--devices", str(len(jax.devices()) + 1)]
    frames = tmp_path / "frames"
    assert main(small + ["--vtk", str(frames)] + too_many) == 2
    assert "--devices" in one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []
    frames.mkdir()
    assert main(small + ["--vtk", str(frames)] + too_many) == 2
    capsys.readouterr()
    assert frames.is_dir()
    # a run refused for its memory once the folder and its missing parents are made removes them all,
    # and none that was there before
    huge = [
        "run",
        "gas-expansion",
        "cells=999999999",
        "--interpolator",
        "mpq",
        "--dt",
        "1e-5",
        "--steps",
        "4",
    ]
    assert main(huge + ["--vtk", str(frames / "a" / "b" / "c")]) == 2
    assert "of memory" in one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == [frames] and list(frames.iterdir()) == []


def test_vtk_refuses_a_folder_holding_a_legacy_vtk_file_of_the_users(capsys, tmp_path):
    mine = tmp_path / "frames" / "particles_00000.vtk"
    mine.parent.mkdir()
    mine.write_text("MINE")
    small = ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--steps", "2"]
    assert main(small + ["--vtk", str(mine.parent)]) == 2
    assert "already holds ParaView files (particles_00000.vtk)" in one_line(capsys.readouterr().err)
    assert mine.read_text() == "MINE"


def test_resume_json_of_a_run_that_breaks_down_prints_the_last_good_state(capsys, tmp_path):
    out = tmp_path / "broken.npz"
    run = ["run", "gas-expansion", "cells=3", "--interpolator", "mpq", "--dt", "5e-4", "--steps", "40"]
    assert main(run + ["--out", str(out), "--no-progress"]) == 3  # dt beyond the stable limit at step 1
    capsys.readouterr()
    assert main(["resume", str(out), "--json", "--no-progress"]) == 3
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report["status"] == 8 and report["failure"]["step"] == 1 and report["failure"]["particle"] == 0
    assert "The last good state is step 0" in one_line(captured.err)


def test_a_t_end_run_that_breaks_at_its_first_step_gives_no_hint_that_is_refused(capsys):
    # with one cell of padding and cfl = 1, the free surface particle reaches past the grid at step 1
    argv = [
        "run",
        "vacuum-expansion",
        "pad=1",
        "--interpolator",
        "mpq",
        "--t-end",
        "1e-1",
        "--max-steps",
        "100",
    ]
    assert main(argv + ["--cfl", "1"]) == 3
    line = one_line(capsys.readouterr().err)
    assert line.endswith("The last good state is step 0. It is the initial state.")
    assert "--t-end 0" not in line


def test_a_scene_parameter_given_under_both_its_names_is_refused(capsys):
    argv = ["run", "detonation", "smooth=true", "smooth_burn=false", "--interpolator", "cpdi"]
    assert main(argv + ["--dt", "1e-9", "--steps", "1"]) == 2
    assert "smooth_burn is given twice: 'smooth=true' and 'smooth_burn=false'" in one_line(
        capsys.readouterr().err
    )


@pytest.mark.parametrize(
    "fit, match",
    [
        (dict(fitted={}, offsets={}, covariance_theta={}), "fits no parameter"),
        (
            dict(
                fitted={"gamma": 1.000001, "P0": 101795.9},
                offsets={"gamma": 1.0, "P0": 1e5},
                covariance_theta={
                    "gamma": {"gamma": 1.0e13, "P0": 9.8e5},
                    "P0": {"gamma": 9.8e5, "P0": 0.0995},
                },
            ),
            r"the data hardly determine gamma \(standard deviation of log\(gamma - offset\) 3.16e\+06\)",
        ),
    ],
)
def test_ensemble_from_a_fit_with_nothing_to_draw_from_is_refused(capsys, tmp_path, fit, match):
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(dict(scene="gas-slab", **fit)))
    assert main(["ensemble", "gas-slab", "--members", "4", "--from-fit", str(path)]) == 2
    line = one_line(capsys.readouterr().err)
    assert re.search(match, line), line


def test_json_is_standard_json_with_null_for_values_that_are_not_finite(capsys):
    argv = ["run", "gas-expansion", "cells=3", "beta=1e308", "--interpolator", "mpq", "--dt", "1e-5"]
    main(argv + ["--steps", "5", "--json"])
    out = capsys.readouterr().out

    def refuse(token):
        raise AssertionError(f"non-standard JSON token {token}")

    report = json.loads(out, parse_constant=refuse)
    assert report["diagnostics"]["energy"] is None  # the kinetic energy overflowed


def test_out_is_not_overwritten_without_the_flag(capsys, tmp_path):
    out = tmp_path / "run.npz"
    small = ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--no-progress"]
    assert main(small + ["--steps", "20", "--chunk", "10", "--out", str(out)]) == 0
    capsys.readouterr()
    saved = out.read_bytes()
    assert main(small + ["--steps", "30", "--chunk", "10", "--out", str(out)]) == 2
    line = one_line(capsys.readouterr().err)
    assert "already exists" in line and "--overwrite" in line and "jaxmpm resume" in line
    assert out.read_bytes() == saved
    assert main(small + ["--steps", "30", "--chunk", "10", "--out", str(out), "--overwrite"]) == 0
    assert long_run.load(out)[1]["step"] == 30
    assert main(small + ["--steps", "3", "--overwrite"]) == 2  # nothing to replace
    assert "--overwrite goes with" in one_line(capsys.readouterr().err)


SMALL = ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--steps", "2"]


@pytest.mark.parametrize(
    "argv, match",
    [
        (SMALL + ["--steps", "3"], "--steps is given twice"),
        (SMALL + ["--interpolator", "mpq"], "--interpolator is given twice"),
        (SMALL + ["--max-steps", "4"], "--max-steps goes with --t-end"),
        (SMALL + ["--cfl", "0.3"], "--cfl goes with --t-end"),
        (SMALL + ["--chunk", "4"], "--chunk needs --out FILE"),
        (SMALL + ["--vtk", ""], "--vtk needs a folder, got an empty name"),
        (SMALL + ["beta=2", "--bogus"], "unrecognized arguments: --bogus"),
        (
            SMALL[:4] + ["--t-end", "1e-4", "--max-steps", "9", "--cfl", "0.8", "--cfl-limit", "0.5"],
            "--cfl 0.8 is above --cfl-limit 0.5: every full step would fail",
        ),
        (
            ["ensemble", "gas-expansion", "--members", "2", "--vary", "beta=1:2", "--cfl", "1.5"],
            "--cfl must be <= 1 (every full step above it fails its check), got 1.5",
        ),
        (["study", "talk", "--small", "--out", ""], "--out needs a folder, got an empty name"),
        (["bench", "--sizes", "100", "--out", ""], "--out needs a folder, got an empty name"),
        (
            ["ensemble", "gas-expansion", "--members", "2", "--vary", "beta=1:2", "--dt", "1e-5"]
            + ["--steps", "2", "--max-steps", "3"],
            "--max-steps goes with a run to an end time, not --dt and --steps",
        ),
        (
            ["ensemble", "gas-expansion", "--members", "2", "--members", "3", "--vary", "beta=1:2"],
            "--members is given twice",
        ),
    ],
)
def test_an_option_given_twice_or_doing_nothing_is_refused(capsys, tmp_path, monkeypatch, argv, match):
    monkeypatch.chdir(tmp_path)  # an empty folder name must not write into the current folder
    usage(capsys, argv, match)
    assert list(tmp_path.iterdir()) == []


def test_scene_parameters_may_follow_the_options(capsys):
    """``name=value`` after the options is a scene parameter, as before them: the same report."""
    reports = []
    for argv in (
        ["run", "gas-expansion", "beta=2", "cells=3"] + SMALL[2:] + ["--json"],
        SMALL + ["beta=2", "--json", "cells=3"],
    ):
        assert main(argv) == 0
        reports.append(json.loads(capsys.readouterr().out))
    assert reports[0]["params"]["beta"] == 2.0 and reports[0]["params"]["cells"] == 3
    for report in reports:
        report.pop("wall_s"), report.pop("compile_s")
    assert reports[0] == reports[1]


def test_a_study_keeps_the_files_of_others_in_its_folder(capsys, tmp_path, monkeypatch):
    import jaxmpm.studies.talk as talk

    ran = []
    monkeypatch.setattr(talk, "main", lambda out, small: ran.append(out))  # what --out gets, not the study
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "table.md").write_text("MINE")
    line = usage(capsys, ["study", "talk", "--small", "--out", str(mine)], "--out")
    assert "already holds files that `jaxmpm study talk` did not write (table.md)" in line
    assert "--overwrite" in line and ran == [] and (mine / "table.md").read_text() == "MINE"
    (mine / ".jaxmpm-study").write_text("convergence\n")  # another study's folder
    (mine / "orders.md").write_text("theirs")  # a file of convergence's
    line = usage(capsys, ["study", "talk", "--small", "--out", str(mine)], "--out")
    assert "holds files that `jaxmpm study convergence` wrote (orders.md) and others (table.md)" in line
    (mine / "orders.md").unlink()
    assert main(["study", "talk", "--small", "--out", str(mine), "--overwrite"]) == 0
    assert (mine / ".jaxmpm-study").read_text() == "talk\n" and ran == [str(mine)]
    assert main(["study", "talk", "--small", "--out", str(mine)]) == 0  # its own folder, again
    fresh = tmp_path / "fresh"
    assert main(["study", "talk", "--small", "--out", str(fresh)]) == 0
    assert (fresh / ".jaxmpm-study").read_text() == "talk\n" and len(ran) == 3


def test_a_refusal_credits_another_study_only_with_the_files_it_writes(capsys, tmp_path, monkeypatch):
    """In a folder marked as another study's, the refusal names the files that study writes apart from
    the rest, which are not its."""
    import jaxmpm.studies.talk as talk

    monkeypatch.setattr(talk, "main", lambda out, small: None)
    folder = tmp_path / "theirs"
    folder.mkdir()
    (folder / ".jaxmpm-study").write_text("convergence\n")
    (folder / "notes.txt").write_text("MINE")
    line = usage(capsys, ["study", "talk", "--small", "--out", str(folder)], "--out")
    assert "wrote" not in line
    assert "holds files (notes.txt), and is marked as the folder of `jaxmpm study convergence`" in line
    (folder / "orders.md").write_text("theirs")  # a file the convergence study writes
    line = usage(capsys, ["study", "talk", "--small", "--out", str(folder)], "--out")
    assert "files that `jaxmpm study convergence` wrote (orders.md) and others (notes.txt)" in line
    (folder / "notes.txt").unlink()
    line = usage(capsys, ["study", "talk", "--small", "--out", str(folder)], "--out")
    assert "already holds files that `jaxmpm study convergence` wrote (orders.md);" in line
    assert (folder / "orders.md").read_text() == "theirs"


def test_a_file_named_as_the_study_mark_that_names_no_study_is_the_users(capsys, tmp_path, monkeypatch):
    """A ``.jaxmpm-study`` that does not name a study is a file of the user's, kept as any other."""
    import jaxmpm.studies.talk as talk

    monkeypatch.setattr(talk, "main", lambda out, small: None)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / ".jaxmpm-study").write_text("my own notes about this folder\n")
    line = usage(capsys, ["study", "talk", "--small", "--out", str(mine)], "--out")
    assert "already holds files that `jaxmpm study talk` did not write (.jaxmpm-study)" in line
    assert (mine / ".jaxmpm-study").read_text() == "my own notes about this folder\n"


def test_a_study_that_draws_figures_checks_for_matplotlib_first(capsys, tmp_path, monkeypatch):
    import jaxmpm.studies.convergence as convergence
    import jaxmpm.studies.talk as talk

    ran = []
    monkeypatch.setattr(talk, "main", lambda out, small: ran.append("talk"))
    monkeypatch.setattr(convergence, "main", lambda out, small, release: ran.append("convergence"))
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` fails
    line = usage(capsys, ["study", "talk", "--small", "--out", str(tmp_path / "talk")], "matplotlib")
    assert "study talk draws figures with matplotlib, which is not installed" in line
    assert ran == [] and not (tmp_path / "talk").exists()
    assert main(["study", "convergence", "--small", "--out", str(tmp_path / "orders")]) == 0  # tables only
    assert ran == ["convergence"]


def test_a_run_of_zero_steps_writes_its_one_frame(capsys, tmp_path):
    frames = tmp_path / "frames"
    argv = ["run", "gas-expansion", "--interpolator", "mpq", "--dt", "1e-5", "--steps", "0"]
    assert main(argv + ["--vtk", str(frames), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["vtk"] == dict(dir=str(frames), frames=1, every=1)
    assert sorted(p.name for p in frames.iterdir()) == [
        "grid.pvd",
        "grid_00000.vtk",
        "particles.pvd",
        "particles_00000.vtk",
    ]


def test_vtk_overwrite_leaves_one_run_in_the_folder(capsys, tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "notes.txt").write_text("MINE")
    argv = ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5"]
    assert main(argv + ["--steps", "20", "--vtk", str(frames), "--vtk-every", "2"]) == 0
    assert len(list(frames.glob("particles_*.vtk"))) == 11
    assert main(argv + ["--steps", "2", "--vtk", str(frames), "--vtk-every", "1", "--overwrite"]) == 0
    capsys.readouterr()
    names = sorted(p.name for p in frames.iterdir())
    assert names == [
        "grid.pvd",
        "grid_00000.vtk",
        "grid_00001.vtk",
        "grid_00002.vtk",
        "notes.txt",
        "particles.pvd",
        "particles_00000.vtk",
        "particles_00001.vtk",
        "particles_00002.vtk",
    ]
    assert (frames / "notes.txt").read_text() == "MINE"
    assert "particles_00003" not in (frames / "particles.pvd").read_text()


def test_an_ensemble_of_a_cold_gas_runs_with_its_end_time_and_step_bound_given(capsys):
    argv = ["ensemble", "noh", "cells=8", "--members", "2", "--vary", "u0=0.5:1", "--interpolator", "cpdi"]
    line = usage(capsys, argv, "give --t-end T and --max-steps N")  # the cold gas has no sound speed
    assert "the default --t-end and --max-steps come from the sound speed" in line
    assert main(argv + ["--t-end", "0.05", "--max-steps", "400", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] == 2 and report["timing"] == dict(t_end=0.05, cfl=0.5, max_steps=400)
    assert [r["t"] for r in report["results"]] == [0.05, 0.05]


@pytest.mark.parametrize(
    "options, named",
    [
        (["--t-end", "-1", "--max-steps", "5"], "--t-end must be > 0, got -1.0"),
        (["--t-end", "1e-4", "--max-steps", "0"], "--max-steps must be an integer >= 1, got 0"),
        (["--dt", "1e-5", "--steps", "2", "--cfl-limit", "-1"], "--cfl-limit must be > 0, got -1.0"),
        (
            ["--dt", "1e-5", "--steps", "2", "--artificial-cells", "-1"],
            "--artificial-cells must be an integer >= 0, got -1",
        ),
    ],
)
def test_a_refused_option_is_named_as_typed(options, named, capsys):
    """The library's checks name their arguments (``t_end``); the command line names the option the
    user typed (``--t-end``)."""
    assert main(["run", "gas-expansion", "--interpolator", "spq", *options]) == 2
    assert one_line(capsys.readouterr().err) == f"jaxmpm: error: {named}"
