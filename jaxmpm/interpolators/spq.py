"""Single point query: standard MPM (Sulsky, Chen & Schreyer 1994)."""

from ._base import AbstractInterpolator, Stencil
from ._transfer import multiplicative_F_update, point_stencil


class SPQ(AbstractInterpolator):
    """Standard MPM: ``phi_ip = S_i(x_p)``, ``dphi_ip = S_i'(x_p)``, ``F <- (1 + dt grad v) F``."""

    name = "spq"

    def stencil(self, grid, r0, x, F, corners, gradients=True):
        del r0, F, corners
        idx, w, slope = point_stencil(grid, x[:, 0])
        if not gradients:
            return Stencil(idx, w, None, None, None)
        return Stencil(idx, w, idx, slope[..., None], None)

    def update_F(self, grid, body, stencil, F, corners, v_new, dt):
        del body
        return multiplicative_F_update(grid, stencil, F, v_new, dt), corners

    def extent(self, r0, x, F, corners):
        del r0, F, corners
        return x[:, 0], x[:, 0]
