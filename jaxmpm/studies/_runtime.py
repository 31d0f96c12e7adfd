"""Where a study runs (the machine it reports, the precision it needs), and how its tables say a run's
status."""

import os
import platform

import jax


def machine() -> str:
    """The machine, in one line.

    Returns:
        The processor, its core count and the operating system.
    """
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()}"


def require_float64(study: str) -> None:
    """Check that float64 is on: the studies' tables report float64 runs, and a study never switches
    it on itself (its caller does: the ``jaxmpm`` command, an experiment script, a notebook).

    Args:
        study: the study's name, for the error.

    Raises:
        RuntimeError: float64 is off.
    """
    if not jax.config.jax_enable_x64:
        raise RuntimeError(
            f"the {study} study runs in float64: call jax.config.update('jax_enable_x64', True) first "
            "(the jaxmpm command does)"
        )


def run_status(sol) -> tuple[str, dict | None]:
    """A run's status for a table: ``("ok", None)``, or the first failed quantity with its step and
    the failure (``Solution.failure()``).

    Args:
        sol: the run's solution.

    Returns:
        ``(status, failure)``.
    """
    fail = sol.failure()
    if fail is None:
        return "ok", None
    return f"{fail['quantities'][0]} at step {fail['step']}", fail


def status_cell(row: dict) -> str:
    """A table's status cell of a row with ``status`` and ``failure`` (``run_status``).

    Args:
        row: the row.

    Returns:
        ``"ok"``, or ``"broken down: "`` and the status.
    """
    return "ok" if row["failure"] is None else f"broken down: {row['status']}"


def number(x, fmt: str = ".2e") -> str:
    """A table's number cell: ``x`` formatted, or ``-`` for ``None`` (a run that broke down).

    Args:
        x: the number, or ``None``.
        fmt: its format.

    Returns:
        The cell.
    """
    return "-" if x is None else format(x, fmt)
