"""The command-line contract: `jaxmpm scenes`, `jaxmpm run ... [--json]`, and its error cases."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from jaxmpm.cli import main


def run_json(capsys, *argv):
    assert main(list(argv) + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_scenes_lists_parameters_and_defaults(capsys):
    assert main(["scenes", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["gas-expansion"]["parameters"]["beta"] == 200.0
    assert set(out["gas-expansion"]["parameters"]) >= {
        "beta",
        "h",
        "cells",
        "ppc",
        "P0",
        "gamma",
        "p_atm",
        "rho0",
    }
    assert main(["scenes"]) == 0
    text = capsys.readouterr().out
    assert "gas-expansion" in text and "beta" in text and "vibrating-bar" in text


def test_run_json_contract(capsys):
    out = run_json(
        capsys,
        "run",
        "gas-expansion",
        "cells=3",
        "ppc=2",
        "beta=200",
        "--interpolator",
        "spq",
        "--dt",
        "1e-5",
        "--steps",
        "1",
    )
    assert {"t", "particles", "params", "errors", "wall_s", "compile_s"} <= set(out)
    assert set(out["particles"]) == {"X", "x", "v", "F", "sigma"}
    assert set(out["errors"]) >= {
        "F_max_rel",
        "F_rms_rel",
        "F_max_rel_boundary",
        "F_max_rel_interior",
        "x_max_abs",
        "separation_max",
    }
    assert out["params"] == {
        "beta": 200.0,
        "h": 0.125,
        "P0": 2e5,
        "gamma": 1.4,
        "p_atm": 1e5,
        "rho0": 1.0,
        "cells": 3,
        "ppc": 2,
        "pad": 10,
    }
    F = np.array(out["particles"]["F"])
    np.testing.assert_allclose((F - 1) / (200 * 1e-5), [5 / 8, 5 / 8, 1, 1, 5 / 8, 5 / 8], rtol=1e-12)
    assert out["t"] == 1e-5
    assert out["errors"]["F_max_rel_boundary"] == pytest.approx((3 / 8) * 200e-5 / (1 + 200e-5), rel=1e-12)
    assert out["errors"]["F_max_rel_interior"] < 1e-15
    X = out["particles"]["X"]
    assert X == sorted(X) and len(X) == 6


def test_run_json_full_precision(capsys):
    out = run_json(
        capsys,
        "run",
        "gas-expansion",
        "cells=3",
        "--interpolator",
        "mpq",
        "--artificial-cells",
        "1",
        "--transfer",
        "apic",
        "--dt",
        "1e-5",
        "--steps",
        "3",
    )
    # repr-exact floats: re-running in Python gives bit-identical numbers.
    import jaxmpm as jm

    sol = jm.simulate(
        jm.GasExpansion(cells=3), jm.MPQ(), dt=1e-5, steps=3, transfer=jm.APIC(), artificial_cells=1
    )
    assert out["particles"]["F"] == np.asarray(sol.state.F[:, 0, 0]).tolist()


def test_run_table(capsys):
    assert main(["run", "vibrating-bar", "--interpolator", "cpdi", "--dt", "1e-4", "--steps", "10"]) == 0
    text = capsys.readouterr().out
    assert "F_exact" in text and "F_max_rel=" in text and "compile_s=" in text


@pytest.mark.parametrize(
    "argv, match",
    [
        (
            ["run", "nosuch", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "unknown scene 'nosuch'",
        ),
        (
            ["run", "gas-expansion", "bogus=1", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "unknown parameter 'bogus'",
        ),
        (
            ["run", "gas-expansion", "ppc=0", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "ppc must be an integer >= 1",
        ),
        (
            ["run", "gas-expansion", "cells=0", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "cells must be an integer >= 1",
        ),
        (
            ["run", "gas-expansion", "cells=2.5", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "cells must be an integer",
        ),
        (["run", "gas-expansion", "--interpolator", "spq", "--dt", "0", "--steps", "1"], "dt must be > 0"),
        (
            ["run", "gas-expansion", "--interpolator", "spq", "--dt", "-1e-5", "--steps", "1"],
            "dt must be > 0",
        ),
        (
            ["run", "gas-expansion", "--interpolator", "spq", "--dt", "inf", "--steps", "1"],
            "dt must be finite",
        ),
        (
            ["run", "gas-expansion", "beta=nan", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "beta must be finite",
        ),
        (
            ["run", "gas-expansion", "h=-1", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "h must be > 0",
        ),
        (
            ["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-5", "--steps", "-2"],
            "steps must be an integer >= 0",
        ),
        (
            ["run", "gas-expansion", "--interpolator", "nope", "--dt", "1e-5", "--steps", "1"],
            "--interpolator",
        ),
        (
            ["run", "gas-expansion", "beta", "--interpolator", "spq", "--dt", "1e-5", "--steps", "1"],
            "name=value",
        ),
    ],
)
def test_bad_input_exits_nonzero_with_one_line(capsys, argv, match):
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0] and lines[0].startswith("jaxmpm: error:")
    assert "Traceback" not in captured.err and captured.out == ""


@pytest.mark.parametrize(
    "argv, hint",
    [
        (
            ["run", "gas-expansion", "--interpolator", "spq", "steps=125", "--dt", "1e-5"],
            "(steps is an option of the command: --steps 125)",
        ),
        (
            ["run", "gas-expansion", "artificial-cells=1", "--interpolator", "mpq"],
            "(artificial-cells is an option of the command: --artificial-cells 1)",
        ),
        (
            ["ensemble", "gas-expansion", "--members", "2", "dt=1e-5"],
            "(dt is an option of the command: --dt 1e-5)",
        ),
        (
            ["calibrate", "gas-slab", "--data", "x.csv", "iterations=9"],
            "(iterations is an option of the command: --iterations 9)",
        ),
        (
            ["run", "gas-expansion", "--interpolator", "spq", "json=1"],
            "(json is an option of the command: --json)",  # a switch: no value
        ),
    ],
)
def test_an_option_written_as_a_scene_parameter_is_named(capsys, argv, hint):
    """``steps=125`` is refused as a scene parameter with the option it looks like spelled out."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("jaxmpm: error: unknown parameter") and len(err.splitlines()) == 1
    assert err.endswith(hint)


def test_a_positional_name_as_a_scene_parameter_gets_no_option_hint(capsys):
    assert main(["run", "gas-expansion", "--interpolator", "spq", "scene=1"]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'scene'" in err and "is an option" not in err
    # calibrate has no --max-steps: no hint
    assert main(["calibrate", "gas-slab", "--data", "x.csv", "max_steps=9"]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'max_steps'" in err and "is an option" not in err


def test_breakdown_exits_nonzero_and_names_step_particle_quantity(capsys):
    assert main(["run", "gas-expansion", "--interpolator", "spq", "--dt", "1e-3", "--steps", "5"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "step 1" in err[0] and "particle" in err[0] and "stable limit" in err[0]


@pytest.mark.skipif(shutil.which("jaxmpm") is None, reason="console script not installed")
@pytest.mark.slow
def test_console_script():
    proc = subprocess.run(
        ["jaxmpm", "run", "gas-expansion", "--interpolator", "spq", "--dt", "0", "--steps", "1"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "dt must be > 0" in proc.stderr
    proc = subprocess.run(
        [
            "jaxmpm",
            "run",
            "gas-expansion",
            "cells=3",
            "--interpolator",
            "cpdi",
            "--dt",
            "1e-5",
            "--steps",
            "2",
            "--json",
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0 and json.loads(proc.stdout)["params"]["cells"] == 3


def test_python_m_jaxmpm_is_the_command(capsys, monkeypatch):
    """``python -m jaxmpm`` runs the ``jaxmpm`` command (as ``python -m jaxmpm.cli`` does)."""
    import runpy
    import signal

    monkeypatch.setattr(sys, "argv", ["jaxmpm", "scenes", "--json"])
    handler = signal.getsignal(signal.SIGINT)  # the command answers Ctrl-C its own way
    try:
        with pytest.raises(SystemExit) as exited:
            runpy.run_module("jaxmpm", run_name="__main__")
    finally:
        signal.signal(signal.SIGINT, handler)
    assert exited.value.code == 0
    assert "gas-expansion" in json.loads(capsys.readouterr().out)
