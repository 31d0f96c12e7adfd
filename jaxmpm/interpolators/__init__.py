"""The interpolators, side by side: SPQ, GIMP (uGIMP and cpGIMP), CPDI, MPQ and CPDI2."""

import functools
from collections.abc import Callable

from ._base import AbstractInterpolator as AbstractInterpolator
from ._base import Stencil as Stencil
from .cpdi import CPDI as CPDI
from .cpdi2 import CPDI2 as CPDI2
from .gimp import GIMP as GIMP
from .mpq import MPQ as MPQ
from .spq import SPQ as SPQ

INTERPOLATORS: dict[str, Callable[..., AbstractInterpolator]] = {
    "spq": SPQ,
    "gimp": GIMP,
    "cpgimp": functools.partial(GIMP, contiguous=True),
    "cpdi": CPDI,
    "mpq": MPQ,
    "cpdi2": CPDI2,
}
"""The one registry of interpolators: the name each is known by (``interpolator.name``, the command
line's ``--interpolator``, a saved run's metadata) and how to make it: called with no argument it
gives the defaults, with keyword arguments the options a saved run recorded (its static fields)."""
