"""Multi point query (Bonifasi-Lista, Brannon & Wiskin, 7th MPM Workshop 2013)."""

import jax.numpy as jnp

from .._util import contract
from ._base import AbstractInterpolator, Stencil
from ._transfer import point_stencil


class MPQ(AbstractInterpolator):
    """MPQ: particle domain corners are tracked as state and moved with the grid velocity.

    Mass, momentum and the particle update use the centre, ``phi_ip = S_i(x_p)`` (as SPQ). The
    internal force uses the domain form ``dphi_ip = (S_i(c2) - S_i(c1)) / (c2 - c1)`` on the tracked
    corners. After the grid update every corner moves, ``x_c += dt sum_i S_i(x_c) v_i^{n+1}``, and
    ``F = (x_c2 - x_c1) / (2 r0)`` (talk, "Algorithm of MPQ"). Neighbours share a corner, stored
    once, so domains stay contiguous.
    """

    name = "mpq"
    tracks_corners = True

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del r0, F
        idx, w, _ = point_stencil(grid, x[:, 0])
        if not gradients:
            return Stencil(idx, w, None, None, None)
        if corners is None:
            raise ValueError("MPQ needs the particles' tracked corners for dphi")
        c = corners[:, :, 0]  # (n, 2)
        cidx, s, _ = point_stencil(grid, c)
        n = x.shape[0]
        sign = jnp.asarray([-1.0, -1.0, 1.0, 1.0], dtype=x.dtype)
        dw = sign[None, :] * s.reshape(n, 4) / (c[:, 1:2] - c[:, 0:1])
        return Stencil(idx, w, cidx.reshape(n, 4), dw[..., None], None)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del stencil, F
        cidx, s, _ = point_stencil(grid, corners[:, 0])
        v_c = contract("ck,ckd->cd", s, grid.gather(cidx, v_new))
        corners = corners + dt * v_c
        c = body.particle_corners(corners)  # (n, 2, dim)
        F = ((c[:, 1, 0] - c[:, 0, 0]) / (2.0 * body.r0[:, 0]))[:, None, None]
        return F, corners

    def extent(self, r0, x, F, corners):
        del r0, F
        return jnp.minimum(x[:, 0], corners[:, 0, 0]), jnp.maximum(x[:, 0], corners[:, 1, 0])
