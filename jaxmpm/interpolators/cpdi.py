"""Convected particle domain interpolation, 1D (Sadeghirad, Brannon & Burghardt 2011)."""

import jax.numpy as jnp

from ._base import AbstractInterpolator, Stencil
from ._transfer import multiplicative_F_update, point_stencil


class CPDI(AbstractInterpolator):
    """CPDI in 1D: corners ``c1,2 = x_p -/+ F r0`` follow from ``F`` (Sadeghirad et al. 2011, eq. 31).

    ``phi_ip = (S_i(c1) + S_i(c2)) / 2``, ``dphi_ip = (S_i(c2) - S_i(c1)) / (c2 - c1)``, and
    ``F <- F + dt / (2 r0) sum_i (S_i(c2) - S_i(c1)) v_i``, which equals ``(1 + dt grad v) F``
    because ``c2 - c1 = 2 F r0``.
    """

    name = "cpdi"

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del corners
        half = r0[:, 0] * F[:, 0, 0]
        c = jnp.stack([x[:, 0] - half, x[:, 0] + half], axis=1)  # (n, 2)
        idx, s, _ = point_stencil(grid, c)  # (n, 2 corners, 2 nodes)
        n = x.shape[0]
        idx = idx.reshape(n, 4)
        w = 0.5 * s.reshape(n, 4)
        if not gradients:
            return Stencil(idx, w, None, None, None)
        sign = jnp.asarray([-1.0, -1.0, 1.0, 1.0], dtype=x.dtype)
        dw = sign[None, :] * s.reshape(n, 4) / (2.0 * half[:, None])
        return Stencil(idx, w, idx, dw[..., None], None)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del corners
        half = r0[:, 0] * F[:, 0, 0]
        return x[:, 0] - half, x[:, 0] + half
