"""The exact Euler solutions of ``jaxmpm.exact_euler``: Toro's tabulated star states, the jump
conditions across every wave, conservation of the integrals, the Noh problem, and the transformations
(jit, vmap, grad). Float64 is on for the whole suite (``conftest.py``)."""

import decimal
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmpm.exact_euler import noh, riemann_solution, riemann_star, riemann_waves, vacuum_generated

GAMMA = 1.4

# Toro, "Riemann solvers and numerical methods for fluid dynamics", Table 4.1 (data) and Table 4.3
# (exact star states p*, u*, rho*_L, rho*_R), with the table's digits as printed.
SOD = (1.0, 0.0, 1.0, 0.125, 0.0, 0.1)
TORO = {
    "1-sod": (SOD, ("0.30313", "0.92745", "0.42632", "0.26557")),
    "2-123": ((1.0, -2.0, 0.4, 1.0, 2.0, 0.4), ("0.00189", "0.00000", "0.02185", "0.02185")),
    "3-left-blast": ((1.0, 0.0, 1000.0, 1.0, 0.0, 0.01), ("460.894", "19.5975", "0.57506", "5.99924")),
    "4-right-blast": ((1.0, 0.0, 0.01, 1.0, 0.0, 100.0), ("46.0950", "-6.19633", "5.99242", "0.57511")),
}
# Test 5 is the collision of the right shock of test 3 with the left shock of test 4; the table's
# star state is that of the unrounded states (see test_toro_test_5_is_the_collision_of_tests_3_and_4).
TEST_5 = (5.99924, 19.5975, 460.894, 5.99242, -6.19633, 46.0950)
TEST_5_TABLE = ("1691.64", "8.68975", "14.2823", "31.0426")
# Test 3 seen from a frame moving with its contact (Toro's stationary-contact variant).
STATIONARY = (1.0, -19.59745, 1000.0, 1.0, -19.59745, 0.01)
CASES = {**{k: v[0] for k, v in TORO.items()}, "5-collision": TEST_5, "stationary-contact": STATIONARY}


def _half_unit(printed: str) -> float:
    """Half a unit in the last printed digit: the rounding of a tabulated value."""
    exponent = decimal.Decimal(printed).as_tuple().exponent
    return 0.5 * 10.0**exponent


def _assert_table(values, table):
    for name, value, printed in zip(("p*", "u*", "rho*L", "rho*R"), values, table):
        err = abs(float(value) - float(printed))
        assert err <= _half_unit(printed), f"{name}: {float(value):.7g} vs table {printed}"


@pytest.mark.parametrize("case", list(TORO))
def test_toro_table_4_3(case):
    data, table = TORO[case]
    _assert_table(riemann_star(*data, GAMMA), table)


def test_toro_test_5_is_the_collision_of_tests_3_and_4():
    """Toro's test 5 is the right star state of test 3 against the left one of test 4. Its data are
    printed to six figures, and the star state the table gives is that of the unrounded states: with
    the printed data p* = 1691.647 and u* = 8.689774, off the table's 1691.64 and 8.68975 (the star
    state is that sensitive to the data's rounding)."""
    p3, u3, _, rho3 = riemann_star(*TORO["3-left-blast"][0], GAMMA)
    p4, u4, rho4, _ = riemann_star(*TORO["4-right-blast"][0], GAMMA)
    # The unrounded states round to the printed data.
    for value, printed in zip((rho3, u3, p3, rho4, u4, p4), TEST_5):
        assert abs(float(value) - printed) <= _half_unit(repr(printed))
    _assert_table(riemann_star(rho3, u3, p3, rho4, u4, p4, GAMMA), TEST_5_TABLE)
    p, u, rho_l, rho_r = riemann_star(*TEST_5, GAMMA)
    assert abs(float(p) - 1691.647) < 5e-4 and abs(float(u) - 8.689774) < 5e-7


def test_stationary_contact_is_test_3_in_a_moving_frame():
    p3, u3, rl3, rr3 = riemann_star(*TORO["3-left-blast"][0], GAMMA)
    p, u, rl, rr = riemann_star(*STATIONARY, GAMMA)
    np.testing.assert_allclose([p, rl, rr], [p3, rl3, rr3], rtol=1e-13)
    np.testing.assert_allclose(u, u3 - 19.59745, atol=1e-12)
    _assert_table((p, u, rl, rr), ("460.894", "0.00000", "0.57506", "5.99924"))


def test_123_problem_is_symmetric():
    p, u, rho_l, rho_r = riemann_star(*TORO["2-123"][0], GAMMA)
    assert float(u) == 0.0 and float(rho_l) == float(rho_r)


def _reference_p_star(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma):
    """The root of Toro's pressure function by bisection in 60-digit decimal arithmetic."""
    D = decimal.Decimal
    with decimal.localcontext() as ctx:
        ctx.prec = 60
        rho_l, u_l, p_l, rho_r, u_r, p_r, g = (
            D(repr(float(v))) for v in (rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)
        )

        def f_k(p, rho, pk):
            if p > pk:
                return (p - pk) * (2 / ((g + 1) * rho) / (p + (g - 1) / (g + 1) * pk)).sqrt()
            c = (g * pk / rho).sqrt()
            return 2 * c / (g - 1) * (((p / pk).ln() * (g - 1) / (2 * g)).exp() - 1)

        lo, hi = D("1e-40"), D("1e40")
        for _ in range(300):  # in log p: 2^-300 of the bracket's 80 decades
            mid = (lo * hi).sqrt()
            if f_k(mid, rho_l, p_l) + f_k(mid, rho_r, p_r) + u_r - u_l > 0:
                hi = mid
            else:
                lo = mid
        return float(lo)


@pytest.mark.slow
def test_newton_reaches_the_root_to_round_off():
    """Random states over many decades of pressure and density ratio, both shock and rarefaction
    branches, gamma from near 1 to 3, against an independent high-precision bisection."""
    rng = np.random.default_rng(0)
    rows = []
    for _ in range(30):
        rho_l, rho_r, p_l, p_r = 10.0 ** rng.uniform(-3, 3, size=4)
        gamma = float(rng.choice([1.001, 1.1, 1.4, 5.0 / 3.0, 3.0]))
        c_l, c_r = math.sqrt(gamma * p_l / rho_l), math.sqrt(gamma * p_r / rho_r)
        # u_r - u_l, a fraction of the vacuum limit: from strong compression to an expansion that
        # leaves p* down to about 1e-8 of the pressures ((1 - fraction)^(1/z) of them for two fans)
        top = 1.0 - 1e-8 ** ((gamma - 1.0) / (2.0 * gamma))
        du = rng.uniform(-1.0, top) * 2.0 * (c_l + c_r) / (gamma - 1.0)
        rows.append((rho_l, 0.3, p_l, rho_r, 0.3 + du, p_r, gamma))
    batch = [jnp.asarray(col) for col in zip(*rows)]
    p_star = jax.jit(jax.vmap(riemann_star))(*batch)[0]
    ref = np.array([_reference_p_star(*row) for row in rows])
    np.testing.assert_allclose(np.asarray(p_star), ref, rtol=1e-12)


def _conserved(rho, u, p, gamma):
    E = p / (gamma - 1.0) + 0.5 * rho * u**2
    return np.stack([rho, rho * u, E])


def _flux(rho, u, p, gamma):
    E = p / (gamma - 1.0) + 0.5 * rho * u**2
    return np.stack([rho * u, rho * u**2 + p, u * (E + p)])


def _sample(x, t, data, gamma=GAMMA, x0=0.0):
    s = riemann_solution(jnp.asarray(x), t, *data, gamma, x0)
    return {k: np.asarray(v) for k, v in s.items()}


@pytest.mark.parametrize("case", list(CASES))
def test_rankine_hugoniot_across_each_shock(case):
    data, t = CASES[case], 0.01
    w = {k: float(v) for k, v in riemann_waves(*data, GAMMA).items()}
    for side in ("l", "r"):
        if not w[f"shock_{side}"]:
            continue
        S = w[f"head_{side}"]
        # just either side of the shock, both points in constant regions
        gap = 1e-6 * t * max(1.0, abs(S))
        st = _sample(np.array([S * t - gap, S * t + gap]), t, data)
        rho, u, p = st["rho"], st["u"], st["p"]
        assert rho[0] != rho[1]
        w_rel = u - S  # velocity in the shock's frame
        mass = rho * w_rel
        momentum = rho * w_rel**2 + p
        energy = mass * (p / ((GAMMA - 1.0) * rho) + p / rho + 0.5 * w_rel**2)
        for q in (mass, momentum, energy):
            assert abs(q[1] - q[0]) <= 1e-12 * np.max(np.abs(q)), (side, q)
        assert st["p"][0 if side == "l" else 1] < st["p"][1 if side == "l" else 0]  # compressive


@pytest.mark.parametrize("case", list(CASES))
def test_contact_carries_pressure_and_velocity(case):
    data, t = CASES[case], 0.01
    w = riemann_waves(*data, GAMMA)
    S = float(w["contact"])
    st = _sample(np.array([S * t - 1e-9, S * t + 1e-9]), t, data)
    assert st["p"][0] == st["p"][1] and st["u"][0] == st["u"][1]
    np.testing.assert_allclose(st["rho"], [w["rho_star_l"], w["rho_star_r"]], rtol=1e-15)
    np.testing.assert_allclose(st["p"][0], w["p_star"], rtol=1e-15)


@pytest.mark.parametrize("case", list(CASES))
def test_rarefaction_fans_keep_invariant_and_entropy(case):
    data, t = CASES[case], 0.01
    rho_l, u_l, p_l, rho_r, u_r, p_r = data
    w = {k: float(v) for k, v in riemann_waves(*data, GAMMA).items()}
    for side, sign, (rho0, u0, p0) in (("l", 1.0, (rho_l, u_l, p_l)), ("r", -1.0, (rho_r, u_r, p_r))):
        if w[f"shock_{side}"]:
            continue
        lo, hi = sorted((w[f"head_{side}"], w[f"tail_{side}"]))
        S = np.linspace(lo, hi, 41)[1:-1]
        st = _sample(S * t, t, data)
        c = np.sqrt(GAMMA * st["p"] / st["rho"])
        invariant = st["u"] + sign * 2.0 * c / (GAMMA - 1.0)
        c0 = math.sqrt(GAMMA * p0 / rho0)
        np.testing.assert_allclose(invariant, u0 + sign * 2.0 * c0 / (GAMMA - 1.0), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(st["p"] / st["rho"] ** GAMMA, p0 / rho0**GAMMA, rtol=1e-13)
        np.testing.assert_allclose(st["u"] - sign * c, S, rtol=1e-13, atol=1e-13)  # characteristics
        # the fan meets the outer state at its head and the star state at its tail
        edge = _sample(np.array([lo, hi]) * t, t, data)
        star = w[f"rho_star_{side}"]
        outer_first = edge["rho"] if side == "l" else edge["rho"][::-1]
        np.testing.assert_allclose(outer_first, [rho0, star], rtol=1e-13)


def _integrals(data, t, a, b, gamma=GAMMA):
    """Integrals of mass, momentum and energy over ``[a, b]``: Gauss-Legendre between the wave
    edges (the fans are smooth there, the rest constant)."""
    w = riemann_waves(*data, gamma)
    edges = [t * float(w[k]) for k in ("head_l", "tail_l", "contact", "tail_r", "head_r")]
    cuts = np.array(sorted([a, b, *edges]))
    nodes, weights = np.polynomial.legendre.leggauss(24)
    total = np.zeros(3)
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        if hi <= lo:
            continue
        x = 0.5 * (lo + hi) + 0.5 * (hi - lo) * nodes
        st = _sample(x, t, data, gamma)
        total += 0.5 * (hi - lo) * _conserved(st["rho"], st["u"], st["p"], gamma) @ weights
    return total


@pytest.mark.parametrize("case", list(CASES))
def test_integrals_change_by_the_end_fluxes(case):
    data, t = CASES[case], 0.035 if case == "1-sod" else 0.01
    rho_l, u_l, p_l, rho_r, u_r, p_r = data
    w = riemann_waves(*data, GAMMA)
    a, b = t * float(w["head_l"]) - 0.3, t * float(w["head_r"]) + 0.7
    U_l, U_r = _conserved(rho_l, u_l, p_l, GAMMA), _conserved(rho_r, u_r, p_r, GAMMA)
    initial = -a * U_l + b * U_r
    expected = initial + t * (_flux(rho_l, u_l, p_l, GAMMA) - _flux(rho_r, u_r, p_r, GAMMA))
    scale = np.maximum(np.abs(initial), 1.0)
    np.testing.assert_array_less(np.abs(_integrals(data, t, a, b) - expected), 1e-12 * scale)


def test_sod_keeps_mass_and_energy():
    t, a, b = 0.2, -0.5, 0.5  # the waves stay inside: head -1.18 t, shock 1.75 t
    total = _integrals(SOD, t, a, b)
    np.testing.assert_allclose(total[0], 0.5 * (1.0 + 0.125), rtol=1e-13)
    np.testing.assert_allclose(total[1], t * (1.0 - 0.1), rtol=1e-13)  # the end pressures push
    np.testing.assert_allclose(total[2], 0.5 * (1.0 + 0.1) / (GAMMA - 1.0), rtol=1e-13)


def test_sod_wave_pattern():
    w = riemann_waves(*SOD, GAMMA)
    assert not bool(w["shock_l"]) and bool(w["shock_r"])
    assert not bool(w["vacuum"])
    np.testing.assert_allclose(w["head_l"], -math.sqrt(GAMMA), rtol=1e-15)
    speeds = [float(w[k]) for k in ("head_l", "tail_l", "contact", "tail_r", "head_r")]
    assert speeds == sorted(speeds)
    st = _sample(np.array([-2.0, 0.5 * (speeds[2] + speeds[4]), 2.0]) * 0.2, 0.2, SOD, x0=0.0)
    np.testing.assert_allclose(st["rho"], [1.0, w["rho_star_r"], 0.125], rtol=1e-15)
    np.testing.assert_allclose(st["e"], st["p"] / (0.4 * st["rho"]), rtol=1e-15)
    shifted = _sample(np.array([-0.2, 0.3, 0.7]) + 0.5, 0.2, SOD, x0=0.5)
    np.testing.assert_allclose(
        shifted["rho"], _sample(np.array([-0.2, 0.3, 0.7]), 0.2, SOD)["rho"], rtol=1e-15
    )


def test_noh_star_state():
    t = 0.6
    x = jnp.array([0.0, 0.1, 0.19, 0.21, 0.5, 2.0])
    s = noh(x, t)
    D = 1.0 / 3.0
    behind = np.asarray(x) < D * t
    np.testing.assert_allclose(s["rho"], np.where(behind, 4.0, 1.0), rtol=1e-14, atol=0)
    np.testing.assert_allclose(s["u"], np.where(behind, 0.0, -1.0), rtol=1e-14, atol=0)
    np.testing.assert_allclose(s["p"], np.where(behind, 4.0 / 3.0, 0.0), rtol=1e-14, atol=0)
    np.testing.assert_allclose(s["e"], np.where(behind, 0.5, 0.0), rtol=1e-14, atol=0)
    mirror = noh(-x, t)
    for k in ("rho", "p", "e"):
        np.testing.assert_array_equal(mirror[k], s[k])
    np.testing.assert_array_equal(mirror["u"][1:], -s["u"][1:])


@pytest.mark.parametrize("gamma,rho0,u0", [(5.0 / 3.0, 1.0, 1.0), (1.4, 2.5, 3.0), (3.0, 0.1, 0.2)])
def test_noh_rankine_hugoniot(gamma, rho0, u0):
    D = 0.5 * (gamma - 1.0) * u0
    t = 1.0
    s = {
        k: np.asarray(v)
        for k, v in noh(jnp.array([D * t * (1 - 1e-9), D * t * (1 + 1e-9)]), t, gamma, rho0, u0).items()
    }
    np.testing.assert_allclose(s["p"][0], (gamma - 1.0) * s["rho"][0] * s["e"][0], rtol=1e-15)
    w_rel = s["u"] - D
    mass = s["rho"] * w_rel
    momentum = s["rho"] * w_rel**2 + s["p"]
    energy = mass * (s["e"] + 0.5 * w_rel**2) + s["p"] * w_rel
    for q in (mass, momentum, energy):
        assert abs(q[1] - q[0]) <= 1e-14 * np.max(np.abs(q))


def test_noh_is_the_limit_of_colliding_riemann_states():
    """Two cold streams colliding: the Riemann solution with a tiny pressure eps approaches Noh's, to
    order eps (measured 11 eps in the density, 2.3 eps in the pressure)."""
    t, eps = 1.0, 1e-10
    x = jnp.array([0.1, 0.25, 0.5, 1.0])
    s = riemann_solution(x, t, 1.0, 1.0, eps, 1.0, -1.0, eps, 5.0 / 3.0)
    n = noh(x, t)
    for k in ("rho", "u", "p"):
        np.testing.assert_allclose(s[k], n[k], atol=100 * eps)


def test_jit_and_vmap_over_points():
    f = jax.jit(lambda x: riemann_solution(x, 0.2, *SOD, GAMMA)["rho"])
    x = jnp.linspace(-0.5, 0.5, 11)
    np.testing.assert_array_equal(jax.vmap(f)(x), f(x))
    np.testing.assert_allclose(f(x), riemann_solution(x, 0.2, *SOD, GAMMA)["rho"], rtol=1e-14)
    g = jax.jit(jax.vmap(lambda x: noh(x, 1.0)["p"]))
    np.testing.assert_allclose(g(x), noh(x, 1.0)["p"], rtol=1e-14)


@pytest.mark.slow
def test_vmap_over_states_and_gamma():
    rows = [CASES[k] for k in CASES]
    batch = [jnp.asarray(col) for col in zip(*rows)]
    gammas = jnp.asarray([1.4, 1.4, 1.4, 1.4, 1.4, 1.4])
    out = jax.vmap(riemann_star)(*batch, gammas)
    for i, row in enumerate(rows):
        one = riemann_star(*row, GAMMA)
        np.testing.assert_allclose([o[i] for o in out], one, rtol=1e-14)
    # over gamma alone, and the whole solution over states at fixed points
    gs = jnp.linspace(1.1, 3.0, 5)
    p_g = jax.vmap(lambda g: riemann_star(*SOD, g)[0])(gs)
    np.testing.assert_allclose(p_g, [riemann_star(*SOD, float(g))[0] for g in gs], rtol=1e-14)
    x = jnp.linspace(-0.01, 0.01, 7)
    rho = jax.vmap(lambda *s: riemann_solution(x, 0.001, *s, GAMMA)["rho"])(*batch)
    assert rho.shape == (len(rows), 7)
    np.testing.assert_allclose(rho[2], riemann_solution(x, 0.001, *rows[2], GAMMA)["rho"], rtol=1e-14)


def _central(f, x, h):
    return (f(x + h) - f(x - h)) / (2.0 * h)


@pytest.mark.slow
@pytest.mark.parametrize("case", ["1-sod", "2-123", "3-left-blast", "4-right-blast"])
def test_gradient_of_p_star_matches_central_differences(case):
    rho_l, u_l, p_l, rho_r, u_r, p_r = CASES[case]
    of_pl = lambda q: riemann_star(rho_l, u_l, q, rho_r, u_r, p_r, GAMMA)[0]
    of_gamma = lambda g: riemann_star(rho_l, u_l, p_l, rho_r, u_r, p_r, g)[0]
    for f, x in ((of_pl, p_l), (of_gamma, GAMMA)):
        grad = jax.grad(f)(x)
        np.testing.assert_allclose(grad, _central(f, x, 1e-5 * x), rtol=1e-6)
        np.testing.assert_allclose(jax.jacfwd(f)(x), grad, rtol=1e-12)


@pytest.mark.slow
def test_gradient_of_the_solution_in_fan_and_star():
    """d rho / d gamma at a point inside Sod's fan and one in its star region, and the Noh state."""
    x = jnp.array([-0.1, 0.2])
    f = lambda g: riemann_solution(x, 0.2, *SOD, g)["rho"]
    np.testing.assert_allclose(jax.jacrev(f)(GAMMA), _central(f, GAMMA, 1e-5), rtol=1e-6)
    h = lambda g: noh(jnp.array(0.1), 1.0, g)["rho"]
    np.testing.assert_allclose(jax.grad(h)(5.0 / 3.0), -2.0 / (2.0 / 3.0) ** 2, rtol=1e-14)


def test_vacuum_is_flagged_and_gives_nan():
    data = (1.0, -5.0, 0.4, 1.0, 5.0, 0.4)  # 2 (c_l + c_r) / 0.4 = 7.48 < 10
    assert bool(vacuum_generated(*data, GAMMA))
    assert not bool(vacuum_generated(*TORO["2-123"][0], GAMMA))
    assert all(np.isnan(float(v)) for v in riemann_star(*data, GAMMA))
    w = riemann_waves(*data, GAMMA)
    assert bool(w["vacuum"]) and np.isnan(float(w["head_l"]))
    assert np.all(np.isnan(riemann_solution(jnp.array([-1.0, 0.0, 1.0]), 0.1, *data, GAMMA)["rho"]))
    # in a batch, only the row that opens a vacuum
    rows = [data, SOD]
    out = jax.vmap(riemann_star)(*[jnp.asarray(c) for c in zip(*rows)], jnp.asarray([GAMMA, GAMMA]))
    assert np.isnan(float(out[0][0])) and abs(float(out[0][1]) - 0.30313) < 5e-6


@pytest.mark.parametrize(
    "index,name,value",
    [
        (0, "rho_l", 0.0),
        (2, "p_l", -1.0),
        (3, "rho_r", -0.1),
        (5, "p_r", 0.0),
        (1, "u_l", math.inf),
        (6, "gamma", 1.0),
    ],
)
def test_bad_states_raise(index, name, value):
    args = [*SOD, GAMMA]
    args[index] = value
    for f in (riemann_star, riemann_waves, vacuum_generated):
        with pytest.raises(ValueError, match=name):
            f(*args)
    with pytest.raises(ValueError, match=name):
        riemann_solution(0.0, 0.1, *args)


def test_bad_times_and_noh_parameters_raise():
    with pytest.raises(ValueError, match="t must be > 0"):
        riemann_solution(0.0, 0.0, *SOD, GAMMA)
    with pytest.raises(ValueError, match="t must be >= 0"):
        noh(0.0, -1.0)
    with pytest.raises(ValueError, match="gamma must be > 1"):
        noh(0.0, 1.0, gamma=0.9)
    with pytest.raises(ValueError, match="rho0"):
        noh(0.0, 1.0, rho0=0.0)
    with pytest.raises(ValueError, match="u0"):
        noh(0.0, 1.0, u0=-1.0)
    with pytest.raises(ValueError, match="p_l must be a real number"):
        riemann_star(1.0, 0.0, "1", 0.125, 0.0, 0.1, GAMMA)


def test_traced_values_are_not_checked():
    """Under jit a negative pressure cannot be seen: it gives NaN, not an error."""
    p = jax.jit(lambda q: riemann_star(1.0, 0.0, q, 0.125, 0.0, 0.1, GAMMA)[0])(-1.0)
    assert np.isnan(float(p))


NAMES = ("rho_l", "u_l", "p_l", "rho_r", "u_r", "p_r", "gamma")


@pytest.mark.parametrize("index", range(7))
def test_arrays_of_states_are_refused_by_name(index):
    """One Riemann problem at a time: an array state is named (not JAX's "cond_fun must return a
    boolean scalar"), with jax.vmap over the function called as the way to solve several."""
    args = [*SOD, GAMMA]
    args[index] = np.array([args[index], args[index]])
    name = NAMES[index]
    for f in (riemann_star, riemann_waves):
        with pytest.raises(ValueError) as info:
            f(*args)
        assert str(info.value) == (
            f"{name} must be one number, got an array of shape (2,); to solve several Riemann "
            f"problems, jax.vmap over {f.__name__}"
        )
    with pytest.raises(
        ValueError,
        match=rf"^{name} must be one number, got an array of shape \(2,\); to solve several Riemann "
        r"problems, jax\.vmap over riemann_solution$",
    ):
        riemann_solution(0.1, 0.1, *args)


def test_zero_dimensional_states_and_elementwise_vacuum_test_are_taken():
    """A 0-d array is one number; ``vacuum_generated`` stays elementwise over arrays of states."""
    p, u, _, _ = riemann_star(*[np.asarray(a) for a in (*SOD, GAMMA)])
    assert abs(float(p) - 0.30313) < 5e-6 and abs(float(u) - 0.92745) < 5e-6
    flags = vacuum_generated(1.0, np.array([0.0, -10.0]), 1.0, 1.0, np.array([0.0, 10.0]), 1.0, GAMMA)
    np.testing.assert_array_equal(np.asarray(flags), [False, True])


def test_traced_bad_time_is_not_checked_and_gives_finite_meaningless_values():
    """As the module docstring says: a traced t = 0 raises nothing and gives no NaN off x0, but the
    initial states (t = 0 concrete is refused)."""
    x = np.array([-0.1, 0.1])
    out = jax.jit(lambda t: riemann_solution(x, t, *SOD, GAMMA))(0.0)
    np.testing.assert_array_equal(np.asarray(out["rho"]), [1.0, 0.125])
    np.testing.assert_array_equal(np.asarray(out["p"]), [1.0, 0.1])
    with pytest.raises(ValueError, match=r"^t must be > 0, got 0\.0$"):
        riemann_solution(x, 0.0, *SOD, GAMMA)


@pytest.mark.parametrize("case", list(CASES))
def test_star_sound_speeds_are_those_of_the_star_states(case):
    """``c_star_l``, ``c_star_r`` are ``sqrt(gamma p* / rho*_K)`` on either kind of wave: behind a
    shock ``rho*_K`` is the Rankine-Hugoniot density, behind a rarefaction the isentropic one (where
    the formula ``c_K (p* / p_K)^((gamma - 1) / (2 gamma))`` gives the same)."""
    w = riemann_waves(*CASES[case], GAMMA)
    for side in ("l", "r"):
        expected = math.sqrt(GAMMA * float(w["p_star"]) / float(w[f"rho_star_{side}"]))
        np.testing.assert_allclose(float(w[f"c_star_{side}"]), expected, rtol=1e-14, err_msg=side)


def test_sod_right_star_sound_speed():
    """Sod's shocked gas: ``sqrt(1.4 * 0.30313 / 0.26557) = 1.26411`` (Toro's Table 4.3 star state);
    the isentropic formula would give 1.23998."""
    w = riemann_waves(*SOD, GAMMA)
    np.testing.assert_allclose(float(w["c_star_r"]), 1.264113483, rtol=1e-9)


def _shock_cases():
    rng = np.random.default_rng(1)
    cases = [TEST_5, TORO["3-left-blast"][0], TORO["4-right-blast"][0], SOD]
    while len(cases) < 60:
        rho_l, rho_r = 10.0 ** rng.uniform(-2, 2, 2)
        p_l, p_r = 10.0 ** rng.uniform(-3, 3, 2)
        u_l, u_r = rng.normal(0.0, 5.0, 2)
        data = tuple(float(a) for a in (rho_l, u_l, p_l, rho_r, u_r, p_r))
        w = riemann_waves(*data, GAMMA)
        if not bool(w["vacuum"]) and (bool(w["shock_l"]) or bool(w["shock_r"])):
            cases.append(data)
    return cases


def test_a_point_exactly_on_a_shock_takes_the_state_on_its_right():
    """A shock's head and tail are the same number, the speeds are ordered, and a point at ``x = S t``
    with ``S`` the shock speed ``riemann_waves`` returns takes the state on the shock's right, as
    documented: Toro's test 5 and random shocks."""
    wrong = []
    for data in _shock_cases():
        w = riemann_waves(*data, GAMMA)
        speeds = [float(w[k]) for k in ("head_l", "tail_l", "contact", "tail_r", "head_r")]
        assert speeds == sorted(speeds), (data, speeds)
        for side, right in (("l", float(w["rho_star_l"])), ("r", data[3])):
            if not bool(w[f"shock_{side}"]):
                continue
            assert float(w[f"head_{side}"]) == float(w[f"tail_{side}"]), (data, side)
            S = float(w[f"head_{side}"])
            got = float(riemann_solution(S, 1.0, *data, GAMMA)["rho"])
            if got != right:
                wrong.append((data, side, got, right))
    assert not wrong, wrong
