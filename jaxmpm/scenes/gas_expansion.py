"""The talk's adiabatic gas expansion with a manufactured solution (SPEC section 6.1)."""

import equinox as eqx
import jax.numpy as jnp

from .._checks import check_finite
from .._util import as_float
from ..materials import AdiabaticGas
from ._base import AbstractScene


class GasExpansion(AbstractScene):
    """Gas on ``[0, L]`` expanding as ``u = beta t X`` (Bonifasi-Lista, Brannon & Wiskin 2013).

    Exact solution: ``x = (1 + beta t) X``, ``F = 1 + beta t``, ``v = beta X``, ``a = 0``,
    ``P = P0 F^-gamma - p_atm`` uniform, no body force. Both ends are free and carry the traction
    the solution implies, ``t = sigma(t) n``, so every nodal acceleration vanishes at ``t = 0``.

    The defaults (SI units) make the talk's times meaningful: with ``beta = 200 /s``, ``F`` grows to
    1.02 by ``t = 0.0001`` and to 1.25 by ``t = 0.00125``. The gas is at 2 bar against 1 bar of
    atmosphere; its sound speed at ``F = 1`` is about 529 m/s, so ``dt = 1e-5`` is a CFL number
    ``dt (c + |v|) / h`` of about 0.06. A stiffer gas (``P0 = 1e6``) turns the kinematic errors of
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
    """

    name = "gas-expansion"
    description = "1D adiabatic gas expansion, u = beta t X (the talk's manufactured solution)"

    beta: jnp.ndarray = eqx.field(converter=as_float, default=200.0)
    h: jnp.ndarray = eqx.field(converter=as_float, default=0.125)
    P0: jnp.ndarray = eqx.field(converter=as_float, default=2.0e5)
    gamma: jnp.ndarray = eqx.field(converter=as_float, default=1.4)
    p_atm: jnp.ndarray = eqx.field(converter=as_float, default=1.0e5)
    rho0: jnp.ndarray = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=8)
    ppc: int = eqx.field(static=True, default=2)
    pad: int = eqx.field(static=True, default=10)

    def __check_init__(self):
        check_finite("beta", self.beta)

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)

    def initial_velocity(self, X):
        return self.beta * X

    def exact(self, X, t):
        F = 1.0 + self.beta * t
        F_mat = jnp.reshape(F, (1, 1)) * jnp.ones((1, 1), dtype=X.dtype)
        return dict(x=F * X, v=self.beta * X, F=F_mat, sigma=self.material().stress(F_mat))

    def traction(self, t):
        F = jnp.reshape(1.0 + self.beta * t, (1, 1))
        sigma = self.material().stress(F)[0]  # (dim,)
        return -sigma, sigma
