"""Shared pieces of the interpolators: the two-node hat stencil of a point, velocity gradients."""

import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._util import contract
from ..grid import Grid
from ._base import Stencil


def point_stencil(
    grid: Grid, y: Float[Array, "..."]
) -> tuple[Int[Array, "... 2"], Float[Array, "... 2"], Float[Array, "... 2"]]:
    """Nodes, hat values ``S_i(y)`` and hat slopes ``S_i'(y)`` of the two nodes around points ``y``.

    A point exactly on node ``j`` gets nodes ``(j, j + 1)`` with values ``(1, 0)`` and the slopes of
    the cell to its right: the one-sided derivative.
    """
    base, frac = grid.locate(y)
    idx = jnp.stack([base, base + 1], axis=-1)
    w = jnp.stack([1.0 - frac, frac], axis=-1)
    inv_h = 1.0 / grid.h
    slope = jnp.stack([-inv_h * jnp.ones_like(frac), inv_h * jnp.ones_like(frac)], axis=-1)
    return idx, w, slope


def velocity_gradient(
    grid: Grid, stencil: Stencil, v_nodes: Float[Array, "n_nodes dim"]
) -> Float[Array, "n dim dim"]:
    """``L_p = sum_i v_i (dphi_ip)^T``, the velocity gradient each particle sees."""
    v = grid.gather(stencil.gidx, v_nodes)  # (n, kg, dim)
    return contract("nka,nkb->nab", v, stencil.dw)


def multiplicative_F_update(
    grid: Grid, stencil: Stencil, F: Float[Array, "n dim dim"], v_new: Float[Array, "n_nodes dim"], dt
) -> Float[Array, "n dim dim"]:
    """``F <- (I + dt L) F``, the update of SPQ, GIMP and CPDI (SPEC section 3)."""
    L = velocity_gradient(grid, stencil, v_new)
    return F + dt * contract("nab,nbc->nac", L, F)
