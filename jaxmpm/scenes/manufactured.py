"""General manufactured solution in 1D: any displacement field, with its body force by autodiff."""

from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_finite, check_greater, check_nonnegative, check_positive, python_int
from .._util import as_float
from ..materials import AdiabaticGas, NeoHookean
from ._displacement import AbstractDisplacementScene

MODELS = ("neo-hookean", "gas")
ENDS = ("wall", "traction")


class Manufactured(AbstractDisplacementScene):
    """A bar moving as a prescribed displacement ``u(X, t)``, held to it by a body force.

    From ``u`` (a JAX function), autodiff gives ``F = 1 + du/dX``, ``v = du/dt``, ``a = d2u/dt2``,
    the stress ``sigma(F)`` of the model, and the body force that makes ``u`` exact,
    ``b = a - (1 / rho0) d sigma / dX`` (Lagrangian form, unit area; the method of manufactured
    solutions as Wallstedt & Guilkey, J. Comput. Phys. 227, 2008, apply it to MPM). The body starts
    at ``x = X + u(X, 0)`` with ``v = du/dt(X, 0)``.

    The default field is the standing wave ``u = A sin(pi X / L) sin(c pi t / L)``, ``c`` the model's
    wave speed at ``F = 1``: a period is ``2 L / c``. It vanishes at both ends, which are walls
    (``ends="wall"``). For a field that moves the ends, ``ends="traction"`` makes them free and loads
    them with the exact traction ``sigma n``.

    A different field: pass ``displacement_fn=u`` with ``u(scene, X, t) -> u`` (``X`` and ``u`` of
    shape ``(1,)``); read parameters from ``scene`` so that they stay differentiable.

    Attributes:
        A: amplitude of the default field (m).
        lam, mu: neo-Hookean constants (Pa).
        P0, gamma, p_atm: gas constants.
        h, rho0, cells, ppc, pad: as for every scene.
        model: ``"neo-hookean"`` (``sigma = lam ln(F)/F + mu (F - 1/F)``) or ``"gas"``
            (``P = P0 F^-gamma - p_atm``) (static).
        ends: ``"wall"`` or ``"traction"`` (static).
        displacement_fn: a field ``u(scene, X, t)`` to use instead of the default, or ``None`` (static).
    """

    name: ClassVar[str] = "manufactured"
    description: ClassVar[str] = (
        "1D manufactured solution, u = A sin(pi X/L) sin(c pi t/L), neo-Hookean or gas"
    )
    dim: ClassVar[int] = 1
    regions: ClassVar[None] = None
    smooth: ClassVar[None] = None

    A: Float[Array, ""] = eqx.field(converter=as_float, default=1.0e-4)
    lam: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    mu: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    P0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 16)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    model: str = eqx.field(static=True, default="neo-hookean")
    ends: str = eqx.field(static=True, default="wall")
    cells: int = eqx.field(static=True, default=16, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=2, converter=python_int)
    displacement_fn: Callable | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {self.model!r}")
        if self.ends not in ENDS:
            raise ValueError(f"ends must be one of {ENDS}, got {self.ends!r}")
        if self.displacement_fn is not None and not callable(self.displacement_fn):
            raise ValueError(
                f"displacement_fn must be a function u(scene, X, t) -> u, or None, got "
                f"{type(self.displacement_fn).__name__} {self.displacement_fn!r:.60}"
            )
        if self.displacement_fn is not None:  # its shape and type, from an abstract evaluation
            point = jax.ShapeDtypeStruct((self.dim,), self.h.dtype)
            time = jax.ShapeDtypeStruct((), self.h.dtype)
            out = jax.eval_shape(self.displacement_fn, self, point, time)
            if not hasattr(out, "shape") or out.shape != (self.dim,) or out.dtype != self.h.dtype:
                got = f"{out.dtype}{list(out.shape)}" if hasattr(out, "shape") else type(out).__name__
                raise ValueError(
                    f"displacement_fn(scene, X, t) must return the displacement at X, {self.h.dtype} of "
                    f"shape ({self.dim},) as X is, got {got}"
                )
        check_finite("A", self.A)
        # Both models' constants are checked whichever model runs: a bad value is refused, not
        # ignored because the other model would have used it.
        check_nonnegative("lam", self.lam)
        check_positive("mu", self.mu)
        check_positive("P0", self.P0)
        check_greater("gamma", self.gamma, 1.0)
        check_nonnegative("p_atm", self.p_atm)

    @property
    def left(self) -> str:
        """``"wall"`` with ``ends="wall"``, else ``"free"``."""
        return "wall" if self.ends == "wall" else "free"

    @property
    def right(self) -> str:
        """``"wall"`` with ``ends="wall"``, else ``"free"``."""
        return "wall" if self.ends == "wall" else "free"

    def material(self):
        if self.model == "gas":
            return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)
        return NeoHookean(lam=self.lam, mu=self.mu)

    def displacement(self, X, t):
        if self.displacement_fn is not None:
            return self.displacement_fn(self, X, t)
        L = self.length
        return self.A * jnp.sin(jnp.pi * X / L) * jnp.sin(self.wave_speed * jnp.pi * t / L)

    def _stress(self, X, t):
        return self.material().stress(self._F(X, t))

    def _flux(self, X, t):
        return self._stress(X, t)  # in 1D with unit area the Cauchy stress is the first Piola stress

    def initial_position(self, X: Float[ArrayLike, " 1"]) -> Float[Array, " 1"]:
        """The body at ``t = 0``, ``x = X + u(X, 0)``.

        Args:
            X: reference position of one material point.

        Returns:
            Its position at ``t = 0``.
        """
        return X + self.displacement(X, jnp.zeros((), X.dtype))

    def traction(
        self, t: Float[ArrayLike, ""]
    ) -> tuple[Float[Array, " 1"] | None, Float[Array, " 1"] | None]:
        """The exact traction ``sigma n`` at both ends with ``ends="traction"``; none with walls.

        Args:
            t: time.

        Returns:
            ``(left, right)``, each ``None`` with ``ends="wall"``.
        """
        if self.ends == "wall":
            return None, None
        zero = jnp.zeros((1,), dtype=self.h.dtype)
        left = -self._stress(zero, t)[:, 0]
        right = self._stress(zero + self.length, t)[:, 0]
        return left, right
