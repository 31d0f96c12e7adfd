"""Validation of user input before anything is traced.

Every check names the parameter and what is allowed. Values that are tracers (a scene built inside
``jax.grad`` or ``jax.vmap``) cannot be inspected and are passed through: they were checked where
they were concrete, or they are the user's own transformation.
"""

import inspect
import math
import reprlib
from collections.abc import Callable, Iterable, Mapping

import jax
import jax.numpy as jnp
import numpy as np


def is_concrete(value) -> bool:
    """Whether ``value`` can be inspected (is not a tracer).

    Args:
        value: anything.

    Returns:
        ``False`` for a JAX tracer, else ``True``.
    """
    return not isinstance(value, jax.core.Tracer)


def any_traced(tree) -> bool:
    """Whether any array of ``tree`` (a scene, a model, ...) is a JAX tracer: the call is inside
    ``jax.jit``, ``jax.grad`` or ``jax.vmap`` with respect to it.

    Args:
        tree: a pytree.

    Returns:
        ``True`` where a leaf is a tracer.
    """
    return not all(is_concrete(a) for a in jax.tree.leaves(tree))


def is_real(value) -> bool:
    """Whether ``value`` is a real number or an array of them (bool, integer or float dtype).

    Args:
        value: anything concrete (a number, an array, a string, ``None``, ...).

    Returns:
        ``True`` for a real number or a real array; ``False`` for a string, ``None``, a complex number
        or anything else numpy reads as non-numeric.
    """
    if isinstance(value, (str, bytes)):
        return False
    dtype = getattr(value, "dtype", None)
    if dtype is None:
        try:
            dtype = np.asarray(value).dtype
        except (TypeError, ValueError, OverflowError):  # ragged lists, objects numpy refuses
            return False
    try:
        dtype = np.dtype(dtype)
    except TypeError:
        return False
    return any(jnp.issubdtype(dtype, kind) for kind in (jnp.bool_, jnp.integer, jnp.floating))


def is_bool(value: object) -> bool:
    """Whether ``value`` is a bool, a bool array, or a list or tuple holding one (a number given as
    ``True`` is a mistake, not the number 1).

    Args:
        value: anything concrete.

    Returns:
        ``True`` for ``True``, ``np.bool_``, an array of bool dtype, or a list or tuple holding one.
    """
    if isinstance(value, (list, tuple)):
        return any(is_bool(v) for v in value)
    return isinstance(value, (bool, np.bool_)) or getattr(value, "dtype", None) == np.bool_


def check_real(name: str, value) -> None:
    """Check that a concrete value is a real number (or an array of them); a tracer passes, and so do
    numbers given together (a tuple or list) of which one is a tracer (``(u, 0.0)`` under ``jax.grad``).

    Args:
        name: the parameter's name, for the message.
        value: its value, as given (before any conversion).

    Raises:
        ValueError: ``value`` is a string, ``None``, a complex number, a bool (``is_bool``) or another
            non-number: ``"{name} must be a real number, got {value!r}"`` (a long value shortened).
    """
    if isinstance(value, (tuple, list)) and any_traced(value):
        for item in value:
            check_real(name, item)
        return
    if is_concrete(value) and (not is_real(value) or is_bool(value)):
        raise ValueError(f"{name} must be a real number, got {brief(value)}")


def check_scalar(name: str, value, batch: str = "") -> None:
    """Check that a concrete value is one number (a 0-d array at most); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.
        batch: appended to the message (how to run several values instead).

    Raises:
        ValueError: ``value`` has a shape.
    """
    if is_concrete(value) and np.ndim(value) != 0:
        raise ValueError(f"{name} must be one number, got an array of shape {np.shape(value)}{batch}")


def check_finite(name: str, value) -> None:
    """Check a concrete value (every entry of an array); a tracer passes.

    Args:
        name: the parameter's name, for the message.
        value: its value.

    Raises:
        ValueError: ``value`` is not a real number (``check_real``) or not finite.
    """
    check_real(name, value)
    if is_concrete(value):
        arr = np.asarray(value)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite, got {show(arr)}")


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
            raise ValueError(f"{name} must be > 0, got {show(arr)}")


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
            raise ValueError(f"{name} must be >= 0, got {show(arr)}")


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
            raise ValueError(f"{name} must be > {bound}, got {show(arr)}{_rounded_onto(arr, bound)}")


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
            raise ValueError(f"{name} must be < {bound}, got {show(arr)}{_rounded_onto(arr, bound)}")


def _rounded_onto(arr: np.ndarray, bound: float) -> str:
    """For a refusal of ``arr`` by a strict ``bound``: where the value is below float64 and sits on
    the bound, the note that it may be a value rounded there (``1 + 1e-8`` is ``1.0`` in float32)."""
    if arr.dtype.kind == "f" and arr.dtype.itemsize < 8 and np.any(arr == bound):
        return (
            f" ({arr.dtype.name}, JAX's float type while jax_enable_x64 is off: a value within its "
            f"rounding of {bound} reads as {bound}; switch float64 on for such a value)"
        )
    return ""


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


def check_bool(name: str, value) -> None:
    """Check a switch: ``True`` or ``False`` (a NumPy bool too), nothing else.

    Args:
        name: the parameter's name, for the message.
        value: its value.

    Raises:
        ValueError: ``value`` is not a bool (a string such as ``"yes"``, a number, ``None``).
    """
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {brief(value)}")


def check_keywords(
    caller: str, given: Iterable[str], takes: Callable, refused: Mapping[str, str] | None = None
) -> None:
    """Refuse keywords that are passed on to another function's checks, naming the function the
    user called (Python would name the inner one, or none).

    Args:
        caller: the public function, as the user wrote it (``"simulate_timed"``).
        given: the keywords given.
        takes: the function whose keyword-only parameters are the keywords allowed.
        refused: keywords refused with a reason (say, those of ``simulate`` that a long run does not
            take), to name in the message.

    Raises:
        ValueError: a keyword of ``refused``, with its reason.
        TypeError: any other keyword that ``takes`` does not take, as Python names one, with the
            keywords allowed.
    """
    allowed = [
        name
        for name, par in inspect.signature(takes).parameters.items()
        if par.kind is inspect.Parameter.KEYWORD_ONLY and not (refused and name in refused)
    ]
    for name in given:
        if refused is not None and name in refused:
            raise ValueError(f"{caller}() does not take {name}: {refused[name]}")
        if name not in allowed:
            raise TypeError(
                f"{caller}() got an unexpected keyword argument {name!r}; it takes {', '.join(allowed)}"
            )


def python_int(value):
    """A NumPy integer as the Python ``int`` it is, for a static field (hashed, and saved with a
    run); anything else unchanged, for the field's check to name.

    Args:
        value: the value given.

    Returns:
        ``int(value)`` for a NumPy integer, else ``value``.
    """
    return int(value) if isinstance(value, np.integer) else value


def python_bool(value):
    """A NumPy bool as the Python ``bool`` it is, for a static field; anything else unchanged, for
    the field's check to name.

    Args:
        value: the value given.

    Returns:
        ``bool(value)`` for a NumPy bool, else ``value``.
    """
    return bool(value) if isinstance(value, np.bool_) else value


_REPR = reprlib.Repr()
_REPR.maxstring = 40
_REPR.maxother = 40


def brief(value) -> str:
    """``repr(value)``, at most about 40 characters (a message stays one readable line)."""
    return _REPR.repr(value)


def show(arr: np.ndarray) -> str:
    """A value for a message: a number as its ``repr`` (``inf``, ``nan`` as such), an array briefly.

    Args:
        arr: the value, as a NumPy array.

    Returns:
        The text.
    """
    if arr.ndim == 0:
        v = float(arr)
        return repr(v) if math.isfinite(v) else str(v)
    return np.array2string(arr, threshold=6)
