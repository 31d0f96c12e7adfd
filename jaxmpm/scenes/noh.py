"""Noh's problem: cold gas streaming onto a wall, stopped by a shock of exact, constant state."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_positive, python_int
from .._util import as_float
from ..exact_euler import noh
from ..geometry import Box
from ..materials import IdealGas
from ..regions import Region
from ._base import AbstractScene


class Noh(AbstractScene):
    """Planar Noh problem: gas at ``rho0``, ``e = p = 0``, moving at ``-u0`` onto a wall at 0.

    A shock leaves the wall at ``D = (gamma - 1) u0 / 2`` and leaves the gas at rest behind it at
    ``rho = rho0 (gamma + 1) / (gamma - 1)``, ``p = rho0 u0^2 (gamma + 1) / 2``, ``e = u0^2 / 2`` (Noh,
    "Errors for calculations of strong shocks using an artificial viscosity and an artificial heat
    flux", J. Comput. Phys. 72, 1987); for ``gamma = 5/3``: ``D = 1/3``, ``rho = 4``, ``p = 4/3``.
    Artificial viscosity heats the first particles at the wall too much and leaves their density
    low (Noh's wall heating), a known error of every viscous scheme. The gas's far end is free and
    carries no pressure (``p = 0`` there), so nothing comes back from it until the shock reaches it,
    at ``t_valid = L / (u0 + D)`` (0.75 for the defaults); then the shocked gas expands from it.

    Attributes:
        rho0: initial density, > 0.
        u0: speed of the incoming gas, > 0.
        gamma: ratio of specific heats, > 1.
        h, cells, ppc, pad: as for every scene (``L = cells h``; the default ``h`` makes ``L = 1``).
    """

    name: ClassVar[str] = "noh"
    description: ClassVar[str] = "1D Noh problem: cold ideal gas onto a wall, exact shock (rho = 4, p = 4/3)"
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "wall"
    right: ClassVar[str] = "free"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    u0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=5.0 / 3.0)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 200)
    cells: int = eqx.field(static=True, default=200, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=4, converter=python_int)

    def __check_init__(self):
        check_positive("u0", self.u0)

    def material(self):
        return IdealGas(gamma=self.gamma)

    def regions(self) -> tuple[Region]:
        """One region: the cold gas filling the tube.

        Returns:
            ``(gas,)``.
        """
        return (Region(Box(0.0, float(self.cells)), IdealGas(gamma=self.gamma), self.rho0, -self.u0, 0.0),)

    def initial_velocity(self, X):
        return -self.u0 * jnp.ones_like(X)

    @property
    def shock_speed(self) -> Float[Array, ""]:
        """The speed ``(gamma - 1) u0 / 2`` at which the shock leaves the wall."""
        return 0.5 * (self.gamma - 1.0) * self.u0

    @property
    def t_valid(self) -> Float[Array, ""]:
        """When the shock reaches the gas's free end, ``L / (u0 + D)`` (the exact solution holds until
        then)."""
        return self.cells * self.h / (self.u0 + self.shock_speed)

    def solution(self, x: Float[ArrayLike, "*shape"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact solution at Eulerian positions ``x`` (``exact_euler.noh``).

        Args:
            x: positions.
            t: time.

        Returns:
            ``dict(rho, u, p, e)``.
        """
        return noh(x, t, self.gamma, self.rho0, self.u0)
