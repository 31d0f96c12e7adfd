"""The benchmark's jaxmpm run compiled with XLA's CPU fusion emitters (its default) and with its classic
emitters (``xla_cpu_use_fusion_emitters=False``, passed to this one compilation), the two alternating
in one process: compile time, M particle-steps/s (best of 3 runs of each compiled program), and a hash
of the final state, equal where the two programs compute the same bits.

The test suite compiles with the classic emitters (``tests/conftest.py``), which compile faster; the
library leaves XLA's default, under which the step runs faster.
A run that breaks down is reported by its status (the benchmark's runs do not break down).

    python experiments/cpu_emitters.py [--dtype f32] [--dim 2] [--n 102400] [--rounds 2]
        [--interpolators spq,mpq,cpdi,gimp]
"""

import argparse
import hashlib
import pathlib
import sys
import time

import jax
from _entry import check_particles, interpolators, positive

import jaxmpm as jm

OPTIONS = {"fusion": None, "classic": {"xla_cpu_use_fusion_emitters": False}}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dtype", choices=("f32", "f64"), default="f32")
    parser.add_argument("--dim", type=int, choices=(1, 2, 3), default=2)
    parser.add_argument("--n", type=positive, default=102_400, help="particles (default 102,400)")
    parser.add_argument("--rounds", type=positive, default=2, help="rounds of each form (default 2)")
    parser.add_argument(
        "--interpolators",
        type=interpolators,
        default="spq,mpq,cpdi,gimp",
        help=f"comma-separated, of {', '.join(jm.INTERPOLATORS)} (default spq,mpq,cpdi,gimp)",
    )
    args = parser.parse_args(argv)
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    check_particles(parser, args.n, args.dim)
    jax.config.update("jax_enable_x64", args.dtype == "f64")
    import numpy as np

    from benchmarks.bench import _scene
    from jaxmpm import _simulate

    scene, dt = _scene(args.n, args.dim)
    steps = 100
    for name in args.interpolators:
        interpolator = jm.INTERPOLATORS[name]()
        model, dt_arr, n_steps, saveat = _simulate.prepare(scene, interpolator, dt=dt, steps=steps)
        block = _simulate.checkpoint_block(False, n_steps)
        rows = {form: [] for form in OPTIONS}
        for _ in range(args.rounds):
            for form, options in OPTIONS.items():
                jax.clear_caches()
                t0 = time.perf_counter()
                lowered = _simulate._run_scan_jit.lower(model, dt_arr, n_steps, saveat, block)
                compiled = lowered.compile(compiler_options=options)
                compile_s = time.perf_counter() - t0
                best = float("inf")
                for _ in range(3):
                    t0 = time.perf_counter()
                    sol = jax.block_until_ready(compiled(model, dt_arr, n_steps, saveat, block))
                    best = min(best, time.perf_counter() - t0)
                s = sol.state
                digest = hashlib.sha1(b"".join(np.asarray(a).tobytes() for a in (s.x, s.v, s.F, s.sigma)))
                speed = args.n * steps / best / 1e6
                rows[form].append((compile_s, speed, digest.hexdigest()[:12], int(s.status)))
        for form, r in rows.items():
            print(
                f"{args.dim}D {args.dtype} {name:5s} {form:7s} compile s "
                + " ".join(f"{c:.2f}" for c, *_ in r)
                + "  M particle-steps/s "
                + " ".join(f"{m:.1f}" for _, m, *_ in r)
                + f"  state {r[0][2]}  status {r[0][3]}",
                flush=True,
            )


if __name__ == "__main__":
    main()
