"""JSON as standard JSON: a number that is not finite (the error of a run that broke down) is
written as ``null``, since JSON has no ``NaN`` or ``Infinity``."""

import json
import math

import numpy as np


def finite_or_null(obj):
    """``obj`` as plain Python (NumPy and JAX scalars and arrays as floats, ints and lists), with every
    float that is not finite replaced by ``None``.

    Args:
        obj: nested dicts, lists and tuples of numbers, strings, ``None`` and arrays.

    Returns:
        The same structure, made of Python values.
    """
    if isinstance(obj, bool) or obj is None or isinstance(obj, (str, int)):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_null(v) for v in obj]
    if isinstance(obj, np.generic) or hasattr(obj, "__array__"):
        return finite_or_null(np.asarray(obj).tolist())
    return obj


def dumps(obj, **kwargs) -> str:
    """``json.dumps`` of ``finite_or_null(obj)``, refusing any float that is still not finite.

    Args:
        obj: as for ``finite_or_null``.
        **kwargs: passed to ``json.dumps`` (``indent``, ``default``).

    Returns:
        The JSON text.
    """
    return json.dumps(finite_or_null(obj), allow_nan=False, **kwargs)
