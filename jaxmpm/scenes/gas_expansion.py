"""Adiabatic gas expansion with a manufactured solution, ``u = beta t X`` (Bonifasi-Lista, Brannon &
Wiskin 2013)."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_finite, python_int
from .._util import as_float
from ..materials import AdiabaticGas
from ._base import AbstractScene, check_point


class GasExpansion(AbstractScene):
    """Gas on ``[0, L]^dim`` expanding as ``u = beta t X`` (Bonifasi-Lista, Brannon & Wiskin 2013).

    Exact solution: ``x = (1 + beta t) X``, ``F = (1 + beta t) I``, ``v = beta X``, ``a = 0``,
    ``P = P0 J^-gamma - p_atm`` uniform with ``J = (1 + beta t)^dim``, no body force. Every face is
    free and carries the traction the solution implies, ``P N`` per unit reference area with the
    first Piola stress ``P = J sigma F^-T = (1 + beta t)^(dim - 1) sigma`` (in 1D ``sigma n``), so
    every nodal acceleration vanishes at ``t = 0``. Along each axis the first step is the 1D one:
    boundary cells ``5/8``, interior and artificial cells exact.

    The defaults (SI units) make the times of Bonifasi-Lista et al. meaningful: with ``beta = 200
    /s``, ``F`` grows to 1.02 by ``t = 0.0001`` and to 1.25 by ``t = 0.00125``. The gas is at 2 bar
    against 1 bar of atmosphere; its sound speed at ``F = 1`` is about 529 m/s, so ``dt = 1e-5`` is a
    CFL number ``dt (c + |v|) / h`` of about 0.06. A stiffer gas (``P0 = 1e6``) turns the kinematic errors of
    SPQ and uGIMP into pressure waves that dominate everything else by ``t = 0.00125``.

    Attributes:
        beta: velocity gradient (1/s).
        h: grid spacing (m); the body is ``cells h`` long.
        P0: absolute pressure at ``F = 1`` (Pa).
        gamma: adiabatic exponent (> 1).
        p_atm: ambient pressure (Pa).
        rho0: initial density (kg/m^3).
        cells: cells the body fills initially (static).
        ppc: particles per cell (static).
        pad: empty cells on each side of the body (static).
        dim: 1, 2 or 3; the body is a square or cube of ``cells^dim`` cells (static).
    """

    name: ClassVar[str] = "gas-expansion"
    description: ClassVar[str] = (
        "adiabatic gas expansion, u = beta t X (the talk's manufactured solution), dim 1-3"
    )
    left: ClassVar[str] = "free"
    right: ClassVar[str] = "free"
    regions: ClassVar[None] = None
    body_force: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    beta: Float[Array, ""] = eqx.field(converter=as_float, default=200.0)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=0.125)
    P0: Float[Array, ""] = eqx.field(converter=as_float, default=2.0e5)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float, default=1.0e5)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=8, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=10, converter=python_int)
    dim: int = eqx.field(static=True, default=1, converter=python_int)

    def __check_init__(self):
        check_finite("beta", self.beta)

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)

    def initial_velocity(self, X):
        return self.beta * X

    def exact(self, X: Float[ArrayLike, " dim"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact fields of one material point.

        Args:
            X: reference position.
            t: time.

        Returns:
            ``dict(x, v, F, sigma)``: ``x = (1 + beta t) X``, ``v = beta X``, ``F = (1 + beta t) I``
            and the gas's stress at that ``F``.

        Raises:
            ValueError: ``X`` is not of shape ``(dim,)``.
        """
        X = check_point(X, self.dim)
        F = 1.0 + self.beta * t
        if self.dim == 1:
            F_mat = jnp.reshape(F, (1, 1)) * jnp.ones((1, 1), dtype=X.dtype)
        else:
            F_mat = F * jnp.eye(self.dim, dtype=X.dtype)
        return dict(x=F * X, v=self.beta * X, F=F_mat, sigma=self.material().stress(F_mat))

    def traction(self, t: Float[ArrayLike, ""]) -> tuple[Float[Array, " dim"], ...]:
        """The traction the exact solution implies on every face, ``P N``.

        Args:
            t: time.

        Returns:
            One traction vector per face: low and high face of axis 0, then of axis 1, ...
        """
        f = 1.0 + self.beta * t
        if self.dim == 1:
            sigma = self.material().stress(jnp.reshape(f, (1, 1)))[0]  # (dim,)
            return -sigma, sigma
        P = f ** (self.dim - 1) * self.material().stress(f * jnp.eye(self.dim, dtype=self.h.dtype))
        out = []
        for a in range(self.dim):  # P N with N = -e_a, +e_a
            out += [-P[:, a], P[:, a]]
        return tuple(out)
