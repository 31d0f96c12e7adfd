"""Quadratic B-spline shape functions: standard MPM on a smoother basis (Steffen, Kirby & Berzins 2008)."""

import functools
import operator
from typing import ClassVar

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from jaxmpm.grid import Grid
from jaxmpm.interpolators._base import AbstractInterpolator, Stencil
from jaxmpm.interpolators._transfer import multiplicative_F_update, tensor


def bspline_axis_stencil(
    grid: Grid, y: Float[Array, "..."], axis: int = 0
) -> tuple[Int[Array, "... 3"], Float[Array, "... 3"], Float[Array, "... 3"], Bool[Array, "..."]]:
    """Nodes, values ``N_i(y)`` and slopes ``N_i'(y)`` of the quadratic B-splines of the three nodes
    around coordinates ``y`` along ``axis`` (per-axis node indices), and whether those nodes exist.

    With ``c`` the node nearest to ``y`` and ``e = (y - x_c) / h`` in ``[-1/2, 1/2)`` (a point halfway
    between two nodes takes the upper one), the nodes are ``c - 1, c, c + 1`` with values ``(1/2 -
    e)^2 / 2``, ``3/4 - e^2``, ``(1/2 + e)^2 / 2`` and slopes ``-(1/2 - e) / h``, ``-2 e / h``, ``(1/2 +
    e) / h``: the kernel ``N(r) = 3/4 - r^2`` for ``|r| < 1/2``, ``(3/2 - |r|)^2 / 2`` for ``1/2 <= |r|
    < 3/2`` and 0 beyond, at ``r = (y - x_i) / h``. The values sum to one and their first moments to
    ``e``, so the basis reproduces linear fields.

    Args:
        grid: the background grid.
        y: coordinates along ``axis``.
        axis: the axis.

    Returns:
        ``(idx, N, N', ok)``: the first three with a last axis of the three nodes; ``ok`` is false
        where a node lies off the grid (``c - 1 < 0`` or ``c + 1`` past the last node).
    """
    cell, frac = grid.locate(y, axis)
    upper = frac >= 0.5
    c = cell + upper.astype(cell.dtype)
    e = jnp.where(upper, frac - 1.0, frac)
    lo, hi = 0.5 - e, 0.5 + e
    idx = jnp.stack([c - 1, c, c + 1], axis=-1)
    w = jnp.stack([0.5 * lo * lo, 0.75 - e * e, 0.5 * hi * hi], axis=-1)
    inv_h = 1.0 / grid.h
    slope = jnp.stack([-inv_h * lo, -2.0 * inv_h * e, inv_h * hi], axis=-1)
    ok = (c >= 1) & (c + 1 <= grid.axes[axis] - 1)
    return idx, w, slope, ok


class BSpline(AbstractInterpolator):
    """Standard MPM with quadratic B-spline shape functions: ``phi_ip = N_i(x_p)``, ``dphi_ip = grad
    N_i(x_p)``, ``F <- (I + dt grad v) F``.

    Each node's shape function is the tensor product of the 1D quadratic B-spline centred on it, ``N(r)
    = 3/4 - r^2`` for ``|r| < 1/2``, ``(3/2 - |r|)^2 / 2`` for ``1/2 <= |r| < 3/2``, 0 beyond, with ``r =
    (x - x_i) / h`` (``bspline_axis_stencil``): three nodes per axis, ``3^dim`` per particle. The basis is
    a partition of unity that reproduces linear fields, and unlike the linear hat of ``SPQ`` its gradient
    is continuous, so a particle that crosses a cell face sees no jump in ``dphi``: the cell-crossing
    error of standard MPM is removed (Steffen, Kirby & Berzins 2008, "Analysis and reduction of
    quadrature errors in the material point method", IJNME 76). The uniform-grid form is the one of
    Stomakhin et al. 2013 and Jiang et al. 2016 (APIC, whose affine matrix it carries exactly). The
    particle is a point, as in ``SPQ``: no domain is tracked.

    The stencil reaches one and a half cells on each side of a particle. Near a wall or a symmetry
    plane it therefore puts mass on the node beyond the face, which ``boundaries.fixed_mask`` holds at
    zero (normal velocity at a plane): that node is not the mirror image of the node inside, so in the
    half cell next to a plane a linear field is reproduced only approximately. Artificial particles
    (``boundaries.artificial_layer``) take B-spline weights like the real ones, and traction points are
    loaded with the step's linear hats.

    ``extent`` is the centre, so ``status.LEFT_GRID`` keeps its meaning for the particle itself; the
    stencil's ``ok`` is false where any of the ``3^dim`` nodes lies off the grid (the centre within half
    a cell of the grid's last node, which ``extent`` cannot see without ``h``), which fails the step that
    would query it (``status.STENCIL``), so no weight is ever dropped or wrapped silently.
    """

    name: ClassVar[str] = "bspline"
    tracks_corners: ClassVar[bool] = False
    stencil_width: ClassVar[int] = 3

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del r0, F, corners
        axes = [bspline_axis_stencil(grid, x[:, a], a) for a in range(x.shape[1])]
        idx, w, dw = tensor(grid, [p[:3] for p in axes], gradients)
        ok = functools.reduce(operator.and_, [p[3] for p in axes])
        if not gradients:
            return Stencil(idx, w, None, None, ok)
        return Stencil(idx, w, idx, dw, ok)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del r0, F, corners
        return x, x
