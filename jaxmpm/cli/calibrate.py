"""``jaxmpm calibrate``: fit material constants to a measured free-surface trajectory."""

import csv
import sys

import numpy as np

import jaxmpm as jm
from jaxmpm._checks import check_positive

from . import _assign
from ._common import UsageError, print_json


def add_parser(subparsers) -> None:
    """Add the ``calibrate`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser(
        "calibrate", help="fit constants (gamma, P0, rho0) to a free-surface trajectory"
    )
    p.add_argument("scene", help="scene name (gas-slab)")
    p.add_argument("params", nargs="*", metavar="name=value", help="scene parameters (the model's)")
    p.add_argument("--data", required=True, metavar="FILE.csv", help="header and columns t,x_free")
    p.add_argument("--fit", default="gamma,P0", metavar="NAME[,NAME...]", help="parameters to fit")
    p.add_argument("--start", metavar="NAME=V[,NAME=V...]", help="start values (default: the scene's)")
    p.add_argument("--interpolator", default="cpdi", choices=list(jm.INTERPOLATORS))
    p.add_argument("--method", default="lbfgs", choices=["lbfgs", "adam"])
    p.add_argument("--iterations", type=int, default=50, help="the most iterations (50)")
    p.add_argument("--dt", type=float, help="model time step (default: CFL 0.2 at the start values)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=command)


def read_trajectory(path: str) -> tuple[np.ndarray, np.ndarray]:
    """The measured trajectory: a CSV file with a header and the columns ``t`` and ``x_free``.

    Args:
        path: the file.

    Returns:
        ``(t, x_free)``, at least two rows, finite, ``t`` from ``>= 0`` increasing.

    Raises:
        UsageError: the file cannot be read, or its columns are missing or wrong.
    """
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise UsageError(f"--data: cannot read {path}: {e.strerror}") from None
    if not rows or not {"t", "x_free"} <= set(rows[0]):
        raise UsageError(f"--data: {path} needs a header with the columns t,x_free")
    try:
        t = np.array([float(r["t"]) for r in rows])
        x = np.array([float(r["x_free"]) for r in rows])
    except (TypeError, ValueError):
        raise UsageError(f"--data: {path} has a value in t or x_free that is not a number") from None
    if len(t) < 2 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(x)):
        raise UsageError("--data: need at least 2 rows of finite t,x_free")
    if t[0] < 0 or np.any(np.diff(t) <= 0):
        raise UsageError("--data: t must start at >= 0 and increase")
    return t, x


def command(args) -> int:
    """Fit ``--fit`` of the gas slab to the trajectory in ``--data`` and print the fitted values.

    Args:
        args: the parsed command line.

    Returns:
        The exit status: 0, or 3 when the fit cannot go on (the model broke down at its start).

    Raises:
        UsageError: bad input.
    """
    scene = _assign.scene(args.scene, args.params)
    if scene.name != "gas-slab":
        raise UsageError(
            f"calibrate fits a free-surface trajectory: the scene must be gas-slab, got {args.scene}"
        )
    t, x = read_trajectory(args.data)
    names = _assign.comma_list(args.fit)
    start = _assign.numbers(args.start, "--start") if args.start else {}
    try:
        jm.sensitivity.check_names(scene, names)
        if args.dt is not None:
            check_positive("dt", args.dt)
        start_scene = type(scene)(**{**scene.parameter_values(), **start})
    except ValueError as e:
        raise UsageError(str(e)) from None
    dt = args.dt if args.dt is not None else 0.2 * float(scene.h) / float(start_scene.wave_speed)
    try:
        fit = jm.calibrate.calibrate(
            scene,
            jm.INTERPOLATORS[args.interpolator](),
            t,
            x,
            fit=names,
            starts=start,
            dt=dt,
            method=args.method,
            iterations=args.iterations,
            progress=False if args.no_progress else None,
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    except jm.calibrate.CalibrationError as e:
        print(f"jaxmpm: {e}", file=sys.stderr)
        return 3
    out = dict(
        fitted=fit.fitted,
        loss=fit.loss,
        iterations=fit.iterations,
        wall_s=fit.wall_s,
        scene=args.scene,
        interpolator=args.interpolator,
        method=args.method,
        dt=dt,
        start={n: float(start.get(n, float(getattr(scene, n)))) for n in names},
        loss_history=[float(v) for v in fit.history[:, 0]],
    )
    if args.json:
        print_json(out)
    else:
        print("fitted: " + "  ".join(f"{k}={v:.10g}" for k, v in fit.fitted.items()))
        print(f"loss={fit.loss:.6g}  iterations={fit.iterations}  wall_s={fit.wall_s:.3f}  dt={dt:.6g}")
    return 0
