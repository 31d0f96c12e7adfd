"""``jaxmpm bench``: particle-steps per second against NumPy, plain JAX, Taichi and Warp.

The benchmark and its reference codes live in ``benchmarks/`` at the root of a source checkout,
beside the package; they are not installed. This command finds them there.

Every option is checked before the benchmark starts: the sizes against the memory available (an
estimate, ``benchmarks.bench.largest_size``), and ``--out`` for a folder that can be written and holds no
``bench.csv``, ``bench.json`` or ``bench.md`` (unless ``--overwrite``).
"""

import importlib
import math
import pathlib
import sys

import jaxmpm as jm
from jaxmpm._memory import readable

from . import _assign
from ._common import CannotWrite, UsageError, print_json, writable_folder


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
    p.add_argument(
        "--dtypes", default="f32,f64", help="f32, f64 or f32,f64, comma-separated (each in its own process)"
    )
    p.add_argument(
        "--codes",
        help="among numpy, jax (plain JAX), taichi, warp (when installed: pip install jaxmpm[bench]), "
        "jaxmpm, comma-separated; each runs in every dimension asked for (--sizes, --sizes-2d, --sizes-3d)",
    )
    p.add_argument("--interpolators", help="jaxmpm's, comma-separated")
    p.add_argument("--no-extras", action="store_true", help="skip the reverse-mode and ensemble measurements")
    p.add_argument("--out", help="directory for bench.csv, bench.json and bench.md")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="with --out: replace the bench.csv, bench.json and bench.md there (else refused)",
    )
    p.add_argument(
        "--rounds",
        type=int,
        default=1,
        help="run every code this many times, each round in new processes, and keep each code's "
        "fastest round (bench.json keeps every round's throughput); default 1",
    )
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


def _sizes(text: str, option: str, dim: int, cells_of) -> list[int]:
    """The particle counts of ``--sizes`` (even, two per cell), ``--sizes-2d`` or ``--sizes-3d``
    (``(2 k)^dim`` each).

    Args:
        text: the option's value, comma-separated integers ('' for none in 2D and 3D).
        option: the option, for the message.
        dim: 1, 2 or 3.
        cells_of: ``(n, dim) -> k``, or ``None`` where ``n`` is not ``(2 k)^dim`` (the benchmark's).

    Returns:
        The counts, in order.

    Raises:
        UsageError: not integers (none in 1D), not of the form asked for, or one given twice.
    """
    if dim == 1 and not text.strip():
        raise UsageError(
            f"{option} needs at least one particle count in 1D (even, two per cell), got {text!r}"
        )
    tokens = [] if dim > 1 and not text.strip() else _items(text, option)
    try:
        sizes = [int(t) for t in tokens]
    except ValueError:
        raise UsageError(f"{option} must be comma-separated integers, got {text!r}") from None
    if dim == 1 and any(n < 2 or n % 2 for n in sizes):
        raise UsageError(f"{option} must be even particle counts >= 2 (two per cell), got {text!r}")
    if dim > 1 and any(cells_of(n, dim) is None for n in sizes):
        shape = "a square of k x k cells, 2 x 2" if dim == 2 else "a cube of k x k x k cells, 2 x 2 x 2"
        raise UsageError(
            f"{option} must be particle counts {2**dim} k^{dim} ({shape} particles each), got {text!r}"
        )
    return _distinct(sizes, option, text)


def _items(text: str, option: str) -> list[str]:
    """The comma-separated items of ``text``, stripped, refused where one is empty (``numpy,,jax``,
    ``1000,``): an empty item is a mistyped list, not nothing, in every option alike."""
    items = [t.strip() for t in text.split(",")]
    if not all(items):
        raise UsageError(f"{option} has an empty item (two commas, or one at an end), got {text!r}")
    return items


def _stays_on_grid(bench, sizes: list[int], steps: int) -> None:
    """Refuse 1D sizes whose body the exact solution carries off its grid within the run's steps
    (``bench.smallest_size``): every code would break down, so nothing would be measured."""
    small = [n for n in sizes if not bench.stays_on_grid(n, steps)]
    if small:
        raise UsageError(
            f"--sizes {small[0]}: at --steps {steps} the body of {small[0]} particles leaves its grid "
            f"(it expands by beta t; the grid reaches cells/8 + 4 cells beyond it); the smallest size "
            f"for {steps} steps is {bench.smallest_size(steps):,}"
        )


def _distinct(items: list, option: str, text: str) -> list:
    """``items``, refused when one is given twice (it would run twice)."""
    for k, item in enumerate(items):
        if item in items[:k]:
            raise UsageError(f"{option} names {item} twice, got {text!r}")
    return items


def _check_memory(bench, codes, interps, sizes: dict) -> None:
    """Refuse sizes whose runs would not fit in the memory this machine has available
    (``bench.largest_size``: the process and the most memory a particle takes among ``codes``).

    Args:
        bench: the benchmark module.
        codes: the codes that will run.
        interps: jaxmpm's interpolators that will run.
        sizes: ``{option: (dim, particle counts)}``.

    Raises:
        UsageError: the largest count of an option does not fit; the message names the option and
            the largest count that fits.
    """
    available = bench.available_memory()
    if available is None:
        return
    for option, (dim, counts) in sizes.items():
        if not counts:
            continue
        largest = bench.largest_size(dim, codes, interps, available)
        if max(counts) > largest:
            per = bench.bytes_per_particle(dim, codes, interps)
            fits = f"the largest that fits is {largest:,}" if largest else "not even the smallest run fits"
            raise UsageError(
                f"{option}: {max(counts):,} particles need more than the {readable(available)} of memory "
                f"available here (an estimated {per:,} bytes a particle, {readable(bench.PROCESS_BYTES)} "
                f"more for the process); {fits}"
            )


def command(args) -> int:
    """Check the options, run the benchmark (one process per float type) and print or write its tables.

    Args:
        args: the parsed command line.

    Returns:
        The exit status: 0; 1 when a benchmark process failed (one line on stderr, nothing printed
        or written), or when the codes' mean final F disagree in float64 beyond round-off
        (``bench.AGREEMENT_BOUND``; one line on stderr, after the results are printed and written).

    Raises:
        UsageError: bad input, or no source checkout to run the benchmark from; all found before the
            benchmark starts.
        CannotWrite: ``--out``'s files cannot be written (a full disk; or, without ``--overwrite``,
            one of them was put there while the benchmark ran): none of them is written, in whole
            or in part.
    """
    bench = benchmark()
    if args.overwrite and args.out is None:
        raise UsageError("--overwrite goes with --out DIR (the files it would replace)")
    sizes = _sizes(args.sizes, "--sizes", 1, bench.cells_of)
    if not 2 <= args.steps <= bench.MAX_STEPS:
        raise UsageError(
            f"--steps must be an integer from 2 to {bench.MAX_STEPS} (the step counter is a 32-bit "
            f"integer), got {args.steps}"
        )
    if args.rounds < 1:
        raise UsageError(f"--rounds must be an integer >= 1, got {args.rounds}")
    sizes_2d = _sizes(args.sizes_2d, "--sizes-2d", 2, bench.cells_of)
    sizes_3d = _sizes(args.sizes_3d, "--sizes-3d", 3, bench.cells_of)
    _stays_on_grid(bench, sizes, args.steps)
    for option, text in (
        ("--dtypes", args.dtypes),
        ("--codes", args.codes),
        ("--interpolators", args.interpolators),
    ):
        if text is not None and text.strip():
            _items(text, option)  # an empty item refused, as in --sizes
    dtypes = _distinct(_assign.choices(args.dtypes, "--dtypes", ("f32", "f64")), "--dtypes", args.dtypes)
    if args.codes is None:
        codes = list(bench.CODES)
    else:
        codes = _distinct(_assign.choices(args.codes, "--codes", bench.CODES), "--codes", args.codes)
    if args.interpolators is None:
        interps = list(jm.INTERPOLATORS)
    else:
        allowed = tuple(jm.INTERPOLATORS)
        interps = _assign.choices(args.interpolators, "--interpolators", allowed)
        interps = _distinct(interps, "--interpolators", args.interpolators)
        if "jaxmpm" not in codes:  # an option that would do nothing
            raise UsageError(
                f"--interpolators goes with jaxmpm in --codes (only jaxmpm has interpolators), "
                f"got --codes {args.codes}"
            )
    missing = [c for c in codes if not bench.available(c)]
    running = [c for c in codes if c not in missing]
    if not running:
        raise UsageError(
            f"--codes {args.codes or ','.join(codes)}: {', '.join(missing)} not installed "
            "(pip install jaxmpm[bench]); nothing to run"
        )
    _check_memory(
        bench,
        running,
        interps,
        {"--sizes": (1, sizes), "--sizes-2d": (2, sizes_2d), "--sizes-3d": (3, sizes_3d)},
    )
    if args.out is not None:  # before minutes of benchmark, not after
        folder = writable_folder(args.out, "--out")
        folders = [name for name in bench.FILES if (folder / name).is_dir()]
        if folders:
            raise UsageError(
                f"--out {args.out}: {folders[0]} is a folder, where the benchmark writes a file of that "
                "name; move it, or choose another folder"
            )
        held = [name for name in bench.FILES if (folder / name).exists()]
        if held and not args.overwrite:
            raise UsageError(
                f"--out {args.out} already holds {', '.join(held)}; pass --overwrite to replace "
                f"{'it' if len(held) == 1 else 'them'}, or choose another folder"
            )
    if missing:
        print(
            f"jaxmpm bench: {', '.join(missing)} not installed, skipped (pip install jaxmpm[bench])",
            file=sys.stderr,
        )
    try:
        result = bench.run(
            sizes,
            args.steps,
            dtypes,
            codes,
            interps,
            extras=not args.no_extras,
            sizes_2d=sizes_2d,
            sizes_3d=sizes_3d,
            rounds=args.rounds,
        )
    except bench.WorkerError as e:
        print(f"jaxmpm: error: {e}", file=sys.stderr)
        return 1
    # the results first: a write that fails (a full disk) does not lose the measurements; and the
    # files whatever becomes of standard output (a reader that went away: written, then status 141)
    gone = None
    try:
        if args.json:
            print_json(result)
        else:
            print(bench.table(result))
        sys.stdout.flush()
    except BrokenPipeError as e:
        gone = e
    if args.out is not None:
        try:
            paths = bench.write(result, args.out, overwrite=args.overwrite)
        except OSError as e:
            raise CannotWrite(f"--out {args.out}", e) from None
        if not args.json and gone is None:
            print("wrote " + ", ".join(str(p) for p in paths))
    if gone is not None:
        raise gone
    bad = result.get("disagreement")
    if bad:  # after the results are out: they are kept, but their throughputs compare different work
        said = "; ".join(
            f"{dtype} {group} by " + (f"{value:.1e}" if math.isfinite(value) else "not a number")
            for dtype, groups in bad.items()
            for group, value in groups.items()
        )
        bound = ", ".join(f"{dtype} {b:.0e}" for dtype, b in bench.AGREEMENT_BOUND.items())
        print(
            f"jaxmpm: error: the codes' mean final F disagree beyond round-off ({bound}): {said}",
            file=sys.stderr,
        )
        return 1
    return 0
