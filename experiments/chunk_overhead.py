"""What chunked running costs over one scan: 100,000 steps, 1,000 particles.

The problem of experiments/grad_memory.py (gas expansion, 500 cells, ppc = 2, MPQ with artificial
cells, dt = 0.1 h / c0, beta = 2 /s). Each configuration runs `repeats` times, interleaved so that
machine noise spreads over all of them. Run time excludes compilation; the median is reported.
Usage: python experiments/chunk_overhead.py [--small]
"""

import argparse
import statistics

import jax

import jaxmpm as jm

H = 0.002
DT = 0.1 * H / (1.4 * 2.0e5) ** 0.5


def measure(small: bool = False, repeats: int = 3) -> dict:
    """Time each configuration ``repeats`` times, interleaved, and print the medians (float64: ``main``
    switches it on).

    Args:
        small: 2,000 steps instead of 100,000.
        repeats: runs of each configuration.

    Returns:
        Per configuration: median ``run_s``, median ``compile_s`` and ``overhead`` against one scan.
    """
    steps = 2_000 if small else 100_000
    scene = jm.GasExpansion(cells=500, ppc=2, h=H, beta=2.0, pad=60)
    configs = {
        "one scan (simulate)": lambda: jm.simulate_timed(
            scene, jm.MPQ(), dt=DT, steps=steps, artificial_cells=1
        ),
        "chunks of 1000": lambda: jm.long_run.run_timed(
            scene, jm.MPQ(), dt=DT, steps=steps, artificial_cells=1, chunk=1000, progress=False
        ),
        "chunks of 10000": lambda: jm.long_run.run_timed(
            scene, jm.MPQ(), dt=DT, steps=steps, artificial_cells=1, chunk=10000, progress=False
        ),
        "chunks of 1000, progress bar": lambda: jm.long_run.run_timed(
            scene, jm.MPQ(), dt=DT, steps=steps, artificial_cells=1, chunk=1000, progress=True
        ),
    }
    times = {name: [] for name in configs}
    compiles = {name: [] for name in configs}
    for _ in range(repeats):
        for name, fn in configs.items():
            _, compile_s, wall_s = fn()
            times[name].append(wall_s)
            compiles[name].append(compile_s)
    base = statistics.median(times["one scan (simulate)"])
    out = {}
    print(f"{steps} steps, 1,000 particles, median of {repeats} (run time, compile apart)")
    for name in configs:
        med = statistics.median(times[name])
        out[name] = dict(run_s=med, compile_s=statistics.median(compiles[name]), overhead=med / base - 1)
        print(
            f"  {name:30s} run {med:7.3f} s  compile {out[name]['compile_s']:.2f} s  "
            f"overhead {100 * (med / base - 1):+5.1f}%  (runs: {', '.join(f'{t:.3f}' for t in times[name])})"
        )
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--small", action="store_true", help="2,000 steps instead of 100,000")
    args = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    return measure(small=args.small)


if __name__ == "__main__":
    main()
