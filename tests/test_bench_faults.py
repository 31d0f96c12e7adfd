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

import numpy as np
import pytest

import jaxmpm as jm
from benchmarks import _baselines, _baselines_2d, bench
from jaxmpm import cli
from jaxmpm import status as st_bits

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
        ("--sizes", 1, "numpy", None),  # --interpolators without jaxmpm would do nothing: refused
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
    options = dict(codes=codes, **({"interpolators": interpolators} if interpolators else {}))
    assert cli.main(argv(**options, **{option[2:].replace("-", "_"): "1" + "0" * 12})) == 2
    err = one_line_error(capsys, f"{option}:", "2 GB", "the largest that fits is ")
    largest = int(re.search(r"the largest that fits is ([\d,]+)", err).group(1).replace(",", ""))
    if dim == 1:
        side, following = largest, largest + 2
    else:
        side = 2 * _baselines_2d.cells_of(largest, dim)
        following = (side + 2) ** dim
    per = bench.bytes_per_particle(dim, codes.split(","), (interpolators or "").split(","))
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


@pytest.mark.parametrize("as_json", [False, True])
def test_the_files_are_written_when_the_reader_of_the_results_went_away(
    as_json, tmp_path, capsys, monkeypatch, replayed
):
    """``jaxmpm bench --out DIR | true``: the reader is gone before the results are printed; the files
    hold them all the same, and the status is 141 (silent)."""

    class Gone:
        def write(self, text):
            raise BrokenPipeError(errno.EPIPE, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(errno.EPIPE, "Broken pipe")

        def fileno(self):  # no descriptor to point at the null device
            raise OSError(errno.EBADF, "no descriptor")

    monkeypatch.setattr(cli.sys, "stdout", Gone())
    assert cli.main(argv(*(["--json"] if as_json else []), out=str(tmp_path))) == 141
    assert capsys.readouterr().err.count("jaxmpm: error") == 0
    assert set(files(tmp_path)) == set(bench.FILES)


# --- Breakdowns, throughput and agreement ------------------------------------------------------------


def _row(code, F_mean=1.5, status=0, n=1000, dim=1, run_s=0.01, dtype="f64"):
    return dict(
        code=code,
        dtype=dtype,
        particles=n,
        steps=10,
        compile_s=0.5,
        run_s=run_s,
        Mpsps=n * 10 / run_s / 1e6 if status == 0 else None,
        F_mean=F_mean,
        status=status,
        dim=dim,
    )


def _result(rows, numpy_with_fold=()):
    agree, notes = bench._agreement(rows, numpy_with_fold)
    return dict(
        date="now",
        machine="here",
        versions={},
        copy_bandwidth_GBps=10.0,
        rows=rows,
        numpy_with_fold=list(numpy_with_fold),
        agreement=agree,
        agreement_notes=notes,
        disagreement=bench.disagreement(agree),
    )


def test_a_reference_code_whose_particles_leave_the_grid_reports_it():
    """Plain JAX clamps its gathers and drops its scatters: its particles leave the grid with F
    finite; NumPy's bincount raises on them. Both report LEFT_GRID (jaxmpm's bit), not a healthy run."""
    L = _baselines.layout(100)
    _, _, F_mean, status = _baselines.plain_jax_spq(100, 400, "f64")[:4]
    assert np.isfinite(F_mean) and status & st_bits.LEFT_GRID
    numpy = _baselines.numpy_spq(100, 400, "f64")
    assert len(numpy) == 4 and numpy[3] & st_bits.LEFT_GRID
    assert _baselines.numpy_spq(100, 20, "f64")[3] == 0 and _baselines.plain_jax_spq(100, 20, "f64")[3] == 0
    assert _baselines.grid_span(L)[1] == pytest.approx(L["x_min"] + (L["nodes"] - 1) * L["h"])


def test_health_sets_jaxmpms_bits():
    ok = dict(x=np.array([[0.1, 0.2]]), v=np.zeros((1, 2)), F=np.eye(2)[None], x_tr=np.zeros((1, 2)))
    assert _baselines.health(**ok, x_lo=-1.0, x_hi=1.0, J=np.ones(1)) == 0
    assert (
        _baselines.health(**dict(ok, x=np.array([[0.1, 1.0]])), x_lo=-1.0, x_hi=1.0, J=np.ones(1))
        == st_bits.LEFT_GRID
    )
    assert (
        _baselines.health(**dict(ok, x_tr=np.array([[-1.5, 0]])), x_lo=-1.0, x_hi=1.0, J=np.ones(1))
        == st_bits.LEFT_GRID
    )
    assert _baselines.health(**ok, x_lo=-1.0, x_hi=1.0, J=np.zeros(1)) == st_bits.NONPOSITIVE_F
    nan = dict(ok, v=np.array([[np.nan, 0]]))
    assert _baselines.health(**nan, x_lo=-1.0, x_hi=1.0, J=np.ones(1)) == st_bits.NONFINITE


def test_a_broken_run_has_no_throughput():
    """Every row of a run that broke down keeps its status and times but no Mpsps (None: null in
    JSON, empty in CSV), and the table says it broke down instead of a number."""
    out = bench.worker("f64", [100], 400, ["numpy", "jax"], [], extras=False)
    assert [r["code"] for r in out["rows"]] == ["NumPy", "plain JAX"]
    for r in out["rows"]:
        assert r["status"] & st_bits.LEFT_GRID and r["Mpsps"] is None, r
    text = bench.table(_result(out["rows"]))
    assert "| plain JAX | broke down (status 4) |" in text.replace("status 5", "status 4")
    assert "nan" not in text.split("Mean final F")[0]


def test_written_rows_of_a_broken_run_have_no_throughput(tmp_path):
    rows = [_row("NumPy"), _row("plain JAX", status=st_bits.LEFT_GRID)]
    bench.write(_result(rows), tmp_path)
    written = json.loads((tmp_path / "bench.json").read_text())["rows"]
    assert [r["Mpsps"] for r in written] == [1.0, None]
    lines = (tmp_path / "bench.csv").read_text().splitlines()
    col = bench.ROW_FIELDS.index("Mpsps")
    assert [line.split(",")[col] for line in lines[1:]] == ["1.0", ""]
    assert "broke down (status 4)" in (tmp_path / "bench.md").read_text()


def test_a_ratio_never_uses_a_broken_run():
    rows = [
        _row("Taichi", n=1000, run_s=0.01),
        _row("Warp", n=1000, status=3),
        _row("jaxmpm spq", n=1000, run_s=0.005),
        _row("Taichi", n=2000, run_s=0.01),
        _row("jaxmpm spq", n=2000, run_s=0.01),
    ]
    text = bench.table(_result(rows))
    assert "| jaxmpm spq / faster of Taichi, Warp | - | 1.00 |" in text
    assert "1,000: Warp broke down (status 3)" in text
    assert "| Warp | broke down (status 3) |" in text


def test_best_of_prefers_a_healthy_round():
    fast_but_broken = dict(_row("Warp", run_s=0.001), status=3, Mpsps=None)
    best = bench.best_of([[fast_but_broken], [_row("Warp", run_s=0.01)]])[0]
    assert best["status"] == 0 and best["run_s"] == 0.01 and best["Mpsps_rounds"] == [None, 1.0]
    assert bench.best_of([[fast_but_broken]])[0]["status"] == 3  # no healthy round: it broke down


def test_agreement_counts_nan_as_a_disagreement():
    rows = [_row("NumPy", 1.5), _row("plain JAX", float("nan"))]
    agree = bench.agreement(rows)
    assert agree["f64"]["reference codes"] == float("inf")
    assert bench.disagreement(agree) == {"f64": {"reference codes": float("inf")}}


def test_agreement_with_numpy_alone_has_nothing_to_compare():
    rows = [_row("NumPy")]
    assert bench.agreement(rows) == {"f64": {}}
    notes = bench.agreement_notes(rows)["f64"]["reference codes"]
    assert notes == ["nothing to compare: fewer than two healthy codes (only NumPy)"]
    text = bench.table(_result(rows))
    assert "reference codes: nothing to compare" in text and "0.0e+00" not in text


def test_agreement_names_a_size_left_out():
    rows = [
        _row("NumPy", n=200, status=st_bits.LEFT_GRID),
        _row("plain JAX", n=200),
        _row("NumPy", n=400),
        _row("plain JAX", n=400),
    ]
    fold = [dict(dtype="f64", particles=400, dim=1, F_mean=1.5, status=st_bits.NONFINITE)]
    rows.append(_row("jaxmpm spq", n=400))
    agree, notes = bench._agreement(rows, fold)
    assert agree["f64"] == {"reference codes": 0.0}
    assert notes["f64"]["reference codes"] == ["plain JAX at 200 left out: NumPy broke down (status 4)"]
    fold_notes = notes["f64"]["jaxmpm spq vs NumPy with the fold"]
    assert (
        fold_notes[0].startswith("nothing to compare")
        and "NumPy with the fold broke down (status 1)" in fold_notes[1]
    )
    assert "plain JAX at 200 left out" in bench.table(_result(rows, fold))


def test_a_disagreement_in_float64_fails_the_command_after_its_outputs(
    tmp_path, capsys, monkeypatch, measured
):
    """A float64 difference beyond round-off: the table and JSON say so, the files are written, and
    the command exits 1 with one line; the same difference in float32 is only reported."""

    def disagreeing(*a, **k):
        result = copy.deepcopy(measured)
        numpy = result["rows"][0]
        for dtype in ("f64", "f32"):
            result["rows"].append(
                dict(numpy, code="plain JAX", dtype=dtype, F_mean=numpy["F_mean"] * (1 + 1e-3))
            )
        result["rows"].append(dict(numpy, dtype="f32"))
        result["agreement"], result["agreement_notes"] = bench._agreement(result["rows"], [])
        result["disagreement"] = bench.disagreement(result["agreement"])
        return result

    monkeypatch.setattr(bench, "run", disagreeing)
    assert cli.main(argv(out=str(tmp_path))) == 1
    cap = capsys.readouterr()
    assert "The codes disagree beyond round-off" in cap.out and "f64 reference codes by 1.0e-03" in cap.out
    assert "f32 reference codes by" not in cap.out
    lines = cap.err.splitlines()
    assert lines[-1].startswith("jaxmpm: error: the codes' mean final F disagree"), cap.err
    assert "f64 reference codes by 1.0e-03" in lines[-1] and "f32" not in lines[-1]
    assert "Traceback" not in cap.err
    held = files(tmp_path)
    assert set(held) == set(bench.FILES)
    assert json.loads(held["bench.json"])["disagreement"] == {"f64": {"reference codes": pytest.approx(1e-3)}}


def test_a_fold_check_that_breaks_down_is_reported_and_the_benchmark_goes_on(monkeypatch):
    """The NumPy code with the fold, like every reference code, is reported broken with its status;
    the float type's results stand (it aborted the whole process before)."""
    out = bench.worker("f64", [100], 400, ["numpy", "jaxmpm"], ["spq"], extras=False)
    (fold,) = out["numpy_with_fold"]
    assert fold["status"] & st_bits.LEFT_GRID
    notes = bench.agreement_notes(out["rows"], out["numpy_with_fold"])["f64"]
    assert "jaxmpm spq vs NumPy with the fold" in notes

    real = _baselines.BASELINES["NumPy"]

    def fold_raises(n, steps, dtype, fold=False):
        if fold:
            raise ValueError("operands could not be broadcast together with shapes (71,) (72,)")
        return real(n, steps, dtype)

    monkeypatch.setitem(_baselines.BASELINES, "NumPy", fold_raises)
    out = bench.worker("f64", [100], 5, ["numpy", "jaxmpm"], ["spq"], extras=False)
    (fold,) = out["numpy_with_fold"]
    assert fold["status"] == st_bits.NONFINITE and "broadcast" in fold["error"]
    assert {r["code"] for r in out["rows"]} == {"NumPy", "jaxmpm spq", "jaxmpm spq, one step a call"}


@pytest.mark.parametrize(
    "options, named",
    [
        (dict(codes="numpy", interpolators="spq"), "--interpolators goes with jaxmpm in --codes"),
        (dict(codes="numpy,,jax"), "--codes has an empty item"),
        (dict(codes="numpy,"), "--codes has an empty item"),
        (dict(dtypes="f64,"), "--dtypes has an empty item"),
        (dict(codes="jaxmpm", interpolators="spq,,mpq"), "--interpolators has an empty item"),
        (dict(sizes="1000,"), "--sizes has an empty item"),
        (dict(sizes=""), "--sizes needs at least one particle count in 1D (even, two per cell), got ''"),
        (dict(sizes_2d="16,"), "--sizes-2d has an empty item"),
        (dict(sizes_3d=",64"), "--sizes-3d has an empty item"),
        (dict(sizes="2", steps="100"), "the smallest size for 100 steps is 32"),
        (dict(sizes="100,30", steps="100"), "--sizes 30"),
        (dict(sizes="100", steps="400"), "the smallest size for 400 steps is 288"),
    ],
)
def test_options_that_would_do_nothing_or_cannot_run_are_refused(options, named, capsys, recorded):
    assert cli.main(argv(**options)) == 2
    one_line_error(capsys, named)
    assert recorded == []


def test_the_smallest_size_for_the_steps_runs(capsys, recorded):
    assert cli.main(argv(sizes="32", steps="100")) == 0
    assert cli.main(argv(sizes="2", steps="2", codes="numpy,jaxmpm", interpolators="spq")) == 0
    assert len(recorded) == 2
    capsys.readouterr()
