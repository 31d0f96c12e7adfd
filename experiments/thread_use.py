"""How jaxmpm's compiled step uses the CPU's cores: the benchmark's SPQ run, profiled.

Runs the benchmark's jaxmpm run (``benchmarks.bench.jaxmpm_simulate``: 100 steps of the gas
expansion) once to compile, once timed for the process's CPU time against its wall time, and once
under ``jax.profiler``, whose trace gives each XLA operation's start, end and thread. It prints:

- the process's CPU time over the wall time of the call (threads that spin while they wait count);
- how many operations run at the same time while any runs (the top-level events of XLA's threads);
- how often one operation runs on two threads at once (a loop split over the threads).

::

    python experiments/thread_use.py [--dtype f32] [--n 1048576] [--dim 1]
"""

import argparse
import collections
import gzip
import json
import pathlib
import resource
import sys
import tempfile
import time

import jax
from _entry import check_particles, positive


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _operations(trace_dir: str) -> list[tuple[float, float, int, str]]:
    """The top-level operations of XLA's threads: ``(start, end, thread, name)`` in microseconds."""
    path = sorted(pathlib.Path(trace_dir).rglob("*.trace.json.gz"))[-1]
    events = json.load(gzip.open(path))["traceEvents"]
    threads = {
        (e["pid"], e["tid"]): e["args"]["name"]
        for e in events
        if e.get("ph") == "M" and e.get("name") == "thread_name"
    }
    by_thread = collections.defaultdict(list)
    for e in events:
        if e.get("ph") != "X" or "Eigen" not in threads.get((e["pid"], e["tid"]), ""):
            continue
        if e["name"].startswith(("ThunkExecutor", "$")):
            continue
        by_thread[e["tid"]].append((e["ts"], e["ts"] + e["dur"], e["name"]))
    ops = []
    for tid, spans in by_thread.items():
        end = float("-inf")
        for a, b, name in sorted(spans):
            if a >= end:  # nested events (a fusion inside a loop's body) are counted once, by the outer
                ops.append((a, b, tid, name))
                end = b
    return ops


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dtype", choices=("f32", "f64"), default="f32")
    parser.add_argument("--n", type=positive, default=1_048_576, help="particles (default 1,048,576)")
    parser.add_argument("--dim", type=int, choices=(1, 2, 3), default=1)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    check_particles(parser, args.n, args.dim)
    jax.config.update("jax_enable_x64", args.dtype == "f64")
    from benchmarks.bench import jaxmpm_simulate

    def run():
        return jaxmpm_simulate("spq", args.n, 100, args.dim)

    run()  # compiles
    c0, w0 = _cpu(), time.perf_counter()
    _, _, _, status = run()
    c1, w1 = _cpu(), time.perf_counter()
    if status:
        sys.exit(f"the run broke down (status {status}): its timing would mean nothing")
    with tempfile.TemporaryDirectory() as trace_dir:
        with jax.profiler.trace(trace_dir):
            run()
        ops = _operations(trace_dir)
    if not ops:
        sys.exit(
            "the profile holds no operation on XLA's threads (a run this small may not use them): raise --n"
        )
    edges = sorted([(a, 1) for a, _, _, _ in ops] + [(b, -1) for _, b, _, _ in ops])
    running, at, busy = 0, edges[0][0], collections.Counter()
    for t, step in edges:
        busy[running] += t - at
        running, at = running + step, t
    active = sum(v for k, v in busy.items() if k > 0)
    spans = collections.defaultdict(list)
    for a, b, tid, name in ops:
        spans[name].append((a, b, tid))
    split = 0
    for s in spans.values():
        s.sort()
        split += sum(1 for (a, b, t), (a2, _, t2) in zip(s, s[1:]) if a2 < b and t2 != t)
    print(f"{args.dtype}, {args.dim}D, {args.n:,} particles, 100 steps")
    print(f"  process CPU time / wall time: {(c1 - c0) / (w1 - w0):.2f}")
    at_a_time = sum(k * v for k, v in busy.items()) / active
    print(
        f"  XLA operations running at a time, while any runs: {at_a_time:.2f} "
        f"({len(ops)} operations; 1 at a time for {busy[1] / 1e3:.0f} ms, 2 for {busy[2] / 1e3:.0f} ms)"
    )
    print(f"  one operation on two threads at once: {split} times")


if __name__ == "__main__":
    main()
