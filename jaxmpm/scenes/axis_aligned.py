"""The axis-aligned manufactured solution of Wallstedt & Guilkey (2008), in 1D, 2D and 3D."""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._checks import check_finite, check_nonnegative, check_positive, python_int
from .._util import as_float
from ..materials import NeoHookean
from ._displacement import AbstractDisplacementScene


class AxisAligned(AbstractDisplacementScene):
    """A neo-Hookean box moving as ``u_a = A sin(2 pi X_a / L) sin(c pi t / L + a pi)`` along every axis.

    The axis-aligned displacement field of Wallstedt & Guilkey, "An evaluation of explicit time
    integration schemes for use with the generalized interpolation material point method" (J.
    Comput. Phys. 227, 2008), the one Uintah's MPM ships as its "AxisAligned" manufactured solution:
    each component depends on its own coordinate only, the second axis half a period out of phase.
    ``F = I + du/dX`` is diagonal, the stress of the compressible neo-Hookean model ``sigma = (lam
    ln J I + mu (B - I)) / J`` too, and the body force that makes ``u`` exact, ``b = a - (1 / rho0)
    Div_X P`` with the first Piola stress ``P = dW/dF``, comes by autodiff. ``c`` is the model's
    wave speed at rest, so ``t = L / c`` is half a period.

    ``u_a`` vanishes on the faces ``X_a = 0`` and ``X_a = L`` while the other components move along
    them and the shear stress there is zero: every face is a roller (``"symmetry"``, the normal
    velocity held at zero). In 1D that is a bar with both ends fixed.

    Attributes:
        A: amplitude (m); ``2 pi A / L`` is the largest strain (0.31 by default: large deformation).
        lam, mu: neo-Hookean constants (Pa).
        h, rho0, cells, ppc, pad: as for every scene; the box is ``L = cells h`` wide.
        dim: 1, 2 or 3 (static).
    """

    name: ClassVar[str] = "axis-aligned"
    description: ClassVar[str] = (
        "axis-aligned manufactured solution (Wallstedt & Guilkey 2008), neo-Hookean, dim 1-3"
    )
    left: ClassVar[str] = "symmetry"
    right: ClassVar[str] = "symmetry"
    regions: ClassVar[None] = None
    traction: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    A: Float[Array, ""] = eqx.field(converter=as_float, default=0.05)
    lam: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    mu: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 16)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=16, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=2, converter=python_int)
    dim: int = eqx.field(static=True, default=2, converter=python_int)

    def __check_init__(self):
        check_finite("A", self.A)
        check_nonnegative("lam", self.lam)
        check_positive("mu", self.mu)

    def material(self):
        return NeoHookean(lam=self.lam, mu=self.mu)

    def displacement(self, X, t):
        L = self.length
        phase = jnp.pi * jnp.arange(self.dim, dtype=X.dtype)
        return self.A * jnp.sin(2.0 * jnp.pi * X / L) * jnp.sin(self.wave_speed * jnp.pi * t / L + phase)

    def _flux(self, X, t):
        return jax.grad(self.material().energy_density)(self._F(X, t))  # P = dW/dF
