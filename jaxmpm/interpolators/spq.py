"""Single point query: standard MPM (Sulsky, Chen & Schreyer 1994)."""

from typing import ClassVar

from ._base import AbstractInterpolator, Stencil
from ._transfer import multiplicative_F_update, points_stencil


class SPQ(AbstractInterpolator):
    """Standard MPM: ``phi_ip = S_i(x_p)``, ``dphi_ip = grad S_i(x_p)``, ``F <- (I + dt grad v) F``."""

    name: ClassVar[str] = "spq"
    tracks_corners: ClassVar[bool] = False
    stencil_width: ClassVar[int] = 2

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del r0, F, corners
        idx, w, dw = points_stencil(grid, x, gradients)
        base = idx[:, :1] if grid.dim == 1 else None
        if not gradients:
            return Stencil(idx, w, None, None, None, base=base)
        return Stencil(idx, w, idx, dw, None, base=base, gbase=base)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del r0, F, corners
        return x, x
