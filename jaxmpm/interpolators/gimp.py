"""Generalized interpolation material point (GIMP), Bardenhagen & Kober 2004."""

import equinox as eqx
import jax.numpy as jnp

from ..shapes import hat, hat_integral
from ._base import AbstractInterpolator, Stencil
from ._transfer import multiplicative_F_update


class GIMP(AbstractInterpolator):
    """GIMP with a top-hat particle domain ``[x_p - l, x_p + l]`` (Bardenhagen & Kober 2004).

    ``phi_ip`` is the hat of node i averaged over the domain, ``dphi_ip = (S_i(x_p + l) -
    S_i(x_p - l)) / (2 l)`` its derivative in ``x_p``; ``F <- (1 + dt sum_i dphi_ip v_i) F``.
    uGIMP keeps ``l = r0``; cpGIMP (contiguous particle GIMP) uses ``l = F r0``.

    The stencil has a fixed width of ``max_span + 2`` nodes, which covers a domain no longer than
    ``max_span`` cells. A domain that outgrows it (cpGIMP under strong expansion) is a failure
    reported by the run's status, never a silent truncation.

    Attributes:
        contiguous: ``False`` for uGIMP, ``True`` for cpGIMP (static).
        max_span: the longest domain, in cells, that the stencil covers (static).
    """

    contiguous: bool = eqx.field(static=True, default=False)
    max_span: int = eqx.field(static=True, default=1)

    def __check_init__(self):
        if isinstance(self.max_span, bool) or not isinstance(self.max_span, int) or self.max_span < 1:
            raise ValueError(f"max_span must be an integer >= 1, got {self.max_span!r}")

    @property
    def name(self) -> str:  # type: ignore[override]
        return "cpgimp" if self.contiguous else "gimp"

    def half_length(self, r0, F):
        return r0[:, 0] * F[:, 0, 0] if self.contiguous else r0[:, 0]

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del corners
        l = self.half_length(r0, F)
        a = x[:, 0] - l
        b = x[:, 0] + l
        base, _ = grid.locate(a)
        last, _ = grid.locate(b)
        k = self.max_span + 2
        idx = base[:, None] + jnp.arange(k, dtype=base.dtype)[None, :]
        x_i = grid.x_min[0] + idx.astype(x.dtype) * grid.h
        xi_a = (a[:, None] - x_i) / grid.h
        xi_b = (b[:, None] - x_i) / grid.h
        w = grid.h * (hat_integral(xi_b) - hat_integral(xi_a)) / (2.0 * l[:, None])
        ok = last - base <= self.max_span
        if not gradients:
            return Stencil(idx, w, None, None, ok)
        dw = (hat(xi_b) - hat(xi_a)) / (2.0 * l[:, None])
        return Stencil(idx, w, idx, dw[..., None], ok)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del corners
        l = self.half_length(r0, F)
        return x[:, 0] - l, x[:, 0] + l
