"""Scenes: one per file, each with its exact or manufactured solution where one exists."""

from ._base import AbstractScene as AbstractScene
from ._displacement import AbstractDisplacementScene as AbstractDisplacementScene
from .axis_aligned import AxisAligned as AxisAligned
from .blast import Blast as Blast
from .bodies import Bodies as Bodies
from .detonation import Detonation as Detonation
from .gas_expansion import GasExpansion as GasExpansion
from .gas_slab import GasSlab as GasSlab
from .gurney import AbstractGurney as AbstractGurney
from .gurney import GurneyCylinder as GurneyCylinder
from .gurney import GurneySlab as GurneySlab
from .interface import Interface as Interface
from .manufactured import Manufactured as Manufactured
from .noh import Noh as Noh
from .radial_blast import AbstractRadialBlast as AbstractRadialBlast
from .radial_blast import BlastDisk as BlastDisk
from .radial_blast import BlastSphere as BlastSphere
from .riemann import Riemann as Riemann
from .shock_tube import ShockTube as ShockTube
from .vacuum_expansion import VacuumExpansion as VacuumExpansion
from .vibrating_bar import VibratingBar as VibratingBar

SCENES: dict[str, type[AbstractScene]] = {
    cls.name: cls
    for cls in (
        GasExpansion,
        VibratingBar,
        Manufactured,
        VacuumExpansion,
        Riemann,
        GasSlab,
        AxisAligned,
        Blast,
        BlastDisk,
        BlastSphere,
        ShockTube,
        Noh,
        Interface,
        Detonation,
        GurneySlab,
        GurneyCylinder,
    )
}
"""The one registry of scenes, by the name each is known by (``scene.name``, the command line, a saved
run's metadata)."""
