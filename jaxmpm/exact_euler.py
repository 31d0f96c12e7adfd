"""Exact solutions of the 1D Euler equations of an ideal gas, ``p = (gamma - 1) rho e``: the Riemann
problem and the planar Noh problem. Pure JAX functions of their parameters, so they jit, vmap and
differentiate; they compute in the default float dtype (float64 once the caller enables x64).

The Riemann problem (Toro, "Riemann solvers and numerical methods for fluid dynamics", ch. 4) starts
from a left state ``W_L = (rho_l, u_l, p_l)`` and a right state ``W_R`` meeting at ``x0``. The
solution depends on ``S = (x - x0) / t`` only: a left wave, a contact moving at ``u*`` and a right
wave, each outer wave a shock or a rarefaction fan. Pressure and velocity are the same on both sides
of the contact (the star region); the density jumps there.

The star pressure ``p*`` is the root of ``f(p) = f_L(p) + f_R(p) + u_r - u_l``, where ``f_K`` gives
the velocity change across the wave of side ``K``:

- ``p > p_K`` (a shock): ``f_K = (p - p_K) sqrt(A_K / (p + B_K))``, ``A_K = 2 / ((gamma + 1) rho_K)``,
  ``B_K = (gamma - 1) p_K / (gamma + 1)``, from the Rankine-Hugoniot conditions;
- ``p <= p_K`` (a rarefaction): ``f_K = 2 c_K ((p / p_K)^z - 1) / (gamma - 1)``,
  ``z = (gamma - 1) / (2 gamma)``, from the Riemann invariant and the isentrope.

Then ``u* = (u_l + u_r + f_R(p*) - f_L(p*)) / 2``. ``f`` is increasing and concave, so Newton's
method started at or above ``p_min = min(p_l, p_r)`` falls below the root after one step and then
climbs to it monotonically. If ``f(p_min) >= 0`` both waves are rarefactions and the root is the
two-rarefaction value ``p_TR`` in closed form (the iteration starts there and stays); otherwise
``p* > p_min``, the iteration starts at Toro's primitive-variable or two-shock guess and an iterate
that falls below ``p_min`` is put back on it. It runs in a ``lax.while_loop`` until the relative
change is below ``sqrt(eps)``, and one more Newton step outside the loop, on the stopped iterate,
carries the derivatives: those of the implicit function ``f(p*; W_L, W_R, gamma) = 0``.

Behind a shock the density follows from the Rankine-Hugoniot relation, behind a rarefaction from the
isentrope ``p / rho^gamma = const``; the fans are sampled as in Toro, section 4.5.

When ``2 (c_l + c_r) / (gamma - 1) <= u_r - u_l`` the data pull apart faster than the gas can follow
and a vacuum forms between two rarefactions: there is no star state. The functions then return NaN
for everything the star state enters (``riemann_star``, ``riemann_waves``, ``riemann_solution``);
``vacuum_generated`` and the ``vacuum`` entry of ``riemann_waves`` tell that case apart.

``riemann_star``, ``riemann_waves`` and ``riemann_solution`` solve one Riemann problem: the states
and ``gamma`` are one number each, and ``jax.vmap`` over the function solves several.
``vacuum_generated`` is elementwise and takes arrays of states.

Input checks (positive densities and pressures, ``gamma > 1``, finite velocities, one number per
state, ``t > 0``) run when the values are concrete and raise a ``ValueError`` naming the parameter.
Under ``jax.jit``, ``jax.vmap`` or ``jax.grad`` the values are tracers and are not checked: bad values
then give NaN or finite but meaningless values, and no error (a traced ``t = 0``, say, gives the
initial states on either side of ``x0`` and a finite state at ``x0``; a traced ``t < 0`` gives a
finite, mirrored wave pattern).
"""

import jax
import jax.numpy as jnp

from ._checks import (
    check_finite,
    check_greater,
    check_nonnegative,
    check_positive,
    check_real,
    check_scalar,
)

_MAX_ITERATIONS = 60


def _float(x):
    return jnp.asarray(x, dtype=jnp.result_type(float))


def _check_states(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    for name, value in (("rho_l", rho_l), ("p_l", p_l), ("rho_r", rho_r), ("p_r", p_r)):
        check_real(name, value)
        check_positive(name, value)
    for name, value in (("u_l", u_l), ("u_r", u_r)):
        check_real(name, value)
        check_finite(name, value)
    check_real("gamma", gamma)
    check_greater("gamma", gamma, 1.0)


def _check_one_problem(caller, rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """Check the states (``_check_states``) and that each of them and ``gamma`` is one number:
    ``caller`` solves one Riemann problem (tracers pass, so ``jax.vmap`` solves several)."""
    _check_states(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    batch = f"; to solve several Riemann problems, jax.vmap over {caller}"
    args = dict(rho_l=rho_l, u_l=u_l, p_l=p_l, rho_r=rho_r, u_r=u_r, p_r=p_r, gamma=gamma)
    for name, value in args.items():
        check_scalar(name, value, batch)


def _sound_speed(rho, p, gamma):
    return jnp.sqrt(gamma * p / rho)


def _pressure_function(p, rho_k, p_k, c_k, gamma):
    """``f_K(p)`` and ``f_K'(p)`` (Toro, sections 4.2 and 4.3)."""
    A = 2.0 / ((gamma + 1.0) * rho_k)
    B = (gamma - 1.0) / (gamma + 1.0) * p_k
    z = (gamma - 1.0) / (2.0 * gamma)
    shock = p > p_k
    q = jnp.sqrt(A / (p + B))
    f_shock = (p - p_k) * q
    df_shock = q * (1.0 - 0.5 * (p - p_k) / (p + B))
    ratio = p / p_k
    f_rare = 2.0 * c_k / (gamma - 1.0) * (ratio**z - 1.0)
    df_rare = ratio ** (-(gamma + 1.0) / (2.0 * gamma)) / (rho_k * c_k)
    return jnp.where(shock, f_shock, f_rare), jnp.where(shock, df_shock, df_rare)


def _vacuum(c_l, u_l, c_r, u_r, gamma):
    return 2.0 * (c_l + c_r) / (gamma - 1.0) <= u_r - u_l


def _f(p, rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """``f(p)`` and ``f'(p)``."""
    f_l, df_l = _pressure_function(p, rho_l, p_l, _sound_speed(rho_l, p_l, gamma), gamma)
    f_r, df_r = _pressure_function(p, rho_r, p_r, _sound_speed(rho_r, p_r, gamma), gamma)
    return f_l + f_r + u_r - u_l, df_l + df_r


def _iterate(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """Newton's iteration for ``p*`` (not differentiable: the caller passes stopped values)."""
    args = (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    c_l, c_r = _sound_speed(rho_l, p_l, gamma), _sound_speed(rho_r, p_r, gamma)
    du = u_r - u_l
    vacuum = _vacuum(c_l, u_l, c_r, u_r, gamma)
    z = (gamma - 1.0) / (2.0 * gamma)
    p_min, p_max = jnp.minimum(p_l, p_r), jnp.maximum(p_l, p_r)
    # Two rarefactions: the closed form (Toro, section 4.3); its numerator is positive unless a vacuum forms.
    numerator = jnp.where(vacuum, 1.0, c_l + c_r - 0.5 * (gamma - 1.0) * du)
    p_tr = (numerator / (c_l / p_l**z + c_r / p_r**z)) ** (1.0 / z)
    two_rarefactions = _f(p_min, *args)[0] >= 0.0
    # Otherwise p* > p_min: Toro's primitive-variable guess, or his two-shock guess
    # where that one lies above p_max.
    p_pv = jnp.maximum(0.5 * (p_l + p_r) - 0.125 * du * (rho_l + rho_r) * (c_l + c_r), p_min)
    g_l = jnp.sqrt(2.0 / ((gamma + 1.0) * rho_l) / (p_pv + (gamma - 1.0) / (gamma + 1.0) * p_l))
    g_r = jnp.sqrt(2.0 / ((gamma + 1.0) * rho_r) / (p_pv + (gamma - 1.0) / (gamma + 1.0) * p_r))
    p_ts = jnp.maximum((g_l * p_l + g_r * p_r - du) / (g_l + g_r), p_min)
    p0 = jnp.where(two_rarefactions, p_tr, jnp.where(p_pv <= p_max, p_pv, p_ts))
    floor = jnp.where(two_rarefactions, 0.5 * p_tr, p_min)
    tol = jnp.sqrt(jnp.finfo(p0.dtype).eps)

    def newton(p):
        value, slope = _f(p, *args)
        return jnp.maximum(p - value / slope, floor)

    def cond(state):
        k, _, change = state
        return (k < _MAX_ITERATIONS) & (change > tol) & ~vacuum

    def body(state):
        k, p, _ = state
        p_next = newton(p)
        return k + 1, p_next, jnp.abs(p_next - p) / p_next

    _, p, _ = jax.lax.while_loop(cond, body, (0, p0, jnp.ones_like(p0)))
    return newton(p), vacuum


@jax.jit
def _star(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """The star state without input checks: ``(p*, u*, rho*_l, rho*_r, vacuum)``."""
    args = (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    p_c, vacuum = _iterate(*jax.lax.stop_gradient(args))
    # One more Newton step, on the parameters themselves, carries the derivatives of the root.
    value, slope = _f(p_c, *args)
    p_star = p_c - value / slope
    f_l, _ = _pressure_function(p_star, rho_l, p_l, _sound_speed(rho_l, p_l, gamma), gamma)
    f_r, _ = _pressure_function(p_star, rho_r, p_r, _sound_speed(rho_r, p_r, gamma), gamma)
    u_star = 0.5 * (u_l + u_r) + 0.5 * (f_r - f_l)
    rho_star_l = _density_behind(p_star, rho_l, p_l, gamma)
    rho_star_r = _density_behind(p_star, rho_r, p_r, gamma)
    nan = lambda a: jnp.where(vacuum, jnp.nan, a)
    return nan(p_star), nan(u_star), nan(rho_star_l), nan(rho_star_r), vacuum


def _density_behind(p_star, rho_k, p_k, gamma):
    """Density behind the wave of side ``K``: Rankine-Hugoniot or the isentrope (Toro, section 4.4)."""
    ratio = p_star / p_k
    mu = (gamma - 1.0) / (gamma + 1.0)
    shock = rho_k * (ratio + mu) / (mu * ratio + 1.0)
    rare = rho_k * ratio ** (1.0 / gamma)
    return jnp.where(p_star > p_k, shock, rare)


def riemann_star(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """The star state of the Euler Riemann problem: pressure and velocity between the two outer waves,
    and the density on each side of the contact.

    Solves ``f_L(p) + f_R(p) + u_r - u_l = 0`` by Newton's method (see the module docstring); the
    derivatives are those of the implicit function. When a vacuum forms (``vacuum_generated``) there
    is no star state and every output is NaN.

    Args:
        rho_l: density of the left state (> 0).
        u_l: velocity of the left state.
        p_l: pressure of the left state (> 0).
        rho_r: density of the right state (> 0).
        u_r: velocity of the right state.
        p_r: pressure of the right state (> 0).
        gamma: the ratio of specific heats (> 1).

    Returns:
        ``(p_star, u_star, rho_star_l, rho_star_r)``.

    Raises:
        ValueError: a concrete density or pressure is not > 0, a velocity is not finite, ``gamma`` is
            not > 1, a value is not a real number, or a value is an array with a shape (one problem
            at a time: ``jax.vmap`` over this function solves several); tracers are not checked.
    """
    _check_one_problem("riemann_star", rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    args = [_float(a) for a in (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)]
    return _star(*args)[:4]


def vacuum_generated(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """Whether the two states pull apart fast enough to open a vacuum between them (no star state).

    Args:
        rho_l: as for ``riemann_star``.
        u_l: as for ``riemann_star``.
        p_l: as for ``riemann_star``.
        rho_r: as for ``riemann_star``.
        u_r: as for ``riemann_star``.
        p_r: as for ``riemann_star``.
        gamma: as for ``riemann_star``.

    Returns:
        ``2 (c_l + c_r) / (gamma - 1) <= u_r - u_l``, ``c = sqrt(gamma p / rho)``, elementwise where
        the states are arrays (this test, unlike ``riemann_star``, broadcasts).

    Raises:
        ValueError: as for ``riemann_star``, for any entry of an array (arrays are allowed here).
    """
    _check_states(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    rho_l, u_l, p_l, rho_r, u_r, p_r, gamma = [_float(a) for a in (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)]
    return _vacuum(_sound_speed(rho_l, p_l, gamma), u_l, _sound_speed(rho_r, p_r, gamma), u_r, gamma)


@jax.jit
def _wave_parts(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """The star state, the shock speeds, the sound speeds of the four states and the kind of each wave."""
    p_s, u_s, rho_sl, rho_sr, vacuum = _star(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    c_l, c_r = _sound_speed(rho_l, p_l, gamma), _sound_speed(rho_r, p_r, gamma)
    shock_l, shock_r = p_s > p_l, p_s > p_r
    z = (gamma - 1.0) / (2.0 * gamma)
    w = (gamma + 1.0) / (2.0 * gamma)
    # Shock speeds (Toro, section 4.4), used on their branch.
    s_l = u_l - c_l * jnp.sqrt(w * p_s / p_l + z)
    s_r = u_r + c_r * jnp.sqrt(w * p_s / p_r + z)
    # Sound speeds of the star states: isentropic behind a fan (whose tail is u* -/+ c*), from the
    # Rankine-Hugoniot density behind a shock.
    c_sl = jnp.where(shock_l, _sound_speed(rho_sl, p_s, gamma), c_l * (p_s / p_l) ** z)
    c_sr = jnp.where(shock_r, _sound_speed(rho_sr, p_s, gamma), c_r * (p_s / p_r) ** z)
    return p_s, u_s, rho_sl, rho_sr, c_sl, c_sr, shock_l, shock_r, s_l, s_r, c_l, c_r, vacuum


def _waves(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    # The wave edges are chosen from the compiled parts, outside their program: within one program
    # XLA's CPU backend computes a shock speed anew in each output that reads it, and may round the
    # copies differently (a shock's head and tail 1 ulp apart).
    parts = _wave_parts(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    p_s, u_s, rho_sl, rho_sr, c_sl, c_sr, shock_l, shock_r, s_l, s_r, c_l, c_r, vacuum = parts
    nan = lambda a: jnp.where(vacuum, jnp.nan, a)
    return dict(
        p_star=p_s,
        u_star=u_s,
        rho_star_l=rho_sl,
        rho_star_r=rho_sr,
        c_star_l=c_sl,
        c_star_r=c_sr,
        shock_l=shock_l,
        shock_r=shock_r,
        head_l=nan(jnp.where(shock_l, s_l, u_l - c_l)),
        tail_l=nan(jnp.where(shock_l, s_l, u_s - c_sl)),
        contact=u_s,
        tail_r=nan(jnp.where(shock_r, s_r, u_s + c_sr)),
        head_r=nan(jnp.where(shock_r, s_r, u_r + c_r)),
        vacuum=vacuum,
    )


def riemann_waves(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """The star state and the speeds of the waves of the Euler Riemann problem.

    The left wave spans ``head_l <= S <= tail_l``, ``S = (x - x0) / t``: a rarefaction fan, or a
    shock where ``head_l == tail_l`` (``shock_l``); the contact moves at ``contact = u_star``; the
    right wave spans ``tail_r <= S <= head_r``. So ``head_l <= tail_l <= contact <= tail_r <= head_r``.
    When a vacuum forms (``vacuum``) every float entry is NaN.

    Args:
        rho_l: as for ``riemann_star``.
        u_l: as for ``riemann_star``.
        p_l: as for ``riemann_star``.
        rho_r: as for ``riemann_star``.
        u_r: as for ``riemann_star``.
        p_r: as for ``riemann_star``.
        gamma: as for ``riemann_star``.

    Returns:
        A dict with ``p_star, u_star, rho_star_l, rho_star_r``, the sound speeds ``c_star_l,
        c_star_r`` in the star region, the booleans ``shock_l, shock_r``, the speeds ``head_l,
        tail_l, contact, tail_r, head_r`` and the boolean ``vacuum``.

    Raises:
        ValueError: as for ``riemann_star`` (naming ``riemann_waves`` for ``jax.vmap``).
    """
    _check_one_problem("riemann_waves", rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    return _waves(*[_float(a) for a in (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)])


def riemann_solution(x, t, rho_l, u_l, p_l, rho_r, u_r, p_r, gamma, x0=0.0):
    """The exact solution of the Euler Riemann problem at positions ``x`` and time ``t > 0``.

    Samples the wave pattern of ``riemann_waves`` at ``S = (x - x0) / t`` (Toro, section 4.5). Inside
    a left fan ``u = 2 (c_l + (gamma - 1) u_l / 2 + S) / (gamma + 1)``,
    ``rho = rho_l b^(2 / (gamma - 1))``, ``p = p_l b^(2 gamma / (gamma - 1))``,
    ``b = 2 / (gamma + 1) + (gamma - 1) (u_l - S) / ((gamma + 1) c_l)``; a right fan mirrors it.
    A point on a shock or on the contact takes the state on its right (the other wave edges are
    continuous); a point put there from the speeds of ``riemann_waves`` (``x = x0 + S t``) is on it
    in a plain call, which samples at those same numbers (inside ``jax.jit`` the speeds are computed
    within the program and may differ from them in the last bit). When a vacuum forms every
    output is NaN (check ``vacuum_generated``).

    Args:
        x: Eulerian position(s), any shape.
        t: time (> 0).
        rho_l: as for ``riemann_star``.
        u_l: as for ``riemann_star``.
        p_l: as for ``riemann_star``.
        rho_r: as for ``riemann_star``.
        u_r: as for ``riemann_star``.
        p_r: as for ``riemann_star``.
        gamma: as for ``riemann_star``.
        x0: where the two states meet at ``t = 0``.

    Returns:
        A dict with ``rho``, ``u``, ``p`` and ``e = p / ((gamma - 1) rho)`` at ``x``.

    Raises:
        ValueError: as for ``riemann_star`` (naming ``riemann_solution`` for ``jax.vmap``), or a
            concrete ``t`` is not > 0, or ``x`` or ``x0`` is not finite.
    """
    _check_one_problem("riemann_solution", rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
    for name, value in (("x", x), ("x0", x0)):
        check_real(name, value)
        check_finite(name, value)
    check_real("t", t)
    check_positive("t", t)
    states = [_float(a) for a in (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)]
    # The wave speeds of riemann_waves, the same numbers (its compiled program), so that a point put
    # exactly on a wave it returns is sampled as documented.
    return _sample(_float(x), _float(t), _waves(*states), *states, _float(x0))


@jax.jit
def _sample(x, t, wv, rho_l, u_l, p_l, rho_r, u_r, p_r, gamma, x0):
    c_l, c_r = _sound_speed(rho_l, p_l, gamma), _sound_speed(rho_r, p_r, gamma)
    S = (x - x0) / t
    gp, gm = gamma + 1.0, gamma - 1.0

    # Left fan, evaluated at its head outside it (where b = 1), so that no branch sees a bad power.
    in_l = ~wv["shock_l"] & (S >= wv["head_l"]) & (S < wv["tail_l"])
    S_l = jnp.where(in_l, S, u_l - c_l)
    b_l = 2.0 / gp + gm / (gp * c_l) * (u_l - S_l)
    fan_l = (
        rho_l * b_l ** (2.0 / gm),
        2.0 / gp * (c_l + 0.5 * gm * u_l + S_l),
        p_l * b_l ** (2.0 * gamma / gm),
    )
    in_r = ~wv["shock_r"] & (S > wv["tail_r"]) & (S < wv["head_r"])
    S_r = jnp.where(in_r, S, u_r + c_r)
    b_r = 2.0 / gp - gm / (gp * c_r) * (u_r - S_r)
    fan_r = (
        rho_r * b_r ** (2.0 / gm),
        2.0 / gp * (-c_r + 0.5 * gm * u_r + S_r),
        p_r * b_r ** (2.0 * gamma / gm),
    )

    left, right = (rho_l, u_l, p_l), (rho_r, u_r, p_r)
    star_l = (wv["rho_star_l"], wv["u_star"], wv["p_star"])
    star_r = (wv["rho_star_r"], wv["u_star"], wv["p_star"])
    out = []
    for k in range(3):
        on_left = jnp.where(S < wv["head_l"], left[k], jnp.where(in_l, fan_l[k], star_l[k]))
        on_right = jnp.where(S >= wv["head_r"], right[k], jnp.where(in_r, fan_r[k], star_r[k]))
        value = jnp.where(S < wv["contact"], on_left, on_right)
        out.append(jnp.where(wv["vacuum"], jnp.nan, value))
    rho, u, p = out
    return dict(rho=rho, u=u, p=p, e=p / (gm * rho))


def noh(x, t, gamma=5.0 / 3.0, rho0=1.0, u0=1.0):
    """The planar Noh problem: cold gas (``rho0``, ``e = p = 0``) streaming at ``u = -u0`` onto a wall
    at ``x = 0``.

    A shock leaves the wall at ``D = (gamma - 1) u0 / 2`` and brings the gas to rest. The
    Rankine-Hugoniot conditions in the shock's frame, with ``u = 0`` behind it, give: mass,
    ``rho0 (u0 + D) = rho D``; momentum, ``p = rho0 u0 (u0 + D)``; energy, ``e = u0^2 / 2``
    (the kinetic energy the gas loses). With ``p = (gamma - 1) rho e`` these fix
    ``rho = rho0 (gamma + 1) / (gamma - 1)`` (the strong-shock limit) and ``p = rho0 u0^2 (gamma + 1) / 2``;
    for ``gamma = 5/3``: ``D = 1/3``, ``rho = 4 rho0``, ``p = 4 rho0 u0^2 / 3``, ``e = u0^2 / 2``.
    Behind the shock (``x < D t``) that state, ahead of it the initial one.

    The problem lives on ``x >= 0``; ``x < 0`` gets the mirror image (``rho, p, e`` even, ``u`` odd),
    the symmetric collision of two streams the wall stands for.

    Args:
        x: Eulerian position(s), any shape.
        t: time (>= 0).
        gamma: the ratio of specific heats (> 1).
        rho0: the initial density (> 0).
        u0: the speed of the incoming gas (> 0).

    Returns:
        A dict with ``rho``, ``u``, ``p`` and ``e`` at ``x``.

    Raises:
        ValueError: a concrete ``t`` is negative, ``gamma`` not > 1, ``rho0`` or ``u0`` not > 0, or
            ``x`` not finite (tracers are not checked).
    """
    for name, value in (("x", x), ("t", t), ("gamma", gamma), ("rho0", rho0), ("u0", u0)):
        check_real(name, value)
    check_finite("x", x)
    check_nonnegative("t", t)
    check_greater("gamma", gamma, 1.0)
    check_positive("rho0", rho0)
    check_positive("u0", u0)
    x, t, gamma, rho0, u0 = [_float(a) for a in (x, t, gamma, rho0, u0)]
    D = 0.5 * (gamma - 1.0) * u0
    behind = jnp.abs(x) < D * t
    rho = jnp.where(behind, rho0 * (gamma + 1.0) / (gamma - 1.0), rho0)
    u = jnp.where(behind, 0.0, -jnp.sign(x) * u0)
    p = jnp.where(behind, 0.5 * rho0 * u0**2 * (gamma + 1.0), 0.0)
    e = jnp.where(behind, 0.5 * u0**2, 0.0)
    return dict(rho=rho, u=u, p=p, e=e)
