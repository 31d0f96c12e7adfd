"""The exact CJ-Taylor detonation wave of ``jaxmpm.exact_detonation``: the gamma = 3 numbers, the
characteristic relations of the Taylor fan, the particle paths against the fields, the free surface,
the quadrature for any isentrope against the closed form (and on JWL's isentrope against a diffrax
integration of the paths), gradients and input checks. Float64 is on for the whole suite
(``conftest.py``)."""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import float32

from jaxmpm import explosives
from jaxmpm.exact_detonation import (
    Isentrope,
    cj_point,
    gamma_law_cj,
    gamma_law_fields,
    gamma_law_isentrope,
    gamma_law_particles,
    gamma_law_wall_pressure,
    gamma_law_wall_time,
    isentrope_fan,
)
from jaxmpm.explosives import GammaLawIsentrope, JWLIsentrope
from jaxmpm.materials import IdealGas

RHO0, D = 1.7, 0.8
T = 1.3
X = jnp.array([0.2, 0.5, 0.9])
# Times as multiples of the burning time X / D: in the fan, around the wall time (2.25 for gamma = 3,
# 2.52 for gamma = 1.4) and long after it.
RATIOS = (1.3, 2.0, 4.0, 10.0)
ENDS = ("wall", "free")
GAMMAS = (3.0, 1.4)
# TNT's JWL principal isentrope (Dobratz & Crawford, LLNL Explosives Handbook; Mbar, g/cm^3, cm/us).
TNT = dict(A=3.712, B=0.03231, C=0.01045, R1=4.15, R2=0.95, w=0.30)
RHO0_TNT = 1.63


def _close(a, b, scale, tol=1e-12):
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0.0, atol=tol * scale)


def _fan_x(gamma, end, n=7):
    """Eulerian points inside the fan at ``T`` (ends excluded)."""
    lo = 0.5 * D * T if end == "wall" else -D * T / (gamma - 1.0)
    return jnp.linspace(lo, D * T, n + 2)[1:-1]


def test_gamma_3_numbers():
    cj = gamma_law_cj(RHO0, D, 3.0)
    P_CJ = RHO0 * D**2 / 4.0
    expected = dict(D=D, P_CJ=P_CJ, J_CJ=0.75, u_CJ=D / 4.0, c_CJ=0.75 * D, rho_CJ=4.0 * RHO0 / 3.0)
    for key, value in expected.items():
        np.testing.assert_allclose(cj[key], value, rtol=1e-15)
    np.testing.assert_allclose(gamma_law_wall_pressure(RHO0, D, 3.0), 8.0 / 27.0 * P_CJ, rtol=1e-15)
    t_w = gamma_law_wall_time(X, D, 3.0)
    np.testing.assert_allclose(t_w, 9.0 * X / (4.0 * D), rtol=1e-15)
    # At burning F = 3/4 and x = X; from t_w on F = 9/8 at x = 9/8 X, at rest under 8/27 p_CJ.
    lit = gamma_law_particles(X, X / D, RHO0, D, 3.0)
    np.testing.assert_allclose(lit["F"], 0.75, rtol=1e-15)
    np.testing.assert_allclose(lit["x"], X, rtol=1e-15)
    np.testing.assert_allclose(lit["p"], P_CJ, rtol=1e-14)
    for t in (t_w, 1.5 * t_w):
        rest = gamma_law_particles(X, t, RHO0, D, 3.0)
        np.testing.assert_allclose(rest["F"], 9.0 / 8.0, rtol=1e-15)
        np.testing.assert_allclose(rest["x"], 9.0 / 8.0 * X, rtol=1e-15)
        np.testing.assert_allclose(rest["p"], 8.0 / 27.0 * P_CJ, rtol=1e-14)
        np.testing.assert_array_equal(rest["u"], 0.0)
    # Between the wall and x = D t / 2 the gas is at rest with c = D / 2.
    near = gamma_law_fields(jnp.linspace(0.0, 0.5 * D * T, 5), T, RHO0, D, 3.0)
    np.testing.assert_allclose(near["c"], 0.5 * D, rtol=1e-15)
    np.testing.assert_allclose(near["J"], 9.0 / 8.0, rtol=1e-15)
    np.testing.assert_allclose(near["p"], 8.0 / 27.0 * P_CJ, rtol=1e-14)


@pytest.mark.parametrize("end", ENDS)
@pytest.mark.parametrize("gamma", GAMMAS)
def test_fan_characteristics(gamma, end):
    cj = gamma_law_cj(RHO0, D, gamma)
    x = _fan_x(gamma, end)
    f = gamma_law_fields(x, T, RHO0, D, gamma, end)
    _close(f["u"] + f["c"], x / T, D)  # the + characteristics fan out from the origin
    invariant = cj["u_CJ"] - 2.0 * cj["c_CJ"] / (gamma - 1.0)
    _close(invariant, -D / (gamma - 1.0), D)
    _close(f["u"] - 2.0 * f["c"] / (gamma - 1.0), invariant, D)  # the - invariant is uniform
    _close(f["c"] ** 2, gamma * f["p"] / f["rho"], D**2)
    _close(f["p"], cj["P_CJ"] * (f["J"] / cj["J_CJ"]) ** (-gamma), cj["P_CJ"])
    _close(f["rho"], RHO0 / f["J"], RHO0)
    # The front carries the CJ state; just ahead of it the explosive is unburnt.
    front = gamma_law_fields(jnp.array([D * T, D * T * (1.0 + 1e-12)]), T, RHO0, D, gamma, end)
    for key, value in (("u", cj["u_CJ"]), ("c", cj["c_CJ"]), ("J", cj["J_CJ"]), ("p", cj["P_CJ"])):
        _close(front[key][0], value, abs(float(value)))
    np.testing.assert_array_equal([front[k][1] for k in ("u", "c", "p", "rho", "J")], [0, 0, 0, RHO0, 1])
    if end == "wall":
        # The fan meets the gas at rest at x = D t / 2, and x < 0 is the mirror image.
        edge = gamma_law_fields(0.5 * D * T * jnp.array([1.0 - 1e-13, 1.0 + 1e-13]), T, RHO0, D, gamma)
        for key in ("u", "c", "p", "rho", "J"):
            _close(edge[key][0], edge[key][1], 1.0, 1e-11)
        _close(edge["u"], 0.0, D, 1e-11)
        mirror = gamma_law_fields(-x, T, RHO0, D, gamma)
        _close(mirror["u"], -f["u"], D, 0.0)
        for key in ("c", "p", "rho", "J"):
            _close(mirror[key], f[key], 1.0, 0.0)


@pytest.mark.parametrize("end", ENDS)
@pytest.mark.parametrize("gamma", GAMMAS)
def test_particle_paths(gamma, end):
    cj = gamma_law_cj(RHO0, D, gamma)
    t_w = gamma_law_wall_time(X, D, gamma)
    for ratio in RATIOS:
        t = ratio * X / D

        def path(X, t):
            return gamma_law_particles(X, t, RHO0, D, gamma, end)

        p, dp_dt = jax.jvp(lambda t: path(X, t), (t,), (jnp.ones_like(t),))
        _, dp_dX = jax.jvp(lambda X: path(X, t), (X,), (jnp.ones_like(X),))
        f = gamma_law_fields(p["x"], t, RHO0, D, gamma, end)
        _close(dp_dt["x"], f["u"], D)  # the particle moves with the flow
        _close(p["u"], f["u"], D)
        _close(dp_dX["x"], p["F"], 1.0)  # F = dx/dX
        _close(p["F"], f["J"], 1.0)  # ... = J, the mass balance
        _close(p["p"], f["p"], cj["P_CJ"])
        if end == "free" or ratio < float(t_w[0] * D / X[0]):
            s = ratio  # D t / X: the fan's closed form, for all t with a free surface
            a = 2.0 / (gamma + 1.0)
            x_fan = gamma / (gamma - 1.0) * X ** (1.0 - a) * (D * t) ** a - D * t / (gamma - 1.0)
            _close(p["x"], x_fan, 1.0)
            _close(p["F"], cj["J_CJ"] * s**a, 1.0)
    # Burning: x = X, F jumps from 1 to J_CJ.
    t_b = X / D
    before = gamma_law_particles(X, t_b * (1.0 - 1e-13), RHO0, D, gamma, end)
    lit = gamma_law_particles(X, t_b, RHO0, D, gamma, end)
    after = gamma_law_particles(X, t_b * (1.0 + 1e-13), RHO0, D, gamma, end)
    np.testing.assert_array_equal(before["F"], 1.0)
    np.testing.assert_array_equal(before["x"], X)
    _close(lit["x"], X, 1.0, 1e-15)
    _close(lit["F"], cj["J_CJ"], 1.0, 1e-15)
    for key in ("x", "F", "u", "p", "rho"):
        _close(after[key], lit[key], 1.0, 1e-11)
    if end == "wall":
        # Coming to rest at t_w: continuous, then fixed.
        sides = [gamma_law_particles(X, t_w * (1.0 + e), RHO0, D, gamma) for e in (-1e-13, 0.0, 1e-13)]
        for key in ("x", "F", "u", "p", "rho"):
            _close(sides[0][key], sides[2][key], 1.0, 1e-11)
        late = gamma_law_particles(X, 7.0 * t_w, RHO0, D, gamma)
        _close(late["x"], sides[1]["x"], 1.0, 1e-15)
        mirror = gamma_law_particles(-X, 1.5 * t_w, RHO0, D, gamma)
        here = gamma_law_particles(X, 1.5 * t_w, RHO0, D, gamma)
        _close(mirror["x"], -here["x"], 1.0, 0.0)
        _close(mirror["F"], here["F"], 1.0, 0.0)


@pytest.mark.parametrize("gamma", GAMMAS)
def test_free_surface(gamma):
    cj = gamma_law_cj(RHO0, D, gamma)
    escape = -D * T / (gamma - 1.0)
    f = gamma_law_fields(jnp.array([escape, escape * 1.01, 0.0]), T, RHO0, D, gamma, "free")
    # The fan reaches c = 0 where u = u_CJ - 2 c_CJ / (gamma - 1) = -D / (gamma - 1): the escape front.
    _close(f["u"][0], cj["u_CJ"] - 2.0 * cj["c_CJ"] / (gamma - 1.0), D)
    _close(f["u"][0], escape / T, D)
    _close(f["c"][0], 0.0, D)  # to round-off in x / t
    _close(f["p"][0], 0.0, float(cj["P_CJ"]))
    _close(f["rho"][0], 0.0, RHO0)
    assert float(f["J"][0]) > 1e15
    assert np.isnan(f["u"][1]) and float(f["rho"][1]) == 0.0 and float(f["J"][1]) == np.inf
    # No gas at rest: the wall's position moves backwards in the fan.
    _close(f["u"][2], -D / (gamma + 1.0), D)
    assert float(f["c"][2]) < 0.5 * D
    # The surface particle rides the escape front.
    s = gamma_law_particles(jnp.array([0.0]), T, RHO0, D, gamma, "free")
    _close(s["x"], escape, 1.0)
    assert float(s["F"][0]) == np.inf and float(s["p"][0]) == 0.0


def _compare(a, b, scales, mask=None, tol=1e-10):
    for key, scale in scales.items():
        u, v = np.asarray(a[key]), np.asarray(b[key])
        if mask is not None:
            assert np.all(np.isnan(u[~mask])), key
            u, v = u[mask], v[mask]
        np.testing.assert_allclose(u, v, rtol=tol, atol=tol * scale, err_msg=key)


@pytest.mark.slow
@pytest.mark.parametrize("end", ENDS)
@pytest.mark.parametrize("gamma", GAMMAS)
def test_quadrature_reproduces_gamma_law(gamma, end):
    p_s = gamma_law_isentrope(RHO0, D, gamma)
    cj = gamma_law_cj(RHO0, D, gamma)
    found = cj_point(p_s, RHO0)
    for key in cj:
        np.testing.assert_allclose(found[key], cj[key], rtol=1e-13, err_msg=key)
    J_max = 1e4
    fan = isentrope_fan(p_s, RHO0, D, cj["J_CJ"], end=end, J_max=J_max)
    scales = dict(u=D, c=D, p=float(cj["P_CJ"]), rho=RHO0, J=1.0)
    # Every region: mirror or vacuum side, rest, fan, front, unburnt.
    x = jnp.linspace(-3.0 * D * T, 1.2 * D * T, 23)
    exact = gamma_law_fields(x, T, RHO0, D, gamma, end)
    mask = None if end == "wall" else np.asarray(exact["J"]) < J_max
    _compare(fan.fields(x, T), exact, scales, mask)
    if end == "wall":
        J_w, p_w, _ = (float(gamma_law_fields(0.0, T, RHO0, D, gamma)[k]) for k in ("J", "p", "c"))
        np.testing.assert_allclose(fan.J_wall, J_w, rtol=1e-13)
        np.testing.assert_allclose(fan.wall_pressure, gamma_law_wall_pressure(RHO0, D, gamma), rtol=1e-12)
    XX = jnp.linspace(0.0, 1.0, 6)
    for t in (0.3, 1.0, 2.5, 6.0):
        exact = gamma_law_particles(XX, t, RHO0, D, gamma, end)
        mask = None if end == "wall" else np.asarray(exact["F"]) < J_max
        _compare(fan.particles(XX, t), exact, dict(u=D, c=D, p=scales["p"], rho=RHO0, x=1.0, F=1.0), mask)


@pytest.mark.slow
@pytest.mark.parametrize("end", ENDS)
def test_a_fan_takes_arrays_of_any_shape_axes_of_length_one_too(end):
    """fields and particles broadcast their arguments like NumPy: an axis of length 1 stays, and each
    entry is what the same point alone gives."""
    p_s = Isentrope(JWLIsentrope(rho0=RHO0_TNT, **TNT))
    cj = cj_point(p_s, RHO0_TNT)
    fan = isentrope_fan(p_s, RHO0_TNT, cj["D"], cj["J_CJ"], end=end)
    t = 0.6 / float(cj["D"])
    for X in (np.array([0.3]), np.array([[0.3], [0.45]]), np.array([0.3, 0.45])):
        for what in ("fields", "particles"):
            out = getattr(fan, what)(X, t)
            for k, v in out.items():
                assert v.shape == X.shape, (what, k, X.shape, v.shape)
                alone = [float(getattr(fan, what)(x, t)[k]) for x in X.ravel()]
                np.testing.assert_array_equal(np.asarray(v).ravel(), alone)


@pytest.mark.slow
def test_quadrature_on_jwl():
    """The TNT detonation on its JWL isentrope: the CJ point, the fan's invariant against its integrand,
    and the particle paths against the fields and against a diffrax integration of dx/dt = u(x, t)."""
    p_s = Isentrope(JWLIsentrope(rho0=RHO0_TNT, **TNT))
    cj = cj_point(p_s, RHO0_TNT)
    D_, J_CJ = float(cj["D"]), float(cj["J_CJ"])
    assert abs(D_ - 0.693) < 1e-3 and abs(float(cj["P_CJ"]) - 0.21) < 1e-3  # the handbook's CJ state
    slope = -jax.grad(p_s)(cj["J_CJ"])
    np.testing.assert_allclose(slope, RHO0_TNT * D_**2, rtol=1e-13)
    np.testing.assert_allclose(p_s(cj["J_CJ"]), RHO0_TNT * D_**2 * (1.0 - J_CJ), rtol=1e-13)
    wall = isentrope_fan(p_s, RHO0_TNT, cj["D"], cj["J_CJ"])
    _close(wall.velocity(wall.J_wall), 0.0, D_)
    J = jnp.linspace(J_CJ, 3.0, 5)
    u, du = jax.jvp(wall.velocity, (J,), (jnp.ones_like(J),))
    _close(du, -wall.lagrangian_speed(J), D_)  # the quadrature against its integrand
    _close(u[0], cj["u_CJ"], D_, 0.0)
    XX = jnp.array([0.3, 0.6, 1.0])
    for end in ENDS:
        fan = wall if end == "wall" else isentrope_fan(p_s, RHO0_TNT, cj["D"], cj["J_CJ"], end="free")
        for ratio in (1.5, 3.0):
            t = ratio * XX / D_
            p, dp_dt = jax.jvp(lambda t: fan.particles(XX, t), (t,), (jnp.ones_like(t),))
            _, dp_dX = jax.jvp(lambda X: fan.particles(X, t), (XX,), (jnp.ones_like(XX),))
            f = fan.fields(p["x"], t)
            _close(dp_dt["x"], f["u"], D_)
            _close(dp_dX["x"], p["F"], 1.0)
            _close(p["F"], f["J"], 1.0)
    # One path of the free case integrated through the fields: dx/dt = u(x, t) from x = X at X / D.
    X0 = 0.5
    t0 = X0 / D_
    ts = t0 * jnp.array([1.5, 2.5, 4.0])
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, x, args: fan.fields(x, t)["u"]),
        diffrax.Tsit5(),
        t0=t0,
        t1=ts[-1],
        dt0=None,
        y0=jnp.asarray(X0),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=1e-11, atol=1e-12),
        max_steps=4096,
    )
    _close(sol.ys, fan.particles(X0, ts)["x"], X0, 1e-9)


@pytest.mark.slow
def test_gradients_match_central_differences():
    h = 1e-6

    def central(f, v):
        return (f(v + h) - f(v - h)) / (2.0 * h)

    gamma = 2.7
    wall_p = lambda D, gamma: gamma_law_wall_pressure(RHO0, D, gamma)
    F_fan = lambda D, gamma: gamma_law_particles(0.5, 1.1, RHO0, D, gamma)["F"]  # in the fan
    x_rest = lambda D, gamma: gamma_law_particles(0.3, 3.0, RHO0, D, gamma)["x"]  # at rest
    for fun in (wall_p, F_fan, x_rest):
        dD, dg = jax.grad(fun, argnums=(0, 1))(D, gamma)
        np.testing.assert_allclose(dD, central(lambda v: fun(v, gamma), D), rtol=1e-8)
        np.testing.assert_allclose(dg, central(lambda v: fun(D, v), gamma), rtol=1e-8)

    # Through the quadrature, the roots and the CJ state of the isentrope: the closed form's gradients.
    def quad_F(D, gamma):
        fan = isentrope_fan(gamma_law_isentrope(RHO0, D, gamma), RHO0, D, gamma / (gamma + 1.0))
        return fan.particles(0.5, 1.1)["F"]

    def quad_wall_p(D, gamma):
        fan = isentrope_fan(gamma_law_isentrope(RHO0, D, gamma), RHO0, D, gamma / (gamma + 1.0))
        return fan.wall_pressure

    for quad, closed in ((quad_F, F_fan), (quad_wall_p, wall_p)):
        got = jax.grad(quad, argnums=(0, 1))(D, gamma)
        want = jax.grad(closed, argnums=(0, 1))(D, gamma)
        np.testing.assert_allclose(got, want, rtol=1e-9)


@pytest.mark.slow
def test_gradients_are_finite_in_every_region():
    """The branches that divide by zero or take a bad power (the escape front, vacuum, X = 0, unburnt
    particles, t = 0) do not poison the derivatives of the others."""

    def total(out):
        return sum(jnp.sum(jnp.where(jnp.isfinite(v), v, 0.0)) for v in out.values())

    x = jnp.concatenate([jnp.linspace(-3.0, 1.5, 19), jnp.array([0.0, 0.5 * D, D, -D / 0.4])])
    XX = jnp.linspace(0.0, 1.5, 7)
    for end in ENDS:
        for t in (0.0, 0.5, 2.0):

            def closed(D, gamma):
                out = total(gamma_law_particles(XX, t, RHO0, D, gamma, end))
                return out + total(gamma_law_fields(x, max(t, 1.0), RHO0, D, gamma, end))

            for gamma in GAMMAS:
                assert np.all(np.isfinite(jax.grad(closed, argnums=(0, 1))(D, gamma)))
            dX = jax.grad(lambda X: total(gamma_law_particles(X, t, RHO0, D, 1.4, end)))(XX)
            assert np.all(np.isfinite(dX))

    def quad(D):
        fan = isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75, end="free", J_max=100.0)
        return total(fan.fields(x, 1.0)) + total(fan.particles(XX, 1.0))

    assert np.isfinite(jax.grad(quad)(D))


def test_transformations():
    jitted = jax.jit(gamma_law_particles, static_argnames="end")
    got = jitted(X, 2.0, RHO0, D, 3.0, end="free")
    _close(got["x"], gamma_law_particles(X, 2.0, RHO0, D, 3.0, "free")["x"], 1.0, 0.0)
    per_gamma = jax.vmap(lambda g: gamma_law_wall_pressure(RHO0, D, g))(jnp.array([3.0, 1.4]))
    _close(per_gamma[0], 8.0 / 27.0 * RHO0 * D**2 / 4.0, 1.0, 1e-15)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: gamma_law_cj(RHO0, 0.0, 3.0), "D"),
        (lambda: gamma_law_cj(RHO0, -1.0, 3.0), "D"),
        (lambda: gamma_law_cj(0.0, D, 3.0), "rho0"),
        (lambda: gamma_law_cj(RHO0, D, 1.0), "gamma"),
        (lambda: gamma_law_wall_pressure(RHO0, D, 0.9), "gamma"),
        (lambda: gamma_law_wall_time(0.5, D, 1.0), "gamma"),
        (lambda: gamma_law_fields(X, 0.0, RHO0, D, 3.0), "t"),
        (lambda: gamma_law_fields(X, T, RHO0, D, 3.0, end="open"), "end"),
        (lambda: gamma_law_fields(jnp.array([np.nan]), T, RHO0, D, 3.0), "x"),
        (lambda: gamma_law_particles(X, -1.0, RHO0, D, 3.0), "t"),
        (lambda: gamma_law_particles(-X, T, RHO0, D, 3.0, end="free"), "X"),
        (lambda: gamma_law_particles(X, T, RHO0, D, 3.0, end=None), "end"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, 1.01 * D, 0.75), "D and J_CJ"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 1.0), "J_CJ"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75, J_max=1.05), "J_max"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75, nodes=1), "nodes"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75, end="x"), "end"),
        (lambda: isentrope_fan(1.0, RHO0, D, 0.75), "p_s"),
        (lambda: cj_point(gamma_law_isentrope(RHO0, D, 3.0), RHO0, J_lo=0.8), "J_lo"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75).fields(X, 0.0), "t"),
        (lambda: isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75).particles(X, -T), "t"),
    ],
)
def test_bad_input_raises(call, name):
    with pytest.raises(ValueError, match=f"^{name} "):
        call()


def test_isentrope_refuses_an_eos_with_energy_and_names_the_principal_isentrope():
    """A JWL with its energy term (b = w rho) is not barotropic: Isentrope took its a alone (9.04e9 Pa
    at J = 0.9 for TNT, against the principal isentrope's 1.143e10)."""
    eos, e0 = explosives.jwl("tnt")
    match = r"^eos must be barotropic \(b = 0 in p = a \+ b e\), got JWL with b = .*JWLIsentrope\.from_jwl"
    with pytest.raises(ValueError, match=match):
        Isentrope(eos)
    principal = Isentrope(JWLIsentrope.from_jwl(eos, e0))
    assert float(principal(0.9)) == pytest.approx(1.1434e10, abs=5e5)  # to its five digits
    with pytest.raises(
        ValueError, match=r"^eos must be a barotropic AbstractEOS with a field rho0, got IdealGas"
    ):
        Isentrope(IdealGas(1.4))


@pytest.mark.parametrize("call", ["cj_point", "isentrope_fan"])
def test_an_isentrope_takes_its_own_rho0(call):
    """p_s(J) of an Isentrope is at rho = eos.rho0 / J: another rho0 gave another CJ speed (1.414 for
    a gamma-law isentrope of rho0 = 1 and D = 2, given rho0 = 2)."""
    p_s = Isentrope(GammaLawIsentrope(1.0, 2.0, 3.0))
    match = r"^rho0 must be the isentrope's own rho0 = 1\.0 \(p_s\.eos\.rho0\), got 2\.0$"
    with pytest.raises(ValueError, match=match):
        if call == "cj_point":
            cj_point(p_s, 2.0)
        else:
            isentrope_fan(p_s, 2.0, 2.0, 0.75, cj_tol=None)
    cj = cj_point(p_s, 1.0)
    assert float(cj["D"]) == pytest.approx(2.0, rel=1e-13) and float(cj["J_CJ"]) == pytest.approx(0.75)
    assert float(isentrope_fan(p_s, 1.0, cj["D"], cj["J_CJ"]).P_CJ) == pytest.approx(1.0, rel=1e-12)


def test_an_isentrope_takes_its_own_rho0_in_float32():
    """In float32 the isentrope keeps rho0 = 1.63 as 1.6299999952: the same density given as 1.63 is its
    own, not refused (the check's tolerance is the stored type's)."""
    with float32():
        p_s = Isentrope(GammaLawIsentrope(rho0=1.63, D=8000.0, gamma=3.0))
        cj = cj_point(p_s, 1.63)
        assert float(cj["D"]) == pytest.approx(8000.0, rel=1e-5)
        fan = isentrope_fan(p_s, 1.63, cj["D"], cj["J_CJ"])
        assert fan.P_CJ.dtype == jnp.float32 and float(fan.J_CJ) == pytest.approx(0.75, rel=1e-6)
        with pytest.raises(ValueError, match=r"^rho0 must be the isentrope's own rho0 = 1\.62999"):
            cj_point(p_s, 1.6301)


_FAN = None


def _fan():
    global _FAN
    if _FAN is None:
        _FAN = isentrope_fan(gamma_law_isentrope(RHO0, D, 3.0), RHO0, D, 0.75)
    return _FAN


@pytest.mark.parametrize(
    "call, match",
    [
        (
            lambda: gamma_law_fields(jnp.ones(3), jnp.ones(2), RHO0, D, 3.0),
            r"^x and t must broadcast together, got x of shape \(3,\) and t of shape \(2,\)$",
        ),
        (
            lambda: gamma_law_particles(jnp.ones(3), jnp.ones(2), RHO0, D, 3.0),
            r"^X and t must broadcast together, got X of shape \(3,\) and t of shape \(2,\)$",
        ),
        (
            lambda: gamma_law_fields(jnp.ones(3), T, jnp.full(2, RHO0), D, 3.0),
            r"^x and rho0 must broadcast together, got x of shape \(3,\) and rho0 of shape \(2,\)$",
        ),
        (
            lambda: gamma_law_particles(jnp.ones(3), jnp.ones(2), RHO0, D, jnp.full(4, 3.0)),
            r"^X, t and gamma must broadcast together, got X of shape \(3,\), t of shape \(2,\) and "
            r"gamma of shape \(4,\)$",
        ),
        (
            lambda: _fan().fields(jnp.ones(3), jnp.ones(2)),
            r"^x and t must broadcast together, got x of shape \(3,\) and t of shape \(2,\)$",
        ),
        (
            lambda: _fan().particles(jnp.ones(3), jnp.ones(2)),
            r"^X and t must broadcast together, got X of shape \(3,\) and t of shape \(2,\)$",
        ),
    ],
)
def test_shapes_that_do_not_broadcast_are_refused_by_name(call, match):
    """Not JAX's "TypeError: ... incompatible shapes for broadcasting"."""
    with pytest.raises(ValueError, match=match):
        call()


def test_positions_and_times_broadcast():
    """A column of positions against a row of times: the grid of both, as each alone gives it."""
    ts = jnp.array([1.0, 2.0]) * T
    for f, pos in ((gamma_law_fields, X * T), (gamma_law_particles, X)):
        grid = f(pos[:, None], ts[None, :], RHO0, D, 3.0)
        assert grid["p"].shape == (3, 2)
        for j, t in enumerate(ts):
            _close(grid["p"][:, j], f(pos, t, RHO0, D, 3.0)["p"], RHO0 * D**2, 0.0)


def test_traced_bad_time_is_not_checked_and_gives_finite_meaningless_values():
    """As the module docstring says: a traced t < 0 raises nothing and gives finite values (the wall's
    state at rest everywhere), where a concrete one is refused."""
    x = jnp.array([-0.1, 0.0, 0.1])
    out = jax.jit(lambda t: gamma_law_fields(x, t, RHO0, D, 3.0))(-1.0)
    assert np.all(np.isfinite(np.asarray(out["p"])))
    _close(out["p"], gamma_law_wall_pressure(RHO0, D, 3.0) * jnp.ones(3), RHO0 * D**2, 1e-15)
    with pytest.raises(ValueError, match=r"^t must be > 0, got -1\.0$"):
        gamma_law_fields(x, -1.0, RHO0, D, 3.0)
