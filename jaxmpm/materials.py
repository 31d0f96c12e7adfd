"""Constitutive models: plain functions of the deformation gradient and array parameters.

Every parameter is an array field, so ``jax.grad`` reaches gamma, P0, p_atm and E. A model maps one
particle's ``F`` (shape ``(dim, dim)``) to its Cauchy stress; the 1D models read ``F[0, 0]``.
"""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._checks import check_greater, check_nonnegative, check_positive
from ._util import as_float


class AbstractMaterial(eqx.Module):
    """A hyperelastic material: stress, stored energy and wave speed as functions of ``F``."""

    @abc.abstractmethod
    def stress(self, F: Float[Array, "dim dim"]) -> Float[Array, "dim dim"]:
        """Cauchy stress of one particle."""

    @abc.abstractmethod
    def energy_density(self, F: Float[Array, "dim dim"]) -> Float[Array, ""]:
        """Stored energy per unit reference volume (``dW/dF`` is the first Piola stress)."""

    @abc.abstractmethod
    def sound_speed(self, F: Float[Array, "dim dim"], rho0: Float[Array, ""]) -> Float[Array, ""]:
        """Eulerian wave speed, used by the stable time step ``dt <= CFL h / max(c + |v|)``."""


class AdiabaticGas(AbstractMaterial):
    """Adiabatic gas of the talk: ``P = P0 J^-gamma - p_atm``, ``sigma = -P I`` (SPEC section 5).

    ``J = det F``. The sound speed is ``c = sqrt(gamma P0 J^(1 - gamma) / rho0)``; the stored
    energy ``W = P0 (J^(1-gamma) - 1) / (gamma - 1) + p_atm (J - 1)`` has ``dW/dJ = -P``.

    Attributes:
        P0: reference absolute pressure (at ``J = 1``).
        gamma: adiabatic exponent, > 1.
        p_atm: ambient pressure subtracted to give the gauge pressure.
    """

    P0: Float[Array, ""] = eqx.field(converter=as_float)
    gamma: Float[Array, ""] = eqx.field(converter=as_float)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("P0", self.P0)
        check_greater("gamma", self.gamma, 1.0)
        check_nonnegative("p_atm", self.p_atm)

    def pressure(self, J: Float[Array, "..."]) -> Float[Array, "..."]:
        return self.P0 * J ** (-self.gamma) - self.p_atm

    def stress(self, F):
        J = jnp.linalg.det(F) if F.shape[0] > 1 else F[0, 0]
        return -self.pressure(J) * jnp.eye(F.shape[0], dtype=F.dtype)

    def energy_density(self, F):
        J = jnp.linalg.det(F) if F.shape[0] > 1 else F[0, 0]
        return self.P0 * (J ** (1.0 - self.gamma) - 1.0) / (self.gamma - 1.0) + self.p_atm * (J - 1.0)

    def sound_speed(self, F, rho0):
        J = jnp.linalg.det(F) if F.shape[0] > 1 else F[0, 0]
        return jnp.sqrt(self.gamma * self.P0 * J ** (1.0 - self.gamma) / rho0)


class LinearElastic(AbstractMaterial):
    """Lagrangian linear elastic bar, 1D: ``sigma = E (F - 1)``, ``c = sqrt(E / rho0)`` (SPEC 5).

    Attributes:
        E: Young's modulus.
    """

    E: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("E", self.E)

    def stress(self, F):
        if F.shape[0] != 1:
            raise NotImplementedError("LinearElastic is the 1D bar model; F must be 1x1")
        return self.E * (F - 1.0)

    def energy_density(self, F):
        return 0.5 * self.E * jnp.square(F[0, 0] - 1.0)

    def sound_speed(self, F, rho0):
        del F
        return jnp.sqrt(self.E / rho0)
