"""A scene built in Python from regions: bodies of any shape and several materials."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._checks import is_concrete, python_int
from .._util import as_float
from ..regions import Region
from ._base import AbstractScene

BOUNDARIES = ("free", "wall", "symmetry")


class Bodies(AbstractScene):
    """Regions in the box ``[0, cells h]^dim``: each a shape (in cells) with a material and a state.

    ``Bodies(parts=(Region(Box(0, 40), gas, rho0=1.0), Region(Box(40, 80), copper, rho0=8930.0)),
    cells=80, h=1e-3)``: the lattice points of the box inside each region's shape are its particles
    (``jaxmpm.regions``). The box's faces are ``left`` and ``right`` for every axis, as in every
    scene. A region's boundary that is not a face of the box is a free surface of zero traction.
    Not in ``SCENES``: its regions are Python objects, not command-line parameters.

    Attributes:
        parts: the regions, a tuple or list, in order (a particle belongs to the one region whose
            shape holds it).
        dim: 1, 2 or 3 (static).
        left, right: the low and high faces of every axis: ``"free"``, ``"wall"`` or ``"symmetry"``
            (static).
        h, cells, ppc, pad: as for every scene.
    """

    name: ClassVar[str] = "bodies"
    description: ClassVar[str] = "regions of any shape and material, built in Python (jaxmpm.regions)"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    parts: tuple[Region, ...] = eqx.field(converter=lambda v: tuple(v) if isinstance(v, list) else v)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=10, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=4, converter=python_int)
    dim: int = eqx.field(static=True, default=1, converter=python_int)
    left: str = eqx.field(static=True, default="free")
    right: str = eqx.field(static=True, default="free")

    def __check_init__(self):
        for side in ("left", "right"):
            if getattr(self, side) not in BOUNDARIES:
                raise ValueError(f"{side} must be one of {BOUNDARIES}, got {getattr(self, side)!r}")
        if (
            not isinstance(self.parts, tuple)
            or not self.parts
            or not all(isinstance(r, Region) for r in self.parts)
        ):
            got = (
                f"{type(self.parts).__name__} of {[type(r).__name__ for r in self.parts]}"
                if isinstance(self.parts, tuple)
                else f"a {type(self.parts).__name__} (a single region goes in a tuple: parts=(region,))"
            )
            raise ValueError(f"parts must be a non-empty tuple (or list) of jaxmpm.regions.Region, got {got}")

    @property
    def rho0(self) -> Float[Array, ""]:
        """The first region's density (each region carries its own)."""
        return self.parts[0].rho0

    def material(self):
        return self.parts[0].material

    def regions(self) -> tuple[Region, ...]:
        """The regions, ``parts``.

        Returns:
            ``parts``.
        """
        return self.parts

    def initial_velocity(self, X):
        """The velocity of the region holding ``X`` (a concrete position; the run itself takes each
        particle's region from the layout).

        Args:
            X: a reference position.

        Returns:
            Its region's velocity (zero outside every region).
        """
        if not is_concrete(X):
            raise ValueError("Bodies.initial_velocity takes a concrete position (the run uses the layout)")
        cells = np.asarray(X, dtype=float)[None, :] / float(self.h)
        for r in self.parts:
            if r.shape.inside(cells)[0]:
                return r.velocity
        return jnp.zeros_like(jnp.asarray(X, dtype=self.h.dtype))
