"""Where the test suite's time goes: JAX's tracing, lowering to MLIR and XLA compilation, per test.

A pytest plugin and the report of what it logged. Run the suite (or part of it) with the plugin,
then read the report::

    PYTHONPATH=experiments python -m pytest -q -p suite_time --suite-time-log=/tmp/suite_time
    python experiments/suite_time.py /tmp/suite_time

Write the option with ``=``. Written apart (``--suite-time-log /tmp/suite_time``), a folder that
already exists is also a path among pytest's arguments. pytest then takes it for the root of the
tests, and the suite's settings in ``pyproject.toml`` are not read: no workers, no markers and no
jaxtyping checks. The plugin refuses to log such a run (``check_settings_read``).

Each process that runs tests (each pytest-xdist worker, or pytest itself without workers) writes
``<log>/<worker>.jsonl``: one line per test with its wall time (and two with its CPU times, below),
and one per compilation event JAX reports to its monitoring listeners (``jaxpr_trace_duration``,
``jaxpr_to_mlir_module_duration``, ``backend_compile_duration``, the last including a read from the
on-disk compilation cache), with the name of the function compiled and the test it happened in, and
one per whole run that ``jm.simulate`` compiles or reuses (the program's structure: its model's
static fields and array shapes, what it saves, its checkpoint block and its step count). The report
sums them per file, per test function (its parametrisations together), per compiled function and per
worker, and counts the distinct whole-run programs with and without their step count (what a step
count that is not static would share).

Each test's CPU time is logged too: its own process's (user and system, ``getrusage``) and that of
the processes it started and waited for (command lines, notebooks, docs examples, multi-process
runs), whose compilations the events above do not see. The report sums it per file and per test
function: on 2 cores the suite's wall time is at least its CPU time over 2.

A jitted function traced inside another's trace reports its own tracing too, so tracing can be
counted twice where jitted functions nest. Give an empty folder: a worker's file replaces the one of
the same name.
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import re
import sys
import time
from pathlib import Path

import pytest

try:
    import resource
except ImportError:  # not Unix: no CPU times
    resource = None

EVENTS = {
    "jaxpr_trace_duration": "trace",
    "jaxpr_to_mlir_module_duration": "lower",
    "backend_compile_duration": "compile",
}


# --- the plugin -------------------------------------------------------------------------------------


def pytest_addoption(parser):
    parser.addoption(
        "--suite-time-log",
        metavar="DIR",
        default=None,
        help="write each test's wall time and JAX compilation events to DIR/<worker>.jsonl",
    )


class _Log:
    def __init__(self, folder: Path):
        self.folder = folder
        self.test = "<outside tests>"
        self.rows: list[tuple[str, str, str, float]] = []

    def listen(self, event, duration, **kwargs):
        kind = EVENTS.get(event.rsplit("/", 1)[-1])
        if kind is not None:
            self.rows.append((self.test, kind, str(kwargs.get("fun_name", "")), float(duration)))


_LOG: list[_Log] = []


def _program(model, dt, steps, saveat, block) -> str:
    """A key of the whole-run program ``jm.simulate`` compiles, the same in every process: the model's
    static part, the tree of its arrays (which carries the static fields) and their shapes and dtypes,
    and the other static arguments, with memory addresses dropped. The step count is kept apart,
    after the last ``|``."""
    import equinox as eqx
    import jax

    arrays, static = eqx.partition(model, eqx.is_array)
    leaves, tree = jax.tree_util.tree_flatten(arrays)
    shapes = [(tuple(a.shape), str(a.dtype)) for a in leaves]
    text = repr(static) + str(tree) + str(shapes)
    text += repr(saveat) + repr(block) + type(dt).__name__ + str(getattr(dt, "dtype", ""))
    text = re.sub(r" at 0x[0-9a-f]+", "", text)
    return f"{hashlib.sha1(text.encode()).hexdigest()}|{steps}"


def _log_programs(log: _Log) -> None:
    """Record every whole run's program key, then run it as before."""
    from jaxmpm import _simulate

    compiled = _simulate._run_scan_jit

    class Logged:
        def __call__(self, model, dt, steps, saveat, block):
            log.rows.append((log.test, "run", _program(model, dt, steps, saveat, block), 0.0))
            return compiled(model, dt, steps, saveat, block)

        def lower(self, model, dt, steps, saveat, block):  # simulate_timed: compiled apart from the run
            log.rows.append((log.test, "run", _program(model, dt, steps, saveat, block), 0.0))
            return compiled.lower(model, dt, steps, saveat, block)

    _simulate._run_scan_jit = Logged()


def check_settings_read(folder: str, inipath: Path | None, rootpath: Path) -> None:
    """Refuse a run whose timings would not be the suite's: one where pytest found no configuration
    file, so that the suite's settings (``-n auto``, its markers, the jaxtyping checks) are not in
    effect. It happens when an existing log folder is written apart from its option, and so taken as
    a test path.

    Args:
        folder: the ``--suite-time-log`` folder.
        inipath: the configuration file pytest read (``config.inipath``), or ``None``.
        rootpath: pytest's root folder (``config.rootpath``).

    Raises:
        pytest.UsageError: no configuration file was read.
    """
    if inipath is None:
        raise pytest.UsageError(
            f"--suite-time-log: pytest read no configuration file (rootdir {rootpath}), so the suite's "
            f"settings (-n auto, its markers, the jaxtyping checks) are not in effect and the times "
            f"would not be the suite's; an existing folder written apart from its option is taken for "
            f"a test path: write --suite-time-log={folder}, from the repository's root"
        )


def pytest_configure(config):
    folder = config.getoption("--suite-time-log")
    if folder is None:
        return
    check_settings_read(folder, config.inipath, config.rootpath)
    import jax

    log = _Log(Path(folder))
    jax.monitoring.register_event_duration_secs_listener(log.listen)
    _log_programs(log)
    _LOG.append(log)


def cpu_times() -> tuple[float, float] | None:
    """CPU seconds (user and system) so far of this process and of the processes it started and
    waited for, or ``None`` where ``getrusage`` is missing."""
    if resource is None:
        return None
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if not _LOG:
        yield
        return
    log = _LOG[0]
    log.test = item.nodeid
    start, cpu = time.perf_counter(), cpu_times()
    yield
    log.rows.append((item.nodeid, "wall", "", time.perf_counter() - start))
    if cpu is not None:
        (own, children), (own0, children0) = cpu_times(), cpu
        log.rows.append((item.nodeid, "cpu", "", own - own0))
        log.rows.append((item.nodeid, "children", "", children - children0))
    log.test = "<between tests>"


def pytest_sessionfinish(session):
    if not _LOG or not any(kind == "wall" for _, kind, _, _ in _LOG[0].rows):
        return  # off, or a process that ran no tests (pytest-xdist's controller)
    log = _LOG[0]
    log.folder.mkdir(parents=True, exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    with open(log.folder / f"{worker}.jsonl", "w") as f:
        for row in log.rows:
            f.write(json.dumps(row) + "\n")


# --- the report -------------------------------------------------------------------------------------


def load(folder: Path) -> dict[str, list[tuple[str, str, str, float]]]:
    """The rows each worker logged, by worker name."""
    files = sorted(folder.glob("*.jsonl"))
    if not files:
        raise SystemExit(f"no *.jsonl in {folder}: run pytest with -p suite_time --suite-time-log={folder}")
    return {f.stem: [tuple(json.loads(line)) for line in f.read_text().splitlines()] for f in files}


def report(logs: dict[str, list[tuple[str, str, str, float]]], top: int = 25) -> str:
    """The tables: totals, per worker, per file, per test function, per compiled function."""
    rows = [r for worker_rows in logs.values() for r in worker_rows]

    def table(key, title, n):
        sums = collections.defaultdict(collections.Counter)
        for test, kind, fun, d in rows:
            if kind == "run":
                continue
            k = key(test, fun)
            if k is None:
                continue
            sums[k][kind] += d
            sums[k][f"n_{kind}"] += 1
        order = sorted(sums.items(), key=lambda kv: -(kv[1]["wall"] or kv[1]["compile"]))[:n]
        out = [
            f"\n{title}\n",
            "| wall s | trace s | lower s | compile s | compilations | tests | |",
            "|---" * 7 + "|",
        ]
        for k, c in order:
            out.append(
                f"| {c['wall']:.1f} | {c['trace']:.1f} | {c['lower']:.1f} | {c['compile']:.1f} | "
                f"{c['n_compile']} | {c['n_wall']} | {k} |"
            )
        return out

    total = collections.Counter()
    count = collections.Counter()
    for _, kind, _, d in rows:
        total[kind] += d
        count[kind] += 1
    jax_s = total["trace"] + total["lower"] + total["compile"]
    lines = [
        f"{count['wall']} tests, {total['wall']:.0f} s of test time over {len(logs)} worker(s); "
        f"{count['compile']} compilations: tracing {total['trace']:.0f} s, lowering {total['lower']:.0f} s, "
        f"XLA compilation {total['compile']:.0f} s ({jax_s / max(total['wall'], 1e-9):.0%} of the test time)",
        "",
        "Per worker (test time, tests): "
        + ", ".join(
            f"{w} {sum(d for _, k, _, d in r if k == 'wall'):.0f} s, {sum(k == 'wall' for _, k, _, _ in r)}"
            for w, r in logs.items()
        ),
    ]
    runs = {w: [fun for _, kind, fun, _ in r if kind == "run"] for w, r in logs.items()}
    every = [p for r in runs.values() for p in r]
    lines += [
        "",
        f"Whole runs (jm.simulate): {len(every)} calls, {len(set(every))} distinct programs over the "
        f"workers ({', '.join(f'{w} {len(set(r))}' for w, r in runs.items())}), "
        f"{len({p.rsplit('|', 1)[0] for p in every})} without their step count",
    ]
    first = {}
    for test, kind, fun, _ in rows:
        if kind == "run":
            first.setdefault(fun, test.split("::")[0])
    per_file = collections.Counter(first.values()).most_common(top)
    lines += ["Distinct whole-run programs per file (where each first ran):"]
    lines += [f"  {n} {f}" for f, n in per_file]
    lines += table(lambda t, f: t.split("::")[0], "Per file", top)
    lines += table(
        lambda t, f: re.sub(r"\[.*\]$", "", t), "Per test function (parametrisations together)", top
    )
    lines += table(
        lambda t, f: re.sub(r"^jit\((.*)\)$", r"\1", f) or None,
        "Per compiled function (its tracing, lowering and compilations; no wall time of its own)",
        top,
    )
    lines += cpu_tables(rows, top)
    return "\n".join(lines)


def cpu_tables(rows: list[tuple[str, str, str, float]], top: int = 25) -> list[str]:
    """The tests' CPU time: in all, then per file and per test function, the test's own process and
    the processes it started apart; nothing for a log without CPU times."""
    own = [(t, d) for t, kind, _, d in rows if kind == "cpu"]
    started = [(t, d) for t, kind, _, d in rows if kind == "children"]
    if not own:
        return []
    total_own, total_started = sum(d for _, d in own), sum(d for _, d in started)
    lines = [
        "",
        f"CPU time of the tests: {total_own + total_started:.0f} s, {total_own:.0f} s in the tests' own "
        f"processes and {total_started:.0f} s in the processes they started",
    ]
    for title, key in (
        ("Per file, by CPU time", lambda t: t.split("::")[0]),
        ("Per test function, by CPU time (parametrisations together)", lambda t: re.sub(r"\[.*\]$", "", t)),
    ):
        sums = collections.defaultdict(collections.Counter)
        for t, d in own:
            sums[key(t)]["own"] += d
            sums[key(t)]["tests"] += 1
        for t, d in started:
            sums[key(t)]["started"] += d
        order = sorted(sums.items(), key=lambda kv: -(kv[1]["own"] + kv[1]["started"]))[:top]
        header = "| CPU s | own process s | started processes s | tests | |"
        lines += [f"\n{title}\n", header, "|---" * 5 + "|"]
        lines += [
            f"| {c['own'] + c['started']:.1f} | {c['own']:.1f} | {c['started']:.1f} | {c['tests']} | {k} |"
            for k, c in order
        ]
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path, help="the folder given to --suite-time-log")
    parser.add_argument("--top", type=int, default=25, help="rows per table (default 25)")
    args = parser.parse_args(argv)
    print(report(load(args.log), args.top))
    return 0


if __name__ == "__main__":
    sys.exit(main())
