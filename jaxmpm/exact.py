"""Exact solutions of the 1D adiabatic gas problems: the isentropic Riemann problem and the expansion
into vacuum. Pure JAX functions of their parameters, so they vmap and differentiate.

The gas is ``P = P0 F^-gamma - p_atm`` in the Lagrangian description (unit cross-section):

    dF/dt = dv/dX,    rho0 dv/dt = -dP/dX,

the p-system. Its waves travel at the Lagrangian speeds ``-C`` and ``+C``, ``C(F) = c(F) / F =
sqrt(gamma P0 / rho0) F^(-(gamma+1)/2)``, ``c`` the Eulerian sound speed. Across a rarefaction the
Riemann invariants ``v -/+ g(F)`` hold, ``g(F) = 2 c(F) / (gamma - 1)``; across a shock, the
Rankine-Hugoniot conditions ``s [F] = -[v]``, ``rho0 s [v] = [P]``. (Toro, "Riemann solvers and
numerical methods for fluid dynamics", ch. 4, written here in Lagrangian form; ``p_atm`` drops out.)

Input checks (stretches and densities > 0, ``P0 > 0``, or ``>= 0`` for the sound speeds, ``gamma > 1``,
finite velocities, positions and times, a similarity variable that is not NaN, reference positions
inside the body, one number per parameter of a Riemann problem) run when the values are concrete and
raise a ``ValueError`` naming the parameter. Under ``jax.jit``, ``jax.vmap`` or ``jax.grad`` the
values are tracers and cannot be checked: bad values then give NaN.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ._checks import (
    check_finite,
    check_greater,
    check_int,
    check_nonnegative,
    check_positive,
    check_real,
    check_scalar,
    is_concrete,
    show,
)


def _check_gas(P0, gamma, rho0, pressureless: bool = False) -> None:
    """Check the gas's parameters (tracers pass): ``P0 > 0`` (``>= 0`` where ``pressureless``),
    ``gamma > 1``, ``rho0 > 0``."""
    (check_nonnegative if pressureless else check_positive)("P0", P0)
    check_greater("gamma", gamma, 1.0)
    check_positive("rho0", rho0)


def _check_states(F_L, v_L, F_R, v_R, P0, gamma, rho0) -> None:
    """Check the two states of a Riemann problem and the gas (tracers pass)."""
    check_positive("F_L", F_L)
    check_finite("v_L", v_L)
    check_positive("F_R", F_R)
    check_finite("v_R", v_R)
    _check_gas(P0, gamma, rho0)


def _check_one_problem(caller: str, F_L, v_L, F_R, v_R, P0, gamma, rho0) -> None:
    """Check the states and the gas of one Riemann problem (``_check_states``) and that each is one
    number: ``caller`` solves for one star state (tracers pass, so ``jax.vmap`` solves several)."""
    _check_states(F_L, v_L, F_R, v_R, P0, gamma, rho0)
    batch = f"; to solve several Riemann problems, jax.vmap over {caller}"
    args = dict(F_L=F_L, v_L=v_L, F_R=F_R, v_R=v_R, P0=P0, gamma=gamma, rho0=rho0)
    for name, value in args.items():
        check_scalar(name, value, batch)


def _sound_speed(F, P0, gamma, rho0):
    return jnp.sqrt(gamma * P0 * F ** (1.0 - gamma) / rho0)


def sound_speed(F, P0, gamma, rho0):
    """Eulerian sound speed of the gas.

    Args:
        F: stretch.
        P0: the gas's pressure at ``F = 1``.
        gamma: its adiabatic exponent.
        rho0: its initial density.

    Returns:
        ``c = sqrt(gamma P0 F^(1-gamma) / rho0)``.

    Raises:
        ValueError: a concrete ``F`` (any entry) or ``rho0`` is not finite and > 0, ``P0`` is not
            finite and >= 0 (``P0 = 0``, a gas without pressure, has ``c = 0``), or ``gamma`` is not
            finite and > 1 (tracers are not checked).
    """
    check_positive("F", F)
    _check_gas(P0, gamma, rho0, pressureless=True)
    return _sound_speed(F, P0, gamma, rho0)


def lagrangian_speed(F, P0, gamma, rho0):
    """Lagrangian wave speed (reference length per time).

    Args:
        F: stretch.
        P0: the gas's pressure at ``F = 1``.
        gamma: its adiabatic exponent.
        rho0: its initial density.

    Returns:
        ``C = c / F``.

    Raises:
        ValueError: as ``sound_speed``.
    """
    check_positive("F", F)
    _check_gas(P0, gamma, rho0, pressureless=True)
    return _sound_speed(F, P0, gamma, rho0) / F


def _branches(F, F0, v0, P0, gamma, rho0, sign):
    """The velocity behind a wave of family ``sign`` (-1 left, +1 right) that brings state ``(F0, v0)``
    to ``F``: a rarefaction for ``F >= F0`` (expansion), a shock for ``F < F0``."""
    g = 2.0 / (gamma - 1.0)
    rare = v0 - sign * g * (_sound_speed(F0, P0, gamma, rho0) - _sound_speed(F, P0, gamma, rho0))
    dP = P0 * (F ** (-gamma) - F0 ** (-gamma))  # >= 0 in compression
    arg = dP * (F0 - F)
    # The shock where it compresses by more than sqrt(eps) of F0; nearer, the rarefaction, which meets
    # it at F0 with the same slope and curvature (the two differ by O((F0 - F)^3), below round-off
    # there). The shock's sqrt(arg) has no usable derivative near arg = 0: infinite at F = F0, which
    # gave the star state's Newton step 0/0 (NaN), and round-off over round-off an ulp below it.
    near = F0 - F <= jnp.sqrt(jnp.finfo(jnp.result_type(F)).eps) * F0
    compressed = ~near & (arg > 0.0)
    shock = v0 + sign * jnp.sqrt(jnp.where(compressed, arg, 1.0) / rho0)
    return jnp.where(compressed, shock, rare)


def riemann_star(F_L, v_L, F_R, v_R, P0, gamma, rho0, iterations: int = 200):
    """The star state ``(F*, v*)`` between the two waves of the p-system's Riemann problem.

    Solves ``v_left(F*) = v_right(F*)`` (the left wave curve is increasing in ``F*``, the right one
    decreasing) by bisection in ``ln F*`` to round-off, then one Newton step on that value, so that
    derivatives follow the implicit function theorem. A vacuum raises nothing: when the data pull
    apart faster than ``g(F_L) + g(F_R)`` a vacuum forms and ``F*`` runs to the top of the bracket;
    check ``vacuum_forms`` first.

    The states and the gas are one number each (one problem); ``jax.vmap`` over this function
    solves several.

    Args:
        F_L: deformation gradient of the left state.
        v_L: velocity of the left state.
        F_R: deformation gradient of the right state.
        v_R: velocity of the right state.
        P0: the gas's pressure at ``F = 1``.
        gamma: its adiabatic exponent.
        rho0: its initial density.
        iterations: bisection steps.

    Returns:
        ``(F_star, v_star)``.

    Raises:
        ValueError: a concrete ``F_L``, ``F_R``, ``P0`` or ``rho0`` is not finite and > 0 (``P0 = 0``
            has no wave curves to solve on), ``v_L`` or ``v_R`` is not finite, ``gamma`` is not finite
            and > 1, or any of them is an array with a shape (tracers are not checked); or
            ``iterations`` is not an integer >= 1.
    """
    _check_one_problem("riemann_star", F_L, v_L, F_R, v_R, P0, gamma, rho0)
    check_int("iterations", iterations, 1)
    return _riemann_star(F_L, v_L, F_R, v_R, P0, gamma, rho0, iterations)


@functools.partial(jax.jit, static_argnums=7)
def _riemann_star(F_L, v_L, F_R, v_R, P0, gamma, rho0, iterations):
    """``riemann_star``, compiled once per dtype (its bisection loop would otherwise compile at every
    call with concrete values)."""

    def f(y):
        F = jnp.exp(y)
        return _branches(F, F_L, v_L, P0, gamma, rho0, -1.0) - _branches(F, F_R, v_R, P0, gamma, rho0, 1.0)

    lo0 = jnp.log(jnp.minimum(F_L, F_R)) - 60.0 / gamma
    hi0 = jnp.log(jnp.maximum(F_L, F_R)) + 400.0 / gamma

    def bisect(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        up = f(mid) > 0.0
        return jnp.where(up, lo, mid), jnp.where(up, mid, hi)

    lo, hi = jax.lax.fori_loop(0, iterations, bisect, (lo0, hi0))
    y = jax.lax.stop_gradient(0.5 * (lo + hi))
    y = y - f(y) / jax.grad(f)(y)
    F = jnp.exp(y)
    return F, _branches(F, F_L, v_L, P0, gamma, rho0, -1.0)


def vacuum_forms(F_L, v_L, F_R, v_R, P0, gamma, rho0):
    """Whether the data pull apart faster than the gas can follow (no star state of finite F).

    Args:
        F_L: as for ``riemann_star``.
        v_L: as for ``riemann_star``.
        F_R: as for ``riemann_star``.
        v_R: as for ``riemann_star``.
        P0: as for ``riemann_star``.
        gamma: as for ``riemann_star``.
        rho0: as for ``riemann_star``.

    Returns:
        ``v_R - v_L >= g(F_L) + g(F_R)``, elementwise where the states are arrays (this test, unlike
        ``riemann_star``, broadcasts).

    Raises:
        ValueError: as ``riemann_star``, for any entry of an array.
    """
    _check_states(F_L, v_L, F_R, v_R, P0, gamma, rho0)
    g = 2.0 / (gamma - 1.0)
    c = lambda F: _sound_speed(F, P0, gamma, rho0)
    return v_R - v_L >= g * (c(F_L) + c(F_R))


def _check_no_vacuum(caller: str, F_L, v_L, F_R, v_R, P0, gamma, rho0) -> None:
    """Refuse concrete data from which a vacuum forms: the waves and fields below assume a star
    state of finite ``F`` (traced data are not checked)."""
    data = (F_L, v_L, F_R, v_R, P0, gamma, rho0)
    if all(is_concrete(a) for a in data) and bool(vacuum_forms(*data)):
        raise ValueError(
            f"{caller}: the data pull apart faster than the gas can follow (v_R - v_L = "
            f"{float(v_R) - float(v_L):.6g} >= 2 (c(F_L) + c(F_R)) / (gamma - 1)): a vacuum "
            "forms between the waves, which this solution does not describe (see vacuum_forms)"
        )


def riemann_waves(F_L, v_L, F_R, v_R, P0, gamma, rho0):
    """The star state and the Lagrangian speeds bounding each wave.

    Returns a dict with ``F_star, v_star`` and ``a1 <= b1 < 0 < a2 <= b2``: the left wave spans
    ``a1 <= (X - X0)/t <= b1`` (a rarefaction fan, or a shock where ``a1 == b1``), the right wave
    ``a2 .. b2``; ``rare1``, ``rare2`` say which waves are rarefactions.

    Args:
        F_L: as for ``riemann_star``.
        v_L: as for ``riemann_star``.
        F_R: as for ``riemann_star``.
        v_R: as for ``riemann_star``.
        P0: as for ``riemann_star``.
        gamma: as for ``riemann_star``.
        rho0: as for ``riemann_star``.

    Returns:
        ``dict(F_star, v_star, a1, b1, a2, b2, rare1, rare2)``.

    Raises:
        ValueError: as ``riemann_star``, or concrete data from which a vacuum forms
            (``vacuum_forms``; traced, such data give meaningless values).
    """
    _check_one_problem("riemann_waves", F_L, v_L, F_R, v_R, P0, gamma, rho0)
    _check_no_vacuum("riemann_waves", F_L, v_L, F_R, v_R, P0, gamma, rho0)
    return _waves(F_L, v_L, F_R, v_R, P0, gamma, rho0)


def _waves(F_L, v_L, F_R, v_R, P0, gamma, rho0):
    """``riemann_waves`` without input checks."""
    F_s, v_s = _riemann_star(F_L, v_L, F_R, v_R, P0, gamma, rho0, 200)
    C = lambda F: _sound_speed(F, P0, gamma, rho0) / F

    def shock_speed(F0):
        dP = P0 * (F_s ** (-gamma) - F0 ** (-gamma))
        return jnp.sqrt(jnp.maximum(dP / (rho0 * (F0 - F_s)), 0.0))

    rare1, rare2 = F_s >= F_L, F_s >= F_R
    # a shock's speed is computed on the branch where it exists (the other branch is discarded)
    s1 = shock_speed(jnp.where(rare1, 2.0 * F_s, F_L))
    s2 = shock_speed(jnp.where(rare2, 2.0 * F_s, F_R))
    return dict(
        F_star=F_s,
        v_star=v_s,
        a1=jnp.where(rare1, -C(F_L), -s1),
        b1=jnp.where(rare1, -C(F_s), -s1),
        a2=jnp.where(rare2, C(F_s), s2),
        b2=jnp.where(rare2, C(F_R), s2),
        rare1=rare1,
        rare2=rare2,
    )


def _check_xi(xi) -> None:
    """Check the similarity variable: real, not NaN (``-inf`` and ``+inf`` are the outer states);
    a tracer passes."""
    check_real("xi", xi)
    if is_concrete(xi):
        arr = np.asarray(xi)
        if np.any(np.isnan(arr)):
            raise ValueError(f"xi must be a real number or +-inf, not NaN, got {show(arr)}")


def riemann_solution(xi, F_L, v_L, F_R, v_R, P0, gamma, rho0):
    """The self-similar solution at ``xi = (X - X0) / t``: ``(F, v, D)``.

    ``D(xi) = int_{-inf}^{xi} (F - F_0) dxi'``, with ``F_0`` the initial data, gives positions:
    ``x(X, t) = x(X, 0) + v_L t + t D(xi)`` (while the waves have not reached the ends).

    Args:
        xi: the similarity variable(s), any shape; ``-inf`` and ``+inf`` give the left and right
            states (``D`` its limit there), as at ``t = 0``.
        F_L: as for ``riemann_star``.
        v_L: as for ``riemann_star``.
        F_R: as for ``riemann_star``.
        v_R: as for ``riemann_star``.
        P0: as for ``riemann_star``.
        gamma: as for ``riemann_star``.
        rho0: as for ``riemann_star``.

    Returns:
        ``(F, v, D)`` at ``xi``.

    Raises:
        ValueError: as ``riemann_star`` (the states are one number each: ``jax.vmap`` over this
            function for several problems), concrete data from which a vacuum forms
            (``vacuum_forms``; traced, such data give meaningless values), or a concrete ``xi`` (any
            entry) is not a real number or is NaN.
    """
    _check_xi(xi)
    _check_one_problem("riemann_solution", F_L, v_L, F_R, v_R, P0, gamma, rho0)
    _check_no_vacuum("riemann_solution", F_L, v_L, F_R, v_R, P0, gamma, rho0)
    w = _waves(F_L, v_L, F_R, v_R, P0, gamma, rho0)
    a1, b1, a2, b2, F_s, v_s = w["a1"], w["b1"], w["a2"], w["b2"], w["F_star"], w["v_star"]
    K = jnp.sqrt(gamma * P0 / rho0)
    g = 2.0 / (gamma - 1.0)
    c = lambda F: _sound_speed(F, P0, gamma, rho0)
    # Inside a fan, C(F) = |xi|: F = (K / |xi|)^(2 / (gamma + 1)).
    fan_F = lambda z: (K / jnp.abs(z)) ** (2.0 / (gamma + 1.0))
    e = (gamma - 1.0) / (gamma + 1.0)
    Kf = K ** (2.0 / (gamma + 1.0))
    A_left = lambda z: -Kf * jnp.abs(z) ** e / e  # antiderivative of fan_F on xi < 0
    A_right = lambda z: Kf * jnp.abs(z) ** e / e  # and on xi > 0

    z1 = jnp.clip(xi, a1, b1)
    z2 = jnp.clip(xi, a2, b2)
    in1 = (xi > a1) & (xi < b1)
    in2 = (xi > a2) & (xi < b2)
    F1, F2 = fan_F(z1), fan_F(z2)
    F = jnp.where(xi <= a1, F_L, jnp.where(in1, F1, jnp.where(xi <= a2, F_s, jnp.where(in2, F2, F_R))))
    v = jnp.where(
        xi <= a1,
        v_L,
        jnp.where(
            in1,
            v_L + g * (c(F_L) - c(F1)),
            jnp.where(xi <= a2, v_s, jnp.where(in2, v_R - g * (c(F_R) - c(F2)), v_R)),
        ),
    )
    D = (
        jnp.where(w["rare1"], A_left(z1) - A_left(a1), 0.0)
        + F_s * (jnp.clip(xi, b1, a2) - b1)
        + jnp.where(w["rare2"], A_right(z2) - A_right(a2), 0.0)
        - F_L * (jnp.clip(xi, a1, 0.0) - a1)
        - F_R * jnp.clip(xi, 0.0, b2)
    )
    return F, v, D


def vacuum_expansion(X, t, L, P0, gamma, rho0):
    """Gas at rest on ``[0, L]`` expanding into vacuum from ``X = L``: ``(x, v, F)``.

    A material point is at rest until the rarefaction head reaches it at ``t_h = (L - X) / c0``;
    then ``x = L + eta t``, ``eta = (2 c0 - (gamma+1) c0 s) / (gamma - 1)``, ``s = (t/t_h)^-k``,
    ``k = (gamma-1)/(gamma+1)``, so ``v = 2 c0 (1 - s) / (gamma - 1)`` and ``F = (t / t_h)^(2/(gamma+1))``.
    Valid until the head reaches the wall, ``0 <= t <= L / c0``. At the front (``X = L``) ``F`` is
    infinite, and so are the derivatives of ``x`` and ``v`` in ``X`` and ``L`` there (one-sided);
    those in ``t``, ``P0``, ``gamma`` and ``rho0`` are finite. (The rarefaction into vacuum of Toro,
    ch. 4, in Lagrangian form.)

    Args:
        X: reference position(s), in ``[0, L]`` (the body).
        t: time.
        L: the gas's initial length.
        P0: the gas's pressure at ``F = 1``.
        gamma: its adiabatic exponent.
        rho0: its initial density.

    Returns:
        ``(x, v, F)``: position, velocity and the point value of ``F``.

    Raises:
        ValueError: a concrete ``X`` (any entry) or ``t`` is not finite, or ``L``, ``P0``, ``rho0``
            are not finite and > 0, or ``gamma`` is not finite and > 1, or a concrete ``X`` (any
            entry) lies outside ``[0, L]``, or a concrete ``t`` (any entry) outside
            ``[0, L / c0]`` (to 8 ulps; tracers are not checked).
    """
    check_finite("X", X)
    check_finite("t", t)
    check_positive("L", L)
    _check_gas(P0, gamma, rho0)
    if is_concrete(X) and is_concrete(L):
        arr, length = np.asarray(X), np.asarray(L)
        if not np.all((arr >= 0) & (arr <= length)):
            raise ValueError(f"X must lie in the body [0, L] = [0, {show(length)}], got {show(arr)}")
    c0 = jnp.sqrt(gamma * P0 / rho0)
    if all(is_concrete(a) for a in (t, L, P0, gamma, rho0)):
        times, t_wall = np.asarray(t), float(np.asarray(L) / np.asarray(c0))
        eps = float(np.finfo(np.result_type(times.dtype, np.float32)).eps)
        if not np.all((times >= 0) & (times <= t_wall * (1.0 + 8.0 * eps))):
            raise ValueError(
                f"t must lie in [0, L / c0] = [0, {t_wall:.6g}] (the solution holds until the "
                f"rarefaction's head reaches the wall), got {show(times)}"
            )
    d = L - X  # the distance from the front, c0 times the head's arrival t_h
    moving = t > d / c0
    # s = (t / t_h)^-k = d^k (c0 t)^-k: at the front (d = 0) it is 0, its derivative in d (X, L)
    # infinite and in c0 and t zero, where the quotient t / t_h would make them all NaN
    k = (gamma - 1.0) / (gamma + 1.0)
    d_m, ct_m = jnp.where(moving, d, 1.0), jnp.where(moving, c0 * t, 1.0)
    s = jnp.where(moving, d_m**k * ct_m ** (-k), 1.0)
    eta = (2.0 * c0 - (gamma + 1.0) * c0 * s) / (gamma - 1.0)
    x = jnp.where(moving, L + eta * t, X)
    v = jnp.where(moving, 2.0 * c0 * (1.0 - s) / (gamma - 1.0), 0.0)
    F = jnp.where(moving, (ct_m / d_m) ** (2.0 / (gamma + 1.0)), 1.0)
    return x, v, F
