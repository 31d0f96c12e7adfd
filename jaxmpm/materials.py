"""Constitutive models: plain functions of the deformation gradient and array parameters.

Every parameter is an array field, so ``jax.grad`` reaches gamma, P0, p_atm and E. A model maps one
particle's ``F`` (shape ``(dim, dim)``) to its Cauchy stress; the 1D models read ``F[0, 0]``.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._checks import check_greater, check_less, check_nonnegative, check_positive
from ._util import as_float, contract, det


class AbstractMaterial(eqx.Module):
    """A hyperelastic material: stress, stored energy and wave speed as functions of ``F``."""

    @abc.abstractmethod
    def stress(self, F: Float[Array, "dim dim"]) -> Float[Array, "dim dim"]:
        """Cauchy stress of one particle.

        Args:
            F: deformation gradient.

        Returns:
            The Cauchy stress ``sigma(F)``.
        """

    @abc.abstractmethod
    def energy_density(self, F: Float[Array, "dim dim"]) -> Float[Array, ""]:
        """Stored energy per unit reference volume (``dW/dF`` is the first Piola stress).

        Args:
            F: deformation gradient of one particle.

        Returns:
            ``W(F)``.
        """

    @abc.abstractmethod
    def sound_speed(self, F: Float[Array, "dim dim"], rho0: Float[Array, ""]) -> Float[Array, ""]:
        """Eulerian wave speed, used by the stable time step ``dt <= CFL h / max(c + |v|)``.

        Args:
            F: deformation gradient of one particle.
            rho0: initial density.

        Returns:
            The largest longitudinal wave speed of the state ``F``.
        """

    def acoustic_speed(self, F: Float[Array, "dim dim"], rho0: Float[Array, ""]) -> Float[Array, ""]:
        """The largest longitudinal wave speed of the state ``F``, from the stored energy alone.

        ``rho c^2`` is the largest eigenvalue of the acoustic tensor ``Q_ik(n) = (1 / rho0) m_J m_L
        d2W / dF_iJ dF_kL`` with ``m = F^T n``, over ``n`` along the principal directions of ``B =
        F F^T`` (Marsden & Hughes, "Mathematical foundations of elasticity", ch. 6). In 1D it is
        ``F sqrt(W''(F) / rho0)``, the closed forms of the 1D models; in 2D and 3D it serves models
        without one (a Hessian of ``W`` and two small eigenproblems per particle).

        Args:
            F: deformation gradient of one particle.
            rho0: initial density.

        Returns:
            The Eulerian wave speed ``c``.
        """
        H = jax.hessian(self.energy_density)(F)  # (dim, dim, dim, dim): d2W / dF_iJ dF_kL
        _, N = jnp.linalg.eigh(F @ F.T)

        def c2(n):
            m = F.T @ n
            Q = jnp.einsum("iJkL,J,L->ik", H, m, m) / rho0
            return jnp.max(jnp.linalg.eigvalsh(Q))

        return jnp.sqrt(jnp.maximum(jnp.max(jax.vmap(c2, in_axes=1)(N)), 0.0))

    @abc.abstractmethod
    def sound_speed_from_stress(
        self, F: Float[Array, "dim dim"], sigma: Float[Array, "dim dim"], rho0: Float[Array, ""]
    ) -> Float[Array, ""]:
        """``sound_speed(F, rho0)`` given also ``sigma = stress(F)``, which a model may reuse to skip
        work (the gas: a power of ``J``). The step's stability check calls it every step.

        Args:
            F: deformation gradient of one particle.
            sigma: its Cauchy stress, ``stress(F)``.
            rho0: initial density.

        Returns:
            The Eulerian wave speed, equal to ``sound_speed(F, rho0)``.
        """


class AdiabaticGas(AbstractMaterial):
    """Adiabatic gas: ``P = P0 J^-gamma - p_atm``, ``sigma = -P I`` (Bonifasi-Lista, Brannon & Wiskin 2013).

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

    def pressure(self, J: Float[Array, "*batch"]) -> Float[Array, "*batch"]:
        """The gauge pressure ``P = P0 J^-gamma - p_atm``.

        Args:
            J: volume ratios ``det F``.

        Returns:
            ``P`` at each ``J``.
        """
        return self.P0 * J ** (-self.gamma) - self.p_atm

    def stress(self, F):
        J = det(F)
        return -self.pressure(J) * jnp.eye(F.shape[0], dtype=F.dtype)

    def energy_density(self, F):
        J = det(F)
        return self.P0 * (J ** (1.0 - self.gamma) - 1.0) / (self.gamma - 1.0) + self.p_atm * (J - 1.0)

    def sound_speed(self, F, rho0):
        J = det(F)
        return jnp.sqrt(self.gamma * self.P0 * J ** (1.0 - self.gamma) / rho0)

    def sound_speed_from_stress(self, F, sigma, rho0):
        # P0 J^-gamma = p_atm - sigma_00, so c^2 = gamma (p_atm - sigma_00) J / rho0: no power.
        J = det(F)
        return jnp.sqrt(jnp.maximum(self.gamma * (self.p_atm - sigma[0, 0]) * J / rho0, 0.0))


class LinearElastic(AbstractMaterial):
    """Linear elastic solid, small strain: ``sigma = lambda tr(eps) I + 2 mu eps``, ``eps = sym(F) - I``.

    ``lambda = E nu / ((1 + nu)(1 - 2 nu))`` and ``mu = E / (2 (1 + nu))``. With the default
    ``nu = 0`` the 1D bar follows exactly: ``sigma = E (F - 1)``, ``c = sqrt(E / rho0)``.
    The wave speed is the P-wave speed ``sqrt((lambda + 2 mu) / rho0)``, independent of ``F`` (the
    model is meant for small strains, where Cauchy, first Piola and the linear stress agree).

    Attributes:
        E: Young's modulus.
        nu: Poisson's ratio, in ``[0, 0.5)`` (default 0).
    """

    E: Float[Array, ""] = eqx.field(converter=as_float)
    nu: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)

    def __check_init__(self):
        check_positive("E", self.E)
        check_nonnegative("nu", self.nu)
        check_less("nu", self.nu, 0.5)

    def lame(self) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """The Lame parameters from ``E`` and ``nu``.

        Returns:
            ``(lambda, mu)``, ``lambda = E nu / ((1 + nu)(1 - 2 nu))`` and ``mu = E / (2 (1 + nu))``.
        """
        lam = self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))
        return lam, self.E / (2.0 * (1.0 + self.nu))

    def _strain(self, F):
        return 0.5 * (F + F.T) - jnp.eye(F.shape[0], dtype=F.dtype)

    def stress(self, F):
        lam, mu = self.lame()
        eps = self._strain(F)
        return lam * jnp.trace(eps) * jnp.eye(F.shape[0], dtype=F.dtype) + 2.0 * mu * eps

    def energy_density(self, F):
        lam, mu = self.lame()
        eps = self._strain(F)
        return 0.5 * lam * jnp.square(jnp.trace(eps)) + mu * jnp.sum(eps * eps)

    def sound_speed(self, F, rho0):
        del F
        lam, mu = self.lame()
        return jnp.sqrt((lam + 2.0 * mu) / rho0)

    def sound_speed_from_stress(self, F, sigma, rho0):
        del sigma
        return self.sound_speed(F, rho0)


class NeoHookean(AbstractMaterial):
    """Compressible neo-Hookean solid: ``sigma = (lambda ln J / J) I + (mu / J) (B - I)``.

    ``B = F F^T``, ``J = det F`` (Bonet & Wood, "Nonlinear continuum mechanics", sec. 5.4), from
    ``W = mu / 2 (tr(F^T F) - dim) - mu ln J + lambda / 2 (ln J)^2``. In 1D (uniaxial strain, unit
    cross-section, where the first Piola stress equals ``sigma``) it reads ``sigma = lambda ln(F) / F
    + mu (F - 1 / F)``, the Lagrangian wave speed is ``sqrt(dsigma/dF / rho0)`` and the Eulerian one,
    used by the stable time step, ``F`` times that; at ``F = 1`` it is ``sqrt((lambda + 2 mu) /
    rho0)``. In 2D and 3D the wave speed is the largest longitudinal one of the current state
    (``AbstractMaterial.acoustic_speed``).

    Attributes:
        lam: first Lame parameter (>= 0).
        mu: shear modulus (> 0).
    """

    lam: Float[Array, ""] = eqx.field(converter=as_float)
    mu: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_nonnegative("lam", self.lam)
        check_positive("mu", self.mu)

    def stress(self, F):
        J = det(F)
        eye = jnp.eye(F.shape[0], dtype=F.dtype)
        B = contract("ab,cb->ac", F, F)  # F F^T, unrolled (a matmul is slow per particle on CPU)
        return (self.lam * jnp.log(J) * eye + self.mu * (B - eye)) / J

    def energy_density(self, F):
        ln = jnp.log(det(F))
        return 0.5 * self.mu * (jnp.sum(F * F) - F.shape[0]) - self.mu * ln + 0.5 * self.lam * ln * ln

    def sound_speed(self, F, rho0):
        if F.shape[0] > 1:
            return self.acoustic_speed(F, rho0)
        f = F[0, 0]
        # dsigma/dF = lambda (1 - ln F) / F^2 + mu (1 + 1 / F^2); it turns negative (the material
        # softens) only for ln F > 1 + mu / lambda, where the speed is taken as zero.
        stiffness = self.lam * (1.0 - jnp.log(f)) / (f * f) + self.mu * (1.0 + 1.0 / (f * f))
        return f * jnp.sqrt(jnp.maximum(stiffness, 0.0) / rho0)

    def sound_speed_from_stress(self, F, sigma, rho0):
        del sigma
        return self.sound_speed(F, rho0)
