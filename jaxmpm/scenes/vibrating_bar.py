"""Vibrating elastic bar, fixed at 0 and free at L."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_finite, check_positive, python_int
from .._util import as_float
from ..materials import LinearElastic
from ._base import AbstractScene, check_point


class VibratingBar(AbstractScene):
    """Linear elastic bar in its first mode; exact at any amplitude in the Lagrangian description.

    ``v(X, 0) = v0 sin(k X)``, ``k = pi / (2 L)``; exact ``u = (v0 / omega) sin(omega t) sin(k X)``,
    ``omega = k sqrt(E / rho0)``. Fixed (wall) at ``X = 0``, traction free at ``X = L``.

    Attributes:
        E: Young's modulus (Pa).
        v0: velocity amplitude (m/s).
        h, rho0, cells, ppc, pad: as for every scene.
    """

    name: ClassVar[str] = "vibrating-bar"
    description: ClassVar[str] = "1D linear elastic bar, first mode, wall at 0, free at L (exact solution)"
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "wall"
    right: ClassVar[str] = "free"
    regions: ClassVar[None] = None
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    E: Float[Array, ""] = eqx.field(converter=as_float, default=100.0)
    v0: Float[Array, ""] = eqx.field(converter=as_float, default=0.1)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=0.0625)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=16, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=2, converter=python_int)

    def __check_init__(self):
        check_positive("E", self.E)
        check_finite("v0", self.v0)

    @property
    def k(self) -> Float[Array, ""]:
        """The wavenumber of the first mode, ``pi / (2 L)``."""
        return jnp.pi / (2.0 * self.length)

    @property
    def omega(self) -> Float[Array, ""]:
        """The angular frequency of the first mode, ``k sqrt(E / rho0)``."""
        return self.k * jnp.sqrt(self.E / self.rho0)

    def material(self):
        return LinearElastic(E=self.E)

    def initial_velocity(self, X):
        return self.v0 * jnp.sin(self.k * X)

    def exact(self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact fields of one material point.

        Args:
            X: reference position.
            t: time.

        Returns:
            ``dict(x, v, F, sigma)`` with ``u = (v0 / omega) sin(omega t) sin(k X)``.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)``.
        """
        X = check_point(X, 1)
        k, w = self.k, self.omega
        amp = self.v0 / w * jnp.sin(w * t)
        u = amp * jnp.sin(k * X)
        F = jnp.reshape(1.0 + amp * k * jnp.cos(k * X[0]), (1, 1))
        return dict(
            x=X + u, v=self.v0 * jnp.cos(w * t) * jnp.sin(k * X), F=F, sigma=self.material().stress(F)
        )
