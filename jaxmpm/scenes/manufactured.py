"""General manufactured solution: any displacement field, with its body force by autodiff (SPEC 6.2)."""

import abc
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .._checks import check_finite, check_nonnegative, check_positive
from .._util import as_float
from ..materials import AdiabaticGas, NeoHookean
from ._base import AbstractScene

MODELS = ("neo-hookean", "gas")
ENDS = ("wall", "traction")


class AbstractDisplacementScene(AbstractScene):
    """A scene moving as a prescribed displacement ``u(X, t)`` (a method ``displacement``), held to it
    by the body force ``b = a - (1 / rho0) Div_X P`` with the stress ``P = _flux(X, t)``; ``F``,
    ``v``, ``a`` and the divergence by autodiff (SPEC 6.2)."""

    @abc.abstractmethod
    def displacement(self, X, t):
        """``u(X, t)``, shape ``(dim,)``."""

    @abc.abstractmethod
    def _flux(self, X, t):
        """The first Piola stress at ``(X, t)``, whose divergence the body force balances."""

    def _F(self, X, t):
        return jnp.eye(X.shape[0], dtype=X.dtype) + jax.jacfwd(self.displacement)(X, t)

    def _velocity(self, X, t):
        return jax.jacfwd(self.displacement, argnums=1)(X, t)

    def initial_velocity(self, X):
        return self._velocity(X, jnp.zeros((), X.dtype))

    def body_force(self, X, t):
        a = jax.jacfwd(self._velocity, argnums=1)(X, t)
        div = jnp.einsum("abb->a", jax.jacfwd(self._flux)(X, t))  # d P_aB / dX_B
        return a - div / self.rho0

    def exact(self, X, t):
        F = self._F(X, t)
        return dict(
            x=X + self.displacement(X, t),
            v=self._velocity(X, t),
            F=F,
            sigma=self.material().stress(F),
        )


class Manufactured(AbstractDisplacementScene):
    """A body moving as a prescribed displacement ``u(X, t)``, held to it by a body force.

    From ``u`` (a JAX function), autodiff gives ``F = 1 + du/dX``, ``v = du/dt``, ``a = d2u/dt2``,
    the stress ``sigma(F)`` of the model, and the body force that makes ``u`` exact,
    ``b = a - (1 / rho0) d sigma / dX`` (Lagrangian form, unit area; SPEC 6.2). The body starts at
    ``x = X + u(X, 0)`` with ``v = du/dt(X, 0)``.

    The default field is the standing wave ``u = A sin(pi X / L) sin(c pi t / L)``, ``c`` the model's
    wave speed at ``F = 1``: a period is ``2 L / c``. It vanishes at both ends, which are walls
    (``ends="wall"``). For a field that moves the ends, ``ends="traction"`` makes them free and loads
    them with the exact traction ``sigma n``.

    A different field: pass ``displacement=u`` with ``u(scene, X, t) -> u`` (``X`` and ``u`` of shape
    ``(1,)``), or subclass and override ``displacement``; read parameters from ``scene`` so that they
    stay differentiable.

    Attributes:
        A: amplitude of the default field (m).
        model: ``"neo-hookean"`` (``sigma = lam ln(F)/F + mu (F - 1/F)``) or ``"gas"``
            (``P = P0 F^-gamma - p_atm``) (static).
        lam, mu: neo-Hookean constants (Pa).
        P0, gamma, p_atm: gas constants.
        ends: ``"wall"`` or ``"traction"`` (static).
        displacement_fn: a field ``u(scene, X, t)`` to use instead of the default, or ``None`` (static).
        h, rho0, cells, ppc, pad: as for every scene.
    """

    name = "manufactured"
    description = "1D manufactured solution, u = A sin(pi X/L) sin(c pi t/L), neo-Hookean or gas"

    A: jnp.ndarray = eqx.field(converter=as_float, default=1.0e-4)
    lam: jnp.ndarray = eqx.field(converter=as_float, default=1.0)
    mu: jnp.ndarray = eqx.field(converter=as_float, default=1.0)
    P0: jnp.ndarray = eqx.field(converter=as_float, default=1.0)
    gamma: jnp.ndarray = eqx.field(converter=as_float, default=1.4)
    p_atm: jnp.ndarray = eqx.field(converter=as_float, default=0.0)
    h: jnp.ndarray = eqx.field(converter=as_float, default=1.0 / 16)
    rho0: jnp.ndarray = eqx.field(converter=as_float, default=1.0)
    model: str = eqx.field(static=True, default="neo-hookean")
    ends: str = eqx.field(static=True, default="wall")
    cells: int = eqx.field(static=True, default=16)
    ppc: int = eqx.field(static=True, default=2)
    pad: int = eqx.field(static=True, default=2)
    displacement_fn: Callable | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {self.model!r}")
        if self.ends not in ENDS:
            raise ValueError(f"ends must be one of {ENDS}, got {self.ends!r}")
        check_finite("A", self.A)
        check_nonnegative("lam", self.lam)
        check_positive("mu", self.mu)

    @property
    def left(self):
        return "wall" if self.ends == "wall" else "free"

    @property
    def right(self):
        return "wall" if self.ends == "wall" else "free"

    def material(self):
        if self.model == "gas":
            return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)
        return NeoHookean(lam=self.lam, mu=self.mu)

    def displacement(self, X, t):
        """``u(X, t)``, shape ``(1,)``."""
        if self.displacement_fn is not None:
            return self.displacement_fn(self, X, t)
        L = self.length
        return self.A * jnp.sin(jnp.pi * X / L) * jnp.sin(self.wave_speed * jnp.pi * t / L)

    def _stress(self, X, t):
        return self.material().stress(self._F(X, t))

    def _flux(self, X, t):
        return self._stress(X, t)  # in 1D with unit area the Cauchy stress is the first Piola stress

    def initial_position(self, X):
        return X + self.displacement(X, jnp.zeros((), X.dtype))

    def traction(self, t):
        if self.ends == "wall":
            return None, None
        zero = jnp.zeros((1,), dtype=self.h.dtype)
        left = -self._stress(zero, t)[:, 0]
        right = self._stress(zero + self.length, t)[:, 0]
        return left, right
