"""Reverse mode with bounded memory: time and memory of jax.grad through long runs.

The problem: the gas expansion with 1,000 particles (500 cells, ppc = 2, h = 2 mm), MPQ with
artificial cells, FLIP, USL, dt = 0.1 h / c0, beta = 2 /s; the objective is the final RMS relative
F error. For each step count it measures, each configuration in its own process:

- forward: compile time and run time of the jitted objective;
- reverse, checkpointed (checkpoint=True: blocks of ceil(sqrt(steps / 8)) steps): compile and run
  time of jax.grad;
- peak resident memory of that process (ru_maxrss, includes Python, JAX and XLA themselves), and
  XLA's own account of the buffers the compiled computation needs (memory_analysis: arguments,
  outputs, temporaries);
- for plain (uncheckpointed) reverse mode, XLA's buffer account only: at 100,000 steps it would
  need tens of GB, so it is compiled, not run.

Usage: python experiments/grad_memory.py [--small] [--out results/grad_memory.csv] [--overwrite]

An existing ``--out`` is refused, before anything is computed, unless ``--overwrite``.
"""

import argparse
import json
import pathlib
import resource
import subprocess
import sys
import time

from _entry import positive, refuse_existing

from jaxmpm.studies._output import csv_text, write_text

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODES = ("forward", "reverse", "plain")
STEPS = (1_000, 10_000, 100_000)
SMALL_STEPS = (200, 1_000)


def one(mode: str, steps: int) -> dict:
    """Measure one configuration in this process.

    Args:
        mode: ``"forward"``, ``"reverse"`` (checkpointed) or ``"plain"`` (uncheckpointed reverse mode,
            compiled only).
        steps: the step count.

    Returns:
        ``mode``, ``steps``, ``compile_s``, ``xla_bytes``, and unless ``plain`` ``run_s``, ``value``
        and ``peak_rss_bytes``.
    """
    import jax
    import jax.numpy as jnp

    from benchmarks.bench import reverse_objective as objective  # the checkout's benchmarks/ (main)
    from benchmarks.bench import xla_bytes

    jax.config.update("jax_enable_x64", True)
    beta = jnp.asarray(2.0)
    if mode == "forward":
        fn = jax.jit(objective(steps, False))
    elif mode == "reverse":
        fn = jax.jit(jax.grad(objective(steps, True)))
    else:
        fn = jax.jit(jax.grad(objective(steps, False)))
    t0 = time.perf_counter()
    compiled = fn.lower(beta).compile()
    compile_s = time.perf_counter() - t0
    out = dict(mode=mode, steps=steps, compile_s=compile_s, xla_bytes=xla_bytes(compiled))
    if mode != "plain":
        t0 = time.perf_counter()
        value = float(jax.block_until_ready(compiled(beta)))
        out["run_s"] = time.perf_counter() - t0
        out["value"] = value
        out["peak_rss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return out


def measure(small: bool = False) -> list[dict]:
    """Measure every configuration, each in its own process, and print a line per step count.

    Args:
        small: 200 and 1,000 steps instead of 1,000 to 100,000.

    Returns:
        One dict per configuration (``mode``, ``steps``, times, bytes).
    """
    rows = []
    for steps in SMALL_STEPS if small else STEPS:
        for mode in MODES:
            proc = subprocess.run(
                [sys.executable, __file__, "--one", mode, "--steps", str(steps)],
                capture_output=True,
                text=True,
            )
            if proc.returncode:
                sys.exit(f"the process for {mode} at {steps} steps failed:\n{proc.stderr[-2000:]}")
            rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        fwd, rev, plain = rows[-3:]
        print(
            f"steps={steps:>7}: forward {fwd['run_s']:.2f} s (compile {fwd['compile_s']:.2f} s), "
            f"reverse {rev['run_s']:.2f} s = {rev['run_s'] / fwd['run_s']:.2f}x forward "
            f"(compile {rev['compile_s']:.2f} s); XLA buffers: forward {fwd['xla_bytes'] / 1e6:.1f} MB, "
            f"checkpointed reverse {rev['xla_bytes'] / 1e6:.1f} MB, "
            f"plain reverse {plain['xla_bytes'] / 1e6:.1f} MB; peak RSS forward "
            f"{fwd['peak_rss_bytes'] / 1e6:.0f} MB, reverse {rev['peak_rss_bytes'] / 1e6:.0f} MB",
            flush=True,
        )
    return rows


def main(argv: list[str] | None = None) -> list[dict]:
    """Measure every configuration (``measure``) and write a CSV of them; or, with ``--one``, measure
    one configuration in this process and print it as JSON (the processes ``measure`` starts).

    Returns:
        One dict per configuration (``mode``, ``steps``, times, bytes).
    """
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--small", action="store_true", help="200 and 1,000 steps instead of 1,000 to 100,000"
    )
    parser.add_argument("--out", default="results/grad_memory.csv", help="the CSV file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace --out where it exists")
    parser.add_argument("--one", choices=MODES, help=argparse.SUPPRESS)  # a child process's configuration
    parser.add_argument("--steps", type=positive, help=argparse.SUPPRESS)  # and its step count
    args = parser.parse_args(argv)
    if args.one is not None:
        if args.steps is None:
            parser.error("--one goes with --steps")
        sys.path.insert(0, str(ROOT))  # the checkout's benchmarks/
        row = one(args.one, args.steps)
        print(json.dumps(row))
        return [row]
    refuse_existing(parser, "--out", [args.out], args.overwrite)
    rows = measure(small=args.small)
    path = pathlib.Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = sorted({k for r in rows for k in r})
    write_text(path, csv_text(rows, keys))
    print(f"wrote {path}")
    return rows


if __name__ == "__main__":
    main()
