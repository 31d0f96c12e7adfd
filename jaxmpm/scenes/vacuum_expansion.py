"""Adiabatic gas expanding into vacuum: a centred rarefaction with an exact solution."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from .._checks import check_positive, python_int
from .._util import as_float
from ..exact import vacuum_expansion
from ..materials import AdiabaticGas
from ._base import AbstractScene, check_point


class VacuumExpansion(AbstractScene):
    """Gas at rest on ``[0, L]``, wall at 0, vacuum beyond ``L`` (``p_atm = 0``): stiff and extreme.

    A rarefaction runs from ``L`` into the gas at ``c0 = sqrt(gamma P0 / rho0)``; the front escapes at
    ``2 c0 / (gamma - 1)`` and its ``F`` grows without bound. ``exact`` gives, for a particle, the
    exact *domain average* ``F = (x(X + r0) - x(X - r0)) / (2 r0)`` (finite at the front), with the
    point values of ``x``, ``v`` and ``sigma`` at its centre. Valid for ``t <= t_valid = L / c0``
    (the head then reaches the wall). ``smooth(X, t)`` marks the particles away from both fronts.

    The free end carries no traction (vacuum). The default ``pad`` leaves room for the front to
    run to ``t_valid`` with ``gamma >= 1.4`` at the default ``cells``: it travels ``2 L / (gamma -
    1)`` by then, ``5 L`` at 1.4, so more cells need a ``pad`` of over five times ``cells``.

    Attributes:
        P0: initial pressure; gamma: adiabatic exponent; rho0: initial density.
        h, cells, ppc, pad: as for every scene.
    """

    name: ClassVar[str] = "vacuum-expansion"
    description: ClassVar[str] = "1D gas expanding into vacuum (centred rarefaction, exact), wall at 0"
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "wall"
    right: ClassVar[str] = "free"
    regions: ClassVar[None] = None
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    initial_position: ClassVar[None] = None

    P0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 32)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=32, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=170, converter=python_int)

    def __check_init__(self):
        check_positive("P0", self.P0)

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=0.0)

    @property
    def c0(self) -> Float[Array, ""]:
        """The sound speed of the gas at rest, ``sqrt(gamma P0 / rho0)``."""
        return jnp.sqrt(self.gamma * self.P0 / self.rho0)

    @property
    def t_valid(self) -> Float[Array, ""]:
        """When the rarefaction's head reaches the wall, ``L / c0`` (the exact solution holds until then)."""
        return self.length / self.c0

    def initial_velocity(self, X):
        return jnp.zeros_like(X)

    def _point(self, X, t):
        return vacuum_expansion(X, t, self.length, self.P0, self.gamma, self.rho0)

    def exact(self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact fields of one particle (``jaxmpm.exact.vacuum_expansion``).

        Args:
            X: reference position of the particle's centre.
            t: time.

        Returns:
            ``dict(x, v, F, sigma)``: ``F`` the exact average over the particle's domain, the others
            point values at its centre.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)``.
        """
        X = check_point(X, 1)
        r0 = 0.5 * self.h / self.ppc
        x, v, F_point = self._point(X[0], t)
        x_lo, _, _ = self._point(X[0] - r0, t)
        x_hi, _, _ = self._point(X[0] + r0, t)
        F = jnp.reshape((x_hi - x_lo) / (2.0 * r0), (1, 1))
        sigma = self.material().stress(jnp.reshape(F_point, (1, 1)))
        return dict(x=jnp.reshape(x, (1,)), v=jnp.reshape(v, (1,)), F=F, sigma=sigma)

    def smooth(
        self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""], margin: float = 0.1
    ) -> Bool[Array, ""]:
        """Whether a particle is farther than ``margin L`` (reference length) from the head and the front.

        Args:
            X: reference position.
            t: time.
            margin: the distance, as a fraction of ``L``.

        Returns:
            ``True`` away from both.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)``.
        """
        X = check_point(X, 1)
        head = self.length - self.c0 * t
        return (jnp.abs(X[0] - head) > margin * self.length) & (X[0] < (1.0 - margin) * self.length)
