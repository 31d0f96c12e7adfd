"""Multi point query (Bonifasi-Lista, Brannon & Wiskin, 7th MPM Workshop 2013)."""

import functools
from typing import ClassVar

import jax.numpy as jnp

from ._base import AbstractInterpolator, Stencil
from ._transfer import corner_matrix, domain_stencil, points_stencil, tracked_corner_update


class MPQ(AbstractInterpolator):
    """MPQ: particle domain corners are tracked as state and moved with the grid velocity.

    Mass, momentum and the particle update use the centre, ``phi_ip = S_i(x_p)`` (as SPQ). The
    internal force uses the domain form on the tracked corners, ``dphi_ip = sum_c S_i(x_c) D^-T s_c``
    with ``D = sum_c x_c s_c^T`` (``domain_gradient``; in 1D ``(S_i(c2) - S_i(c1)) / (c2 - c1)``).
    After the grid update every corner moves, ``x_c += dt sum_i S_i(x_c) v_i^{n+1}``, and ``F = D
    diag(1 / (2^dim r0))`` (``tracked_corner_update``): in 1D ``(x_c2 - x_c1) / (2 r0)``
    (Bonifasi-Lista, Brannon & Wiskin 2013, "Algorithm of MPQ"), in 2D and 3D the mean gradient of the
    map from the reference cube to the tracked corners, exact for a parallelogram (the corner tracking
    of CPDI2, Sadeghirad, Brannon & Guilkey 2013, which ``CPDI2`` implements). Neighbours meet at one
    corner, stored once, so domains stay contiguous.
    """

    name: ClassVar[str] = "mpq"
    tracks_corners: ClassVar[bool] = True
    stencil_width: ClassVar[int] = 4

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del r0, F
        idx, w, _ = points_stencil(grid, x, gradients=False)
        base = idx[:, :1] if grid.dim == 1 else None
        if not gradients:
            return Stencil(idx, w, None, None, None, base=base)
        if corners is None:
            raise ValueError("MPQ needs the particles' tracked corners for dphi")
        n, d = x.shape
        cidx, s, _ = points_stencil(grid, corners, gradients=False)  # (n, 2^d corners, 2^d nodes)
        st = domain_stencil(idx, w, cidx.reshape(n, -1), s, corner_matrix(corners))
        return st._replace(base=base, gbase=cidx[:, :, 0] if d == 1 else None)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del stencil
        return tracked_corner_update(grid, body, F, corners, v_new, dt)

    def extent(self, r0, x, F, corners):
        del r0, F
        if corners is None:  # a particle without tracked corners (an artificial one) queries at x
            return x, x
        if corners.shape[1] == 2:  # 1D: the corners are ordered, left then right
            return jnp.minimum(x, corners[:, 0]), jnp.maximum(x, corners[:, 1])
        parts = [x] + [corners[:, i] for i in range(corners.shape[1])]
        return functools.reduce(jnp.minimum, parts), functools.reduce(jnp.maximum, parts)
