"""Scenes: one per file, each with its exact or manufactured solution where one exists."""

from ._base import AbstractScene as AbstractScene
from .gas_expansion import GasExpansion as GasExpansion
from .vibrating_bar import VibratingBar as VibratingBar

SCENES: dict[str, type[AbstractScene]] = {cls.name: cls for cls in (GasExpansion, VibratingBar)}
