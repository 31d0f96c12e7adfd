"""The ``jaxmpm`` command: ``scenes``, ``run``, ``calibrate``, ``ensemble``, ``resume``, ``bench`` and
``study``, one module each.

A contract that outside scripts rely on: command names, options, ``name=value`` scene parameters, the
JSON keys of ``--json``, exit statuses (2: bad input; 3: a run broke down) and the text printed are
kept stable (extended, never renamed).
"""

import os
import signal
import sys
import threading

import jax

from ..long_run import InterruptLatch
from . import bench, calibrate, ensemble, resume, run, scenes, study
from ._common import Breakdown, Parser, UsageError

_COMMANDS = (scenes, run, calibrate, ensemble, resume, bench, study)  # in the order --help lists them


def parser() -> Parser:
    """The ``jaxmpm`` argument parser, one subparser per command.

    Returns:
        The parser; its errors raise ``UsageError``.
    """
    p = Parser(
        prog="jaxmpm", description="Differentiable MPM in JAX: SPQ, GIMP, CPDI, MPQ and more, side by side."
    )
    subparsers = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in _COMMANDS:
        command.add_parser(subparsers)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxmpm`` console script.

    Switches on float64 before anything is built. Figures are drawn on ``matplotlib.figure.Figure``
    objects, which need no display backend.

    Args:
        argv: the arguments after ``jaxmpm`` (default: ``sys.argv[1:]``).

    Returns:
        The exit status: 0; 2 for bad input (one line on stderr naming it); 3 for a run that broke
        down (one line on stderr naming the step, the particle and the quantity); 130 for Ctrl-C
        (one line: the step reached and, with ``--out``, the file that holds it); 141 when stdout
        is closed by its reader (``jaxmpm ... | head``), silently.
    """
    jax.config.update("jax_enable_x64", True)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGINT) if main_thread else None
    if main_thread:
        InterruptLatch.install()  # a Ctrl-C that Python ignores (in a gc callback) is not lost
    try:
        return _dispatch(argv)
    finally:
        if main_thread:  # a caller in this process (a test, a notebook) keeps its own handler
            signal.signal(signal.SIGINT, previous)


def _dispatch(argv):
    try:
        args = parser().parse_command(argv)
        return args.handler(args)
    except UsageError as e:
        print(f"jaxmpm: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except Breakdown as e:
        print(e, file=sys.stderr)
        return 3
    except KeyboardInterrupt as e:
        print(f"jaxmpm: {_one_line(e) or 'interrupted'}", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away: send what is still buffered nowhere, so that exiting does not fail again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141


def console() -> None:
    """The ``jaxmpm`` console script: ``main``, then exit with its status.

    After Ctrl-C the process exits at once (``os._exit``), without waiting for a compiled chunk that
    was abandoned mid-run to finish computing; everything the run saved is already on disk.
    """
    code = main()
    if code == 130:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split())
