"""jaxmpm: a differentiable Material Point Method solver in JAX.

The library never enables float64 on import; call ``jax.config.update("jax_enable_x64", True)``
first (the CLI, experiments, notebooks and tests do).
"""

from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version

from . import exact as exact
from . import exact_detonation as exact_detonation
from . import exact_euler as exact_euler
from . import explosives as explosives
from . import geometry as geometry
from . import long_run as long_run
from . import metrics as metrics
from . import regions as regions
from . import sensitivity as sensitivity
from . import status as status
from . import vtk as vtk
from ._simulate import (
    SaveAt as SaveAt,
)
from ._simulate import (
    SimulationError as SimulationError,
)
from ._simulate import (
    Solution as Solution,
)
from ._simulate import (
    simulate as simulate,
)
from ._simulate import (
    simulate_timed as simulate_timed,
)
from ._step import Model as Model
from ._step import initial_state as initial_state
from ._step import setup as setup
from ._step import step as step
from .ensemble import Ensemble as Ensemble
from .ensemble import ensemble as ensemble
from .grid import Grid as Grid
from .interpolators import (
    CPDI as CPDI,
)
from .interpolators import (
    CPDI2 as CPDI2,
)
from .interpolators import (
    GIMP as GIMP,
)
from .interpolators import INTERPOLATORS as INTERPOLATORS
from .interpolators import (
    MPQ as MPQ,
)
from .interpolators import (
    SPQ as SPQ,
)
from .interpolators import (
    AbstractInterpolator as AbstractInterpolator,
)
from .materials import (
    MIE_GRUNEISEN as MIE_GRUNEISEN,
)
from .materials import (
    STRENGTH as STRENGTH,
)
from .materials import (
    AbstractEOS as AbstractEOS,
)
from .materials import (
    AbstractMaterial as AbstractMaterial,
)
from .materials import (
    AbstractStatelessEOS as AbstractStatelessEOS,
)
from .materials import (
    AdiabaticGas as AdiabaticGas,
)
from .materials import (
    ElasticPlastic as ElasticPlastic,
)
from .materials import (
    IdealGas as IdealGas,
)
from .materials import (
    LinearElastic as LinearElastic,
)
from .materials import (
    MieGruneisen as MieGruneisen,
)
from .materials import (
    NeoHookean as NeoHookean,
)
from .metrics import corner_gap as corner_gap
from .metrics import density as density
from .metrics import diagnostics as diagnostics
from .metrics import domain_corners as domain_corners
from .metrics import errors as errors
from .metrics import euler_errors as euler_errors
from .metrics import pressure as pressure
from .metrics import separation as separation
from .particles import Body as Body
from .particles import State as State
from .regions import Region as Region
from .scenes import SCENES as SCENES
from .scenes import AbstractScene as AbstractScene
from .scenes import AxisAligned as AxisAligned
from .scenes import Blast as Blast
from .scenes import BlastDisk as BlastDisk
from .scenes import BlastSphere as BlastSphere
from .scenes import Bodies as Bodies
from .scenes import Detonation as Detonation
from .scenes import GasExpansion as GasExpansion
from .scenes import GasSlab as GasSlab
from .scenes import GurneyCylinder as GurneyCylinder
from .scenes import GurneySlab as GurneySlab
from .scenes import Interface as Interface
from .scenes import Manufactured as Manufactured
from .scenes import Noh as Noh
from .scenes import Riemann as Riemann
from .scenes import ShockTube as ShockTube
from .scenes import VacuumExpansion as VacuumExpansion
from .scenes import VibratingBar as VibratingBar
from .sensitivity import continuous_parameters as continuous_parameters
from .sensitivity import gradient as gradient
from .transfers import APIC as APIC
from .transfers import FLIP as FLIP
from .transfers import PIC as PIC
from .transfers import TRANSFERS as TRANSFERS
from .transfers import AbstractTransfer as AbstractTransfer
from .viscosity import ArtificialViscosity as ArtificialViscosity

_LAZY = ("calibrate", "plotting", "reference")
"""Submodules imported on first use: they bring optax, diffrax and matplotlib, which a run does not
need."""


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


try:
    __version__ = _version("jaxmpm")
except _PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
