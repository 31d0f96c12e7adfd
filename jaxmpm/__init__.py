"""jaxmpm: a differentiable Material Point Method solver in JAX.

The library never enables float64 on import; call ``jax.config.update("jax_enable_x64", True)``
first (the CLI, experiments, notebooks and tests do).
"""

from importlib.metadata import PackageNotFoundError, version

from . import status as status
from .grid import Grid as Grid
from .interpolators import (
    CPDI as CPDI,
    GIMP as GIMP,
    MPQ as MPQ,
    SPQ as SPQ,
    AbstractInterpolator as AbstractInterpolator,
)
from .materials import (
    AbstractMaterial as AbstractMaterial,
    AdiabaticGas as AdiabaticGas,
    LinearElastic as LinearElastic,
)
from .metrics import diagnostics as diagnostics, errors as errors, separation as separation
from .particles import Body as Body, State as State
from .scenes import SCENES as SCENES, AbstractScene as AbstractScene, GasExpansion as GasExpansion
from .scenes import VibratingBar as VibratingBar
from ._simulate import (
    SaveAt as SaveAt,
    SimulationError as SimulationError,
    Solution as Solution,
    simulate as simulate,
    simulate_timed as simulate_timed,
)
from ._step import Model as Model, initial_state as initial_state, setup as setup, step as step
from .transfers import APIC as APIC, FLIP as FLIP, PIC as PIC, AbstractTransfer as AbstractTransfer

INTERPOLATORS = {
    "spq": SPQ,
    "gimp": GIMP,
    "cpgimp": lambda: GIMP(contiguous=True),
    "cpdi": CPDI,
    "mpq": MPQ,
}
TRANSFERS = {"flip": FLIP, "pic": PIC, "apic": APIC}

try:
    __version__ = version("jaxmpm")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
