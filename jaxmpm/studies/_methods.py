"""The interpolators every study compares, under the names its tables and figures use."""

import jaxmpm as jm

_LABELS = {"spq": "SPQ", "gimp": "uGIMP", "cpgimp": "cpGIMP", "cpdi": "CPDI", "mpq": "MPQ", "cpdi2": "CPDI2"}

METHODS = {_LABELS.get(name, name.upper()): make for name, make in jm.INTERPOLATORS.items()}
"""Every interpolator of ``jaxmpm.INTERPOLATORS``, in its order, by its label in the studies' tables
(``uGIMP`` is ``gimp``, ``cpGIMP`` is ``cpgimp``), to the callable that makes it."""
