"""Particle velocity transfers: FLIP, PIC and APIC.

The step calls ``momentum`` for particle-to-grid momentum and ``update`` for grid-to-particle.
"""

import abc
from typing import ClassVar

import equinox as eqx
from jaxtyping import Array, Float

from ._util import contract
from .grid import Grid
from .interpolators import Stencil
from .interpolators._transfer import gradient_outer


class AbstractTransfer(eqx.Module):
    """How particle velocities go to the grid and come back.

    Concrete transfers are final: they implement the abstract members below and nothing else.

    Attributes:
        name: the name the transfer is known by (``TRANSFERS``, ``--transfer``).
        affine: whether particles carry an affine velocity matrix ``C`` (APIC).
    """

    name: eqx.AbstractClassVar[str]
    affine: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def momentum(
        self,
        grid: Grid,
        stencil: Stencil,
        x: Float[Array, "n dim"],
        v: Float[Array, "n dim"],
        C: Float[Array, "n dim dim"] | None,
        m: Float[Array, " n"],
    ) -> Float[Array, "n k dim"]:
        """Per-stencil-entry momentum ``phi_ip m_p v_p`` (plus APIC's affine part).

        Args:
            grid: the background grid.
            stencil: the particles' stencil.
            x: particle centres.
            v: particle velocities.
            C: APIC's affine matrices (``None`` for the other transfers).
            m: particle masses.

        Returns:
            The momentum of each stencil entry, to be scattered onto nodes ``stencil.idx``.
        """

    @abc.abstractmethod
    def update(
        self,
        grid: Grid,
        stencil: Stencil,
        v: Float[Array, "n dim"],
        a_nodes: Float[Array, "n_nodes dim"],
        v_new: Float[Array, "n_nodes dim"],
        dt: Float[Array, ""],
    ) -> tuple[Float[Array, "n dim"], Float[Array, "n dim dim"] | None]:
        """New particle velocities (and APIC's ``C``) from the grid.

        Args:
            grid: the background grid.
            stencil: the particles' stencil.
            v: particle velocities at the start of the step.
            a_nodes: nodal accelerations.
            v_new: nodal velocities at the end of the step.
            dt: the time step.

        Returns:
            ``(v_new_particles, C)``, ``C`` ``None`` unless the transfer is affine.
        """


def _point_momentum(stencil: Stencil, v, m):
    """``phi_ip m_p v_p``: each particle's momentum carried by its weights (FLIP and PIC)."""
    return (stencil.w * m[:, None])[..., None] * v[:, None, :]


def _interp(grid: Grid, stencil: Stencil, field):
    return contract("nk,nkd->nd", stencil.w, grid.gather(stencil.idx, field, stencil.base))


class FLIP(AbstractTransfer):
    """FLIP: ``v_p += dt sum_i phi_ip a_i`` (Brackbill & Ruppel 1986), the particle update of
    standard MPM (Sulsky, Chen & Schreyer 1994) and of Bonifasi-Lista, Brannon & Wiskin 2013."""

    name: ClassVar[str] = "flip"
    affine: ClassVar[bool] = False

    def momentum(self, grid, stencil, x, v, C, m):
        del grid, x, C
        return _point_momentum(stencil, v, m)

    def update(self, grid, stencil, v, a_nodes, v_new, dt):
        del v_new
        return v + dt * _interp(grid, stencil, a_nodes), None


class PIC(AbstractTransfer):
    """PIC: ``v_p = sum_i phi_ip v_i^{n+1}`` (dissipative, but free of FLIP's ringing)."""

    name: ClassVar[str] = "pic"
    affine: ClassVar[bool] = False

    def momentum(self, grid, stencil, x, v, C, m):
        del grid, x, C
        return _point_momentum(stencil, v, m)

    def update(self, grid, stencil, v, a_nodes, v_new, dt):
        del v, a_nodes, dt
        return _interp(grid, stencil, v_new), None


class APIC(AbstractTransfer):
    """Affine PIC (Jiang, Schroeder, Selle, Teran & Stomakhin 2015).

    Particle to grid carries ``m_p (v_p + C_p (x_i - x_p))``; grid to particle sets
    ``v_p = sum_i phi_ip v_i^{n+1}`` and ``C_p = sum_i v_i^{n+1} (dphi_ip)^T``, the form that paper
    gives for multilinear weights (their section 5.3, ``B_p D_p^-1 = sum_i v_i grad w_ip^T``), here
    with the interpolator's own ``dphi``.

    With CPDI's weights it does not keep the energy at a free surface that expands into near vacuum:
    in the 1D slab at 100:1 (32 cells) the outermost particle gains 80% of the slab's kinetic energy
    by 0.3 of two sound transits and is flung off the grid, where FLIP's total energy falls by 1.8%
    of it. With MPQ's or GIMP's weights APIC gains none there (+1.0% and -23%; the documentation's
    known limitations).
    """

    name: ClassVar[str] = "apic"
    affine: ClassVar[bool] = True

    def momentum(self, grid, stencil, x, v, C, m):
        x_i = grid.nodes()[stencil.idx]  # (n, k, dim)
        dx = x_i - x[:, None, :]
        vel = v[:, None, :] + contract("nab,nkb->nka", C, dx)
        return (stencil.w * m[:, None])[..., None] * vel

    def update(self, grid, stencil, v, a_nodes, v_new, dt):
        del v, a_nodes, dt
        v_g = grid.gather(stencil.gidx, v_new, stencil.gbase)
        C = gradient_outer(stencil, v_g)
        return _interp(grid, stencil, v_new), C


TRANSFERS: dict[str, type[AbstractTransfer]] = {cls.name: cls for cls in (FLIP, PIC, APIC)}
"""The one registry of transfers, by the name each is known by (``transfer.name``, ``--transfer``)."""
