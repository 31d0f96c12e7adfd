"""experiments/suite_time.py: the report of where the suite's time goes adds up what it logged."""

import json

from experiments.suite_time import load, report


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
