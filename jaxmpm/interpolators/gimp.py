"""Generalized interpolation material point (GIMP), Bardenhagen & Kober 2004."""

import functools
import operator
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._checks import check_bool, check_int, python_bool, python_int
from .._util import materialise
from ..shapes import hat, hat_integral
from ._base import AbstractInterpolator, Stencil
from ._transfer import multiplicative_F_update, tensor


class GIMP(AbstractInterpolator):
    """GIMP with an axis-aligned top-hat particle domain ``x_p + [-l, l]^dim`` (Bardenhagen & Kober 2004).

    Along each axis ``phi`` is the hat of node i averaged over ``[x_p - l, x_p + l]`` and its slope
    ``(S_i(x_p + l) - S_i(x_p - l)) / (2 l)``; in 2D and 3D the weight is the product of the axis
    averages and ``dphi`` along axis ``a`` the axis slope times the other axes' averages (the exact
    average over a box). ``F <- (I + dt sum_i v_i dphi_ip^T) F``. uGIMP keeps ``l_a = r0_a``;
    cpGIMP (contiguous particle GIMP) stretches each axis with the diagonal of ``F``, ``l_a = F_aa
    r0_a`` (the usual axis-aligned approximation of a deformed domain).

    The stencil has a fixed width of ``max_span + 2`` nodes per axis, which covers a domain no
    longer than ``max_span`` cells. A domain that outgrows it (cpGIMP under strong expansion) is a
    failure reported by the run's status, never a silent truncation.

    Attributes:
        contiguous: ``False`` for uGIMP, ``True`` for cpGIMP (static).
        max_span: the longest domain, in cells, that the stencil covers (static; cpGIMP's only:
            uGIMP's domains never outgrow a cell).
    """

    contiguous: bool = eqx.field(static=True, default=False, converter=python_bool)
    max_span: int = eqx.field(static=True, default=1, converter=python_int)
    tracks_corners: ClassVar[bool] = False

    @property
    def stencil_width(self) -> int:
        """``max_span + 2`` nodes per axis."""
        return self.max_span + 2

    def __check_init__(self):
        """Check the options.

        Raises:
            ValueError: ``contiguous`` is not ``True`` or ``False``, or ``max_span`` is not an
                integer >= 1 (a NumPy integer is one), or above 1 for uGIMP (whose domains, ``2 r0 =
                h / ppc``, never outgrow a cell: a wider stencil would do nothing).
        """
        check_bool("contiguous", self.contiguous)
        check_int("max_span", self.max_span, 1)
        if not self.contiguous and self.max_span > 1:
            raise ValueError(
                f"max_span={self.max_span} would do nothing for uGIMP (contiguous=False), whose domains "
                "keep their length, h / ppc, at most a cell: leave it at 1, or give contiguous=True (cpGIMP)"
            )

    @property
    def name(self) -> str:
        """``"cpgimp"`` for cpGIMP, ``"gimp"`` for uGIMP."""
        return "cpgimp" if self.contiguous else "gimp"

    def half_length(
        self, r0: Float[Array, "n dim"], F: Float[Array, "n dim dim"], axis: int = 0
    ) -> Float[Array, " n"]:
        """The domain's half-length along ``axis``: ``r0_a`` (uGIMP) or ``F_aa r0_a`` (cpGIMP).

        Args:
            r0: initial half-lengths of the particle domains.
            F: deformation gradients.
            axis: the axis.

        Returns:
            The half-length ``l_a`` of each particle's domain.
        """
        return r0[:, axis] * F[:, axis, axis] if self.contiguous else r0[:, axis]

    def _axis(self, grid, r0, x, F, axis, gradients):
        l = self.half_length(r0, F, axis)
        a = x[:, axis] - l
        b = x[:, axis] + l
        base, _ = grid.locate(a, axis)
        last, _ = grid.locate(b, axis)
        k = self.max_span + 2
        idx = base[:, None] + jnp.arange(k, dtype=base.dtype)[None, :]
        x_i = grid.x_min[axis] + idx.astype(x.dtype) * grid.h
        xi_a = (a[:, None] - x_i) / grid.h
        xi_b = (b[:, None] - x_i) / grid.h
        w = grid.h * (hat_integral(xi_b) - hat_integral(xi_a)) / (2.0 * l[:, None])
        dw = (hat(xi_b) - hat(xi_a)) / (2.0 * l[:, None]) if gradients else None
        # A domain exactly max_span cells long, with an end on a node, may reach past the stencil by
        # round-off in x +- l: the node it misses would get a weight of that round-off squared.
        x_last = grid.x_min[axis] + last.astype(x.dtype) * grid.h
        grazes = (last - base == self.max_span + 1) & (b - x_last <= 1e-9 * grid.h)
        return (idx, w, dw), (last - base <= self.max_span) | grazes

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del corners
        parts, oks = zip(*[self._axis(grid, r0, x, F, a, gradients) for a in range(x.shape[1])])
        if x.shape[1] > 1 and gradients:
            # Each axis's weights written once: fused into the tensor product, XLA's CPU backend
            # redoes an axis's piecewise-quadratic weights for every node and component of it.
            parts = [(i, materialise(w), None if dw is None else materialise(dw)) for i, w, dw in parts]
        idx, w, dw = tensor(grid, list(parts), gradients)
        ok = functools.reduce(operator.and_, oks)
        if not gradients:
            return Stencil(idx, w, None, None, ok)
        return Stencil(idx, w, idx, dw, ok)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del corners
        l = jnp.stack([self.half_length(r0, F, a) for a in range(x.shape[1])], axis=1)
        return x - l, x + l
