"""Where a study runs: the machine it reports, and the precision it needs."""

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
