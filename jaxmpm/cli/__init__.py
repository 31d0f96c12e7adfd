"""The ``jaxmpm`` command: ``scenes``, ``run``, ``calibrate``, ``ensemble``, ``resume``, ``bench`` and
``study``, one module each.

A contract that outside scripts rely on: command names, options, ``name=value`` scene parameters, the
JSON keys of ``--json``, exit statuses and the text printed are kept stable (extended, never renamed).

Exit statuses: 0; 2 for bad input; 3 for a run that broke down; 74 (``EX_IOERR`` of ``sysexits.h``)
for output that cannot be written (a full disk under ``--out``, ``--vtk`` or standard output: one
line ``jaxmpm: error: cannot write WHAT: REASON``; a file saved before is intact, and a ``--vtk``
series that fails leaves its folder as it was); 130 for Ctrl-C (one line, from the moment ``console``
runs); 141 when stdout is closed by its reader; 1 for ``bench`` when one of its benchmark processes
fails (one line naming it). Each failure is one line on stderr, never a traceback.
"""

import contextlib
import errno
import os
import signal
import sys
import threading

import jax

from jaxmpm_console import interrupted as _quiet_interrupt

from ..long_run import InterruptLatch
from . import bench, calibrate, ensemble, resume, run, scenes, study
from ._common import Breakdown, CannotWrite, Parser, UsageError

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

    Switches on float64 before anything is built, and gives the caller's setting back on return (a
    notebook that calls it keeps its own). Figures are drawn on ``matplotlib.figure.Figure`` objects,
    which need no display backend.

    Args:
        argv: the arguments after ``jaxmpm`` (default: ``sys.argv[1:]``).

    Returns:
        The exit status: 0; 2 for bad input (one line on stderr naming it); 3 for a run that broke
        down (one line on stderr naming the step, the particle and the quantity); 74 for output that
        cannot be written (one line, ``jaxmpm: error: cannot write WHAT: REASON``: a full disk under
        ``--out``, ``--vtk`` or standard output); 130 for Ctrl-C (one line: the step reached and,
        with ``--out``, the file that holds it); 143 for SIGTERM (the same, as for Ctrl-C: the last
        finished chunk saved, one line); 141 when stdout is closed by its reader
        (``jaxmpm ... | head``), silently; 1 for ``bench`` when one of its benchmark processes fails.
    """
    x64 = bool(jax.config.jax_enable_x64)
    jax.config.update("jax_enable_x64", True)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) if main_thread else None
    if main_thread:
        latch = InterruptLatch.install()  # a Ctrl-C that Python ignores (in a gc callback) is not lost
        signal.signal(signal.SIGTERM, _Terminate(latch))  # kill, a scheduler: stopped as by Ctrl-C
    stdout = sys.stdout
    sys.stdout = _Output(_Closed() if stdout is None else stdout)
    try:
        return _dispatch(argv)
    finally:
        if isinstance(sys.stdout, _Output):  # not replaced meanwhile (start_processes may)
            sys.stdout = stdout
        if main_thread:  # a caller in this process (a test, a notebook) keeps its own handlers
            signal.signal(signal.SIGINT, previous[0])
            signal.signal(signal.SIGTERM, previous[1])
        jax.config.update("jax_enable_x64", x64)  # and its own float type


class _Terminate(InterruptLatch):
    """The command line's SIGTERM handler: the interrupt of Ctrl-C (the SIGINT ``InterruptLatch``'s),
    noted as a SIGTERM, so that a run stops as it does for Ctrl-C (its last finished chunk saved
    whole) and the process exits with 143."""

    received = False

    def __init__(self, latch: InterruptLatch):
        super().__init__()
        self._latch = latch

    def note(self, signum) -> None:
        _Terminate.received = True
        self.pending = True
        self._latch.note(signum)


def _dispatch(argv):
    try:
        try:
            code = _command(argv)
        finally:
            sys.stdout.flush()  # a full disk under stdout fails here, not at exit
        return code
    except BrokenPipeError:
        # The reader went away: send what is still buffered nowhere, so that exiting does not fail again.
        _discard_stdout()
        return 141
    except CannotWrite as e:
        print(f"jaxmpm: error: {_one_line(e)}", file=sys.stderr)
        _discard_stdout()
        return 74
    except OSError as e:  # input or output the command did not name (it names --out, --vtk and stdout)
        where = f"{e.filename}: " if e.filename else ""
        print(f"jaxmpm: error: {where}{e.strerror or e}", file=sys.stderr)
        _discard_stdout()
        return 74


def _command(argv) -> int:
    """Parse and run the command, a failure being its exit status and one line on stderr."""
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
        if _Terminate.received:
            _Terminate.received = False
            print(f"jaxmpm: terminated (SIGTERM): {_one_line(e) or 'interrupted'}", file=sys.stderr)
            return 143
        print(f"jaxmpm: {_one_line(e) or 'interrupted'}", file=sys.stderr)
        return 130


class _Output:
    """Standard output, each failed write (other than a closed pipe, ``BrokenPipeError``) raised as
    ``CannotWrite("standard output", ...)``: a full disk under ``jaxmpm ... > FILE`` is named as such."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as e:
            raise CannotWrite("standard output", e) from None

    def flush(self):
        try:
            return self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as e:
            raise CannotWrite("standard output", e) from None

    def __getattr__(self, name):
        return getattr(self._stream, name)


class _Closed:
    """Standard output where the process has none (``jaxmpm ... >&-``: Python's ``sys.stdout`` is
    ``None``): what the command writes there cannot be written, exit status 74."""

    def write(self, text):
        raise OSError(errno.EBADF, "it is closed")

    def flush(self):
        pass

    def isatty(self):
        return False

    def fileno(self):
        raise OSError(errno.EBADF, "it is closed")


def _discard_stdout() -> None:
    """Point standard output at the null device, so that what is still buffered goes nowhere and
    exiting does not fail on it again (a stream without a descriptor, as in a test, is left)."""
    stream = sys.stdout._stream if isinstance(sys.stdout, _Output) else sys.stdout
    try:
        fd = stream.fileno()
    except (OSError, ValueError):
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


def console() -> None:
    """The ``jaxmpm`` console script: ``main``, then exit with its status.

    Ctrl-C is answered with one line and status 130 from the moment this function runs (the console
    script's launcher, ``jaxmpm_console``, answers it so during the imports before): until ``main``
    installs its handler, the process leaves at once. After Ctrl-C the
    process exits at once (``os._exit``), without waiting for a compiled chunk that was abandoned
    mid-run to finish computing; everything the run saved is already on disk.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _quiet_interrupt)
    code = main()
    if code in (130, 143):
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
        os._exit(code)
    sys.exit(code)


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split())
