"""Where a run's compile time goes: tracing, lowering to MLIR and XLA's compilation, per interpolator.

The benchmark's 2D and 3D scenes (``benchmarks.bench._scene``: the gas expansion on a unit square or
cube, 100 steps), each interpolator in a process of its own (as ``jaxmpm bench`` times them, so the
first compilation's one-time costs count), XLA's default options. ``jaxmpm bench`` reports the sum of
the three (compile s in brackets); this splits it and gives the size of the optimised program.

Usage: python experiments/compile_split.py [--dim 3] [--n 32768] [--f64] [--interpolators spq,mpq]
"""

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from _entry import check_particles, interpolators, positive

import jaxmpm as jm

ROOT = Path(__file__).resolve().parents[1]


def one(name: str, dim: int, n: int, f64: bool) -> dict:
    """Trace, lower and compile one run in this process.

    Args:
        name: the interpolator (a key of ``jaxmpm.INTERPOLATORS``).
        dim: 2 or 3.
        n: particles (``(2 k)^dim``).
        f64: float64 instead of float32.

    Returns:
        The three times in seconds, their sum, and the optimised program's computations and lines.
    """
    import jax

    jax.config.update("jax_enable_x64", f64)
    from benchmarks.bench import _scene
    from jaxmpm import _simulate

    scene, dt = _scene(n, dim)
    model, dt_arr, steps, saveat = _simulate.prepare(scene, jm.INTERPOLATORS[name](), dt=dt, steps=100)
    fn = jax.jit(_simulate.run_scan, static_argnums=(2, 3, 4))
    t0 = time.perf_counter()
    traced = fn.trace(model, dt_arr, steps, saveat, None)
    t1 = time.perf_counter()
    lowered = traced.lower()
    t2 = time.perf_counter()
    compiled = lowered.compile()
    t3 = time.perf_counter()
    text = compiled.as_text()
    heads = [s for s in text.splitlines() if s and not s.startswith(" ") and s.rstrip().endswith("{")]
    return dict(
        interpolator=name,
        trace_s=t1 - t0,
        lower_s=t2 - t1,
        compile_s=t3 - t2,
        total_s=t3 - t0,
        computations=len(heads),
        hlo_lines=text.count("\n"),
    )


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dim", type=int, default=3, choices=(2, 3))
    parser.add_argument(
        "--n", type=positive, default=None, help="particles (default 32,768 in 3D, 102,400 in 2D)"
    )
    parser.add_argument("--f64", action="store_true", help="float64 (default float32)")
    parser.add_argument(
        "--interpolators",
        type=interpolators,
        default="spq,gimp,cpdi,mpq,cpdi2",
        help=f"comma-separated, of {', '.join(jm.INTERPOLATORS)} (default spq,gimp,cpdi,mpq,cpdi2)",
    )
    parser.add_argument(  # a child process's interpolator
        "--one", default=None, choices=list(jm.INTERPOLATORS), help=argparse.SUPPRESS
    )
    args = parser.parse_args(argv)
    n = (32_768 if args.dim == 3 else 102_400) if args.n is None else args.n
    sys.path.insert(0, str(ROOT))
    check_particles(parser, n, args.dim)
    if args.one:
        print(json.dumps(one(args.one, args.dim, n, args.f64)))
        return []
    rows = []
    print(f"{args.dim}D, {n:,} particles, {'float64' if args.f64 else 'float32'}, 100 steps (seconds)")
    print("| interpolator | trace | lower | XLA compile | total | computations | HLO lines |")
    print("|---|---|---|---|---|---|---|")
    for name in args.interpolators:
        cmd = [sys.executable, __file__, "--dim", str(args.dim), "--n", str(n), "--one", name]
        cmd += ["--f64"] if args.f64 else []
        out = subprocess.run(cmd, capture_output=True, text=True)
        if out.returncode:
            sys.exit(f"the process for {name} failed (status {out.returncode}):\n{out.stderr[-2000:]}")
        r = json.loads(out.stdout.strip().splitlines()[-1])
        rows.append(r)
        print(
            f"| {name} | {r['trace_s']:.2f} | {r['lower_s']:.2f} | {r['compile_s']:.2f} | {r['total_s']:.2f} "
            f"| {r['computations']} | {r['hlo_lines']} |"
        )
    return rows


if __name__ == "__main__":
    main()
