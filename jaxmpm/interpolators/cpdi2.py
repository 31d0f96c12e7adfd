"""Second-order convected particle domain interpolation, CPDI2 (Sadeghirad, Brannon & Guilkey 2013)."""

import functools
from typing import ClassVar

import jax.numpy as jnp

from ..particles import parallelogram_corners
from ._base import AbstractInterpolator, Stencil
from ._transfer import corner_matrix, domain_stencil, points_stencil, tracked_corner_update


class CPDI2(AbstractInterpolator):
    """CPDI2: each particle's domain is spanned by ``2^dim`` tracked corners (a segment in 1D, a
    quadrilateral in 2D, a hexahedron in 3D), stored once for all the particles that meet at them and
    moved with the grid velocity (Sadeghirad, Brannon & Guilkey 2013, "Second-order convected particle
    domain interpolation (CPDI2) with enrichment for weak discontinuities at material interfaces",
    IJNME 95).

    Every transfer goes through the domain. Mass, momentum, body force and the particle update use the
    corner average ``phi_ip = 2^-dim sum_c S_i(x_c)`` (as ``CPDI``); the internal force and the
    velocity gradient use ``dphi_ip = sum_c S_i(x_c) D^-T s_c`` with ``D = sum_c x_c s_c^T`` on the
    tracked corners (``domain_gradient``, as ``MPQ``). After the grid update each corner moves, ``x_c
    += dt sum_i S_i(x_c) v_i^{n+1}``, and ``F = D diag(1 / (2^dim r0))`` (``tracked_corner_update``,
    as ``MPQ``). The centre moves by ``dt sum_i phi_ip v_i^{n+1}``, the mean of its corners' moves, so
    a centre that starts at its corners' mean stays there.

    For a parallelogram (parallelepiped) domain both weights are the exact domain averages of the
    corner-interpolated shape functions. For any quadrilateral (2D) ``dphi`` is still the exact
    average of their gradient (``det D`` is four times the area, and ``D^-T s_c`` is the perpendicular
    of the diagonal joining corner ``c``'s two neighbours over twice the area), and ``V0 det F`` is the
    area; ``phi`` keeps equal corner weights, where the exact average would weight each corner by the
    integral of its bilinear function over the domain.

    Against ``CPDI``: there each domain is the parallelogram ``x_p + F diag(r0) [-1, 1]^dim`` of the
    particle's own ``F``, and neighbours can open gaps or overlap; here neighbours share corners and a
    domain may take any quadrilateral shape. In 1D a segment is a parallelogram and CPDI's update of
    ``x_p -/+ F r0`` is the corners' own, so where CPDI's segments start as the tracked corners
    (touching, each centre at its segment's midpoint: an undeformed start) the two agree to round-off;
    a body placed on a curve starts with each centre off its corners' mean, and they part. Against
    ``MPQ``: MPQ takes ``phi`` at the centre alone.

    A particle without tracked corners (an artificial particle, ``jaxmpm.boundaries``) gets the
    parallelogram of its ``x`` and ``F`` (``particles.parallelogram_corners``), CPDI's domain.
    """

    name: ClassVar[str] = "cpdi2"
    tracks_corners: ClassVar[bool] = True
    stencil_width: ClassVar[int] = 4

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        c = parallelogram_corners(r0, x, F) if corners is None else corners
        n, d = x.shape
        idx, s, _ = points_stencil(grid, c, gradients=False)  # (n, 2^d corners, 2^d nodes)
        base = idx[:, :, 0] if d == 1 else None  # in 1D each corner's two nodes are consecutive
        idx = idx.reshape(n, -1)
        w = (0.5**d) * s.reshape(n, -1)
        if not gradients:
            return Stencil(idx, w, None, None, None, base=base)
        return domain_stencil(idx, w, idx, s, corner_matrix(c))._replace(base=base, gbase=base)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del stencil
        return tracked_corner_update(grid, body, F, corners, v_new, dt)

    def extent(self, r0, x, F, corners):
        c = parallelogram_corners(r0, x, F) if corners is None else corners
        parts = [c[:, i] for i in range(c.shape[1])]
        return functools.reduce(jnp.minimum, parts), functools.reduce(jnp.maximum, parts)
