"""``jaxmpm bench``: particle-steps per second against NumPy, plain JAX, Taichi and Warp.

The benchmark and its reference codes live in ``benchmarks/`` at the root of a source checkout,
beside the package; they are not installed. This command finds them there.
"""

import importlib
import pathlib
import sys

import jaxmpm as jm

from . import _assign
from ._common import UsageError, print_json, writable_folder


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
        help="particle counts of the 2D runs (4 k^2: k^2 cells of 2 x 2), comma-separated; '' for none",
    )
    p.add_argument(
        "--sizes-3d",
        default="",
        help="particle counts of the 3D runs (8 k^3: k^3 cells of 2 x 2 x 2), comma-separated; "
        "'' (the default) for none",
    )
    p.add_argument("--dtypes", default="f32,f64", help="f32, f64 or both (each in its own process)")
    p.add_argument(
        "--codes",
        help="among numpy, jax (plain JAX), taichi, warp (when installed: pip install jaxmpm[bench]), "
        "jaxmpm, comma-separated; each runs in every dimension asked for (--sizes, --sizes-2d, --sizes-3d)",
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


def _sizes_nd(text: str, dim: int, cells_of) -> list[int]:
    """The particle counts of ``--sizes-2d`` or ``--sizes-3d``: ``(2 k)^dim`` each.

    Args:
        text: the option's value, comma-separated integers ('' for none).
        dim: 2 or 3.
        cells_of: ``(n, dim) -> k``, or ``None`` where ``n`` is not ``(2 k)^dim`` (the benchmark's).

    Returns:
        The counts.

    Raises:
        UsageError: not integers, or not ``(2 k)^dim``.
    """
    option = f"--sizes-{dim}d"
    try:
        sizes = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise UsageError(f"{option} must be comma-separated integers, got {text!r}") from None
    if any(cells_of(n, dim) is None for n in sizes):
        shape = "a square of k x k cells, 2 x 2" if dim == 2 else "a cube of k x k x k cells, 2 x 2 x 2"
        raise UsageError(
            f"{option} must be particle counts {2**dim} k^{dim} ({shape} particles each), got {text!r}"
        )
    return sizes


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
    sizes_2d = _sizes_nd(args.sizes_2d, 2, bench.cells_of)
    sizes_3d = _sizes_nd(args.sizes_3d, 3, bench.cells_of)
    dtypes = _assign.choices(args.dtypes, "--dtypes", ("f32", "f64"))
    codes = list(bench.CODES) if args.codes is None else _assign.choices(args.codes, "--codes", bench.CODES)
    interps = (
        list(jm.INTERPOLATORS)
        if args.interpolators is None
        else _assign.choices(args.interpolators, "--interpolators", tuple(jm.INTERPOLATORS))
    )
    if args.out is not None:
        writable_folder(args.out, "--out")  # before minutes of benchmark, not after
    missing = [c for c in codes if not bench.available(c)]
    if missing:
        print(
            f"jaxmpm bench: {', '.join(missing)} not installed, skipped (pip install jaxmpm[bench])",
            file=sys.stderr,
        )
    result = bench.run(
        sizes,
        args.steps,
        dtypes,
        codes,
        interps,
        extras=not args.no_extras,
        sizes_2d=sizes_2d,
        sizes_3d=sizes_3d,
    )
    if args.out is not None:
        paths = bench.write(result, args.out)
        if not args.json:
            print("wrote " + ", ".join(str(p) for p in paths))
    if args.json:
        print_json(result)
    else:
        print(bench.table(result))
    return 0
