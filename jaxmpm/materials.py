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
from ._util import ONE_VALUE, as_float, check_real_fields, contract, det, power


class AbstractMaterial(eqx.Module):
    """A hyperelastic material: stress, stored energy and wave speed as functions of ``F``."""

    def __post_init__(self):
        """Name a parameter that is not a number before the converters run (``check_real_fields``).

        Raises:
            ValueError: a parameter is not a real number ("P0 must be a real number, got None"), or is
                an array with a shape (a material's parameters are one number each).
        """
        check_real_fields(self, ONE_VALUE)

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
        ``F sqrt(W''(F) / rho0)``, the closed forms of the gas and the neo-Hookean solid (not of
        ``LinearElastic``, whose small-strain speed leaves out the factor ``F``); in 2D and 3D it
        serves models without one (a Hessian of ``W`` and two small eigenproblems per particle). Its
        derivative holds the principal directions fixed: the speed's own for an isotropic ``W``, and
        finite where principal stretches repeat (``F = I``).

        Args:
            F: deformation gradient of one particle.
            rho0: initial density.

        Returns:
            The Eulerian wave speed ``c``.
        """
        H = jax.hessian(self.energy_density)(F)  # (dim, dim, dim, dim): d2W / dF_iJ dF_kL
        # The directions are held fixed under differentiation. For an isotropic energy the speed is
        # stationary in n at a principal direction (a reflection through the other principal
        # directions maps the state onto itself), so this is the speed's own derivative; and where
        # principal stretches repeat (F = I, any isotropic stretch) the eigenvectors' derivative is
        # infinite, which would make the derivative of every run that calls this NaN.
        N = jax.lax.stop_gradient(jnp.linalg.eigh(F @ F.T)[1])

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
        work (the gas: a power of ``J``). The step's stability check calls it every step. (With
        ``volume_average``, the stored stress is that of the averaged ``F`` while ``F`` is the
        particle's own: the gas's speed is then off by ``sqrt(J / J_avg)``, a few per cent.)

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
        return self.P0 * power(J, -self.gamma) - self.p_atm

    def stress(self, F):
        J = det(F)
        return -self.pressure(J) * jnp.eye(F.shape[0], dtype=F.dtype)

    def energy_density(self, F):
        J = det(F)
        return self.P0 * (power(J, 1.0 - self.gamma) - 1.0) / (self.gamma - 1.0) + self.p_atm * (J - 1.0)

    def sound_speed(self, F, rho0):
        J = det(F)
        return jnp.sqrt(self.gamma * self.P0 * power(J, 1.0 - self.gamma) / rho0)

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
        # softens) only for ln F > 1 + mu (1 + F^2) / lambda, where the speed is taken as zero.
        stiffness = self.lam * (1.0 - jnp.log(f)) / (f * f) + self.mu * (1.0 + 1.0 / (f * f))
        stiff = stiffness > 0.0  # (the square root of the clamp at 0 would give 0 * inf derivatives)
        return jnp.where(stiff, f * jnp.sqrt(jnp.where(stiff, stiffness, 1.0) / rho0), 0.0)

    def sound_speed_from_stress(self, F, sigma, rho0):
        del sigma
        return self.sound_speed(F, rho0)


class AbstractEOS(eqx.Module):
    """A fluid-like material with an energy equation: pressure from density and internal energy.

    The pressure is affine in the specific internal energy ``e`` (per unit mass),

        ``p = a(rho, z) + b(rho, z) e``,

    which holds for the ideal gas, Mie-Grueneisen and JWL forms. ``z`` are the particle's internal
    variables (a dict of scalars, or ``None`` for a material without any). The stress is ``-p I``;
    the step updates ``e`` from the stress power, ``rho0 de = -(p + q) dJ`` (``q`` the artificial
    viscosity), with the pressure taken at the middle of the step (the trapezoid rule, solved
    exactly because ``p`` is affine in ``e``; Wilkins, "Calculation of elastic-plastic flow", 1964).

    A concrete EOS implements ``pressure_terms``, ``initial_internal``, ``update_internal``,
    ``front_speed`` and ``nonnegative_energy``; one without internal variables or a front of its own
    derives from ``AbstractStatelessEOS`` and implements ``pressure_terms`` and
    ``nonnegative_energy``.
    """

    def __post_init__(self):
        """Name a parameter that is not a number before the converters run (``check_real_fields``).

        Raises:
            ValueError: a parameter is not a real number ("gamma must be a real number, got None"), or
                is an array with a shape (an equation of state's parameters are one number each).
        """
        check_real_fields(self, ONE_VALUE)

    @abc.abstractmethod
    def pressure_terms(
        self, rho: Float[Array, ""], z: dict[str, Array] | None
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """The two terms of ``p = a + b e`` at density ``rho`` (one particle).

        Args:
            rho: current density.
            z: the particle's internal variables, or ``None``.

        Returns:
            ``(a, b)``.
        """

    @abc.abstractmethod
    def initial_internal(self, X: Float[Array, " dim"]) -> dict[str, Array] | None:
        """The internal variables of a particle at ``t = 0``.

        Args:
            X: its reference position.

        Returns:
            A dict of scalars, or ``None`` for a material without internal variables.
        """

    @abc.abstractmethod
    def update_internal(
        self,
        z: dict[str, Array] | None,
        X: Float[Array, " dim"],
        t: Float[Array, ""],
        dt: Float[Array, ""],
        J_old: Float[Array, ""],
        J_new: Float[Array, ""],
    ) -> dict[str, Array] | None:
        """The internal variables after a step from ``t`` to ``t + dt`` (one particle).

        Args:
            z: the internal variables before the step (``None`` for none).
            X: the particle's reference position.
            t: time at the start of the step.
            dt: the step.
            J_old: volume ratio ``det F`` before the step.
            J_new: volume ratio after it.

        Returns:
            The new internal variables.
        """

    @abc.abstractmethod
    def front_speed(self) -> Float[Array, ""] | None:
        """The speed of a front the material carries itself (a programmed detonation), or ``None``.

        Information then travels at least this fast, so it bounds the stable time step like a sound
        speed: ``dt <= CFL h / max(max(c, front_speed) + |v|)``.

        Returns:
            The speed, or ``None`` for a material without such a front.
        """

    @abc.abstractmethod
    def nonnegative_energy(self) -> bool:
        """Whether the specific internal energy ``e`` is >= 0 in every state of this material (an
        ideal gas's, whose pressure ``(gamma - 1) rho e`` would turn negative with it), so that a step
        leaving a particle with ``e < 0`` is a breakdown (``jaxmpm.status.NEGATIVE_ENERGY``); ``False``
        where ``e`` is measured from a reference state and may go below it (Mie-Grueneisen).

        Returns:
            The flag (static: it decides what the compiled step checks).
        """

    def pressure(
        self, rho: Float[Array, ""], e: Float[Array, ""], z: dict[str, Array] | None = None
    ) -> Float[Array, ""]:
        """The pressure ``a(rho, z) + b(rho, z) e``.

        Args:
            rho: density.
            e: specific internal energy.
            z: internal variables, or ``None``.

        Returns:
            ``p``.
        """
        a, b = self.pressure_terms(rho, z)
        return a + b * e

    def sound_speed(
        self, rho: Float[Array, ""], e: Float[Array, ""], z: dict[str, Array] | None = None
    ) -> Float[Array, ""]:
        """The isentropic sound speed, ``c^2 = dp/drho|_e + (p / rho^2) dp/de|_rho``.

        Args:
            rho: density.
            e: specific internal energy.
            z: internal variables, or ``None``.

        Returns:
            ``c`` (0 where ``c^2 < 0``).
        """
        a, b = self.pressure_terms(rho, z)
        da, db = jax.jvp(lambda r: self.pressure_terms(r, z), (rho,), (jnp.ones_like(rho),))[1]
        p = a + b * e
        c2 = da + db * e + p * b / (rho * rho)
        pos = c2 > 0.0  # (a zero derivative, not NaN, where c = 0: an unburnt inert explosive)
        return jnp.where(pos, jnp.sqrt(jnp.where(pos, c2, 1.0)), 0.0)


class AbstractStatelessEOS(AbstractEOS):
    """An EOS without internal variables or a front of its own: a concrete one implements
    ``pressure_terms`` and ``nonnegative_energy`` (the ideal gas, Mie-Grueneisen, the explosives'
    products and reactants)."""

    def initial_internal(self, X):
        del X
        return None

    def update_internal(self, z, X, t, dt, J_old, J_new):
        del X, t, dt, J_old, J_new
        return z

    def front_speed(self):
        return None


class IdealGas(AbstractStatelessEOS):
    """Ideal (polytropic) gas: ``p = (gamma - 1) rho e``, ``c = sqrt(gamma p / rho)``.

    The Euler equations' gas of the shock tube and Noh's problem (Toro, "Riemann Solvers and
    Numerical Methods for Fluid Dynamics", ch. 1). No internal variables.

    Attributes:
        gamma: ratio of specific heats, > 1.
    """

    gamma: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_greater("gamma", self.gamma, 1.0)

    def pressure_terms(self, rho, z):
        del z
        return jnp.zeros_like(rho), (self.gamma - 1.0) * rho

    def nonnegative_energy(self):
        return True


class MieGruneisen(AbstractStatelessEOS):
    """Mie-Grueneisen solid on its linear ``Us = c0 + s up`` Hugoniot, with ``rho Gamma = rho_ref Gamma0``.

    With ``eta = 1 - rho_ref / rho`` (compression > 0), the Hugoniot pressure and energy are ``p_H =
    rho_ref c0^2 eta / (1 - s eta)^2`` and ``e_H = p_H eta / (2 rho_ref)``, and off the Hugoniot

        ``p = p_H (1 - Gamma0 eta / 2) + Gamma0 rho_ref e``

    (Meyers, "Dynamic Behavior of Materials", 1994, sec. 5.3; the form of Uintah's MPM
    ``MieGruneisenEOS``). The same expression is used in tension (``eta < 0``), where it is smooth
    and close to linear. The Hugoniot has a pole at ``eta = 1 / s`` (copper: ``rho = 3.05 rho_ref``);
    the model holds below it. Past it the pressure falls as the density rises and the sound speed
    is taken as 0, which the run does not report as a breakdown. ``MIE_GRUNEISEN`` holds standard
    constants of copper, 4340 steel and 6061-T6 aluminium. No internal variables.

    Attributes:
        rho_ref: reference (ambient) density of the Hugoniot.
        c0: bulk sound speed, the intercept of ``Us(up)``.
        s: slope of ``Us(up)``, >= 0.
        Gamma0: Grueneisen coefficient at ``rho_ref``, >= 0.
    """

    rho_ref: Float[Array, ""] = eqx.field(converter=as_float)
    c0: Float[Array, ""] = eqx.field(converter=as_float)
    s: Float[Array, ""] = eqx.field(converter=as_float)
    Gamma0: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("rho_ref", self.rho_ref)
        check_positive("c0", self.c0)
        check_nonnegative("s", self.s)
        check_nonnegative("Gamma0", self.Gamma0)

    def pressure_terms(self, rho, z):
        del z
        eta = 1.0 - self.rho_ref / rho
        p_h = self.rho_ref * self.c0**2 * eta / jnp.square(1.0 - self.s * eta)
        return p_h * (1.0 - 0.5 * self.Gamma0 * eta), self.Gamma0 * self.rho_ref * jnp.ones_like(rho)

    def nonnegative_energy(self):
        """``False``: ``e`` is measured from the reference state (``rho_ref``, ``e = 0``, ``p = 0``), and a
        solid released from it, or started off it, may go below (``e < 0`` is no breakdown).

        Returns:
            ``False``.
        """
        return False


MIE_GRUNEISEN: dict[str, dict[str, float]] = {
    "copper": dict(rho_ref=8930.0, c0=3940.0, s=1.489, Gamma0=2.02),
    "steel-4340": dict(rho_ref=7810.0, c0=4578.0, s=1.33, Gamma0=1.67),
    "al-6061": dict(rho_ref=2703.0, c0=5240.0, s=1.40, Gamma0=1.97),
}
"""Mie-Grueneisen constants (SI: kg/m^3, m/s) of OFHC copper, 4340 steel and 6061-T6 aluminium, from
Steinberg, "Equation of state and strength properties of selected materials", LLNL report
UCRL-MA-106439 (1991, change 1 1996). ``MieGruneisen(**MIE_GRUNEISEN["copper"])``."""


DEVIATORIC_KEYS: tuple[str, ...] = ("s_xx", "s_yy", "s_zz", "s_xy", "s_xz", "s_yz")
"""The internal variables of an ``ElasticPlastic`` particle: the six components of its symmetric
deviatoric Cauchy stress (3x3 in every dimension: 1D is uniaxial strain, 2D plane strain)."""

_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # (row, column) of each of DEVIATORIC_KEYS


class ElasticPlastic(AbstractEOS):
    """An EOS with strength: elastic-perfectly-plastic deviatoric stress on top of a pressure.

    The Cauchy stress is ``sigma = -(p + q) I + s``: ``p`` from ``eos`` (an ``AbstractStatelessEOS``,
    e.g. ``MieGruneisen``), ``q`` the artificial viscosity, and ``s`` the deviatoric stress, carried
    per particle as six internal variables (``DEVIATORIC_KEYS``, 3x3 in every dimension). The step
    advances ``s`` with ``deviatoric`` in the hydrocode form of Wilkins, "Calculation of
    elastic-plastic flow", Methods in Computational Physics 3 (1964): a hypoelastic Jaumann-rate
    update ``ds/dt = 2 G dev(D) + W s - s W``, then a radial return to the von Mises yield surface
    ``sqrt(3/2 s:s) = Y``. The deviatoric work is added to the internal energy ``e`` (all of it: ``e``
    holds the elastic strain energy and the plastic work, as in Wilkins' scheme), so kinetic plus
    internal energy is conserved.
    The longitudinal wave speed ``sqrt(c_eos^2 + 4 G / (3 rho))`` bounds the stable step.

    ``STRENGTH`` holds ``G`` and ``Y`` of the metals of ``MIE_GRUNEISEN``:
    ``ElasticPlastic(MieGruneisen(**MIE_GRUNEISEN["copper"]), **STRENGTH["copper"])``.

    Attributes:
        eos: the pressure, an ``AbstractStatelessEOS``.
        G: shear modulus (> 0).
        Y: von Mises yield stress (>= 0; 0 is a fluid, ``s = 0``).
    """

    eos: AbstractEOS  # an AbstractStatelessEOS: checked below, with a message that names it
    G: Float[Array, ""] = eqx.field(converter=as_float)
    Y: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        if not isinstance(self.eos, AbstractStatelessEOS):
            raise ValueError(
                f"eos must be an AbstractStatelessEOS (a pressure without internal variables, e.g. "
                f"MieGruneisen), got {type(self.eos).__name__}"
            )
        check_positive("G", self.G)
        check_nonnegative("Y", self.Y)

    def pressure_terms(self, rho, z):
        del z  # the deviatoric stress does not enter the pressure
        return self.eos.pressure_terms(rho, None)

    def initial_internal(self, X):
        return {k: jnp.zeros((), dtype=X.dtype) for k in DEVIATORIC_KEYS}

    def update_internal(self, z, X, t, dt, J_old, J_new):
        del X, t, dt, J_old, J_new  # the deviatoric stress needs F: the step calls ``deviatoric``
        return z

    def front_speed(self):
        return None

    def nonnegative_energy(self):
        """As its pressure's, ``eos`` (``e`` holds the elastic strain energy and the plastic work on top).

        Returns:
            ``eos.nonnegative_energy()``.
        """
        return self.eos.nonnegative_energy()

    def deviatoric(
        self,
        z: dict[str, Array],
        F_old: Float[Array, "dim dim"],
        F_new: Float[Array, "dim dim"],
        dt: Float[Array, ""],
    ) -> tuple[dict[str, Array], Float[Array, "dim dim"], Float[Array, ""]]:
        """One particle's deviatoric stress after a step from ``F_old`` to ``F_new`` (Wilkins 1964).

        With the velocity gradient ``L = (F_new F_old^-1 - I) / dt`` (embedded in 3x3, zero outside the
        ``dim x dim`` block), ``D = sym(L)`` and ``W = skew(L)``, the trial stress is the Jaumann-rate
        update ``s* = s + dt (2 G dev(D) + W s - s W)`` (``dev`` over 3x3), and the radial return
        ``s_new = s* min(1, Y / q*)``, ``q* = sqrt(3/2 s*:s*)``, puts it on the yield surface where it
        lies outside. Where ``q* = 0`` the values and their derivatives are finite.

        Args:
            z: the particle's internal variables (``DEVIATORIC_KEYS``).
            F_old: deformation gradient before the step.
            F_new: deformation gradient after it.
            dt: the step.

        Returns:
            ``(z_new, s, power)``: the new internal variables, the ``dim x dim`` block of ``s_new``, and
            the deviatoric stress power per unit current volume over the step, ``(s + s_new) / 2 : D``.
        """
        dim = F_new.shape[-1]
        dtype = F_new.dtype
        eye3 = jnp.eye(3, dtype=dtype)
        L_dim = (F_new @ jnp.linalg.inv(F_old) - jnp.eye(dim, dtype=dtype)) / dt
        L = jnp.zeros((3, 3), dtype=dtype).at[:dim, :dim].set(L_dim)
        D = 0.5 * (L + L.T)
        W = 0.5 * (L - L.T)
        s = self._tensor(z)
        dev_D = D - (jnp.trace(D) / 3.0) * eye3
        trial = s + dt * (2.0 * self.G * dev_D + W @ s - s @ W)
        q2 = 1.5 * jnp.sum(trial * trial)
        pos = q2 > 0.0
        q = jnp.where(pos, jnp.sqrt(jnp.where(pos, q2, 1.0)), 0.0)
        over = q > self.Y  # (then q > 0)
        s_new = trial * jnp.where(over, self.Y / jnp.where(over, q, 1.0), 1.0)
        power = 0.5 * jnp.sum((s + s_new) * D)
        z_new = {k: s_new[i, j] for k, (i, j) in zip(DEVIATORIC_KEYS, _PAIRS)}
        return z_new, s_new[:dim, :dim], power

    def stress_of(self, z: dict[str, Array], dim: int) -> Float[Array, "dim dim"]:
        """The deviatoric stress that one particle's internal variables hold, as the step adds it to
        ``-(p + q) I``.

        Args:
            z: the particle's internal variables (``DEVIATORIC_KEYS``).
            dim: the dimension of the run (static).

        Returns:
            The ``dim x dim`` block of the 3x3 deviatoric stress.
        """
        return self._tensor(z)[:dim, :dim]

    def _tensor(self, z):
        """The symmetric 3x3 deviatoric stress of the internal variables."""
        s_xx, s_yy, s_zz, s_xy, s_xz, s_yz = (z[k] for k in DEVIATORIC_KEYS)
        return jnp.stack(
            [
                jnp.stack([s_xx, s_xy, s_xz]),
                jnp.stack([s_xy, s_yy, s_yz]),
                jnp.stack([s_xz, s_yz, s_zz]),
            ]
        )


STRENGTH: dict[str, dict[str, float]] = {
    "copper": dict(G=46e9, Y=90e6),
    "steel-4340": dict(G=77.5e9, Y=792e6),
    "al-6061": dict(G=26e9, Y=324e6),
}
"""Shear modulus ``G`` and yield stress ``Y`` (Pa) of OFHC copper, 4340 steel and 6061-T6 aluminium,
the metals of ``MIE_GRUNEISEN``, for ``ElasticPlastic``. ``Y`` is the Johnson-Cook ``A``, the yield
stress at zero plastic strain: copper's and 4340 steel's from Johnson & Cook, "A constitutive model and
data for metals subjected to large strains, high strain rates and high temperatures", 7th International
Symposium on Ballistics (1983); 6061-T6's from Lesuer, Kay & LeBlanc, "Modeling large-strain,
high-rate deformation in metals", LLNL report UCRL-JC-134118 (2001). ``G`` of 4340 steel from ``E =
200 GPa`` and ``nu = 0.29``. ``ElasticPlastic(MieGruneisen(**MIE_GRUNEISEN["copper"]),
**STRENGTH["copper"])``."""
