"""Particle velocity transfers: FLIP (the talk's), PIC and APIC.

The step calls ``momentum`` for particle-to-grid momentum and ``update`` for grid-to-particle.
"""

import abc
from typing import ClassVar

import equinox as eqx
from jaxtyping import Array, Float

from ._util import contract
from .grid import Grid
from .interpolators import Stencil


class AbstractTransfer(eqx.Module):
    """How particle velocities go to the grid and come back."""

    name: ClassVar[str]
    affine: ClassVar[bool] = False  # whether particles carry an affine matrix C

    def momentum(self, grid: Grid, stencil: Stencil, x, v, C, m) -> Float[Array, "n k dim"]:
        """Per-stencil-entry momentum ``phi_ip m_p v_p`` (plus APIC's affine part)."""
        del grid, x, C
        return (stencil.w * m[:, None])[..., None] * v[:, None, :]

    @abc.abstractmethod
    def update(self, grid: Grid, stencil: Stencil, v, a_nodes, v_new, dt) -> tuple[Array, Array | None]:
        """New particle velocities (and APIC's ``C``)."""


def _interp(grid: Grid, stencil: Stencil, field):
    return contract("nk,nkd->nd", stencil.w, grid.gather(stencil.idx, field))


class FLIP(AbstractTransfer):
    """FLIP, the update in the talk: ``v_p += dt sum_i phi_ip a_i`` (Brackbill & Ruppel 1986)."""

    name = "flip"

    def update(self, grid, stencil, v, a_nodes, v_new, dt):
        del v_new
        return v + dt * _interp(grid, stencil, a_nodes), None


class PIC(AbstractTransfer):
    """PIC: ``v_p = sum_i phi_ip v_i^{n+1}`` (dissipative, but free of FLIP's ringing)."""

    name = "pic"

    def update(self, grid, stencil, v, a_nodes, v_new, dt):
        del v, a_nodes, dt
        return _interp(grid, stencil, v_new), None


class APIC(AbstractTransfer):
    """Affine PIC (Jiang, Schroeder, Selle, Teran & Stomakhin 2015).

    Particle to grid carries ``m_p (v_p + C_p (x_i - x_p))``; grid to particle sets
    ``v_p = sum_i phi_ip v_i^{n+1}`` and ``C_p = sum_i v_i^{n+1} (dphi_ip)^T``, the form that paper
    gives for multilinear weights (their section 5.3, ``B_p D_p^-1 = sum_i v_i grad w_ip^T``), here
    with the interpolator's own ``dphi``.
    """

    name = "apic"
    affine = True

    def momentum(self, grid, stencil, x, v, C, m):
        x_i = grid.nodes()[stencil.idx]  # (n, k, dim)
        dx = x_i - x[:, None, :]
        vel = v[:, None, :] + contract("nab,nkb->nka", C, dx)
        return (stencil.w * m[:, None])[..., None] * vel

    def update(self, grid, stencil, v, a_nodes, v_new, dt):
        del v, a_nodes, dt
        v_g = grid.gather(stencil.gidx, v_new)
        C = contract("nka,nkb->nab", v_g, stencil.dw)
        return _interp(grid, stencil, v_new), C


TRANSFERS = {"flip": FLIP, "pic": PIC, "apic": APIC}


TRANSFERS: dict[str, type[AbstractTransfer]] = {cls.name: cls for cls in (FLIP, PIC, APIC)}
"""The one registry of transfers, by the name each is known by (``transfer.name``, ``--transfer``)."""
