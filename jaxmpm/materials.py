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

    def sound_speed_from_stress(
        self, F: Float[Array, "dim dim"], sigma: Float[Array, "dim dim"], rho0: Float[Array, ""]
    ) -> Float[Array, ""]:
        """``sound_speed(F, rho0)`` given also ``sigma = stress(F)``, which a model may reuse to skip
        work (the gas: a power of ``J``). The step's stability check calls it every step."""
        del sigma
        return self.sound_speed(F, rho0)


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

    def sound_speed_from_stress(self, F, sigma, rho0):
        # P0 J^-gamma = p_atm - sigma_00, so c^2 = gamma (p_atm - sigma_00) J / rho0: no power.
        J = jnp.linalg.det(F) if F.shape[0] > 1 else F[0, 0]
        return jnp.sqrt(jnp.maximum(self.gamma * (self.p_atm - sigma[0, 0]) * J / rho0, 0.0))


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


class NeoHookean(AbstractMaterial):
    """Compressible neo-Hookean solid in 1D: ``sigma = lambda ln(F) / F + mu (F - 1 / F)``.

    The 1D (uniaxial strain) reading of ``sigma = (lambda ln J / J) I + (mu / J) (B - I)`` with
    ``B = F^2`` (Bonet & Wood, "Nonlinear continuum mechanics", sec. 5.4). With unit cross-section the
    first Piola stress equals ``sigma`` (SPEC 1), so ``W = lambda ln(F)^2 / 2 + mu ((F^2 - 1) / 2 -
    ln F)`` and the Lagrangian wave speed is ``sqrt(dsigma/dF / rho0)``; the Eulerian one used by the
    stable time step is ``F`` times that. At ``F = 1`` it is ``sqrt((lambda + 2 mu) / rho0)``.

    Attributes:
        lam: first Lame parameter (>= 0).
        mu: shear modulus (> 0).
    """

    lam: Float[Array, ""] = eqx.field(converter=as_float)
    mu: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_nonnegative("lam", self.lam)
        check_positive("mu", self.mu)

    def _F(self, F):
        if F.shape[0] != 1:
            raise NotImplementedError("NeoHookean is the 1D model; F must be 1x1")
        return F[0, 0]

    def stress(self, F):
        f = self._F(F)
        return jnp.reshape(self.lam * jnp.log(f) / f + self.mu * (f - 1.0 / f), (1, 1))

    def energy_density(self, F):
        f = self._F(F)
        ln = jnp.log(f)
        return 0.5 * self.lam * ln * ln + self.mu * (0.5 * (f * f - 1.0) - ln)

    def sound_speed(self, F, rho0):
        f = self._F(F)
        # dsigma/dF = lambda (1 - ln F) / F^2 + mu (1 + 1 / F^2); it turns negative (the material
        # softens) only for ln F > 1 + mu / lambda, where the speed is taken as zero.
        stiffness = self.lam * (1.0 - jnp.log(f)) / (f * f) + self.mu * (1.0 + 1.0 / (f * f))
        return f * jnp.sqrt(jnp.maximum(stiffness, 0.0) / rho0)
