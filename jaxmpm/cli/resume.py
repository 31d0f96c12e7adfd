"""``jaxmpm resume``: continue a run saved with ``jaxmpm run --out FILE``."""

import pathlib

import jaxmpm as jm

from ._common import Breakdown, UsageError
from .run import report


def add_parser(subparsers) -> None:
    """Add the ``resume`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser("resume", help="continue a run saved with `run --out FILE`")
    p.add_argument("file", help="the saved run (.npz)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=command)


def command(args) -> int:
    """Run the saved run on to its target step count, saving to the same file, and report it as ``run``
    does.

    Args:
        args: the parsed command line.

    Returns:
        The exit status, 0.

    Raises:
        UsageError: no such file, or not a saved run.
        Breakdown: the run broke down (now, or before it was saved).
    """
    try:
        sol, compile_s, wall_s, meta = jm.long_run.resume_timed(
            args.file, progress=False if args.no_progress else None
        )
    except (FileNotFoundError, ValueError) as e:
        raise UsageError(str(e)) from None
    except jm.SimulationError as e:
        dt = jm.long_run.load(args.file)[1]["dt"]  # saved with the failure: the run's fixed step
        raise Breakdown(e.solution, dt=dt, saved_in=pathlib.Path(args.file)) from None
    scene = jm.SCENES[meta["scene"]](**meta["params"])
    run = dict(
        scene=meta["scene"],
        interpolator=meta["interpolator"]["name"],
        transfer=meta["transfer"],
        artificial_cells=meta["artificial_cells"],
        ordering=meta["ordering"],
        dt=meta["dt"],
        steps=meta["steps"],
        out=str(args.file),
    )
    return report(run, scene, sol, compile_s, wall_s, as_json=args.json)
