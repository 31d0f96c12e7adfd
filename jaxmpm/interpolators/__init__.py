"""The interpolators, side by side: SPQ, GIMP (uGIMP and cpGIMP), CPDI and MPQ."""

from ._base import AbstractInterpolator as AbstractInterpolator
from ._base import Stencil as Stencil
from .cpdi import CPDI as CPDI
from .gimp import GIMP as GIMP
from .mpq import MPQ as MPQ
from .spq import SPQ as SPQ
