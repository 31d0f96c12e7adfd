"""Artificial viscosity for shocks (von Neumann & Richtmyer 1950, with Landshoff's linear term).

A shock is a jump that the grid cannot resolve; without dissipation MPM rings behind it. Under
compression, a bulk viscous pressure

    q = rho (c_quad (h d)^2 + c_lin c h |d|),     d = dJ/dt / J < 0,

is added to the pressure (``sigma -= q I``); under expansion ``q = 0``, so rarefactions and smooth
flows are untouched. ``rho = rho0 / J`` is the current density, ``c`` the material's sound speed,
``h`` the grid spacing (the length over which the grid velocity jumps), and ``d`` the volumetric
rate of deformation of the step, ``(J_new - J_old) / (dt J_new)``. This is the form of Wilkins,
"Use of artificial viscosity in multidimensional fluid dynamic calculations" (J. Comput. Phys.
36, 1980), as Uintah's MPM applies it per particle.

A shear viscosity (``c_shear``, off by default) adds a deviatoric viscous stress in every flow,

    s = 2 mu dev(D),     mu = c_shear rho c h,     D = sym(F_new F_old^-1 - I) / dt,

a linear (Landshoff-type) viscosity on the deviatoric rate of deformation. A gas has no shear
stiffness, so nothing else resists the spurious shear of its particle arrangement in 2D and 3D; this
damps it, at the price of also damping the physical shear of the flow (a radial expansion has a
deviatoric rate too). Its work heats a material with an energy equation.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._checks import check_nonnegative, check_real, check_scalar
from ._util import ONE_VALUE, as_float, check_real_fields, det
from .materials import AbstractMaterial


def _optional_float(x):
    return None if x is None else as_float(x)


class ArtificialViscosity(eqx.Module):
    """Bulk artificial viscosity, active in compression only, and optionally a shear viscosity.

    Attributes:
        c_quad: quadratic (von Neumann-Richtmyer) coefficient, dimensionless (default 2.0).
        c_lin: linear (Landshoff) coefficient, dimensionless (default 0.2).
        c_shear: coefficient of the shear viscosity ``mu = c_shear rho c h``, dimensionless, or
            ``None`` (default) for none.
    """

    c_quad: Float[Array, ""] = eqx.field(converter=as_float, default=2.0)
    c_lin: Float[Array, ""] = eqx.field(converter=as_float, default=0.2)
    c_shear: Float[Array, ""] | None = eqx.field(converter=_optional_float, default=None)

    def __post_init__(self):
        """Name a coefficient that is not a number before the converters run (``check_real_fields``).

        Raises:
            ValueError: a coefficient is not a real number ("c_lin must be a real number, got 'x'"),
                or ``c_shear`` is neither ``None`` nor one, or a coefficient is an array with a shape.
        """
        check_real_fields(self, ONE_VALUE)
        if self.c_shear is not None:
            check_real("c_shear", self.c_shear)
            check_scalar("c_shear", self.c_shear, ONE_VALUE)

    def __check_init__(self):
        check_nonnegative("c_quad", self.c_quad)
        check_nonnegative("c_lin", self.c_lin)
        if self.c_shear is not None:
            check_nonnegative("c_shear", self.c_shear)

    def coefficients(self) -> list[float]:
        """``[c_quad, c_lin]``, and ``c_shear`` after them when there is a shear viscosity (as the
        command line's ``--viscosity`` and a saved run's ``meta`` write them).

        Returns:
            The coefficients.
        """
        out = [float(self.c_quad), float(self.c_lin)]
        return out if self.c_shear is None else out + [float(self.c_shear)]

    def shear_stress(
        self,
        F_old: Float[Array, "n dim dim"],
        F_new: Float[Array, "n dim dim"],
        dt: Float[Array, ""],
        rho: Float[Array, " n"],
        c: Float[Array, " n"],
        h: Float[Array, ""],
    ) -> tuple[Float[Array, "n dim dim"], Float[Array, " n"]]:
        """The deviatoric viscous stress ``2 mu dev(D)`` of each particle and its power per unit
        mass, ``s : D / rho`` (>= 0), for ``c_shear`` not ``None``.

        Args:
            F_old: deformation gradients before the step.
            F_new: deformation gradients after the step.
            dt: the time step.
            rho: current densities.
            c: sound speeds.
            h: grid spacing.

        Returns:
            ``(s, power)``.
        """
        dim = F_new.shape[-1]
        eye = jnp.eye(dim, dtype=F_new.dtype)
        L = (jnp.einsum("nij,njk->nik", F_new, jnp.linalg.inv(F_old)) - eye[None]) / dt
        D = 0.5 * (L + jnp.swapaxes(L, 1, 2))
        dev = D - (jnp.trace(D, axis1=1, axis2=2) / dim)[:, None, None] * eye[None]
        mu = self.c_shear * rho * c * h
        s = 2.0 * mu[:, None, None] * dev
        return s, jnp.sum(s * dev, axis=(1, 2)) / rho

    def pressure(
        self,
        material: AbstractMaterial,
        F_old: Float[Array, "n dim dim"],
        F_new: Float[Array, "n dim dim"],
        dt: Float[Array, ""],
        rho0: Float[Array, ""],
        h: Float[Array, ""],
    ) -> Float[Array, " n"]:
        """The viscous pressure ``q >= 0`` of each particle after a step from ``F_old`` to ``F_new``.

        Args:
            material: the material (its sound speed).
            F_old: deformation gradients before the step.
            F_new: deformation gradients after the step.
            dt: the time step.
            rho0: initial density.
            h: grid spacing.

        Returns:
            ``q = rho (c_quad (h d)^2 + c_lin c h |d|)`` where the volumetric rate ``d = (J_new -
            J_old) / (dt J_new)`` is negative (compression), 0 where it is not.
        """
        J_old, J_new = det(F_old), det(F_new)
        c = jax.vmap(material.sound_speed, in_axes=(0, None))(F_new, rho0)
        return self.pressure_of(J_old, J_new, dt, rho0 / J_new, c, h)

    def pressure_of(
        self,
        J_old: Float[Array, " n"],
        J_new: Float[Array, " n"],
        dt: Float[Array, ""],
        rho: Float[Array, " n"],
        c: Float[Array, " n"],
        h: Float[Array, ""],
    ) -> Float[Array, " n"]:
        """The viscous pressure from the volume ratios, density and sound speed (any material).

        Args:
            J_old: volume ratios before the step.
            J_new: volume ratios after the step.
            dt: the time step.
            rho: current densities ``rho0 / J_new``.
            c: sound speeds.
            h: grid spacing.

        Returns:
            ``q = rho (c_quad (h d)^2 + c_lin c h |d|)`` where the volumetric rate ``d = (J_new -
            J_old) / (dt J_new)`` is negative (compression), 0 where it is not.
        """
        rate = (J_new - J_old) / (dt * J_new)
        compress = jnp.minimum(rate, 0.0)
        return rho * (self.c_quad * jnp.square(h * compress) + self.c_lin * c * h * (-compress))

    def stress(
        self,
        material: AbstractMaterial,
        F_old: Float[Array, "n dim dim"],
        F_new: Float[Array, "n dim dim"],
        dt: Float[Array, ""],
        rho0: Float[Array, ""],
        h: Float[Array, ""],
    ) -> Float[Array, "n dim dim"]:
        """The viscous stress ``-q I`` (plus ``2 mu dev(D)`` with ``c_shear``) to add to each
        particle's Cauchy stress.

        Args:
            material: as for ``pressure``.
            F_old: as for ``pressure``.
            F_new: as for ``pressure``.
            dt: as for ``pressure``.
            rho0: as for ``pressure``.
            h: as for ``pressure``.

        Returns:
            The viscous stress per particle.
        """
        q = self.pressure(material, F_old, F_new, dt, rho0, h)
        dim = F_new.shape[-1]
        bulk = -q[:, None, None] * jnp.eye(dim, dtype=F_new.dtype)[None]
        if self.c_shear is None:
            return bulk
        J_new = det(F_new)
        c = jax.vmap(material.sound_speed, in_axes=(0, None))(F_new, rho0)
        return bulk + self.shear_stress(F_old, F_new, dt, rho0 / J_new, c, h)[0]
