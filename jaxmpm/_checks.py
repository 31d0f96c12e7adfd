"""Validation of user input before anything is traced.

Every check names the parameter and what is allowed. Values that are tracers (a scene built inside
``jax.grad`` or ``jax.vmap``) cannot be inspected and are passed through: they were checked where
they were concrete, or they are the user's own transformation.
"""

import math

import jax
import numpy as np


def is_concrete(value) -> bool:
    """Whether ``value`` can be inspected (is not a tracer).

    Args:
        value: anything.

    Returns:
        ``False`` for a JAX tracer, else ``True``.
    """
    return not isinstance(value, jax.core.Tracer)


def check_finite(name: str, value) -> None:
    """Check a concrete value (every entry of an array); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.

    Raises:
        ValueError: ``value`` is not finite.
    """
    if is_concrete(value):
        arr = np.asarray(value)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite, got {_show(arr)}")


def check_positive(name: str, value) -> None:
    """Check a concrete value (every entry of an array); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.

    Raises:
        ValueError: ``value`` is not finite or not > 0.
    """
    check_finite(name, value)
    if is_concrete(value):
        arr = np.asarray(value)
        if not np.all(arr > 0):
            raise ValueError(f"{name} must be > 0, got {_show(arr)}")


def check_nonnegative(name: str, value) -> None:
    """Check a concrete value (every entry of an array); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.

    Raises:
        ValueError: ``value`` is not finite or not >= 0.
    """
    check_finite(name, value)
    if is_concrete(value):
        arr = np.asarray(value)
        if not np.all(arr >= 0):
            raise ValueError(f"{name} must be >= 0, got {_show(arr)}")


def check_greater(name: str, value, bound: float) -> None:
    """Check a concrete value (every entry of an array); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.
        bound: the bound.

    Raises:
        ValueError: ``value`` is not finite or not > ``bound``.
    """
    check_finite(name, value)
    if is_concrete(value):
        arr = np.asarray(value)
        if not np.all(arr > bound):
            raise ValueError(f"{name} must be > {bound}, got {_show(arr)}")


def check_less(name: str, value, bound: float) -> None:
    """Check a concrete value (every entry of an array); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.
        bound: the bound.

    Raises:
        ValueError: ``value`` is not finite or not < ``bound``.
    """
    check_finite(name, value)
    if is_concrete(value):
        arr = np.asarray(value)
        if not np.all(arr < bound):
            raise ValueError(f"{name} must be < {bound}, got {_show(arr)}")


def check_int(name: str, value, minimum: int) -> None:
    """Check a structural integer.

    Args:
        name: the parameter's name, for the message.
        value: its value.
        minimum: the smallest value allowed.

    Raises:
        ValueError: ``value`` is not an integer (a bool is not one) or is below ``minimum``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value}")


def _show(arr: np.ndarray) -> str:
    if arr.ndim == 0:
        v = float(arr)
        return repr(v) if math.isfinite(v) else str(v)
    return np.array2string(arr, threshold=6)
