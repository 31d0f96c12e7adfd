"""The isentropic Riemann problem of the adiabatic gas (the p-system), with its exact solution."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from .._checks import (
    check_finite,
    check_greater,
    check_int,
    check_nonnegative,
    check_positive,
    is_concrete,
    python_int,
)
from .._util import as_float
from ..exact import riemann_solution, riemann_waves, vacuum_forms
from ..materials import AdiabaticGas
from ._base import AbstractScene, check_point


class Riemann(AbstractScene):
    """Two uniform gas states meeting at ``X0 = L / 2``: ``(F_left, v_left)`` and ``(F_right, v_right)``.

    The body starts deformed, ``x(X, 0) = F_left X`` left of ``X0`` and continuing with slope
    ``F_right`` right of it, and the data break into a left and a right wave (each a rarefaction
    fan or a shock) around a star state ``(F*, v*)`` that ``jaxmpm.exact`` computes from the wave
    curves. Both ends are free and carry their state's traction, so the solution is exact there
    until a wave arrives (with uGIMP not from the first step: its undeformed domains do not see the
    left state's compression): ``t_valid`` is when the first wave reaches an end.

    The defaults are a shock tube: gas compressed to ``F = 0.5`` (pressure 2^1.4 = 2.64 times that
    on the right) next to gas at ``F = 1``, both at rest: a rarefaction runs left, a shock right.
    MPM rings behind a shock; ``simulate(..., viscosity=jm.ArtificialViscosity())`` damps it.

    Attributes:
        F_left, v_left, F_right, v_right: the two states.
        P0, gamma, p_atm, rho0: the gas (``p_atm`` shifts the pressure and changes nothing else).
        h, cells (even, so ``X0`` is a cell face), ppc, pad: as for every scene.
    """

    name: ClassVar[str] = "riemann"
    description: ClassVar[str] = (
        "1D isentropic gas Riemann problem (p-system), exact star state, fans and shocks"
    )
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "free"
    right: ClassVar[str] = "free"
    regions: ClassVar[None] = None
    body_force: ClassVar[None] = None

    F_left: Float[Array, ""] = eqx.field(converter=as_float, default=0.5)
    v_left: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    F_right: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    v_right: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    P0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 64)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=64, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=8, converter=python_int)

    def __check_init__(self):
        """Check the parameters, each by its own name, before the derived quantities that combine
        them (the states' pressures and sound speeds, the vacuum condition, the star state).

        Raises:
            ValueError: ``cells`` is not an even integer >= 2; ``P0``, ``rho0``, ``F_left`` or
                ``F_right`` is not finite and > 0; ``gamma`` is not finite and > 1; ``p_atm`` is not
                finite and >= 0; ``v_left`` or ``v_right`` is not finite; a state's pressure ``P0
                F^-gamma`` or sound speed is not finite and > 0 in the float dtype (naming the
                parameters that give it); a vacuum forms between the states; the star state or a
                wave speed is not finite (naming every parameter). Tracers are not checked.
        """
        check_int("cells", self.cells, 2)
        if self.cells % 2:
            raise ValueError(f"cells must be even (X0 = L/2 is a cell face), got {self.cells}")
        # The gas before the states: with P0 = 0, gamma < 1 or rho0 = inf the sound speeds vanish or
        # change sign, and the vacuum condition below would hold for any velocities.
        check_positive("P0", self.P0)
        check_greater("gamma", self.gamma, 1.0)
        check_positive("rho0", self.rho0)
        check_nonnegative("p_atm", self.p_atm)
        check_positive("F_left", self.F_left)
        check_positive("F_right", self.F_right)
        check_finite("v_left", self.v_left)
        check_finite("v_right", self.v_right)
        args = self._args()
        if not all(is_concrete(a) for a in args):
            return
        self._check_states()
        vacuum = vacuum_forms(*args)
        if is_concrete(vacuum) and bool(vacuum):
            raise ValueError(
                "v_right - v_left must be below 2 (c(F_left) + c(F_right)) / (gamma - 1), or a vacuum "
                f"forms between the states; got v_left={float(self.v_left)}, v_right={float(self.v_right)}"
            )
        self._check_waves()

    def _check_states(self):
        """Each state's pressure ``P0 F^-gamma`` and sound speed, finite and > 0 in the float dtype."""
        for side, name in (("left", "F_left"), ("right", "F_right")):
            F = getattr(self, name)
            p = self.P0 * F ** (-self.gamma)
            c = jnp.sqrt(self.gamma * self.P0 * F ** (1.0 - self.gamma) / self.rho0)
            if not (is_concrete(p) and is_concrete(c)):
                return
            if not (jnp.isfinite(p) and p > 0 and jnp.isfinite(c) and c > 0):
                raise ValueError(
                    f"{name}={float(F)!r} with P0={float(self.P0)!r}, gamma={float(self.gamma)!r} and "
                    f"rho0={float(self.rho0)!r} gives the {side} state a pressure P0 {name}^-gamma = "
                    f"{float(p)!r} and a sound speed {float(c)!r} in {F.dtype}; both must be finite and > 0"
                )

    def _check_waves(self):
        """The star state and the wave speeds, finite (``F*`` > 0)."""
        w = riemann_waves(*self._args())
        values = [w[k] for k in ("F_star", "v_star", "a1", "b1", "a2", "b2")]
        if not all(is_concrete(v) for v in values):
            return
        if not (all(bool(jnp.isfinite(v)) for v in values) and w["F_star"] > 0):
            given = ", ".join(
                f"{k}={float(getattr(self, k))!r}"
                for k in ("F_left", "v_left", "F_right", "v_right", "P0", "gamma", "rho0")
            )
            raise ValueError(
                f"{given} give no finite star state and wave speeds in {self.P0.dtype} (F*="
                f"{float(w['F_star'])!r}, v*={float(w['v_star'])!r}, speeds "
                f"{[float(v) for v in values[2:]]}); they must be finite, with F* > 0"
            )

    def _args(self):
        return (self.F_left, self.v_left, self.F_right, self.v_right, self.P0, self.gamma, self.rho0)

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)

    @property
    def X0(self) -> Float[Array, ""]:
        """Where the two states meet, ``L / 2``."""
        return 0.5 * self.length

    def waves(self) -> dict[str, Array]:
        """Star state and wave speeds.

        Returns:
            The dict of ``jaxmpm.exact.riemann_waves``.
        """
        return riemann_waves(*self._args())

    @property
    def t_valid(self) -> Float[Array, ""]:
        """When the fastest wave reaches an end of the body (the exact solution holds until then)."""
        w = self.waves()
        return jnp.minimum(self.X0 / -w["a1"], (self.length - self.X0) / w["b2"])

    def initial_position(self, X: Float[ArrayLike, " 1"]) -> Float[Array, " 1"]:
        """The deformed start: ``F_left X`` left of ``X0``, continuing with slope ``F_right``.

        Args:
            X: reference position of one material point.

        Returns:
            Its position at ``t = 0``.
        """
        return jnp.where(X < self.X0, self.F_left * X, self.F_left * self.X0 + self.F_right * (X - self.X0))

    def initial_velocity(self, X):
        return jnp.where(X < self.X0, self.v_left, self.v_right) * jnp.ones_like(X)

    def _stress(self, F):
        return self.material().stress(jnp.reshape(F, (1, 1)))[:, 0]

    def traction(self, t: Float[ArrayLike, ""]) -> tuple[Float[Array, " 1"], Float[Array, " 1"]]:
        """Each end's state's traction ``sigma n``, exact until a wave reaches the end.

        Args:
            t: time.

        Returns:
            ``(left, right)``.
        """
        del t
        return -self._stress(self.F_left), self._stress(self.F_right)

    def exact(self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact self-similar solution at one material point (``jaxmpm.exact.riemann_solution``).

        Args:
            X: reference position.
            t: time.

        Returns:
            ``dict(x, v, F, sigma)``.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)``.
        """
        X = check_point(X, 1)
        positive = t > 0
        ts = jnp.where(positive, t, 1.0)
        xi = jnp.where(positive, (X[0] - self.X0) / ts, jnp.where(X[0] < self.X0, -jnp.inf, jnp.inf))
        F, v, D = riemann_solution(xi, *self._args())
        D = jnp.where(positive, D, 0.0)
        x = self.initial_position(X) + (self.v_left + D) * t
        F_mat = jnp.reshape(F, (1, 1))
        return dict(x=x, v=jnp.reshape(v, (1,)), F=F_mat, sigma=self.material().stress(F_mat))

    def smooth(
        self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""], margin: float = 0.05
    ) -> Bool[Array, ""]:
        """Whether a particle is farther than ``margin L`` (reference length) from every wave edge.

        Args:
            X: reference position.
            t: time.
            margin: the distance, as a fraction of ``L``.

        Returns:
            ``True`` away from the waves' edges.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)``.
        """
        X = check_point(X, 1)
        w = self.waves()
        edges = jnp.stack([w["a1"], w["b1"], w["a2"], w["b2"]]) * t + self.X0
        return jnp.all(jnp.abs(X[0] - edges) > margin * self.length)

    def star(
        self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""], margin: float = 0.05
    ) -> tuple[Bool[Array, ""], Bool[Array, ""]]:
        """Whether a particle is in the star region, farther than ``margin L`` from the waves bounding it.

        Args:
            X: reference position.
            t: time.
            margin: the distance, as a fraction of ``L``.

        Returns:
            ``(left, right)``: in the star region left and right of ``X0`` (on the two sides the gas
            went through different waves).
        """
        w = self.waves()
        xi_lo, xi_hi = self.X0 + w["b1"] * t, self.X0 + w["a2"] * t
        inside = (X[0] > xi_lo + margin * self.length) & (X[0] < xi_hi - margin * self.length)
        return inside & (X[0] < self.X0), inside & (X[0] > self.X0)
