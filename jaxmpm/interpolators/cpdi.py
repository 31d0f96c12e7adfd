"""Convected particle domain interpolation (Sadeghirad, Brannon & Burghardt 2011), CPDI1."""

import functools
from typing import ClassVar

import jax.numpy as jnp

from ..particles import parallelogram_corners
from ._base import AbstractInterpolator, Stencil
from ._transfer import domain_stencil, multiplicative_F_update, points_stencil


class CPDI(AbstractInterpolator):
    """CPDI with parallelogram domains that follow ``F`` (Sadeghirad, Brannon & Burghardt 2011).

    The domain is ``x_p + F diag(r0) [-1, 1]^dim`` with corners ``x_c = x_p + F diag(r0) s_c``
    (``particles.parallelogram_corners``); ``phi_ip = 2^-dim sum_c S_i(x_c)`` and ``dphi_ip = sum_c
    S_i(x_c) D^-T s_c`` with ``D = 2^dim F diag(r0)`` (see ``domain_gradient``); ``F <- (I + dt
    sum_i v_i dphi_ip^T) F``. In 1D the corners are ``x_p -/+ F r0`` (their eq. 31) and ``dphi_ip =
    (S_i(c2) - S_i(c1)) / (c2 - c1)``, so the update is ``F + dt / (2 r0) sum_i (S_i(c2) - S_i(c1))
    v_i``. Neighbouring domains are built from each particle's own ``F``: they can open gaps or
    overlap (``metrics.corner_gap``).
    """

    name: ClassVar[str] = "cpdi"
    tracks_corners: ClassVar[bool] = False
    stencil_width: ClassVar[int] = 4

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del corners
        n, d = x.shape
        if d == 1:  # the segment x_p -/+ F r0, written directly (measured faster than the general form)
            half = r0[:, 0] * F[:, 0, 0]
            c = jnp.stack([x[:, 0] - half, x[:, 0] + half], axis=1)[..., None]
            D = (2.0 * half)[:, None, None]
        else:
            c = parallelogram_corners(r0, x, F)
            D = (2.0**d) * (F * r0[:, None, :])
        idx, s, _ = points_stencil(grid, c, gradients=False)  # (n, 2^d corners, 2^d nodes)
        base = idx[:, :, 0] if d == 1 else None  # in 1D each corner's two nodes are consecutive
        idx = idx.reshape(n, -1)
        w = (0.5**d) * s.reshape(n, -1)
        if not gradients:
            return Stencil(idx, w, None, None, None, base=base)
        return domain_stencil(idx, w, idx, s, D)._replace(base=base, gbase=base)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del corners
        if x.shape[1] == 1:
            half = r0 * F[:, :, 0]
            return x - half, x + half
        c = parallelogram_corners(r0, x, F)
        parts = [c[:, i] for i in range(c.shape[1])]
        return functools.reduce(jnp.minimum, parts), functools.reduce(jnp.maximum, parts)
