"""The interpolators every study compares, under the names its tables and figures use."""

import jaxmpm as jm

METHODS = {
    "SPQ": jm.SPQ,
    "uGIMP": jm.GIMP,
    "cpGIMP": lambda: jm.GIMP(contiguous=True),
    "CPDI": jm.CPDI,
    "MPQ": jm.MPQ,
}
