"""experiments/suite_time.py: the report adds up what the plugin logged, and the plugin logs only runs
with the suite's settings."""

import json
import re

import pytest

from experiments.suite_time import check_settings_read, load, report


def test_report_sums_per_file_test_function_and_compiled_function(tmp_path):
    a = "tests/test_a.py::test_x[spq]"
    b = "tests/test_a.py::test_x[mpq]"
    c = "tests/test_b.py::test_y"
    rows = {
        "gw0": [
            (a, "trace", "run_scan", 0.5),
            (a, "lower", "jit(run_scan)", 0.25),
            (a, "compile", "jit(run_scan)", 1.0),
            (a, "wall", "", 2.0),
        ],
        "gw1": [
            (b, "compile", "jit(run_scan)", 2.0),
            (b, "wall", "", 3.0),
            (c, "compile", "jit(add)", 0.5),
            (c, "wall", "", 1.0),
        ],
    }
    for worker, r in rows.items():
        (tmp_path / f"{worker}.jsonl").write_text("".join(json.dumps(x) + "\n" for x in r))
    text = report(load(tmp_path))
    assert text.splitlines()[0] == (
        "3 tests, 6 s of test time over 2 worker(s); 3 compilations: tracing 0 s, lowering 0 s, "
        "XLA compilation 4 s (71% of the test time)"
    )
    assert "gw0 2 s, 1, gw1 4 s, 2" in text
    assert "| 5.0 | 0.5 | 0.2 | 3.0 | 2 | 2 | tests/test_a.py |" in text
    assert "| 5.0 | 0.5 | 0.2 | 3.0 | 2 | 2 | tests/test_a.py::test_x |" in text
    assert "| 1.0 | 0.0 | 0.0 | 0.5 | 1 | 1 | tests/test_b.py::test_y |" in text
    # the trace event names the function bare, the compilation as jit(...): one row
    assert "| 0.0 | 0.5 | 0.2 | 3.0 | 2 | 0 | run_scan |" in text


def test_report_counts_distinct_whole_run_programs_with_and_without_their_step_count(tmp_path):
    rows = {
        "gw0": [
            ("tests/test_a.py::test_x", "run", "k1|10", 0.0),
            ("tests/test_a.py::test_x", "run", "k1|10", 0.0),  # the same program again
            ("tests/test_a.py::test_x", "run", "k1|20", 0.0),  # the same structure, other steps
            ("tests/test_a.py::test_x", "wall", "", 1.0),
        ],
        "gw1": [
            ("tests/test_b.py::test_y", "run", "k2|10", 0.0),
            ("tests/test_b.py::test_y", "run", "k1|10", 0.0),  # first ran in test_a.py
            ("tests/test_b.py::test_y", "wall", "", 1.0),
        ],
    }
    for worker, r in rows.items():
        (tmp_path / f"{worker}.jsonl").write_text("".join(json.dumps(x) + "\n" for x in r))
    text = report(load(tmp_path))
    assert (
        "Whole runs (jm.simulate): 5 calls, 3 distinct programs over the workers (gw0 2, gw1 2), "
        "2 without their step count"
    ) in text
    assert "  2 tests/test_a.py\n  1 tests/test_b.py" in text
    assert "| 1.0 | 0.0 | 0.0 | 0.0 | 0 | 1 | tests/test_a.py |" in text  # run rows add no time


def test_the_plugin_logs_each_whole_run_with_its_program(monkeypatch):
    import jaxmpm as jm
    from experiments.suite_time import _Log, _log_programs
    from jaxmpm import _simulate

    monkeypatch.setattr(_simulate, "_run_scan_jit", _simulate._run_scan_jit)  # restored afterwards
    log = _Log(None)
    log.test = "t"
    _log_programs(log)
    for cells, steps in ((3, 1), (3, 1), (3, 2), (4, 1)):
        sol = jm.simulate(jm.GasExpansion(cells=cells), jm.SPQ(), dt=1e-5, steps=steps)
        assert int(sol.status) == 0
    keys = [fun for test, kind, fun, _ in log.rows if kind == "run"]
    assert len(keys) == 4 and all(test == "t" for test, *_ in log.rows)
    assert keys[0] == keys[1]  # the same run: the same program
    assert keys[2] != keys[0] and keys[2].rsplit("|", 1)[0] == keys[0].rsplit("|", 1)[0]  # steps only
    assert keys[3].rsplit("|", 1)[0] != keys[0].rsplit("|", 1)[0]  # another size, another program


def test_the_plugin_refuses_a_run_without_the_suites_settings(tmp_path):
    # `--suite-time-log DIR` with DIR existing: pytest took DIR for the root and read no pyproject.toml
    with pytest.raises(pytest.UsageError, match=re.escape(f"write --suite-time-log={tmp_path}")):
        check_settings_read(str(tmp_path), None, tmp_path)
    check_settings_read(str(tmp_path), tmp_path / "pyproject.toml", tmp_path)  # settings read: logged


def test_report_sums_cpu_time_of_the_tests_and_of_the_processes_they_started(tmp_path):
    a, b, c = "tests/test_a.py::test_x[spq]", "tests/test_a.py::test_x[mpq]", "tests/test_b.py::test_y"
    rows = {
        "gw0": [(a, "wall", "", 2.0), (a, "cpu", "", 1.5), (a, "children", "", 0.0)],
        "gw1": [
            (b, "wall", "", 3.0),
            (b, "cpu", "", 2.5),
            (b, "children", "", 0.25),
            (c, "wall", "", 9.0),  # waits on a command line it started
            (c, "cpu", "", 0.5),
            (c, "children", "", 6.0),
        ],
    }
    for worker, r in rows.items():
        (tmp_path / f"{worker}.jsonl").write_text("".join(json.dumps(x) + "\n" for x in r))
    text = report(load(tmp_path))
    assert (
        "CPU time of the tests: 11 s, 4 s in the tests' own processes and 6 s in the processes they started"
    ) in text
    by_file = text.split("Per file, by CPU time")[1].split("Per test function, by CPU time")[0]
    assert by_file.index("| 6.5 | 0.5 | 6.0 | 1 | tests/test_b.py |") < by_file.index(
        "| 4.2 | 4.0 | 0.2 | 2 | tests/test_a.py |"
    )
    assert "| 4.2 | 4.0 | 0.2 | 2 | tests/test_a.py::test_x |" in text
    assert "| 5.0 | 0.0 | 0.0 | 0.0 | 0 | 2 | tests/test_a.py |" in text  # the wall-time table as before


def test_a_log_without_cpu_times_has_no_cpu_tables(tmp_path):
    (tmp_path / "gw0.jsonl").write_text(json.dumps(["tests/test_a.py::test_x", "wall", "", 1.0]) + "\n")
    assert "CPU" not in report(load(tmp_path))


def test_cpu_times_count_this_process_and_the_processes_it_waited_for():
    import subprocess
    import sys

    from experiments.suite_time import cpu_times

    own0, children0 = cpu_times()
    sum(i * i for i in range(2_000_000))  # about 0.1 s of this process's CPU
    subprocess.run([sys.executable, "-c", "sum(i * i for i in range(2_000_000))"], check=True)
    own1, children1 = cpu_times()
    assert own1 - own0 > 0.02 and children1 - children0 > 0.02
