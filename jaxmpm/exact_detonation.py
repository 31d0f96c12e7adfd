"""The exact planar CJ-Taylor detonation wave: a Chapman-Jouguet front followed by the Taylor rarefaction
(Fickett & Davis, "Detonation", 1979, ch. 2; Zel'dovich & Raizer, "Physics of shock waves and
high-temperature hydrodynamic phenomena", ch. XII). Pure JAX functions of their parameters, so they jit,
vmap and differentiate; they compute in the default float dtype (float64 once the caller enables x64).

An explosive of density ``rho0`` fills ``X >= 0`` at rest, unreacted and at zero pressure. It is lit at
``X = 0`` at ``t = 0``; the front moves at the CJ speed ``D``, so the particle at ``X`` burns at
``t = X / D`` (``X`` is the reference position: ahead of the front ``x = X``). The products follow one
isentrope ``p_s(J)``, ``J = rho0 / rho`` (the stretch ``F`` of a particle in 1D). At the CJ point the
Rayleigh line from the unreacted state ``(J, p) = (1, 0)`` touches the isentrope:

    p_s(J_CJ) = rho0 D^2 (1 - J_CJ),    -p_s'(J_CJ) = rho0 D^2,

so ``u_CJ = D (1 - J_CJ)`` (mass balance) and the flow is sonic there, ``u_CJ + c_CJ = D``, with the
Eulerian sound speed ``c(J) = J C(J)`` and the Lagrangian one ``C(J) = sqrt(-p_s'(J) / rho0)``.

Behind the front the flow is a centred simple wave of the ``+`` family: the ``-`` Riemann invariant

    u(J) = u_CJ - int_{J_CJ}^{J} C(s) ds = u_CJ - int_{J_CJ}^{J} c(s) / s ds

is uniform (expansion, ``J > J_CJ``, lowers ``u``), and the characteristics fan out from the origin:
``x / t = u(J) + c(J)`` in the Eulerian frame, ``X / t = C(J)`` in the Lagrangian one. A particle keeps
``C(J) = X / t`` while in the fan, so its path is ``x = t (u(J) + c(J))`` and ``F = dx/dX = J``. Two
ends close the problem:

- ``end="wall"``: a rigid wall at ``x = 0`` (equivalently the symmetry plane of a detonation lit on a
  plane in an unbounded charge). The fan stops where ``u = 0``, at ``J_w``; the gas between the wall and
  ``x = c(J_w) t`` is at rest in that state, and a particle that reaches it at ``t_w = X / C(J_w)``
  stays at ``x = J_w X``. Positions ``x < 0`` (``X < 0``) get the mirror image: ``u`` and ``x`` odd,
  the rest even.
- ``end="free"``: the charge faces vacuum at ``X = 0``. The fan continues until ``c = 0``, the escape
  front, and there is no region at rest. Beyond the escape front (vacuum) ``rho = p = c = 0``,
  ``J = inf`` and ``u = NaN`` (no material).

For the gamma-law products ``p_s = p_CJ (J / J_CJ)^-gamma`` everything is in closed form (the
``gamma_law_*`` functions): ``p_CJ = rho0 D^2 / (gamma + 1)``, ``J_CJ = gamma / (gamma + 1)``,
``u_CJ = D / (gamma + 1)``, ``c_CJ = gamma D / (gamma + 1)``, and in the fan

    u = (2 x / t - D) / (gamma + 1),    c = ((gamma - 1) x / t + D) / (gamma + 1),

from ``u - 2 c / (gamma - 1) = -D / (gamma - 1)``. Against a wall the fan ends at ``x = D t / 2`` with
``c = D / 2``; at a free surface it reaches ``c = 0`` at ``x / t = -D / (gamma - 1)``. A particle in the
fan follows ``x = gamma / (gamma - 1) X^((gamma - 1) / (gamma + 1)) (D t)^(2 / (gamma + 1)) - D t /
(gamma - 1)`` with ``F = gamma / (gamma + 1) (D t / X)^(2 / (gamma + 1))``, and reaches the wall's
region at ``t_w = (X / D) (2 gamma / (gamma + 1))^((gamma + 1) / (gamma - 1))``. For ``gamma = 3``:
``F`` rises from ``3/4`` at burning to ``9/8``, ``t_w = 9 X / (4 D)`` and the wall pressure is
``8/27 p_CJ``.

For any other barotropic isentrope (JWL's principal isentrope: ``Isentrope(JWLIsentrope(...))``, with
``jaxmpm.explosives.JWLIsentrope``) ``isentrope_fan`` builds the same solution by quadrature: ``int C ds``
by Gauss-Legendre in ``ln J`` (``nodes`` points), and the states in the fan by bisection on the monotone
``x / t = u(J) + c(J)`` (fields) or ``X / t = C(J)`` (particles), which needs ``p_s`` decreasing and
convex on ``[J_CJ, J_max]``. ``cj_point`` finds the CJ point of an isentrope.

Conventions: a point on the front (``x = D t``, a particle at ``t = X / D``) takes the CJ state; ahead of
the front the explosive is at rest with ``p = 0``, ``rho = rho0``, ``J = F = 1`` and ``c = 0`` (its
sound speed is not part of the model). The roots are found on stopped values and one Newton step on the
live ones carries the first derivatives (those of the implicit function).

Input checks (``rho0 > 0``, ``D > 0``, ``gamma > 1``, ``t > 0`` or ``t >= 0``, finite positions, ``end``
one of ``"wall"`` and ``"free"``) run when the values are concrete and raise a ``ValueError`` naming the
parameter; positions and times whose shapes do not broadcast together are refused the same way.
Under ``jax.jit``, ``jax.vmap`` or ``jax.grad`` the values are tracers and are not checked: bad values
then give NaN or finite but meaningless values, and no error (a traced ``t < 0`` in
``gamma_law_fields``, say, gives the wall's state at rest at every ``x``; a traced ``gamma < 1`` a
finite pressure).
"""

import functools
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._checks import (
    any_traced,
    check_finite,
    check_greater,
    check_int,
    check_less,
    check_nonnegative,
    check_positive,
    check_real,
    is_concrete,
    show,
)
from .explosives import GammaLawIsentrope, _check_stateless
from .materials import AbstractEOS

_ENDS = ("wall", "free")
_BISECTIONS = 64


def _float(x):
    return jnp.asarray(x, dtype=jnp.result_type(float))


def _check_end(end) -> None:
    if not isinstance(end, str) or end not in _ENDS:
        raise ValueError(f"end must be 'wall' or 'free', got {end!r}")


def _check_explosive(rho0, D, gamma=None) -> None:
    for name, value in (("rho0", rho0), ("D", D)):
        check_real(name, value)
        check_positive(name, value)
    if gamma is not None:
        check_real("gamma", gamma)
        check_greater("gamma", gamma, 1.0)


def _check_broadcast(**values) -> None:
    """Check that the arrays among ``values`` broadcast together (shapes are known even for tracers).

    Raises:
        ValueError: they do not, naming each array and its shape.
    """
    shapes = {name: np.shape(value) for name, value in values.items() if np.ndim(value) > 0}
    try:
        np.broadcast_shapes(*shapes.values())
    except ValueError:
        names = list(shapes)
        listed = [f"{name} of shape {shape}" for name, shape in shapes.items()]
        raise ValueError(
            f"{', '.join(names[:-1])} and {names[-1]} must broadcast together, got "
            f"{', '.join(listed[:-1])} and {listed[-1]}"
        ) from None


def _check_position(name, value, end) -> None:
    check_real(name, value)
    check_finite(name, value)
    if end == "free":  # the charge is X >= 0
        check_nonnegative(name, value)


# -- Gamma-law products: closed form ---------------------------------------------------------------------


def gamma_law_cj(rho0, D, gamma):
    """The CJ state of gamma-law products ``p = p_CJ (J / J_CJ)^-gamma`` behind a front moving at ``D``.

    Args:
        rho0: the explosive's initial density (> 0).
        D: the detonation speed (> 0).
        gamma: the products' adiabatic exponent (> 1).

    Returns:
        A dict with ``D``, ``P_CJ = rho0 D^2 / (gamma + 1)``, ``J_CJ = gamma / (gamma + 1)``,
        ``u_CJ = D / (gamma + 1)``, ``c_CJ = gamma D / (gamma + 1)`` and
        ``rho_CJ = rho0 (gamma + 1) / gamma``.

    Raises:
        ValueError: a concrete ``rho0`` or ``D`` is not > 0, or ``gamma`` not > 1.
    """
    _check_explosive(rho0, D, gamma)
    rho0, D, gamma = _float(rho0), _float(D), _float(gamma)
    return _gamma_cj(rho0, D, gamma)


def _gamma_cj(rho0, D, gamma):
    cj = GammaLawIsentrope(rho0=rho0, D=D, gamma=gamma).cj()
    return {k: v for k, v in cj.items() if k != "e_CJ"}


def _gamma_wall(rho0, D, gamma):
    """The state at rest against the wall: ``(J_w, p_w, c_w)``, ``c_w = D / 2``."""
    cj = _gamma_cj(rho0, D, gamma)
    ratio = (gamma + 1.0) / (2.0 * gamma)  # c_w / c_CJ
    J_w = cj["J_CJ"] * ratio ** (-2.0 / (gamma - 1.0))
    p_w = cj["P_CJ"] * ratio ** (2.0 * gamma / (gamma - 1.0))
    return J_w, p_w, 0.5 * D


def gamma_law_wall_pressure(rho0, D, gamma):
    """The pressure at the wall (``end="wall"``), uniform between the wall and ``x = D t / 2``.

    Args:
        rho0: the explosive's initial density (> 0).
        D: the detonation speed (> 0).
        gamma: the products' adiabatic exponent (> 1).

    Returns:
        ``p_CJ ((gamma + 1) / (2 gamma))^(2 gamma / (gamma - 1))``; ``8/27 p_CJ`` for ``gamma = 3``.

    Raises:
        ValueError: as for ``gamma_law_cj``.
    """
    _check_explosive(rho0, D, gamma)
    return _gamma_wall(_float(rho0), _float(D), _float(gamma))[1]


def gamma_law_wall_time(X, D, gamma):
    """When the particle at ``X`` leaves the fan and comes to rest (``end="wall"``).

    Args:
        X: reference position(s) (finite; ``|X|`` is used, the mirror image).
        D: the detonation speed (> 0).
        gamma: the products' adiabatic exponent (> 1).

    Returns:
        ``t_w = (|X| / D) (2 gamma / (gamma + 1))^((gamma + 1) / (gamma - 1))``; ``9 X / (4 D)`` for
        ``gamma = 3``.

    Raises:
        ValueError: a concrete ``X`` is not finite, ``D`` not > 0 or ``gamma`` not > 1.
    """
    check_real("X", X)
    check_finite("X", X)
    check_real("D", D)
    check_positive("D", D)
    check_real("gamma", gamma)
    check_greater("gamma", gamma, 1.0)
    X, D, gamma = _float(X), _float(D), _float(gamma)
    return jnp.abs(X) / D * (2.0 * gamma / (gamma + 1.0)) ** ((gamma + 1.0) / (gamma - 1.0))


def gamma_law_isentrope(rho0, D, gamma):
    """The products' isentrope through the CJ point, ``p_s(J) = p_CJ (J / J_CJ)^-gamma``, as a callable
    for ``isentrope_fan`` and ``cj_point``.

    Args:
        rho0: the explosive's initial density (> 0).
        D: the detonation speed (> 0).
        gamma: the products' adiabatic exponent (> 1).

    Returns:
        An ``Isentrope`` of ``jaxmpm.explosives.GammaLawIsentrope``.

    Raises:
        ValueError: as for ``gamma_law_cj``.
    """
    gamma_law_cj(rho0, D, gamma)  # the checks
    return Isentrope(GammaLawIsentrope(rho0=_float(rho0), D=_float(D), gamma=_float(gamma)))


@jax.jit
def _gamma_fields(x, t, rho0, D, gamma, wall):
    gp, gm = gamma + 1.0, gamma - 1.0
    cj = _gamma_cj(rho0, D, gamma)
    xi = jnp.where(wall, jnp.abs(x), x) / t
    ahead = xi > D
    escape = -D / gm
    rest = wall & (xi <= 0.5 * D)
    vacuum = ~wall & (xi < escape)
    fan = ~ahead & ~rest & ~vacuum
    # The fan's formulas on its own points; elsewhere at the front, where every power is safe.
    xi_f = jnp.where(fan, xi, D)
    u_f = (2.0 * xi_f - D) / gp
    c_f = (gm * xi_f + D) / gp
    ratio = c_f / cj["c_CJ"]
    live = ratio > 0.0  # false only on the escape front
    ratio_s = jnp.where(live, ratio, 1.0)
    p_f = jnp.where(live, cj["P_CJ"] * ratio_s ** (2.0 * gamma / gm), 0.0)
    J_f = jnp.where(live, cj["J_CJ"] * ratio_s ** (-2.0 / gm), jnp.inf)
    rho_f = jnp.where(live, rho0 / cj["J_CJ"] * ratio_s ** (2.0 / gm), 0.0)
    J_w, p_w, c_w = _gamma_wall(rho0, D, gamma)

    def pick(on_fan, at_rest, in_vacuum, unburnt):
        return jnp.where(ahead, unburnt, jnp.where(rest, at_rest, jnp.where(vacuum, in_vacuum, on_fan)))

    u = pick(u_f, 0.0, jnp.nan, 0.0)
    u = jnp.where(wall & (x < 0.0), -u, u)
    return dict(
        u=u,
        c=pick(c_f, c_w, 0.0, 0.0),
        p=pick(p_f, p_w, 0.0, 0.0),
        rho=pick(rho_f, rho0 / J_w, 0.0, rho0),
        J=pick(J_f, J_w, jnp.inf, 1.0),
    )


def gamma_law_fields(x, t, rho0, D, gamma, end="wall"):
    """The CJ-Taylor wave of gamma-law products at Eulerian positions ``x`` and time ``t > 0``.

    Behind the front (``x <= D t``) the Taylor fan ``u = (2 x / t - D) / (gamma + 1)``,
    ``c = ((gamma - 1) x / t + D) / (gamma + 1)``, ``p = p_CJ (c / c_CJ)^(2 gamma / (gamma - 1))``,
    ``J = J_CJ (c / c_CJ)^(-2 / (gamma - 1))``; against a wall, rest (``u = 0``, ``c = D / 2``) for
    ``x <= D t / 2`` and the mirror image for ``x < 0``; at a free surface the fan down to the escape
    front ``x = -D t / (gamma - 1)`` and vacuum beyond it (``u = NaN``, ``J = inf``). Ahead of the
    front the unburnt explosive: ``u = c = p = 0``, ``rho = rho0``, ``J = 1``.

    Args:
        x: Eulerian position(s), any shape (broadcast with ``t``).
        t: time (> 0), one number or an array that broadcasts with ``x``.
        rho0: the explosive's initial density (> 0).
        D: the detonation speed (> 0).
        gamma: the products' adiabatic exponent (> 1).
        end: ``"wall"`` (a rigid wall at ``x = 0``) or ``"free"`` (a free surface there).

    Returns:
        A dict with ``u``, ``c``, ``p``, ``rho`` and ``J = rho0 / rho`` at ``x``, of the broadcast
        shape.

    Raises:
        ValueError: as for ``gamma_law_cj``, or a concrete ``t`` is not > 0, ``x`` not finite, or
            ``end`` unknown; or the shapes of ``x``, ``t`` (and of ``rho0``, ``D``, ``gamma`` where
            they are arrays) do not broadcast together, checked for tracers too.
    """
    _check_end(end)
    _check_explosive(rho0, D, gamma)
    _check_broadcast(x=x, t=t, rho0=rho0, D=D, gamma=gamma)
    check_real("x", x)
    check_finite("x", x)
    check_real("t", t)
    check_positive("t", t)
    args = [_float(a) for a in (x, t, rho0, D, gamma)]
    return _gamma_fields(*args, jnp.asarray(end == "wall"))


@jax.jit
def _gamma_particles(X, t, rho0, D, gamma, wall):
    gp, gm = gamma + 1.0, gamma - 1.0
    a = 2.0 / gp
    cj = _gamma_cj(rho0, D, gamma)
    J_w, p_w, c_w = _gamma_wall(rho0, D, gamma)
    R = jnp.abs(X)
    Dt = D * t
    outside = ~wall & (X < 0.0)
    lit = (t > 0.0) & (Dt >= R) & ~outside
    k = (2.0 * gamma / gp) ** (gp / gm)  # D t_w / X
    rest = wall & lit & (Dt >= k * R)
    fan = lit & ~rest & (R > 0.0)
    edge = lit & ~wall & (R == 0.0)  # the free surface's own particle rides the escape front
    # s = D t / X >= 1 in the fan; 1 (the burning point) elsewhere.
    s = jnp.where(fan, Dt, 1.0) / jnp.where(fan, R, 1.0)
    x_f = R * (gamma / gm * s**a - s / gm)
    F_f = cj["J_CJ"] * s**a
    c_f = cj["c_CJ"] * s ** (a - 1.0)
    u_f = cj["u_CJ"] + 2.0 / gm * (c_f - cj["c_CJ"])
    p_f = cj["P_CJ"] * s ** (-a * gamma)

    def pick(on_fan, at_rest, on_edge, unburnt):
        burnt = jnp.where(rest, at_rest, jnp.where(edge, on_edge, on_fan))
        return jnp.where(outside, jnp.nan, jnp.where(lit, burnt, unburnt))

    sign = jnp.where(X < 0.0, -1.0, 1.0)
    return dict(
        x=sign * pick(x_f, J_w * R, -Dt / gm, R),
        F=pick(F_f, J_w, jnp.inf, 1.0),
        u=sign * pick(u_f, 0.0, -D / gm, 0.0),
        c=pick(c_f, c_w, 0.0, 0.0),
        p=pick(p_f, p_w, 0.0, 0.0),
        rho=pick(rho0 / F_f, rho0 / J_w, 0.0, rho0),
    )


def gamma_law_particles(X, t, rho0, D, gamma, end="wall"):
    """The CJ-Taylor wave of gamma-law products seen by the particles at reference positions ``X``.

    A particle burns at ``t = X / D`` (at ``x = X``, with ``F = J_CJ``), then follows the fan:
    ``x = gamma / (gamma - 1) X^((gamma - 1) / (gamma + 1)) (D t)^(2 / (gamma + 1)) - D t / (gamma - 1)``,
    ``F = gamma / (gamma + 1) (D t / X)^(2 / (gamma + 1))``. Against a wall it comes to rest at
    ``t_w`` (``gamma_law_wall_time``) at ``x = J_w X`` with ``F = J_w``; at a free surface it stays in
    the fan (the particle ``X = 0`` rides the escape front: ``F = inf``). Before burning ``x = X``,
    ``F = 1``, ``p = 0``. With ``end="wall"``, ``X < 0`` gets the mirror image.

    Args:
        X: reference position(s), any shape (broadcast with ``t``); ``>= 0`` with ``end="free"``.
        t: time (>= 0), one number or an array that broadcasts with ``X``.
        rho0: the explosive's initial density (> 0).
        D: the detonation speed (> 0).
        gamma: the products' adiabatic exponent (> 1).
        end: ``"wall"`` or ``"free"``, as for ``gamma_law_fields``.

    Returns:
        A dict with the position ``x``, the stretch ``F = dx/dX = J``, and ``u``, ``c``, ``p``,
        ``rho`` at the particles, of the broadcast shape.

    Raises:
        ValueError: as for ``gamma_law_cj``, or a concrete ``t`` is negative, ``X`` not finite (or
            negative with ``end="free"``), or ``end`` unknown; or the shapes of ``X``, ``t`` (and of
            ``rho0``, ``D``, ``gamma`` where they are arrays) do not broadcast together, checked for
            tracers too.
    """
    _check_end(end)
    _check_explosive(rho0, D, gamma)
    _check_broadcast(X=X, t=t, rho0=rho0, D=D, gamma=gamma)
    _check_position("X", X, end)
    check_real("t", t)
    check_nonnegative("t", t)
    args = [_float(a) for a in (X, t, rho0, D, gamma)]
    return _gamma_particles(*args, jnp.asarray(end == "wall"))


# -- Any barotropic isentrope: quadrature ----------------------------------------------------------------


class Isentrope(eqx.Module):
    """A barotropic products EOS (``b = 0`` in ``p = a + b e``: ``jaxmpm.explosives.GammaLawIsentrope``,
    ``JWLIsentrope``) as the callable ``p_s(J)``, ``J = rho0 / rho``, for ``isentrope_fan`` and
    ``cj_point``. The EOS's constants are leaves, so the fan differentiates through them and compiles
    once for all their values.

    An EOS with energy (``b != 0``: ``JWL``, ``IdealGas``) is refused, its pressure depending on the
    energy that ``p_s`` does not carry; ``Isentrope(JWLIsentrope.from_jwl(jwl, e0))`` is the principal
    isentrope of a full-form JWL. ``b`` is checked at ``J = 1`` and ``J = 2`` where the EOS's fields
    are concrete (a tracer passes).

    Attributes:
        eos: the EOS, without internal variables; it has a reference density ``rho0``, the ``rho0``
            that ``isentrope_fan`` and ``cj_point`` take with it.
    """

    eos: AbstractEOS

    def __check_init__(self):
        if not isinstance(self.eos, AbstractEOS) or not hasattr(self.eos, "rho0"):
            raise ValueError(f"eos must be a barotropic AbstractEOS with a field rho0, got {self.eos!r}")
        _check_stateless("eos", self.eos)
        if any_traced(self.eos):
            return
        for J in (1.0, 2.0):
            rho = self.eos.rho0 / J
            _, b = self.eos.pressure_terms(rho, None)
            if not bool(jnp.all(b == 0.0)):
                raise ValueError(
                    f"eos must be barotropic (b = 0 in p = a + b e), got {type(self.eos).__name__} with b = "
                    f"{show(np.asarray(b))} at rho = {show(np.asarray(rho))}: p_s would drop its energy "
                    "term; the principal isentrope of a JWL with energy is JWLIsentrope.from_jwl(eos, e0)"
                )

    def __call__(self, J):
        """The pressure.

        Args:
            J: volume ratio(s) ``rho0 / rho`` (> 0).

        Returns:
            ``p_s(J)``, the EOS's pressure at ``rho = rho0 / J`` (its ``a``; a barotropic EOS has ``b = 0``).
        """
        a, _ = self.eos.pressure_terms(self.eos.rho0 / J, None)
        return a


def _derivative(f, J):
    """``f'(J)`` of an elementwise ``f``."""
    return jax.jvp(f, (J,), (jnp.ones_like(J),))[1]


def _stopped(tree):
    """``tree`` with its array leaves detached from differentiation."""
    arrays, rest = eqx.partition(tree, eqx.is_array)
    return eqx.combine(jax.lax.stop_gradient(arrays), rest)


def _bisect(f, target, hi):
    """The ``y`` in ``[0, hi]`` where the decreasing ``f(y)`` meets ``target`` (clamped to the ends), to
    round-off. Not differentiable: the caller passes stopped values."""

    def body(_, bounds):
        lo, up = bounds
        mid = 0.5 * (lo + up)
        right = f(mid) > target
        return jnp.where(right, mid, lo), jnp.where(right, up, mid)

    lo, up = jax.lax.fori_loop(0, _BISECTIONS, body, (jnp.zeros_like(hi), hi))
    return 0.5 * (lo + up)


@functools.cache
def _gauss_legendre(nodes: int):
    return np.polynomial.legendre.leggauss(nodes)


class IsentropeFan(eqx.Module):
    """The CJ-Taylor detonation wave of products on the isentrope ``p_s``; build it with
    ``isentrope_fan``.

    Attributes:
        p_s: the isentrope, a callable of ``J`` (elementwise on arrays).
        rho0: the explosive's initial density.
        D: the detonation speed.
        J_CJ: ``J`` at the CJ point.
        u_CJ: ``D (1 - J_CJ)``.
        c_CJ: ``c(J_CJ)``.
        P_CJ: ``p_s(J_CJ)``.
        J_max: where the fan is cut (``end="free"``) and the bracket of the wall's state.
        J_wall: ``J`` of the gas at rest against the wall (``u(J_wall) = 0``); NaN with ``end="free"``.
        end: ``"wall"`` or ``"free"``.
        nodes: the Gauss-Legendre points of the quadrature of ``u(J)``.
    """

    p_s: Callable
    rho0: Float[Array, ""]
    D: Float[Array, ""]
    J_CJ: Float[Array, ""]
    u_CJ: Float[Array, ""]
    c_CJ: Float[Array, ""]
    P_CJ: Float[Array, ""]
    J_max: Float[Array, ""]
    J_wall: Float[Array, ""]
    end: str = eqx.field(static=True)
    nodes: int = eqx.field(static=True)

    def lagrangian_speed(self, J):
        """The Lagrangian sound speed, the fan's speed in reference coordinates.

        Args:
            J: specific volume ratio(s).

        Returns:
            ``C(J) = sqrt(-p_s'(J) / rho0)``.
        """
        return jnp.sqrt(-_derivative(self.p_s, J) / self.rho0)

    def sound_speed(self, J):
        """The Eulerian sound speed of the products.

        Args:
            J: specific volume ratio(s).

        Returns:
            ``c(J) = J C(J)``.
        """
        return J * self.lagrangian_speed(J)

    def velocity(self, J):
        """The particle velocity in the fan, from the ``-`` Riemann invariant.

        Args:
            J: specific volume ratio(s) (> 0).

        Returns:
            ``u(J) = u_CJ - int_{J_CJ}^{J} C(s) ds``, by Gauss-Legendre quadrature in ``ln s``
            (``int c(s) d(ln s)``).
        """
        J = _float(J)
        xg, wg = (jnp.asarray(a, dtype=J.dtype) for a in _gauss_legendre(self.nodes))

        def integral(J):
            half = 0.5 * jnp.log(J / self.J_CJ)
            return half * jnp.sum(wg * self.sound_speed(self.J_CJ * jnp.exp(half * (1.0 + xg))))

        return self.u_CJ - jnp.vectorize(integral)(J)

    def _characteristic(self, J):
        """``u(J) + c(J)``, the Eulerian speed of the fan's characteristic where the products are at ``J``."""
        return self.velocity(J) + self.sound_speed(J)

    @property
    def wall_pressure(self):
        """The pressure of the gas at rest against the wall, ``p_s(J_wall)`` (NaN with ``end="free"``)."""
        return self.p_s(self.J_wall)

    def fields(self, x, t):
        """The wave at Eulerian positions ``x`` and time ``t > 0``: the fan where
        ``u(J) + c(J) = x / t``, the gas at rest (``J_wall``, ``end="wall"``) below it, the unburnt
        explosive ahead of the front ``x = D t``. With ``end="free"``, NaN where the fan would need
        ``J > J_max``; with ``end="wall"``, the mirror image for ``x < 0``.

        Args:
            x: Eulerian position(s), any shape (broadcast with ``t``).
            t: time (> 0).

        Returns:
            A dict with ``u``, ``c``, ``p``, ``rho`` and ``J`` at ``x``.

        Raises:
            ValueError: a concrete ``x`` is not finite or ``t`` not > 0, or the shapes of ``x`` and
                ``t`` do not broadcast together.
        """
        check_real("x", x)
        check_finite("x", x)
        check_real("t", t)
        check_positive("t", t)
        _check_broadcast(x=x, t=t)
        return _fan_fields(self, _float(x), _float(t))

    def particles(self, X, t):
        """The wave seen by the particles at reference positions ``X``: burnt at ``t = X / D``, then in
        the fan where ``C(J) = X / t``, at ``x = t (u(J) + c(J))`` with ``F = J``; with ``end="wall"``
        at rest from ``t_w = X / C(J_wall)`` at ``x = J_wall X``. With ``end="free"``, NaN once
        ``J > J_max``; with ``end="wall"``, the mirror image for ``X < 0``.

        Args:
            X: reference position(s), any shape (broadcast with ``t``); ``>= 0`` with ``end="free"``.
            t: time (>= 0).

        Returns:
            A dict with ``x``, ``F``, ``u``, ``c``, ``p`` and ``rho`` at the particles.

        Raises:
            ValueError: a concrete ``X`` is not finite (or negative with ``end="free"``), or ``t`` is
                negative, or the shapes of ``X`` and ``t`` do not broadcast together.
        """
        _check_position("X", X, self.end)
        check_real("t", t)
        check_nonnegative("t", t)
        _check_broadcast(X=X, t=t)
        return _fan_particles(self, _float(X), _float(t))


@eqx.filter_jit
def _fan_fields(fan, x, t):
    frozen = _stopped(fan)
    wall = fan.end == "wall"
    J_hi = fan.J_wall if wall else fan.J_max
    y_hi = jax.lax.stop_gradient(jnp.log(J_hi / fan.J_CJ))
    lam_hi = fan._characteristic(J_hi)
    lam_lo = frozen._characteristic(frozen.J_CJ)
    p_hi = fan.p_s(J_hi)
    c_hi = fan.sound_speed(J_hi)

    def one(x, t):
        xi = (jnp.abs(x) if wall else x) / t
        ahead = xi > fan.D
        below = xi < lam_hi
        fan_here = ~ahead & ~below
        target = jax.lax.stop_gradient(jnp.clip(jnp.where(fan_here, xi, lam_lo), lam_hi, lam_lo))
        y = _bisect(lambda y: frozen._characteristic(frozen.J_CJ * jnp.exp(y)), target, y_hi)
        J_c = jax.lax.stop_gradient(frozen.J_CJ * jnp.exp(y))
        xi_s = jnp.where(fan_here, xi, target)
        slope = J_c * _derivative(fan.lagrangian_speed, J_c)  # d(u + c)/dJ
        J = J_c - (fan._characteristic(J_c) - xi_s) / slope
        u, c, p = fan.velocity(J), fan.sound_speed(J), fan.p_s(J)
        if wall:
            u = jnp.where(below, 0.0, u)
            c, p, J = (jnp.where(below, b, f) for b, f in ((c_hi, c), (p_hi, p), (J_hi, J)))
            u = jnp.where(x < 0.0, -u, u)
        else:
            u, c, p, J = (jnp.where(below, jnp.nan, f) for f in (u, c, p, J))
        return (
            jnp.where(ahead, 0.0, u),
            jnp.where(ahead, 0.0, c),
            jnp.where(ahead, 0.0, p),
            jnp.where(ahead, fan.rho0, fan.rho0 / J),
            jnp.where(ahead, 1.0, J),
        )

    # a tuple, not a dict: jnp.vectorize restores the axes of length 1 of a tuple's arrays only
    return dict(zip(("u", "c", "p", "rho", "J"), jnp.vectorize(one)(x, t)))


@eqx.filter_jit
def _fan_particles(fan, X, t):
    frozen = _stopped(fan)
    wall = fan.end == "wall"
    J_hi = fan.J_wall if wall else fan.J_max
    y_hi = jax.lax.stop_gradient(jnp.log(J_hi / fan.J_CJ))
    C_hi = fan.lagrangian_speed(J_hi)
    C_lo = frozen.lagrangian_speed(frozen.J_CJ)
    p_hi = fan.p_s(J_hi)
    c_hi = fan.sound_speed(J_hi)

    def one(X, t):
        R = jnp.abs(X) if wall else X
        lit = (t > 0.0) & (fan.D * t >= R) & (R >= 0.0)
        r = R / jnp.where(lit, t, 1.0)  # X / t, the fan's Lagrangian speed at the particle
        below = lit & (r < C_hi)
        fan_here = lit & ~below
        target = jax.lax.stop_gradient(jnp.clip(jnp.where(fan_here, r, C_lo), C_hi, C_lo))
        y = _bisect(lambda y: frozen.lagrangian_speed(frozen.J_CJ * jnp.exp(y)), target, y_hi)
        J_c = jax.lax.stop_gradient(frozen.J_CJ * jnp.exp(y))
        r_s = jnp.where(fan_here, r, target)
        J = J_c - (fan.lagrangian_speed(J_c) - r_s) / _derivative(fan.lagrangian_speed, J_c)
        u, c, p = fan.velocity(J), fan.sound_speed(J), fan.p_s(J)
        x = jnp.where(lit, t, 0.0) * (u + c)
        if wall:
            x, u = jnp.where(below, J_hi * R, x), jnp.where(below, 0.0, u)
            c, p, J = (jnp.where(below, b, f) for b, f in ((c_hi, c), (p_hi, p), (J_hi, J)))
            sign = jnp.where(X < 0.0, -1.0, 1.0)
            x, u = sign * x, sign * u
        else:
            x, u, c, p, J = (jnp.where(below, jnp.nan, f) for f in (x, u, c, p, J))
        out = (
            jnp.where(lit, x, X),
            jnp.where(lit, J, 1.0),
            jnp.where(lit, u, 0.0),
            jnp.where(lit, c, 0.0),
            jnp.where(lit, p, 0.0),
            jnp.where(lit, fan.rho0 / J, fan.rho0),
        )
        if wall:
            return out
        return tuple(jnp.where(X < 0.0, jnp.nan, v) for v in out)  # not explosive

    # a tuple, not a dict: jnp.vectorize restores the axes of length 1 of a tuple's arrays only
    return dict(zip(("x", "F", "u", "c", "p", "rho"), jnp.vectorize(one)(X, t)))


def _check_own_rho0(p_s, rho0) -> None:
    """Check that ``rho0`` is the ``rho0`` of an ``Isentrope``'s EOS, the density its ``J`` is relative
    to (another ``p_s`` passes, and so do tracers).

    Raises:
        ValueError: both are concrete numbers and differ (relative 1e-12, or 4 ulps of the type ``own``
            is stored in where that is more: in float32 1.63 is kept as 1.6299999952).
    """
    if not isinstance(p_s, Isentrope):
        return
    own = p_s.eos.rho0
    if is_concrete(own) and is_concrete(rho0) and np.ndim(rho0) == 0 and np.ndim(own) == 0:
        tol = max(1e-12, 4.0 * float(jnp.finfo(jnp.result_type(own)).eps))
        if not math.isclose(float(rho0), float(own), rel_tol=tol):
            raise ValueError(
                f"rho0 must be the isentrope's own rho0 = {float(own)!r} (p_s.eos.rho0), got {float(rho0)!r}"
            )


def _wall_state(fan):
    """``J_wall``: the root of ``u(J) = 0`` in ``[J_CJ, J_max]``, with one Newton step on live values."""
    frozen = _stopped(fan)
    y_hi = jax.lax.stop_gradient(jnp.log(fan.J_max / fan.J_CJ))
    y = _bisect(lambda y: frozen.velocity(frozen.J_CJ * jnp.exp(y)), jnp.zeros_like(y_hi), y_hi)
    J_c = jax.lax.stop_gradient(frozen.J_CJ * jnp.exp(y))
    return J_c + fan.velocity(J_c) / fan.lagrangian_speed(J_c)  # u' = -C


def isentrope_fan(p_s, rho0, D, J_CJ, end="wall", J_max=1e3, nodes=64, cj_tol=1e-6):
    """The CJ-Taylor detonation wave of products on any isentrope ``p_s`` (a JWL principal isentrope,
    say), by quadrature.

    ``D`` and ``J_CJ`` must be the CJ point of ``p_s``: ``p_s(J_CJ) = rho0 D^2 (1 - J_CJ)`` and
    ``-p_s'(J_CJ) = rho0 D^2`` (``cj_point`` finds them). The construction uses
    ``u_CJ = D (1 - J_CJ)`` and the sound speed of ``p_s``, and is exact (to the quadrature's round-off)
    when the two conditions hold; ``cj_tol`` bounds how far from them concrete values may be.
    ``p_s`` must be decreasing and convex on ``[J_CJ, J_max]`` (``c > 0`` there), so that the fan's
    speeds are monotone in ``J``.

    Args:
        p_s: the isentrope, a callable of a JAX array ``J`` (elementwise); ``gamma_law_isentrope`` and
            ``Isentrope`` build them. A pytree (an equinox Module) is traced through, so its
            parameters differentiate and one compilation serves all their values.
        rho0: the explosive's initial density (> 0); of an ``Isentrope``, its EOS's own ``rho0``.
        D: the detonation speed (> 0).
        J_CJ: ``rho0 / rho`` at the CJ point (in ``(0, 1)``).
        end: ``"wall"`` (a rigid wall at ``x = 0``, the fan stops where ``u = 0``) or ``"free"`` (a
            free surface: the fan runs until ``c = 0``, here cut at ``J_max``).
        J_max: the largest ``J`` the fan is computed to (> ``J_CJ``); with ``end="wall"`` the bracket
            of the state at rest.
        nodes: Gauss-Legendre points of the quadrature of ``u(J)`` (an integer >= 2).
        cj_tol: the relative misfit of the two CJ conditions allowed for concrete values (``None``:
            unchecked).

    Returns:
        An ``IsentropeFan``.

    Raises:
        ValueError: ``p_s`` is not callable, ``end`` unknown, ``nodes`` not an integer >= 2, or a
            concrete ``rho0`` or ``D`` not > 0, ``rho0`` not the own ``rho0`` of an ``Isentrope``
            ``p_s``, ``J_CJ`` not in ``(0, 1)``, ``J_max`` not > ``J_CJ``,
            ``D`` and ``J_CJ`` not the CJ point of ``p_s`` within ``cj_tol``, or (``end="wall"``) the
            fan not coming to rest below ``J_max``.
    """
    if not callable(p_s):
        raise ValueError(f"p_s must be callable (the isentrope p_s(J)), got {p_s!r}")
    _check_end(end)
    check_int("nodes", nodes, 2)
    _check_explosive(rho0, D)
    _check_own_rho0(p_s, rho0)
    check_real("J_CJ", J_CJ)
    check_positive("J_CJ", J_CJ)
    check_less("J_CJ", J_CJ, 1.0)
    check_real("J_max", J_max)
    check_positive("J_max", J_max)
    if is_concrete(J_max) and is_concrete(J_CJ) and not float(J_max) > float(J_CJ):
        raise ValueError(f"J_max must be > J_CJ = {float(J_CJ)!r}, got {float(J_max)!r}")
    rho0, D, J_CJ, J_max = (_float(a) for a in (rho0, D, J_CJ, J_max))
    P_CJ = p_s(J_CJ)
    c_CJ = J_CJ * jnp.sqrt(-_derivative(p_s, J_CJ) / rho0)
    if cj_tol is not None:
        check_positive("cj_tol", cj_tol)
        if all(is_concrete(a) for a in (rho0, D, J_CJ, P_CJ, c_CJ)):
            rayleigh = float(rho0 * D**2)
            misfit = max(
                abs(float(P_CJ) - rayleigh * (1.0 - float(J_CJ))) / rayleigh,
                abs(float(c_CJ) - float(J_CJ * D)) / float(J_CJ * D),
            )
            if not misfit <= cj_tol:
                raise ValueError(
                    f"D and J_CJ must be the CJ point of p_s (p_s(J_CJ) = rho0 D^2 (1 - J_CJ), "
                    f"-p_s'(J_CJ) = rho0 D^2): relative misfit {misfit:.3g} > cj_tol = {cj_tol!r}; "
                    "cj_point(p_s, rho0) finds it"
                )
    nan = jnp.full_like(D, jnp.nan)
    fan = IsentropeFan(
        p_s=p_s,
        rho0=rho0,
        D=D,
        J_CJ=J_CJ,
        u_CJ=D * (1.0 - J_CJ),
        c_CJ=c_CJ,
        P_CJ=P_CJ,
        J_max=J_max,
        J_wall=nan,
        end=end,
        nodes=nodes,
    )
    if end == "free":
        return fan
    u_max = fan.velocity(J_max)
    if is_concrete(u_max) and not float(u_max) < 0.0:
        raise ValueError(
            f"J_max must exceed J where u = 0 (the gas at rest at the wall); u(J_max) = {float(u_max)!r}"
        )
    J_wall = jnp.where(u_max < 0.0, _wall_state(fan), jnp.nan)
    return eqx.tree_at(lambda f: f.J_wall, fan, J_wall)


def cj_point(p_s, rho0, J_lo=0.1, J_hi=1.0):
    """The CJ point of the isentrope ``p_s``: where the Rayleigh line from the unreacted state
    ``(J, p) = (1, 0)`` touches it, ``p_s(J) + p_s'(J) (1 - J) = 0``, then ``D = sqrt(-p_s'(J_CJ) / rho0)``.

    The root is found by bisection in ``[J_lo, J_hi]`` (unique for a decreasing convex ``p_s``: the
    left side increases with ``J``) and one Newton step on the live values carries the derivatives.

    Args:
        p_s: the isentrope, as for ``isentrope_fan``.
        rho0: the explosive's initial density (> 0); of an ``Isentrope``, its EOS's own ``rho0`` (its
            ``J`` is relative to that density).
        J_lo: the bracket's lower end (in ``(0, J_hi)``, where the left side is negative).
        J_hi: the bracket's upper end (<= 1, where the left side is positive).

    Returns:
        A dict as ``gamma_law_cj``'s: ``D``, ``P_CJ``, ``J_CJ``, ``u_CJ = D (1 - J_CJ)``,
        ``c_CJ = J_CJ D`` and ``rho_CJ = rho0 / J_CJ``.

    Raises:
        ValueError: ``p_s`` is not callable, or a concrete ``rho0`` is not > 0 or not the own ``rho0``
            of an ``Isentrope`` ``p_s``, the bracket not in ``(0, 1]`` or not holding a sign change.
    """
    if not callable(p_s):
        raise ValueError(f"p_s must be callable (the isentrope p_s(J)), got {p_s!r}")
    check_real("rho0", rho0)
    check_positive("rho0", rho0)
    _check_own_rho0(p_s, rho0)
    for name, value in (("J_lo", J_lo), ("J_hi", J_hi)):
        check_real(name, value)
        check_positive(name, value)
    if is_concrete(J_hi) and not float(J_hi) <= 1.0:
        raise ValueError(f"J_hi must be <= 1 (the unreacted state), got {float(J_hi)!r}")
    rho0, J_lo, J_hi = (_float(a) for a in (rho0, J_lo, J_hi))

    def tangency(p_s, J):
        return p_s(J) + _derivative(p_s, J) * (1.0 - J)

    if all(is_concrete(a) for a in (J_lo, J_hi)):
        g_lo, g_hi = float(tangency(p_s, J_lo)), float(tangency(p_s, J_hi))
        if not float(J_lo) < float(J_hi):
            raise ValueError(f"J_lo must be < J_hi = {float(J_hi)!r}, got {float(J_lo)!r}")
        if not g_lo < 0.0 <= g_hi:
            raise ValueError(
                f"J_lo and J_hi must bracket the CJ point: p_s(J) + p_s'(J) (1 - J) is {g_lo:.3g} at J_lo "
                f"and {g_hi:.3g} at J_hi (it must go from negative to positive)"
            )
    frozen = _stopped(p_s) if isinstance(p_s, eqx.Module) else p_s
    lo_s, hi_s = jax.lax.stop_gradient(J_lo), jax.lax.stop_gradient(J_hi)
    y = _bisect(lambda y: -tangency(frozen, lo_s + y), jnp.zeros_like(lo_s), hi_s - lo_s)
    J_c = jax.lax.stop_gradient(lo_s + y)
    J_CJ = J_c - tangency(p_s, J_c) / (_derivative(lambda J: tangency(p_s, J), J_c))
    D = jnp.sqrt(-_derivative(p_s, J_CJ) / rho0)
    return dict(
        D=D,
        P_CJ=p_s(J_CJ),
        J_CJ=J_CJ,
        u_CJ=D * (1.0 - J_CJ),
        c_CJ=J_CJ * D,
        rho_CJ=rho0 / J_CJ,
    )
