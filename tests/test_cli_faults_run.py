"""``jaxmpm run`` and ``jaxmpm resume`` under faults: scene parameters that round-trip through a saved
run, a report with nothing yet to measure, output that cannot be written (exit status 74, the files
saved before intact), Ctrl-C before the command's own handler, and messages in the command line's
terms."""

import errno
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from helpers import usage

import jaxmpm as jm
import jaxmpm.vtk as vtk
from jaxmpm.cli import main

SMALL = ["run", "gas-expansion", "cells=2", "--interpolator", "mpq", "--dt", "1e-5", "--steps", "2"]
EARLY_DETONATION = ["run", "detonation", "cells=20", "--interpolator", "cpdi"]  # the front is < 12 cells in


def failed(capsys, argv, status: int) -> str:
    """Run ``jaxmpm argv``: exit status ``status``, one line on stderr (returned), no traceback."""
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == status, (argv, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.slow
def test_every_scene_parameter_round_trips():
    for name, cls in jm.SCENES.items():
        dims = (1, 2, 3) if "dim" in cls.parameters() else (None,)
        for dim in dims:
            try:
                scene = cls() if dim is None else cls(dim=dim)
            except ValueError:  # a dim this scene does not take (the blast: 2 and 3)
                continue
            again = cls(**scene.parameter_values())
            for key, value in cls.parameters().items():
                assert np.array_equal(getattr(again, key), getattr(scene, key)), (name, dim, key)
    assert jm.AxisAligned(dim=1).parameter_values()["dim"] == 1  # its default is 2
    assert "dim" not in jm.GasExpansion(dim=1).parameter_values()  # its default is 1: a 1D scene


@pytest.mark.slow
def test_a_1d_axis_aligned_run_saved_and_resumed(capsys, tmp_path):
    out = tmp_path / "aa.npz"
    argv = ["run", "axis-aligned", "cells=2", "dim=1", "--interpolator", "cpdi", "--dt", "1e-4"]
    assert main(argv + ["--steps", "2", "--out", str(out), "--no-progress", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["params"]["dim"] == 1
    assert jm.long_run.load(out)[1]["params"]["dim"] == 1
    assert main(["resume", str(out), "--no-progress", "--json"]) == 0
    captured = capsys.readouterr()
    resumed = json.loads(captured.out)
    assert captured.err == "" and resumed["params"]["dim"] == 1 and resumed["steps"] == 2
    assert len(resumed["particles"]["x"]) == 4 and not isinstance(resumed["particles"]["x"][0], list)


@pytest.mark.slow
def test_a_detonation_with_nothing_to_measure_yet_reports_null_errors(capsys, tmp_path):
    assert main(EARLY_DETONATION + ["--t-end", "1e-7", "--max-steps", "20", "--json"]) == 0
    errors = json.loads(capsys.readouterr().out)["errors"]
    assert errors["F_rms_rel"] is None and errors["p_rms_rel"] is None and errors["x_max_abs"] is None
    assert errors["separation_max"] is not None
    out = tmp_path / "det.npz"
    assert main(EARLY_DETONATION + ["--dt", "1e-8", "--steps", "3", "--out", str(out), "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and "errors against the exact solution" in captured.out
    assert "not measurable yet" in captured.out and "errors: separation_max=" in captured.out
    assert main(["resume", str(out), "--no-progress", "--json"]) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert resumed["errors"]["F_rms_rel"] is None and resumed["errors"]["p_rms_rel"] is None


@pytest.mark.slow
def test_a_run_that_breaks_down_reports_its_vtk_frames(capsys, tmp_path):
    frames = tmp_path / "frames"
    argv = ["run", "gas-expansion", "cells=2", "--interpolator", "mpq", "--dt", "1e-3", "--steps", "10"]
    argv += ["--cfl-limit", "none", "--vtk", str(frames), "--vtk-every", "1", "--json"]
    assert main(argv) == 3
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["status"] != 0 and out["vtk"] == dict(dir=str(frames), frames=3, every=1)
    assert len(list(frames.glob("particles_*.vtk"))) == 3 and (frames / "particles.pvd").exists()
    assert "broke down at step 3" in captured.err


@pytest.mark.parametrize("width, shown", [("0", "0.0"), ("0.5", "0.5"), ("1e-13", "1e-13")])
def test_a_burn_width_below_one_is_named_as_given(capsys, width, shown):
    for scene in ("detonation", "gurney-slab"):
        argv = ["run", scene, f"burn_width={width}", "--interpolator", "cpdi", "--dt", "1e-9", "--steps", "1"]
        line = usage(capsys, argv, "burn_width must be >= 1 (the burn's length in particle sizes), got ")
        assert line.endswith(f"got {shown}"), line


BAD_ADDRESSES = ["garbage", "host:", ":1234", "host:0", "host:99999", "host:12x", "::1:5"]


@pytest.mark.parametrize("address", BAD_ADDRESSES)
def test_a_coordinator_without_a_port_is_refused(capsys, tmp_path, address):
    distributed = ["--coordinator", address, "--processes", "1", "--process-id", "0"]
    expected = "--coordinator must be HOST:PORT (a host name or address and a port from 1 to 65535, "
    line = usage(capsys, SMALL + distributed, expected)
    assert line.endswith(f"got {address!r}")
    usage(capsys, ["resume", str(tmp_path / "none.npz")] + distributed, expected)


def test_output_to_a_full_disk_is_one_line_with_status_74(capsys, monkeypatch):
    with open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", full)
        line = failed(capsys, ["scenes"], 74)
    assert line == "jaxmpm: error: cannot write standard output: No space left on device"


@pytest.mark.slow
def test_a_report_to_a_full_disk_is_one_line_with_status_74(capsys, monkeypatch):
    with open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", full)
        line = failed(capsys, SMALL + ["--json"], 74)
    assert line == "jaxmpm: error: cannot write standard output: No space left on device"


def fill_disk_after(monkeypatch, files: int) -> None:
    """Make ``jm.vtk``'s writes fail as on a full disk once ``files`` files are written, the failing
    one having written half of itself."""
    real = vtk.write_whole
    count = [0]

    def write_whole(path, write, **kwargs):
        count[0] += 1
        if count[0] > files:

            def half(f):
                f.write(b"# vtk DataFile Version 3.0\n")
                raise OSError(errno.ENOSPC, "No space left on device")

            return real(path, half, **kwargs)
        return real(path, write, **kwargs)

    monkeypatch.setattr(vtk, "write_whole", write_whole)


@pytest.mark.slow
def test_a_vtk_series_that_fills_the_disk_leaves_nothing_behind(capsys, tmp_path, monkeypatch):
    frames = tmp_path / "frames"
    argv = SMALL + ["--vtk", str(frames), "--vtk-every", "1", "--no-progress"]
    fill_disk_after(monkeypatch, 3)
    line = failed(capsys, argv + ["--json"], 74)
    assert line == f"jaxmpm: error: cannot write --vtk {frames}: No space left on device"
    assert not frames.exists() and list(tmp_path.iterdir()) == []  # the folder it made is gone
    monkeypatch.undo()  # the disk has room again: the same command runs
    assert main(argv) == 0
    assert sorted(p.name for p in frames.iterdir())[-2:] == ["particles_00001.vtk", "particles_00002.vtk"]


@pytest.mark.slow
def test_a_vtk_series_that_fills_the_disk_keeps_the_files_there(capsys, tmp_path, monkeypatch):
    frames = tmp_path / "frames"
    frames.mkdir()
    before = {"particles_00000.vtk": "OLD0", "grid.pvd": "OLD", "notes.txt": "mine"}
    before["particles_00007.vtk"] = "OLD7"  # a frame the new series would not replace
    for name, text in before.items():
        (frames / name).write_text(text)
    fill_disk_after(monkeypatch, 5)
    line = failed(capsys, SMALL + ["--vtk", str(frames), "--vtk-every", "1", "--overwrite"], 74)
    assert line.startswith(f"jaxmpm: error: cannot write --vtk {frames}: ")
    assert {p.name: p.read_text() for p in frames.iterdir()} == before  # as it was: no new, no temporary


def test_a_full_disk_while_saving_a_run_is_status_74(capsys, tmp_path, monkeypatch):
    out = tmp_path / "run.npz"
    mine = tmp_path / "run.npz.tmp"
    mine.write_text("MINE")  # a file of the user's beside the run: never written over

    def full(f, **arrays):
        f.write(b"PK\x03\x04 half an archive")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(jm.long_run.np, "savez", full)
    line = failed(capsys, SMALL + ["--out", str(out), "--no-progress"], 74)
    assert line == f"jaxmpm: error: cannot write --out {out}: No space left on device"
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz.tmp"] and mine.read_text() == "MINE"


@pytest.mark.slow
def test_ctrl_c_before_the_command_handles_it_is_one_line_and_130():
    # SIGINT while the console script is still starting (as during the imports), before main installs
    # its handler: the process leaves at once with one line.
    code = (
        "import os, signal, time\n"
        "import jaxmpm.cli as cli\n"
        "def main():\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(30)\n"
        "    return 0\n"
        "cli.main = main\n"
        "cli.console()\n"
    )
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)
    assert proc.returncode == 130 and proc.stderr == "jaxmpm: interrupted\n" and proc.stdout == ""


def test_grad_on_a_scene_without_an_exact_solution_says_what_it_needs(capsys):
    for scene, name in (("noh", "u0"), ("shock-tube", "x0")):
        argv = ["run", scene, "cells=8", "--interpolator", "cpdi", "--dt", "1e-5", "--steps", "2"]
        line = usage(capsys, argv + ["--grad", name], f"and {scene} has none; scenes with one: gas-expansion")
        assert line.startswith("jaxmpm: error: --grad gives d(F_rms_rel)/d(NAME)")
        assert "error must" not in line
    usage(capsys, SMALL + ["--grad", "cells"], "--grad: cells is structural (an integer), so it has no")


def test_messages_in_the_command_lines_terms(capsys, tmp_path):
    mine = tmp_path / "notes.txt"
    mine.write_text("precious")
    line = usage(capsys, SMALL + ["--out", str(mine)], f"--out {mine} already exists (an existing file")
    assert "pass --overwrite to replace it" in line and "overwrite=True" not in line
    assert mine.read_text() == "precious"
    usage(
        capsys,
        ["run"],
        "jaxmpm run needs a scene name (see `jaxmpm scenes`) and --interpolator (one of spq, gimp,",
    )
    usage(capsys, ["run", "gas-expansion"], "jaxmpm run needs --interpolator (one of spq,")
    line = usage(capsys, SMALL + ["--viscosity", "-1,0.2"], "--viscosity must be QUAD,LIN or QUAD,LIN,SHEAR")
    assert line.endswith("got '-1,0.2': c_quad must be >= 0, got -1.0")
    line = usage(capsys, SMALL + ["--viscosity", "1"], "--viscosity must be QUAD,LIN or QUAD,LIN,SHEAR")
    assert line.endswith("got '1' (1 number)")


def test_ctrl_c_while_jaxmpm_is_imported_is_one_line_and_130():
    # The console script's launcher answers SIGINT before it imports jaxmpm (seconds, with JAX): here
    # the signal arrives as the import of the command line starts.
    code = (
        "import builtins, os, signal, time\n"
        "real = builtins.__import__\n"
        "def slow_import(name, *args, **kwargs):\n"
        "    if name == 'jaxmpm.cli':\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        time.sleep(30)\n"
        "    return real(name, *args, **kwargs)\n"
        "import jaxmpm_console\n"
        "builtins.__import__ = slow_import\n"
        "jaxmpm_console.console()\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130 and proc.stderr == "jaxmpm: interrupted\n" and proc.stdout == ""


# -- --grad, the report's keys, and options that would do nothing ------------------------------------


def test_grad_past_t_valid_is_refused_before_the_run(capsys):
    argv = ["run", "riemann", "cells=32", "h=0.03125", "--interpolator", "cpdi", "--dt", "2e-3"]
    line = failed(capsys, [*argv, "--steps", "400", "--grad", "P0"], 2)
    assert line == (
        "jaxmpm: error: --grad: the run ends at t = 0.8, past t_valid = 0.183937, where the scene's exact "
        "solution stops holding, so F_rms_rel is not measured there: give fewer --steps or a smaller --dt"
    )


@pytest.mark.slow
def test_grad_where_nothing_is_measured_yet_is_null_not_a_number(capsys):
    # the front has not moved far enough in: F_rms_rel is null, and so is its derivative
    argv = [*EARLY_DETONATION, "--dt", "1e-9", "--steps", "10", "--viscosity", "--grad", "D"]
    assert main([*argv, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["errors"]["F_rms_rel"] is None and out["grad"] == {"D": None} and out["grad_s"] is None
    assert main(argv) == 0
    assert "d(F_rms_rel)/d D: none (F_rms_rel is not measured at this time)" in capsys.readouterr().out


def test_grad_names_the_option_of_a_name_given_twice(capsys):
    assert failed(capsys, [*SMALL, "--grad", "beta,beta"], 2) == "jaxmpm: error: --grad: beta is given twice"


def test_a_shear_coefficient_in_1d_is_refused(capsys):
    line = failed(capsys, [*SMALL, "--viscosity", "2,0.2,0.5"], 2)
    assert line.startswith("jaxmpm: error: --viscosity 2,0.2,0.5: the third number, SHEAR, is a shear ")
    assert "vanishes in 1D, and gas-expansion is 1D here: give QUAD,LIN" in line


@pytest.mark.slow
@pytest.mark.parametrize(
    "timing", [["--dt", "1e-4", "--steps", "0"], ["--t-end", "0.5", "--max-steps", "5000"]]
)
def test_the_euler_errors_keys_are_null_where_not_measured(capsys, timing):
    # at t = 0 and past t_valid (0.5 > the shock tube's) the exact Euler solution is not measured
    argv = ["run", "shock-tube", "cells=32", "--interpolator", "cpdi", "--viscosity", *timing, "--json"]
    assert main(argv) == 0
    errors = json.loads(capsys.readouterr().out)["errors"]
    assert {k: errors[k] for k in ("rho_L1", "u_L1", "p_L1", "e_L1")} == dict.fromkeys(
        ("rho_L1", "u_L1", "p_L1", "e_L1")
    )


@pytest.mark.slow
def test_a_breakdown_report_keeps_devices_and_resume_keeps_viscosity(capsys, tmp_path):
    argv = ["run", "gas-expansion", "cells=2", "--interpolator", "mpq", "--dt", "1e-2", "--steps", "2"]
    assert main([*argv, "--devices", "1", "--json"]) == 3
    broken = json.loads(capsys.readouterr().out)
    assert broken["status"] != 0 and broken["devices"] == 1
    out = str(tmp_path / "v.npz")
    assert main([*SMALL, "--viscosity", "1,0.1", "--out", out, "--json", "--no-progress"]) == 0
    ran = json.loads(capsys.readouterr().out)
    assert main(["resume", out, "--json"]) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert resumed["viscosity"] == ran["viscosity"] == [1.0, 0.1]
    assert list(resumed)[:9] == list(ran)[:9]  # the same settings, in the same order


@pytest.mark.parametrize(
    "late, message",
    [
        ("t-end=3", "unknown parameter 't-end' for scene gas-expansion; allowed: "),
        ("beta", "scene parameters are name=value, got 'beta'"),
    ],
)
def test_scene_parameters_after_the_options_are_read_as_those_before_them(capsys, late, message):
    before = failed(capsys, ["run", "gas-expansion", late, *SMALL[2:]], 2)
    after = failed(capsys, [*SMALL, late], 2)
    assert before == after and message in after
    if late == "t-end=3":
        assert after.endswith("(t-end is an option of the command: --t-end 3)")


def test_options_are_named_as_typed_in_their_messages(capsys, tmp_path):
    assert failed(capsys, [*SMALL, "--artificial-cells", "1000000"], 2) == (
        "jaxmpm: error: pad must be > --artificial-cells so the artificial layer stays on the grid; got "
        "pad=10, --artificial-cells=1000000"
    )
    data = tmp_path / "d.csv"
    data.write_text("t,x_free\n0,1\n0.001,1.01\n")
    line = failed(capsys, ["calibrate", "gas-slab", "--data", str(data), "--devices", "3"], 2)
    assert line.startswith("jaxmpm: error: --devices must be from 1 to ")
    assert line.endswith(" or 'all', got 3")
    ensemble = ["ensemble", "gas-slab", "--vary", "gamma=1.3:1.5", "--members", "2"]
    line = failed(capsys, [*ensemble, "--max-steps", "99999999999"], 2)
    assert line == (
        "jaxmpm: error: --max-steps must be <= 2147483647 (the bound of a step counter), got 99999999999"
    )


def test_a_fit_whose_draws_reach_a_bound_is_refused_naming_from_fit(capsys, tmp_path):
    fit = dict(
        scene="gas-slab",
        fitted=dict(gamma=1.4, P0=3e5),
        offsets=dict(gamma=1.0, P0=1e5),
        covariance_theta=dict(gamma=dict(gamma=1e4, P0=0.0), P0=dict(gamma=0.0, P0=0.01)),
    )
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(fit))
    argv = ["ensemble", "gas-slab", "--from-fit", str(path), "--members", "2", "--dt", "1e-5", "--steps", "3"]
    line = failed(capsys, argv, 2)
    assert line.startswith(f"jaxmpm: error: --from-fit: {path}: the data hardly determine gamma ")
    assert line.endswith("members drawn from this fit would reach gamma = 1, its bound, in float64")


@pytest.mark.slow
@pytest.mark.parametrize(
    "bad, message",
    [
        (["bogus=1", "--dt", "1e-5"], "unknown parameter 'bogus' for scene gas-expansion"),
        (["--dt", "-1"], "--dt must be > 0, got -1.0"),
    ],
)
def test_bad_input_is_refused_before_joining_other_processes(bad, message):
    """Process 1 of 2 started alone, with bad input: refused at once, not after waiting minutes for a
    coordinator that never comes (and then aborting in the native code)."""
    argv = ["run", "gas-expansion", "--interpolator", "mpq", "--steps", "2", *bad]
    argv += ["--coordinator", "127.0.0.1:1", "--processes", "2", "--process-id", "1"]
    proc = subprocess.run(
        [sys.executable, "-m", "jaxmpm.cli", *argv], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert message in proc.stderr


def test_out_that_is_not_a_regular_file_is_never_replaced(capsys, tmp_path):
    import stat

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    for extra in ([], ["--overwrite"]):
        line = failed(capsys, [*SMALL, "--out", str(fifo), *extra], 2)
        assert line == (
            f"jaxmpm: error: --out {fifo} is not a regular file (a device, pipe or socket), which a saved "
            "run would replace; give a file path"
        )
        assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    with pytest.raises(ValueError, match=rf"^out={fifo} is not a regular file"):
        jm.long_run.run(jm.GasExpansion(cells=2), jm.MPQ(), dt=1e-5, steps=2, out=fifo, overwrite=True)


@pytest.mark.parametrize(
    "argv, given",
    [
        (["run", "detonation", "explosive=compb", "D=8000", "--interpolator", "cpdi"], "D=8000"),
        (["run", "manufactured", "P0=5", "--interpolator", "cpdi"], "P0=5"),
        (["run", "detonation", "burn=volume", "burn_width=2", "--interpolator", "cpdi"], "burn_width=2"),
        (["ensemble", "manufactured", "model=gas", "mu=3", "--vary", "P0=1:2", "--members", "2"], "mu=3"),
        (["calibrate", "gurney-slab", "explosive=jwl", "gamma=3", "--fit", "A", "--data", "DATA"], "gamma=3"),
    ],
)
def test_a_scene_parameter_the_run_does_not_read_is_refused(capsys, tmp_path, argv, given):
    """A parameter the scene's run never reads would do nothing (a sweep over it would label identical
    runs with different values): refused before anything runs, with why."""
    data = tmp_path / "data.csv"
    data.write_text("t,v_plate\n1e-6,100\n2e-6,200\n")
    argv = [str(data) if a == "DATA" else a for a in argv]
    run = [] if argv[0] == "calibrate" else ["--dt", "1e-8", "--steps", "1"]
    line = usage(capsys, [*argv, *run], f"{given} would do nothing")
    assert "does not use it" in line


def test_grad_of_a_parameter_the_run_does_not_read_is_refused(capsys):
    """Its derivative would be 0 because the run never reads it, not because the error is
    insensitive to it: refused, with why."""
    argv = ["run", "manufactured", "--interpolator", "cpdi", "--dt", "1e-3", "--steps", "2"]
    line = usage(capsys, [*argv, "--grad", "mu,P0"], "--grad: P0 would do nothing")
    assert "the run of model=neo-hookean does not use it" in line


def test_the_gurney_constant_is_taken_for_gurneys_formula(capsys):
    """sqrt_2E is not the run's but the command reports Gurney's velocity with it: taken."""
    argv = ["run", "gurney-slab", "cells=5", "ppc=1", "pad=4", "sqrt_2E=2500", "--interpolator", "cpdi"]
    assert main([*argv, "--dt", "1e-9", "--steps", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    expected = float(jm.GurneySlab(cells=5, ppc=1, pad=4, sqrt_2E=2500.0).gurney_velocity())
    assert repr(expected) in json.dumps(out)
