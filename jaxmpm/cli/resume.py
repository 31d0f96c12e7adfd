"""``jaxmpm resume``: continue a run saved with ``jaxmpm run --out FILE``.

Exit statuses: 0; 2 for a file that is missing or is not a saved run this jaxmpm can continue (one
line naming the file and what is wrong); 3 for a run that broke down; 74 for a save that cannot be
written (a full disk: the previous save is intact); 130 for Ctrl-C (143 for SIGTERM), after saving
the last finished chunk to the file (one line saying at which step).
"""

import pathlib

import jaxmpm as jm

from ._common import (
    Breakdown,
    CannotWrite,
    UsageError,
    add_process_options,
    local_solution,
    start_processes,
)
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
    add_process_options(p, devices=False)  # a run continues on as many devices as it was saved from
    p.set_defaults(handler=command)


def command(args) -> int:
    """Run the saved run on to its target step count, saving to the same file, and report it as ``run``
    does.

    Args:
        args: the parsed command line.

    Returns:
        The exit status: 0.

    Raises:
        jaxmpm.long_run.Interrupted: Ctrl-C or SIGTERM, the run saved up to its last finished chunk
            (the command line answers with one line on stderr saying so, and status 130 or 143).
        UsageError: no such file, or not a saved run (one line naming the file and what is wrong).
        CannotWrite: the file cannot be written (the previous save is intact).
        Breakdown: the run broke down (now, or before it was saved).
    """
    first = start_processes(args)
    try:
        sol, compile_s, wall_s, meta = jm.long_run.resume_timed(
            args.file, progress=False if args.no_progress or not first else None
        )
    except (FileNotFoundError, ValueError) as e:
        raise UsageError(_one_line(e)) from None
    except OSError as e:  # e.g. the disk filled up while saving: the previous save is intact
        raise CannotWrite(args.file, e) from None
    except jm.SimulationError as e:
        meta = jm.long_run.load(args.file)[1]  # saved with the failure
        failed = local_solution(e.solution)
        if args.json:  # the last good state's report, with its status and failure, as run prints it
            report(_settings(meta, args.file), _scene(meta), failed, None, None, as_json=True)
        raise Breakdown(failed, dt=meta["dt"], saved_in=pathlib.Path(args.file)) from None
    sol = local_solution(sol)
    return report(_settings(meta, args.file), _scene(meta), sol, compile_s, wall_s, as_json=args.json)


def _scene(meta: dict):
    """The saved run's scene."""
    return jm.SCENES[meta["scene"]](**meta["params"])


def _settings(meta: dict, file) -> dict:
    """The saved run's settings as ``report`` prints them first."""
    run = dict(
        scene=meta["scene"],
        interpolator=meta["interpolator"]["name"],
        transfer=meta["transfer"],
        artificial_cells=meta["artificial_cells"],
        ordering=meta["ordering"],
        dt=meta["dt"],
        steps=meta["steps"],
    )
    if meta.get("viscosity") is not None:  # in run's order: after the settings, before out
        run["viscosity"] = meta["viscosity"]
    run["out"] = str(file)
    if meta.get("devices") is not None:
        run["devices"] = meta["devices"]
    return run


def _one_line(e: Exception) -> str:
    """The first line of ``e``'s message (messages are one line; this keeps the CLI's promise)."""
    lines = str(e).strip().splitlines()
    return lines[0] if lines else type(e).__name__
