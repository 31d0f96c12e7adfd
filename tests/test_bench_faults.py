"""``jaxmpm bench`` on bad input and on output that cannot be written: every bad value is refused
with one line naming its option (exit status 2) before the benchmark runs; sizes beyond the memory
available are refused with the largest that fits; ``--out`` never replaces a user's file without
``--overwrite``; a full disk leaves no file written in part; a benchmark process that fails is one
line (exit status 1), never a traceback."""

import copy
import errno
import json
import os
import re
import subprocess

import pytest

import jaxmpm as jm
from benchmarks import _baselines_2d, bench
from jaxmpm import cli

TINY = {
    "--sizes": "100",
    "--sizes-2d": "",
    "--dtypes": "f64",
    "--codes": "numpy",
    "--steps": "2",
}


def argv(*flags, **options) -> list[str]:
    """``jaxmpm bench`` with the tiny run's options, ``options`` (``sizes_2d="16"``) replacing them."""
    values = dict(TINY)
    for key, value in options.items():
        values["--" + key.replace("_", "-")] = value
    out = ["bench", "--no-extras", *flags]
    for option, value in values.items():
        out += [option, value]
    return out


def one_line_error(capsys, *named) -> str:
    """The error on stderr: one line naming each of ``named`` (after the benchmark's progress lines,
    ``jaxmpm bench: f64 (1 of 1), one process ...``, where it ran), no traceback."""
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert err.endswith("\n") and lines and lines[-1].startswith("jaxmpm: error: "), err
    assert all(line.startswith("jaxmpm bench: ") for line in lines[:-1]), err
    assert "Traceback" not in err
    for word in named:
        assert word in lines[-1], (word, err)
    return lines[-1]


def files(folder) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted(folder.iterdir())}


@pytest.fixture
def recorded(monkeypatch):
    """``bench.run`` replaced by a recorder of its arguments, returning an empty result: a refused
    command never reaches it."""
    calls = []

    def record(*a, **k):
        calls.append((a, k))
        return dict(date="now", machine="here", versions={}, rows=[], agreement={})

    monkeypatch.setattr(bench, "run", record)
    return calls


@pytest.fixture(scope="module")
def measured():
    """The result of one real tiny benchmark (its own process, a few seconds)."""
    return bench.run([100], 2, ["f64"], ["numpy"], [], extras=False)


@pytest.fixture
def replayed(monkeypatch, measured):
    """``bench.run`` returning the real tiny result at once."""
    monkeypatch.setattr(bench, "run", lambda *a, **k: copy.deepcopy(measured))


@pytest.mark.parametrize("name", bench.FILES)
def test_out_with_a_bench_file_is_refused_before_the_benchmark(name, tmp_path, capsys, recorded):
    (tmp_path / name).write_text("my own notes")
    (tmp_path / "other.txt").write_text("kept")
    assert cli.main(argv(out=str(tmp_path))) == 2
    one_line_error(capsys, f"--out {tmp_path}", name, "--overwrite")
    assert recorded == []
    assert files(tmp_path) == {name: "my own notes", "other.txt": "kept"}


@pytest.mark.slow
def test_overwrite_replaces_the_bench_files_and_keeps_the_rest(tmp_path, capsys):
    (tmp_path / "bench.md").write_text("my own notes")
    (tmp_path / "other.txt").write_text("kept")
    assert cli.main(argv("--overwrite", out=str(tmp_path))) == 0
    capsys.readouterr()
    held = files(tmp_path)
    assert set(held) == {*bench.FILES, "other.txt"} and held["other.txt"] == "kept"
    assert held["bench.md"].startswith("Measured ")
    assert held["bench.csv"].startswith(",".join(bench.ROW_FIELDS))
    assert [r["code"] for r in json.loads(held["bench.json"])["rows"]] == ["NumPy"]


def test_overwrite_without_out_is_refused(capsys, recorded):
    assert cli.main(argv("--overwrite")) == 2
    one_line_error(capsys, "--overwrite", "--out")
    assert recorded == []


def full_disk_at(k: int):
    """An ``open`` for ``benchmarks.bench`` whose ``k``-th new file (0: the first) takes half of what
    is written to it and then fails: no space left on the device."""
    real_open = open
    made = []

    def fake(path, mode="r", *args, **kwargs):
        f = real_open(path, mode, *args, **kwargs)
        if "x" not in mode:
            return f
        made.append(path)
        if len(made) - 1 != k:
            return f

        class Full:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                f.close()
                return False

            def write(self, data):
                f.write(data[: len(data) // 2])
                f.flush()
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        return Full()

    return fake


@pytest.mark.parametrize("failing", range(len(bench.FILES)))
@pytest.mark.parametrize("earlier", [False, True])
def test_a_full_disk_leaves_no_bench_file_in_part(failing, earlier, tmp_path, capsys, monkeypatch, replayed):
    """Whichever file the disk fills on, none of the three is written, in whole or in part: a new
    folder stays empty, and the files of an earlier benchmark (with ``--overwrite``) stay as they were."""
    before = {name: f"the earlier {name}" for name in bench.FILES} if earlier else {}
    for name, text in before.items():
        (tmp_path / name).write_text(text)
    monkeypatch.setattr(bench, "open", full_disk_at(failing), raising=False)
    flags = ("--overwrite",) if earlier else ()
    assert cli.main(argv(*flags, out=str(tmp_path))) == 74
    one_line_error(capsys, f"cannot write --out {tmp_path}", os.strerror(errno.ENOSPC))
    assert files(tmp_path) == before


def test_a_bench_file_put_there_during_the_benchmark_is_kept(tmp_path, capsys, monkeypatch, measured):
    def run_meanwhile(*a, **k):
        (tmp_path / "bench.json").write_text("saved while it ran")
        return copy.deepcopy(measured)

    monkeypatch.setattr(bench, "run", run_meanwhile)
    assert cli.main(argv(out=str(tmp_path))) == 74
    one_line_error(capsys, f"--out {tmp_path}", "bench.json")
    assert files(tmp_path) == {"bench.json": "saved while it ran"}


def test_sizes_beyond_the_memory_here_are_refused(capsys, recorded):
    """A hundred billion particles need terabytes (the probe that met NumPy's ArrayMemoryError)."""
    assert cli.main(argv(sizes="100000000000")) == 2
    err = one_line_error(capsys, "--sizes:", "100,000,000,000 particles", "the largest that fits is ")
    assert "available here" in err and recorded == []


@pytest.mark.parametrize(
    "option, dim, codes, interpolators",
    [
        ("--sizes", 1, "numpy", "spq"),
        ("--sizes-2d", 2, "numpy,jaxmpm", "spq"),
        ("--sizes-3d", 3, "jaxmpm", "spq,cpdi"),
    ],
)
def test_the_largest_size_that_fits_is_the_bound(
    option, dim, codes, interpolators, capsys, monkeypatch, recorded
):
    """With 2 GB available, the size the refusal names runs, and the next size of its form is refused;
    by the estimate the one fits and the other does not."""
    available = 2_000_000_000
    monkeypatch.setattr(bench, "available_memory", lambda: available)
    options = dict(codes=codes, interpolators=interpolators)
    assert cli.main(argv(**options, **{option[2:].replace("-", "_"): "1" + "0" * 12})) == 2
    err = one_line_error(capsys, f"{option}:", "2 GB", "the largest that fits is ")
    largest = int(re.search(r"the largest that fits is ([\d,]+)", err).group(1).replace(",", ""))
    if dim == 1:
        side, following = largest, largest + 2
    else:
        side = 2 * _baselines_2d.cells_of(largest, dim)
        following = (side + 2) ** dim
    per = bench.bytes_per_particle(dim, codes.split(","), interpolators.split(","))
    assert bench.PROCESS_BYTES + largest * per <= available < bench.PROCESS_BYTES + following * per
    size = option[2:].replace("-", "_")
    assert cli.main(argv(**options, **{size: str(largest)})) == 0
    assert len(recorded) == 1
    assert cli.main(argv(**options, **{size: f"{largest},{following}"})) == 2
    one_line_error(capsys, f"{option}: {following:,} particles", f"the largest that fits is {largest:,}")
    assert len(recorded) == 1 and side > 2


def test_no_run_fits_in_too_little_memory(capsys, monkeypatch, recorded):
    monkeypatch.setattr(bench, "available_memory", lambda: 1000)
    assert cli.main(argv()) == 2
    one_line_error(capsys, "--sizes:", "not even the smallest run fits")
    assert recorded == []


@pytest.mark.parametrize(
    "options, named",
    [
        (dict(steps="0"), "--steps"),
        (dict(steps="-5"), "--steps"),
        (dict(steps=str(2**31)), "--steps"),
        (dict(steps="99999999999999999999999"), "--steps"),
        (dict(sizes="-2"), "--sizes"),
        (dict(sizes="0"), "--sizes"),
        (dict(sizes=""), "--sizes"),
        (dict(sizes="100,100"), "--sizes"),
        (dict(sizes="1" + "0" * 400), "--sizes"),
        (dict(sizes_2d="-4"), "--sizes-2d"),
        (dict(sizes_2d="16,16"), "--sizes-2d"),
        (dict(sizes_2d="1" + "0" * 400), "--sizes-2d"),  # (2 k)^2: too large for the memory
        (dict(sizes_2d="1" + "0" * 401), "--sizes-2d"),  # not (2 k)^2
        (dict(sizes_3d="-8"), "--sizes-3d"),
        (dict(sizes_3d="8" + "0" * 399), "--sizes-3d"),  # (2 k)^3: too large for the memory
        (dict(sizes_3d="8" + "0" * 400), "--sizes-3d"),  # not (2 k)^3
        (dict(dtypes=""), "--dtypes"),
        (dict(dtypes="f64,f64"), "--dtypes"),
        (dict(dtypes="f128"), "--dtypes"),
        (dict(codes=""), "--codes"),
        (dict(codes="numpy,numpy"), "--codes"),
        (dict(codes="cuda"), "--codes"),
        (dict(codes="jaxmpm", interpolators=""), "--interpolators"),
        (dict(codes="jaxmpm", interpolators="spq,spq"), "--interpolators"),
        (dict(rounds="0"), "--rounds"),
        (dict(rounds="-2"), "--rounds"),
        (dict(rounds="two"), "--rounds"),
    ],
)
def test_bad_values_are_one_line_naming_the_option(options, named, capsys, recorded):
    assert cli.main(argv(**options)) == 2
    one_line_error(capsys, named)
    assert recorded == []


def test_codes_none_of_which_is_installed_are_refused(capsys, monkeypatch, recorded):
    monkeypatch.setattr(bench, "available", lambda code: code not in ("taichi", "warp"))
    assert cli.main(argv(codes="taichi,warp")) == 2
    one_line_error(capsys, "--codes taichi,warp", "not installed", "nothing to run")
    assert recorded == []
    assert cli.main(argv(codes="numpy,taichi")) == 0  # taichi skipped, numpy runs
    assert "taichi not installed, skipped" in capsys.readouterr().err
    assert recorded[0][0][3] == ["numpy", "taichi"]


@pytest.mark.parametrize(
    "returncode, stderr, said",
    [
        (
            1,
            'Traceback (most recent call last):\n  File "x.py", line 1\nValueError: boom\n',
            "ValueError: boom",
        ),
        (-9, "", "killed by SIGKILL (out of memory?)"),
        (1, "", "exit status 1, nothing on stderr"),
    ],
)
def test_a_failed_benchmark_process_is_one_line(returncode, stderr, said, capsys, monkeypatch, tmp_path):
    def failed(cmd, **kwargs):
        return subprocess.CompletedProcess(cmd, returncode, stdout="", stderr=stderr)

    monkeypatch.setattr(bench.subprocess, "run", failed)
    assert cli.main(argv(out=str(tmp_path / "b"))) == 1
    one_line_error(capsys, f"the f64 benchmark process failed: {said}")
    assert files(tmp_path / "b") == {}


def test_every_interpolator_has_a_memory_estimate():
    assert set(jm.INTERPOLATORS) <= set(bench.BYTES_PER_PARTICLE)
    for per in bench.BYTES_PER_PARTICLE.values():
        assert sorted(per) == [1, 2, 3] and per[1] < per[2] < per[3]


def test_cells_of_is_exact_for_any_integer():
    for dim in (2, 3):
        for k in (1, 2, 7, 10**50 + 3):
            assert _baselines_2d.cells_of((2 * k) ** dim, dim) == k
            assert _baselines_2d.cells_of((2 * k) ** dim + 1, dim) is None
            assert _baselines_2d.cells_of((2 * k) ** dim - 1, dim) is None
            assert _baselines_2d.cells_of((2 * k + 1) ** dim, dim) is None  # an odd side
        assert _baselines_2d.cells_of(0, dim) is None and _baselines_2d.cells_of(-(2**dim), dim) is None


def test_a_folder_under_a_bench_files_name_is_refused_before_the_benchmark(tmp_path, capsys, recorded):
    """A folder where the benchmark writes a file: said before the benchmark (after it, the whole
    measurement was lost with "Is a directory"), even with --overwrite."""
    (tmp_path / "bench.csv").mkdir()
    assert cli.main(argv("--overwrite", out=str(tmp_path))) == 2
    one_line_error(capsys, f"--out {tmp_path}", "bench.csv is a folder")
    assert recorded == []


def test_the_results_are_printed_before_the_files_are_written(tmp_path, capsys, monkeypatch, replayed):
    """A write that fails after the benchmark (a full disk) still leaves the measurements on stdout."""

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(bench, "write", full)
    assert cli.main(argv(out=str(tmp_path))) == 74
    cap = capsys.readouterr()
    assert "NumPy" in cap.out and "No space left on device" in cap.err
