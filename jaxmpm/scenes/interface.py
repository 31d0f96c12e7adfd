"""A contact at rest: two gases at one pressure and different densities, which must not move."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._checks import check_nonnegative, check_positive, python_int
from .._util import as_float, static_fraction
from ..materials import IdealGas
from ..regions import Region
from ._base import AbstractScene
from .shock_tube import check_split, split_tube


class Interface(AbstractScene):
    """Two ideal gases at rest at one pressure ``p``, densities ``rho_l`` and ``rho_r``, walls at both ends.

    The exact solution is the initial state for all time: a contact discontinuity does not move.
    Every interpolator keeps it still to round-off, because equal stresses on particles of equal
    volume balance at every node whatever their masses.

    Attributes:
        rho_l, rho_r: the two densities, > 0.
        p: the common pressure, >= 0.
        gamma: ratio of specific heats of both gases, > 1.
        x0: where the gases meet, as a fraction of the length (static, in ``(0, 1)``).
        h, cells, ppc, pad: as for every scene.
    """

    name: ClassVar[str] = "interface"
    description: ClassVar[str] = "1D contact at rest: two ideal gases at equal pressure, nothing moves"
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "wall"
    right: ClassVar[str] = "wall"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    rho_l: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    rho_r: Float[Array, ""] = eqx.field(converter=as_float, default=0.125)
    p: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    x0: float = eqx.field(static=True, converter=static_fraction, default=0.5)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 100)
    cells: int = eqx.field(static=True, default=100, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=4, converter=python_int)

    def __check_init__(self):
        check_positive("rho_l", self.rho_l)
        check_positive("rho_r", self.rho_r)
        check_nonnegative("p", self.p)
        if not isinstance(self.x0, (int, float)) or not 0.0 < float(self.x0) < 1.0:
            raise ValueError(f"x0 must be a fraction of the length in (0, 1), got {self.x0!r}")
        check_split("x0", self.x0, self.cells, self.ppc)

    @property
    def rho0(self) -> Float[Array, ""]:
        """The left gas's density (each region carries its own)."""
        return self.rho_l

    def material(self):
        return IdealGas(gamma=self.gamma)

    def regions(self) -> tuple[Region, Region]:
        """The two gases, split at ``x0``.

        Returns:
            ``(left, right)``.
        """
        left, right = split_tube(self.cells, self.x0)
        gas = IdealGas(gamma=self.gamma)
        e = lambda rho: self.p / ((self.gamma - 1.0) * rho)  # noqa: E731
        return Region(left, gas, self.rho_l, 0.0, e(self.rho_l)), Region(
            right, gas, self.rho_r, 0.0, e(self.rho_r)
        )

    def initial_velocity(self, X):
        return jnp.zeros_like(X)
