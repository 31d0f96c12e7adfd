"""``jaxmpm bench``: particle-steps per second against NumPy, plain JAX, Taichi and Warp.

The benchmark and its reference codes live in ``benchmarks/`` at the root of a source checkout,
beside the package; they are not installed. This command finds them there.
"""

import importlib
import math
import pathlib
import sys

import jaxmpm as jm

from . import _assign
from ._common import UsageError, print_json


def add_parser(subparsers) -> None:
    """Add the ``bench`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser(
        "bench", help="particle-steps per second against NumPy, plain JAX, Taichi and Warp"
    )
    p.add_argument(
        "--sizes", default="1000,8000,64000,256000,1000000", help="particle counts, comma-separated"
    )
    p.add_argument("--steps", type=int, default=100, help="steps per run (a quarter from 500k particles up)")
    p.add_argument(
        "--sizes-2d",
        default="16384,102400",
        help="particle counts of jaxmpm's 2D runs (4 k^2: k^2 cells of 2 x 2), comma-separated; '' for none",
    )
    p.add_argument("--dtypes", default="f32,f64", help="f32, f64 or both (each in its own process)")
    p.add_argument(
        "--codes",
        help="among numpy, jax (plain JAX), taichi, warp (when installed: pip install jaxmpm[bench]), jaxmpm",
    )
    p.add_argument("--interpolators", help="jaxmpm's, comma-separated")
    p.add_argument("--no-extras", action="store_true", help="skip the reverse-mode and ensemble measurements")
    p.add_argument("--out", help="directory for bench.csv, bench.json and bench.md")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(handler=command)


def benchmark():
    """The benchmark module, ``benchmarks/bench.py`` of the source checkout this jaxmpm runs from.

    Returns:
        The module.

    Raises:
        UsageError: jaxmpm was not imported from a source checkout (no ``benchmarks/`` beside it).
    """
    root = pathlib.Path(jm.__file__).resolve().parents[1]
    folder = root / "benchmarks"
    if not (folder / "bench.py").is_file():
        raise UsageError(
            f"the benchmark needs a source checkout of jaxmpm (no benchmarks/ folder in {root}); "
            "clone the repository and install it with pip install -e ."
        )
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    module = importlib.import_module("benchmarks.bench")
    if pathlib.Path(module.__file__).resolve().parent != folder:
        raise UsageError(f"the benchmark: 'benchmarks' is imported from {module.__file__}, not from {folder}")
    return module


def command(args) -> int:
    """Check the options, run the benchmark (one process per float type) and print or write its tables.

    Args:
        args: the parsed command line.

    Returns:
        The exit status, 0.

    Raises:
        UsageError: bad input, or no source checkout to run the benchmark from.
    """
    bench = benchmark()
    try:
        sizes = [int(t) for t in args.sizes.split(",")]
    except ValueError:
        raise UsageError(f"--sizes must be comma-separated integers, got {args.sizes!r}") from None
    if any(n < 2 or n % 2 for n in sizes):
        raise UsageError(f"--sizes must be even particle counts >= 2 (two per cell), got {args.sizes!r}")
    if args.steps < 2:
        raise UsageError(f"--steps must be an integer >= 2, got {args.steps}")
    try:
        sizes_2d = [int(t) for t in args.sizes_2d.split(",") if t.strip()]
    except ValueError:
        raise UsageError(f"--sizes-2d must be comma-separated integers, got {args.sizes_2d!r}") from None
    if any(n < 4 or n % 4 or round(math.sqrt(n // 4)) ** 2 != n // 4 for n in sizes_2d):
        raise UsageError(
            f"--sizes-2d must be particle counts 4 k^2 (a square of k x k cells, 2 x 2 particles each), "
            f"got {args.sizes_2d!r}"
        )
    dtypes = _assign.choices(args.dtypes, "--dtypes", ("f32", "f64"))
    codes = list(bench.CODES) if args.codes is None else _assign.choices(args.codes, "--codes", bench.CODES)
    interps = (
        list(jm.INTERPOLATORS)
        if args.interpolators is None
        else _assign.choices(args.interpolators, "--interpolators", tuple(jm.INTERPOLATORS))
    )
    missing = [c for c in codes if not bench.available(c)]
    if missing:
        print(
            f"jaxmpm bench: {', '.join(missing)} not installed, skipped (pip install jaxmpm[bench])",
            file=sys.stderr,
        )
    result = bench.run(
        sizes, args.steps, dtypes, codes, interps, extras=not args.no_extras, sizes_2d=sizes_2d
    )
    if args.out:
        paths = bench.write(result, args.out)
        if not args.json:
            print("wrote " + ", ".join(str(p) for p in paths))
    if args.json:
        print_json(result)
    else:
        print(bench.table(result))
    return 0
