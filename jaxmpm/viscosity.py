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
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._checks import check_nonnegative
from ._util import as_float, det
from .materials import AbstractMaterial


class ArtificialViscosity(eqx.Module):
    """Bulk artificial viscosity, active in compression only.

    Attributes:
        c_quad: quadratic (von Neumann-Richtmyer) coefficient, dimensionless (default 2.0).
        c_lin: linear (Landshoff) coefficient, dimensionless (default 0.2).
    """

    c_quad: Float[Array, ""] = eqx.field(converter=as_float, default=2.0)
    c_lin: Float[Array, ""] = eqx.field(converter=as_float, default=0.2)

    def __check_init__(self):
        check_nonnegative("c_quad", self.c_quad)
        check_nonnegative("c_lin", self.c_lin)

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
            ``q``, as in the module's docstring.
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
            ``q``, as in the module's docstring.
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
        """The viscous stress ``-q I`` to add to each particle's Cauchy stress.

        Args:
            material: as for ``pressure``.
            F_old: as for ``pressure``.
            F_new: as for ``pressure``.
            dt: as for ``pressure``.
            rho0: as for ``pressure``.
            h: as for ``pressure``.

        Returns:
            ``-q I`` per particle.
        """
        q = self.pressure(material, F_old, F_new, dt, rho0, h)
        dim = F_new.shape[-1]
        return -q[:, None, None] * jnp.eye(dim, dtype=F_new.dtype)[None]
