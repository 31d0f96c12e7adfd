"""What the subcommands share: the argument parser, the failures with their exit statuses (bad
input: 2, a run that broke down: 3, output that cannot be written: 74), and JSON output."""

import argparse
import os
import pathlib
import re
import sys
import tempfile

import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps

_NUMBER = r"(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"  # a number without its sign


class UsageError(Exception):
    """Bad input from the command line: one line, exit status 2."""


OPTIONS = {
    "dt": "--dt",
    "steps": "--steps",
    "t_end": "--t-end",
    "cfl": "--cfl",
    "max_steps": "--max-steps",
    "cfl_limit": "--cfl-limit",
    "artificial_cells": "--artificial-cells",
    "devices": "--devices",
    "chunk": "--chunk",
    "checkpoint_every": "--checkpoint-every",
}
"""The library's argument names that the command line's options set, and those options."""


def as_option(error: Exception) -> UsageError:
    """A library's ``ValueError`` about an argument that an option sets, as the command line's error
    naming the option the user typed (``t_end must be > 0`` as ``--t-end must be > 0``).

    Args:
        error: the library's error.

    Returns:
        The ``UsageError`` to raise.
    """
    text = str(error)
    name, sep, rest = text.partition(" ")
    if sep and name in OPTIONS and rest.startswith(("must ", "is ")):
        text = f"{OPTIONS[name]} {rest}"
    return UsageError(in_options(text))


_SPELLED = re.compile(r"(?<![\w.-])(" + "|".join(n for n in OPTIONS if "_" in n) + r")\b")


def in_options(text: str) -> str:
    """``text`` with the library's argument names that only an option sets spelled as the options
    (``raise max_steps`` as ``raise --max-steps``); the names without an underscore (``dt``,
    ``steps``) are words of the text too, and stay.

    Args:
        text: a message of the library.

    Returns:
        The message in the command line's terms.
    """
    return _SPELLED.sub(lambda m: OPTIONS[m.group(1)], text)


class CannotWrite(Exception):
    """Output that cannot be written (a full disk, a folder taken away, a read-only file system): one
    line ``cannot write WHAT: REASON``, exit status 74 (``EX_IOERR`` of ``sysexits.h``).

    Args:
        what: what was being written, as the user named it (``"--out run.npz"``, ``"--vtk frames"``,
            ``"standard output"``).
        error: the ``OSError``.
    """

    def __init__(self, what: str, error: OSError):
        super().__init__(f"cannot write {what}: {error.strerror or error}")


class _StoreOnce(argparse._StoreAction):
    """argparse's ``store``, refusing an option given twice (``--steps 5 --steps 7``) rather than
    keeping the last, and recording in ``namespace.given`` the options that were given."""

    def __call__(self, parser, namespace, values, option_string=None):
        if option_string is not None:
            given = namespace.__dict__.setdefault("given", set())
            if self.dest in given:
                parser.error(f"{'/'.join(self.option_strings)} is given twice")
            given.add(self.dest)
        super().__call__(parser, namespace, values, option_string)


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one ``UsageError`` line (no usage dump, no traceback).

    argparse takes ``-1e-5`` for an option (its matcher has no exponent); this one reads it as a
    number, and ``-1,0.2`` as a list of numbers, so that the check that follows can say "dt must be
    > 0", not "expected one argument".
    An option that takes a value may be given once (argparse keeps the last of several).
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # a negative number, or a comma-separated list that starts with one (--viscosity -1,0.2)
        self._negative_number_matcher = re.compile(rf"^-{_NUMBER}(,[-+]?{_NUMBER})*$")
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)

    def parse_command(self, argv: list[str] | None):
        """Parse a command line whose ``name=value`` scene parameters may also follow its options
        (``jaxmpm run gas --dt 1e-5 --steps 2 beta=2``), which argparse alone leaves unrecognized.

        Args:
            argv: the arguments after ``jaxmpm`` (default: ``sys.argv[1:]``).

        Returns:
            The namespace; ``given`` holds the names of the options given a value.

        Raises:
            UsageError: bad input.
        """
        args, extra = self.parse_known_args(argv)
        if hasattr(args, "params"):
            # every item after the options that is not an option is a scene parameter (read, and
            # refused if need be, as those before them are); "--" ends the options
            late = [a for a in extra if a != "--" and not a.startswith("-")]
            if late or "--" in extra:
                args.params = list(args.params) + late
                extra = [a for a in extra if a.startswith("-") and a != "--"]
        if extra:
            self.error(f"unrecognized arguments: {' '.join(extra)}")
        if not hasattr(args, "given"):
            args.given = set()
        return args

    def error(self, message):
        """Raise ``UsageError(message)`` instead of printing the usage and exiting; argparse's list of
        missing arguments is said in words (``jaxmpm run needs a scene name (see `jaxmpm scenes`) and
        --interpolator, one of ...``).

        Args:
            message: argparse's description of what is wrong.

        Raises:
            UsageError: always.
        """
        missing = message.removeprefix("the following arguments are required: ")
        if missing != message:
            needed = [self._needed(name.strip()) for name in missing.split(",")]
            needed = [n for n in needed if n is not None]
            if needed:
                message = f"{self.prog} needs " + (
                    needed[0] if len(needed) == 1 else ", ".join(needed[:-1]) + " and " + needed[-1]
                )
        raise UsageError(message)

    def _needed(self, name: str) -> str | None:
        """A missing argument in words, ``None`` for a list that may be empty (``name=value ...``)."""
        for action in self._actions:
            if name in action.option_strings:
                if action.choices:
                    return f"{name} (one of {', '.join(map(str, action.choices))})"
                return f"{name} {action.metavar or action.dest.upper()}"
            if not action.option_strings and name in (action.metavar, action.dest):
                if action.nargs in ("*", argparse.REMAINDER):
                    return None
                if action.choices:  # the subcommands
                    return f"a {name} (one of {', '.join(action.choices)})"
                if not action.help:
                    return name
                return action.help if action.help.startswith(("a ", "an ", "the ")) else "a " + action.help
        return name


class Breakdown(Exception):
    """A run broke down: exit status 3 and one line naming the step, the particle and the quantities.

    The line is built from ``solution.failure()`` and the last good state, then says what to do next:
    where the run was saved, or which ``--steps`` or ``--t-end`` reproduces the last good state.

    Args:
        solution: the ``Solution`` of the failed run (``error.solution`` of a ``SimulationError``).
        dt: the fixed time step, or ``None`` for a run to an end time (variable steps).
        saved_in: the file the run was saved to, or ``None``.
    """

    def __init__(self, solution: jm.Solution, *, dt: float | None, saved_in=None):
        super().__init__(_line(solution, dt, saved_in))


def _line(solution: jm.Solution, dt: float | None, saved_in) -> str:
    failure = solution.failure()
    st = solution.state
    step, p = failure["step"], failure["particle"]
    when = f"t = {step * dt:.6g}" if dt is not None else f"after t = {float(st.t):.6g}"
    who = "the run" if p < 0 else f"particle {p} ({_particle(solution, p)} at step {max(step - 1, 0)})"
    if step == 0:  # the initial state failed its checks
        return f"jaxmpm: the initial state is not valid: {who}: {' and '.join(failure['quantities'])}."
    last = int(st.step)
    if saved_in is not None:
        hint = f"Everything up to it is saved in {saved_in}."
    elif dt is not None:
        hint = f"Rerun with --steps {last} to see the last good state."
    elif failure["status"] & jm.status.MAX_STEPS:
        hint = ""
    elif float(st.t) == 0:  # --t-end must be > 0
        hint = "It is the initial state."
    else:
        hint = f"Rerun with --t-end {float(st.t):.9g} to see the last good state."
    line = (
        f"jaxmpm: the run broke down at step {step} ({when}): {who}: {' and '.join(failure['quantities'])}. "
        f"The last good state is step {last}. {hint}"
    )
    return line.rstrip()


def _particle(solution: jm.Solution, p: int) -> str:
    """Particle ``p`` in the last good state: ``X``, ``x`` and ``F`` in 1D; vectors and ``det F`` above."""
    X = np.asarray(solution.body.X[p])
    x = np.asarray(solution.state.x[p])
    F = np.asarray(solution.state.F[p])
    extra = "" if solution.body.region is None else f", region {int(solution.body.region[p])}"
    extra += "" if solution.state.e is None else f", e = {float(solution.state.e[p]):.6g}"
    if X.shape[0] == 1:
        return f"X = {X[0]:.6g}, x = {x[0]:.6g}, F = {F[0, 0]:.6g}{extra}"
    return f"X = {_vector(X)}, x = {_vector(x)}, J = det F = {_det(F):.6g}{extra}"


def _vector(a) -> str:
    return "(" + ", ".join(f"{float(c):.6g}" for c in a) + ")"


def _det(F) -> float:
    """``det F`` of one 2x2 or 3x3 matrix by its closed form (the solver's own, term for term)."""
    if F.shape[0] == 2:
        return float(F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0])
    a, b, c = F[0, 0], F[0, 1], F[0, 2]
    return float(
        a * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
        - b * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
        + c * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
    )


def flags(args: argparse.Namespace) -> dict[str, bool]:
    """The names of a command's options (``steps`` for ``--steps``), without its positional arguments
    and the parser's own entries: what a ``name=value`` item that is not a scene parameter may have
    meant.

    Args:
        args: the parsed command line.

    Returns:
        Each option's name, with ``_`` where the option has ``-``, and whether it takes a value
        (``False`` for a switch such as ``--json``, whose parsed value is a bool).
    """
    skip = {"command", "handler", "scene", "params"}
    return {k: not isinstance(v, bool) for k, v in vars(args).items() if k not in skip}


def writable_folder(folder, option: str) -> pathlib.Path:
    """A folder to write into, made if missing, checked before any work is done.

    Args:
        folder: the folder given.
        option: the option that gave it (``"--out"``, ``"--vtk"``), for the message.

    Returns:
        The folder, which exists and takes a new file.

    Raises:
        UsageError: ``folder`` is empty, a file, cannot be made, or cannot be written.
    """
    if not str(folder).strip():
        raise UsageError(f"{option} needs a folder, got an empty name")
    path = pathlib.Path(folder)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} {folder} is a file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".jaxmpm-write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise UsageError(f"{option} {folder}: cannot write there ({e.strerror or e})") from None
    return path


def print_json(obj) -> None:
    """Print ``obj`` on stdout as one JSON object; floats in shortest round-trip form (full float64),
    and a float that is not finite as ``null`` (standard JSON has no ``Infinity`` or ``NaN``).

    Args:
        obj: a JSON-serialisable object.
    """
    print(dumps(obj))


def floats(a) -> list:
    """An array as nested lists of Python floats.

    Args:
        a: an array (or array-like) of any shape.

    Returns:
        ``a`` as float64 nested lists (a float for a scalar).
    """
    return np.asarray(a, dtype=float).tolist()


def scalar(x) -> float | None:
    """A scalar as a Python float, keeping ``None``.

    Args:
        x: a scalar, or ``None`` (an error the scene does not define).

    Returns:
        ``float(x)``, or ``None``.
    """
    return None if x is None else float(x)


def add_viscosity_option(p, note: str = "") -> None:
    """Add ``--viscosity [QUAD,LIN[,SHEAR]]`` (read by ``_assign.viscosity``) to the parser ``p``.

    Args:
        p: a subcommand's parser.
        note: appended to the help, e.g. ``" (with --from-fit: the fit's)"``.
    """
    p.add_argument(
        "--viscosity",
        nargs="?",
        const="2.0,0.2",
        metavar="QUAD,LIN[,SHEAR]",
        help="artificial viscosity in compression (default coefficients 2.0,0.2), and a shear viscosity "
        f"with a third coefficient{note}",
    )


def add_process_options(p, devices: bool = True, spread: str = "the particles") -> None:
    """Options to spread a run over several devices and to start as one of several processes.

    Args:
        p: a subcommand's parser.
        devices: also ``--devices`` (a command that picks its devices itself has none).
        spread: what ``--devices`` spreads, for its help.
    """
    g = p.add_argument_group("several devices and processes")
    if devices:
        g.add_argument(
            "--devices",
            metavar="K",
            help=f"spread {spread} over K devices, or 'all' (jax.devices(); the default with "
            "several processes)",
        )
    g.add_argument(
        "--distributed",
        action="store_true",
        help="start as one of several processes (jax.distributed.initialize); SLURM's or Open MPI's "
        "environment gives the coordinator, the process count and this process's id",
    )
    g.add_argument(
        "--coordinator", metavar="HOST:PORT", help="instead of a cluster's environment (with the next two)"
    )
    g.add_argument("--processes", type=int, metavar="N", help="with --coordinator: the number of processes")
    g.add_argument("--process-id", type=int, metavar="I", help="with --coordinator: this process, 0 to N-1")


def start_processes(args) -> bool:
    """Join the other processes of ``--distributed`` or ``--coordinator`` (before anything touches
    a device), and silence the output of every process but the first (the processes compute
    together and hold the same gathered results; the first reports them, its exit status is theirs).

    Args:
        args: the parsed command line (``add_process_options``).

    Returns:
        Whether this process is the one that reports (the first, or the only one).

    Raises:
        UsageError: incomplete or inconsistent options, or no cluster to join.
    """
    import jax

    explicit = (args.coordinator, args.processes, args.process_id)
    if any(v is not None for v in explicit):
        if any(v is None for v in explicit):
            raise UsageError("--coordinator, --processes and --process-id go together")
        if args.processes < 1 or not 0 <= args.process_id < args.processes:
            raise UsageError(
                f"--processes must be >= 1 and --process-id from 0 to {args.processes - 1}, got "
                f"--processes {args.processes} --process-id {args.process_id}"
            )
        _check_coordinator(args.coordinator)
        kwargs = dict(
            coordinator_address=args.coordinator, num_processes=args.processes, process_id=args.process_id
        )
    elif args.distributed:
        kwargs = {}
    else:
        return True
    jax.config.update("jax_cpu_collectives_implementation", "gloo")  # CPU devices talk through Gloo
    try:
        jax.distributed.initialize(**kwargs)
    except (RuntimeError, ValueError) as e:
        raise UsageError(f"--distributed: could not join the other processes: {e}") from None
    first = jax.process_index() == 0
    sys.stdout.flush()
    sys.stderr.flush()
    if first:
        # The collectives' own lines (Gloo's "connected to N peer ranks") are written to the C-level
        # standard output: send them to stderr, and keep stdout for the report (--json).
        report = os.dup(1)
        os.dup2(2, 1)
        sys.stdout = os.fdopen(report, "w")
    else:  # one report, the first process's: they all hold the same, gathered results
        quiet = os.open(os.devnull, os.O_WRONLY)
        os.dup2(quiet, 1)
        os.dup2(quiet, 2)
        sys.stdout = sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - for the rest of this process
    return first


def _check_coordinator(address: str) -> None:
    """``--coordinator HOST:PORT``: a host name or address (an IPv6 one in brackets, ``[::1]:1234``)
    and a port from 1 to 65535.

    Raises:
        UsageError: not of that form.
    """
    host, sep, port = address.rpartition(":")
    ok = bool(sep) and bool(host.strip()) and port.isdigit() and 1 <= int(port) <= 65535
    if ok and ":" in host:  # an IPv6 address is written in brackets
        ok = host.startswith("[") and host.endswith("]") and len(host) > 2
    if not ok:
        raise UsageError(
            f"--coordinator must be HOST:PORT (a host name or address and a port from 1 to 65535, "
            f"e.g. node0:1234), got {address!r}"
        )


def devices_option(args) -> int | None:
    """The ``--devices`` value: a count, ``None`` (one device), or every device with ``all`` (the
    default when several processes run).

    Args:
        args: the parsed command line.

    Returns:
        The count of devices, or ``None``.

    Raises:
        UsageError: neither an integer from 1 to the devices there nor ``all``.
    """
    import jax

    value = args.devices
    if value is None:
        return len(jax.devices()) if jax.process_count() > 1 else None
    if value == "all":
        return len(jax.devices())
    try:
        k = int(value)
    except ValueError:
        k = 0
    if k < 1:
        raise UsageError(f"--devices must be an integer >= 1 or 'all', got {value!r}")
    if k > len(jax.devices()):
        raise UsageError(
            f"--devices must be from 1 to {len(jax.devices())} (the devices here, jax.devices()) or "
            f"'all', got {k}"
        )
    return k


def local_solution(sol: jm.Solution) -> jm.Solution:
    """``sol`` with every array whole on this process (gathered from all processes when a run was
    spread over several; every process must call it).

    Args:
        sol: a solution.

    Returns:
        The same solution, its arrays local.
    """
    import jax
    import jax.numpy as jnp

    from jaxmpm._util import host

    if jax.process_count() == 1:
        return sol
    return jax.tree.map(lambda a: jnp.asarray(host(a)), sol)


def measured_where(scene, sol):
    """Where a run's errors against the exact solution are measured (``run``, ``ensemble``): ``None``
    (every particle), or for a scene of regions with fronts (the detonation) the particles away from
    them, which before the front has moved far enough in are none."""
    if scene.regions is not None and float(sol.state.t) > 0:
        return jm.metrics.smooth_mask(scene, sol.body, sol.state.t)
    return None
