"""experiments/*.py: entry points that parse their command line before they compute anything.

Every script (each ``experiments/*.py`` but the modules of ``MODULES``, found by glob so that a new
one is covered) is imported under a name of its own, in this process, with ``experiments/`` first on
``sys.path`` as Python puts it for ``python experiments/NAME.py`` (the scripts import ``_entry``):
importing it changes no global configuration (float64, ``sys.path``) and runs nothing;
``main(["--help"])`` prints its usage and exits 0, an unknown option or a bad value exits 2, all
without computing or writing anything. The documented command lines parse and go on to compute
(stopped at the first computation by a trap); a script that writes files refuses, before computing,
to replace one unless ``--overwrite``.
"""

from __future__ import annotations

import importlib.util
import json
import pathlib
import subprocess
import sys

import jax
import pytest

import jaxmpm
import jaxmpm._simulate
import jaxmpm.long_run
import jaxmpm.reference
import jaxmpm.studies.blast
import jaxmpm.studies.sensitivity
import jaxmpm.studies.talk

ROOT = pathlib.Path(__file__).resolve().parents[1]
FILES = sorted((ROOT / "experiments").glob("*.py"))
MODULES = {
    "bspline.py": "the interpolator that experiments/bspline_disk.py runs: a module, not a script",
    "_entry.py": "what the scripts' command lines share (argparse types, checks): a module, not a script",
}
SCRIPTS = [f for f in FILES if f.name not in MODULES]


class Computed(Exception):
    """A computation started (a trap below was called)."""


def _traps():
    import benchmarks.bench

    return [
        (jaxmpm, "simulate"),
        (jaxmpm, "simulate_timed"),
        (jaxmpm, "ensemble"),
        (jaxmpm.long_run, "run_timed"),
        (jaxmpm._simulate, "prepare"),
        (jaxmpm.reference, "gas_slab"),
        (jaxmpm.studies.talk, "main"),
        (jaxmpm.studies.sensitivity, "main"),
        (jaxmpm.studies.blast, "run_row"),
        (jaxmpm.studies.blast, "References"),
        (jaxmpm.studies.blast, "make_slab"),
        (subprocess, "run"),
        (jax, "block_until_ready"),
        (jax.random, "PRNGKey"),
        (benchmarks.bench, "run"),
    ]


@pytest.fixture(autouse=True)
def _isolated(monkeypatch, tmp_path):
    """Each test in an empty working folder, with ``experiments/`` first on ``sys.path`` (as for a script
    run from the command line) and every computation trapped; float64, ``sys.path`` and the
    interpolators' registry restored after it."""
    x64 = bool(jax.config.jax_enable_x64)
    registry = dict(jaxmpm.INTERPOLATORS)
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.syspath_prepend(str(ROOT / "experiments"))
    monkeypatch.chdir(tmp_path)
    for target, name in _traps():

        def trap(*args, _name=f"{getattr(target, '__name__', target)}.{name}", **kwargs):
            raise Computed(_name)

        monkeypatch.setattr(target, name, trap)
    yield
    jax.config.update("jax_enable_x64", x64)
    jaxmpm.INTERPOLATORS.clear()
    jaxmpm.INTERPOLATORS.update(registry)


def _load(path: pathlib.Path):
    spec = importlib.util.spec_from_file_location(f"_experiment_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _exit_code(module, argv) -> int:
    with pytest.raises(SystemExit) as e:
        module.main(argv)
    return e.value.code


def test_scripts_are_found():
    assert len(SCRIPTS) >= 20
    for name in MODULES:
        assert "__main__" not in (ROOT / "experiments" / name).read_text(), f"{name} is a script"


@pytest.mark.parametrize("path", FILES, ids=[f.name for f in FILES])
def test_import_changes_nothing(path, capsys):
    jax.config.update("jax_enable_x64", False)
    before = list(sys.path)
    _load(path)
    assert jax.config.jax_enable_x64 is False, f"importing {path.name} switched float64 on"
    assert sys.path == before, f"importing {path.name} changed sys.path"
    assert capsys.readouterr().out == "", f"importing {path.name} ran something"


@pytest.mark.parametrize("path", SCRIPTS, ids=[f.name for f in SCRIPTS])
def test_help(path, tmp_path, capsys):
    module = _load(path)
    assert _exit_code(module, ["--help"]) == 0
    assert "usage:" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("path", SCRIPTS, ids=[f.name for f in SCRIPTS])
def test_unknown_option(path, tmp_path, capsys):
    module = _load(path)
    assert _exit_code(module, ["--no-such-option"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "error: " in err[-1], err  # the option, or a required argument missing
    assert list(tmp_path.iterdir()) == []


BAD = [
    ("apic_free_surface.py", ["100", "32", "foo"]),
    ("apic_free_surface.py", ["abc"]),
    ("apic_free_surface.py", ["100", "0"]),
    ("blast_disk.py", ["cpdi"]),
    ("blast_disk.py", ["foo", "flip"]),
    ("blast_disk.py", ["cpdi", "foo"]),
    ("blast_disk.py", ["cpdi", "flip", "nope"]),
    ("blast_disk.py", ["cpdi", "flip", "cells=abc"]),
    ("blast_disk.py", ["cpdi", "flip", "size=3"]),
    ("compile_split.py", ["--interpolators", "foo"]),
    ("compile_split.py", ["--n", "0"]),
    ("compile_split.py", ["--dim", "2", "--n", "1000"]),
    ("cpu_emitters.py", ["--rounds", "0", "--n", "1024"]),
    ("cpu_emitters.py", ["--n", "-4"]),
    ("cpu_emitters.py", ["--interpolators", "foo"]),
    ("power_ab.py", ["--n", "0"]),
    ("power_ab.py", ["--interpolator", "foo"]),
    ("power_ab.py", ["--rounds", "0"]),
    ("thread_use.py", ["--n", "0"]),
    ("power_forms.py", ["--n", "0"]),
    ("scatter_forms.py", ["--n", "abc"]),
    ("scatter_forms.py", ["--n", "0"]),
    ("grad_memory.py", ["--small", "--out"]),
    ("state_hashes.py", ["--out", "x.json", "--compare", "/nonexistent"]),
    ("talk.py", ["--smalll"]),
    ("talk.py", ["out", "extra"]),
    ("sensitivity.py", ["--smalll"]),
    ("sensitivity.py", ["a", "b"]),
    ("uneven_shards.py", ["--n", "1000,0"]),
    ("uneven_shards.py", ["--layouts", "one,foo"]),
    ("uneven_shards.py", ["--devices", "1"]),
    ("uneven_shards.py", ["--interpolator", "spq,mpq"]),
]


@pytest.mark.parametrize("name, argv", BAD, ids=[f"{n} {' '.join(a)}" for n, a in BAD])
def test_bad_input(name, argv, tmp_path, capsys):
    module = _load(ROOT / "experiments" / name)
    assert _exit_code(module, argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "error: " in err[-1], err
    assert list(tmp_path.iterdir()) == []


# The command lines of the scripts' docstrings and of docs/*.md (smaller sizes where they only
# change how long the computation takes): each parses and starts computing.
DOCUMENTED = [
    ("apic_free_surface.py", []),
    ("apic_free_surface.py", ["100", "64"]),
    ("apic_free_surface.py", ["100", "32", "mpq"]),
    ("bench.py", ["--sizes", "1000", "--steps", "100", "--dtypes", "f64", "--codes", "numpy,jaxmpm"]),
    ("blast_disk.py", []),
    ("blast_disk.py", ["cpdi", "flip", "node"]),
    ("blast_disk.py", ["cpdi", "flip", "cells=16"]),
    ("blast_disk.py", ["cpdi2", "apic", "shear=2.0", "ratio=100", "pad=6"]),
    ("blast_disk.py", ["mpq", "apic", "musl", "visc", "cutoff=0.03", "ppc1", "cell"]),
    ("blast_robustness.py", []),
    ("blast_square.py", []),
    ("bspline_disk.py", []),
    ("calibration_truth.py", ["--out", "out"]),
    ("chunk_overhead.py", []),
    ("chunk_overhead.py", ["--small"]),
    ("compile_split.py", []),
    ("compile_split.py", ["--dim", "2", "--n", "1024", "--f64", "--interpolators", "spq,mpq"]),
    ("cpgimp_boundary.py", []),
    ("cpgimp_boundary.py", ["--small"]),
    ("cpu_emitters.py", ["--dtype", "f64", "--dim", "2", "--n", "1024", "--rounds", "1"]),
    ("ensemble_throughput.py", []),
    ("ensemble_throughput.py", ["--out", "e.csv"]),
    ("grad_memory.py", []),
    ("grad_memory.py", ["--small", "--out", "g.csv"]),
    ("ordering_stability.py", ["--small"]),
    ("power_ab.py", ["--dtype", "f64", "--n", "1024"]),
    ("power_ab.py", ["--dim", "3", "--n", "4096", "--interpolator", "mpq", "--rounds", "1"]),
    ("power_forms.py", ["--n", "1024"]),
    ("scatter_forms.py", ["--n", "1024,2048", "--x64"]),
    ("sensitivity.py", []),
    ("sensitivity.py", ["out", "--small", "--musl"]),
    ("state_hashes.py", ["--out", "h.json"]),
    ("talk.py", []),
    ("talk.py", ["out", "--small"]),
    ("thread_use.py", ["--dtype", "f64", "--n", "1024", "--dim", "2"]),
    ("uneven_shards.py", []),
    ("uneven_shards.py", ["--n", "1000,1001", "--devices", "4", "--layouts", "one,aligned"]),
    ("uneven_shards.py", ["--n", "500001", "--layouts", "one,one-unpadded", "--interpolator", "mpq"]),
]


@pytest.mark.parametrize("name, argv", DOCUMENTED, ids=[f"{n} {' '.join(a)}" for n, a in DOCUMENTED])
def test_documented_command_lines_parse(name, argv):
    module = _load(ROOT / "experiments" / name)
    with pytest.raises(Computed):
        module.main(argv)


def test_state_hashes_compare_is_read_first(tmp_path):
    (tmp_path / "before.json").write_text("{}")
    module = _load(ROOT / "experiments" / "state_hashes.py")
    with pytest.raises(Computed):
        module.main(["--out", "after.json", "--compare", "before.json"])
    (tmp_path / "bad.json").write_text("not json")
    assert _exit_code(module, ["--out", "after.json", "--compare", "bad.json"]) == 2


def test_state_hashes_compare_fails_on_a_changed_or_missing_run_and_lists_new_ones(monkeypatch, capsys):
    """A run whose hash changed, or one of the earlier file not run here, fails the comparison; a run
    the earlier file lacks (added to the matrix since) is listed as new and does not."""
    import numpy as np

    module = _load(ROOT / "experiments" / "state_hashes.py")
    runs = {"same": 1.0, "changed": 2.0, "added": 3.0}
    fake = lambda: ((k, lambda v=v: (np.array([v]), 0)) for k, v in runs.items())
    monkeypatch.setattr(module, "_runs", fake)
    monkeypatch.setattr(jax, "clear_caches", lambda: None)  # the worker's compiled programs stay
    same = module._hash(np.array([1.0]))
    pathlib.Path("before.json").write_text(json.dumps({"same": same, "changed": "0" * 16, "gone": "0" * 16}))
    assert module.main(["--out", "a.json", "--compare", "before.json"]) == 1
    out = capsys.readouterr().out
    assert "3 runs, 1 differ from before.json, 1 missing, 1 new (not in it, not compared)" in out
    assert "  differs: changed\n" in out and "  not run here: gone\n" in out and "  new: added\n" in out
    pathlib.Path("older.json").write_text(json.dumps({"same": same}))
    assert module.main(["--out", "b.json", "--compare", "older.json"]) == 0
    assert "3 runs, 0 differ from older.json, 2 new (not in it, not compared)" in capsys.readouterr().out


# A script that writes files: its command line, with OUT for a folder, and a file of that folder it
# writes.
WRITERS = [
    ("talk.py", ["OUT", "--small"], "table.md"),
    ("talk.py", ["OUT"], "separation.png"),
    ("sensitivity.py", ["OUT", "--small"], "sensitivity.csv"),
    ("sensitivity.py", ["OUT", "--musl"], "sensitivity_h_musl.png"),
    ("calibration_truth.py", ["--out", "OUT"], "results.json"),
    ("calibration_truth.py", ["--out", "OUT"], "table.md"),
    ("ensemble_throughput.py", ["--out", "OUT/e.csv"], "e.csv"),
    ("grad_memory.py", ["--small", "--out", "OUT/g.csv"], "g.csv"),
    ("state_hashes.py", ["--out", "OUT/h.json"], "h.json"),
    ("bench.py", ["--out", "OUT", "--sizes", "1000", "--dtypes", "f64", "--codes", "numpy"], "bench.csv"),
]


@pytest.mark.parametrize("name, argv, held", WRITERS, ids=[f"{n} {h}" for n, _, h in WRITERS])
def test_existing_output_is_refused_unless_overwrite(name, argv, held, tmp_path, capsys):
    out = tmp_path / "OUT"
    out.mkdir()
    (out / held).write_text("the user's own")
    argv = [a.replace("OUT", str(out)) for a in argv]
    module = _load(ROOT / "experiments" / name)
    assert _exit_code(module, argv) == 2  # no Computed: refused before computing
    err = capsys.readouterr().err.strip().splitlines()
    assert held in err[-1] and "--overwrite" in err[-1], err
    assert (out / held).read_text() == "the user's own"
    assert sorted(p.name for p in out.iterdir()) == [held]
    with pytest.raises(Computed):
        module.main([*argv, "--overwrite"])
    assert (out / held).read_text() == "the user's own"


def test_every_script_that_writes_is_checked():
    writers = {name for name, _, _ in WRITERS}
    for path in SCRIPTS:
        if "--overwrite" in path.read_text() or "--out" in path.read_text():
            assert path.name in writers, f"{path.name} writes files: add it to WRITERS"
