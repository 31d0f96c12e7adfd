"""Faults of the exact solutions (``jaxmpm.exact``) and of the diffrax references
(``jaxmpm.reference``): each bad value is named, with what is allowed, in one line before anything is
traced or solved; tracers pass unchecked; valid calls are unchanged."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import exact, reference


def _one_line(make, match):
    with pytest.raises(ValueError, match=match) as info:
        make()
    assert "\n" not in str(info.value)
    return str(info.value)


STATES = (0.5, 0.0, 1.0, 0.0, 1.0, 1.4, 1.0)  # F_L, v_L, F_R, v_R, P0, gamma, rho0
NAMES = ("F_L", "v_L", "F_R", "v_R", "P0", "gamma", "rho0")

# ---------------------------------------------------------------- riemann_solution's xi


@pytest.mark.parametrize("xi", [math.nan, np.float32("nan"), jnp.asarray([0.1, jnp.nan])])
def test_riemann_solution_refuses_a_nan_xi(xi):
    # not (2.0, 0.0, nan): F and v of the right state with D NaN
    _one_line(lambda: exact.riemann_solution(xi, *STATES), r"^xi must be a real number or \+-inf, not NaN")


@pytest.mark.parametrize("xi", ["a", None, 1j])
def test_riemann_solution_refuses_an_xi_that_is_not_a_number(xi):
    # "a": refused by name, not a JAX TypeError about clip
    _one_line(lambda: exact.riemann_solution(xi, *STATES), r"^xi must be a real number, got ")


def test_riemann_solution_takes_infinite_xi_as_the_outer_states():
    # xi = -inf, +inf: the data on either side (as the scene's exact solution asks for at t = 0)
    F, v, D = exact.riemann_solution(jnp.asarray([-jnp.inf, jnp.inf]), 0.5, 0.3, 1.0, -0.2, 1.0, 1.4, 1.0)
    np.testing.assert_array_equal(np.asarray(F), [0.5, 1.0])
    np.testing.assert_array_equal(np.asarray(v), [0.3, -0.2])
    assert float(D[0]) == 0.0
    assert float(D[1]) == pytest.approx(-0.2 - 0.3, abs=1e-12)  # x(L) moves with v_R = v_L + D


@pytest.mark.slow
def test_riemann_solution_passes_a_traced_xi():
    xi = jnp.linspace(-2.0, 2.0, 9)
    F = jax.vmap(lambda z: exact.riemann_solution(z, *STATES)[0])(xi)
    np.testing.assert_array_equal(np.asarray(F), np.asarray(exact.riemann_solution(xi, *STATES)[0]))
    dF = jax.grad(lambda z: exact.riemann_solution(z, *STATES)[0])(0.0)
    assert math.isfinite(float(dF))


# ---------------------------------------------------------------- one Riemann problem at a time


@pytest.mark.parametrize("index", range(7))
def test_riemann_star_refuses_arrays_of_states_by_name(index):
    # not JAX's "TypeError: Gradient only defined for scalar-output functions"
    args = list(STATES)
    args[index] = jnp.asarray([STATES[index], STATES[index]])
    name = NAMES[index]
    for fn in ("riemann_star", "riemann_waves"):
        _one_line(
            lambda: getattr(exact, fn)(*args),
            rf"^{name} must be one number, got an array of shape \(2,\); to solve several Riemann "
            rf"problems, jax\.vmap over {fn}$",
        )
    _one_line(
        lambda: exact.riemann_solution(0.1, *args),
        rf"^{name} must be one number, got an array of shape \(2,\).*jax\.vmap over riemann_solution$",
    )


def test_riemann_star_takes_zero_dimensional_arrays_and_vmaps():
    one = exact.riemann_star(*[jnp.asarray(a) for a in STATES])
    assert float(one[0]) == float(exact.riemann_star(*STATES)[0])
    F_L = jnp.asarray([0.5, 2.0])
    many = jax.vmap(lambda F: exact.riemann_star(F, *STATES[1:]))(F_L)
    for i in range(2):
        np.testing.assert_array_equal(
            np.asarray([many[0][i], many[1][i]]),
            np.asarray(exact.riemann_star(float(F_L[i]), *STATES[1:])),
        )


def test_vacuum_forms_still_broadcasts_over_arrays_of_states():
    out = exact.vacuum_forms(0.5, jnp.asarray([0.0, -20.0]), 1.0, jnp.asarray([0.0, 20.0]), 1.0, 1.4, 1.0)
    np.testing.assert_array_equal(np.asarray(out), [False, True])
    _one_line(
        lambda: exact.vacuum_forms(jnp.asarray([0.5, -1.0]), *STATES[1:]),
        r"^F_L must be > 0, got \[ 0\.5 -1\. \]$",
    )


# ---------------------------------------------------------------- vacuum_expansion's X


@pytest.mark.parametrize(
    "X, shown",
    [
        (jnp.asarray([0.5, 1.5]), r"\[0\.5 1\.5\]"),  # not [0.5, nan]
        (-0.1, r"-0\.1"),
        (1.0 + 1e-12, r"1\.000000000001"),
    ],
)
def test_vacuum_expansion_refuses_X_outside_the_body(X, shown):
    _one_line(
        lambda: exact.vacuum_expansion(X, 1e-3, 1.0, 1e5, 1.4, 1.0),
        rf"^X must lie in the body \[0, L\] = \[0, 1\.0\], got {shown}$",
    )


def test_vacuum_expansion_takes_the_whole_body_and_passes_tracers():
    X = jnp.asarray([0.0, 0.5, 1.0])
    x, v, F = exact.vacuum_expansion(X, 1e-3, 1.0, 1e5, 1.4, 1.0)
    assert float(x[0]) == 0.0 and float(v[1]) == 0.0 and math.isinf(float(F[2]))  # the front's F
    # under vmap X is a tracer: unchecked (outside the body it is the caller's NaN)
    xs = jax.vmap(lambda X: exact.vacuum_expansion(X, 1e-3, 1.0, 1e5, 1.4, 1.0)[0])(X)
    np.testing.assert_array_equal(np.asarray(xs), np.asarray(x))


@pytest.mark.parametrize("t", [-1e-3, jnp.asarray([1e-3, -1e-9]), 1.01])
def test_vacuum_expansion_refuses_t_outside_its_validity(t):
    """Before 0 the body is at rest and after L / c0 the head has met the wall: neither is this
    solution (with c0 = sqrt(1.4e5), L / c0 = 1 / 374.17 = 0.00267)."""
    _one_line(
        lambda: exact.vacuum_expansion(0.5, t, 1.0, 1e5, 1.4, 1.0),
        r"^t must lie in \[0, L / c0\] = \[0, 0\.00267261\] \(the solution holds until the rarefaction's",
    )


def test_vacuum_expansion_holds_up_to_the_wall_time():
    t_wall = 1.0 / math.sqrt(1.4e5)
    x, v, _ = exact.vacuum_expansion(jnp.asarray([0.0, 1.0]), t_wall, 1.0, 1e5, 1.4, 1.0)
    assert float(x[0]) == 0.0 and float(v[0]) == 0.0  # the head has just reached the wall
    np.testing.assert_allclose(float(x[1]), 1.0 + 5.0 * math.sqrt(1.4e5) * t_wall, rtol=1e-15)


def test_vacuum_expansion_front_has_finite_derivatives_in_t_and_the_gas():
    """At the front (X = L) x = L + 2 c0 t / (gamma - 1) and v = 2 c0 / (gamma - 1): their derivatives
    in t, P0, gamma and rho0 are finite (c0 = sqrt(gamma P0 / rho0)); in L the front's x is that of
    an interior point a little behind it, whose derivative is infinite (one-sided)."""
    t, P0, g, rho0 = 1e-3, 1e5, 1.4, 1.2
    c0 = math.sqrt(g * P0 / rho0)

    def x_front(a):
        return exact.vacuum_expansion(1.0, *a)[0]

    grad = np.asarray(jax.grad(x_front)(jnp.asarray([t, 1.0, P0, g, rho0])))
    d_c0 = 2.0 * t / (g - 1.0)  # dx/dc0 at the front
    expected = [
        2.0 * c0 / (g - 1.0),  # dx/dt = v
        -math.inf,
        d_c0 * c0 / (2.0 * P0),
        d_c0 * c0 / (2.0 * g) - 2.0 * c0 * t / (g - 1.0) ** 2,
        -d_c0 * c0 / (2.0 * rho0),
    ]
    np.testing.assert_allclose(grad, expected, rtol=1e-13)


def test_riemann_waves_and_solution_refuse_data_from_which_a_vacuum_forms():
    data = (1.0, -5000.0, 1.0, 5000.0, 1e5, 1.4, 1.2)
    assert bool(exact.vacuum_forms(*data))
    for name, call in (
        ("riemann_waves", lambda: exact.riemann_waves(*data)),
        ("riemann_solution", lambda: exact.riemann_solution(jnp.asarray([-100.0, 0.0]), *data)),
    ):
        _one_line(call, rf"^{name}: the data pull apart faster than the gas can follow .* a vacuum forms")


# ---------------------------------------------------------------- reference: max_steps

SLAB = dict(cells=4, ppc=1, pad=8)
GAS = dict(P0=1e6, gamma=1.4, p_atm=1e5, rho0=1.0, radius=0.5)


@pytest.mark.slow
def test_gas_slab_names_max_steps_when_the_solve_needs_more():
    # not diffrax's multi-screen EquinoxRuntimeError
    _one_line(
        lambda: reference.gas_slab(jm.GasSlab(**SLAB), [0.0, 1e-3], cells=8, max_steps=1),
        r"^max_steps=1 was too few: the solve to ts\[-1\]=0\.001 needs more steps; raise max_steps$",
    )


@pytest.mark.slow
def test_gas_radial_names_max_steps_when_the_solve_needs_more():
    _one_line(
        lambda: reference.gas_radial(**GAS, dim=2, ts=[0.0, 1e-3], cells=8, max_steps=1),
        r"^max_steps=1 was too few: the solve to ts\[-1\]=0\.001 needs more steps; raise max_steps$",
    )


# ---------------------------------------------------------------- reference: convergence resolutions


@pytest.mark.parametrize(
    "cells, match",
    [
        # () and (4, 4, 4): refused by name, not an IndexError or an order of NaN
        ((), r"^cells must hold at least two resolutions, to compare against the finest, got \[\]$"),
        ((8,), r"^cells must hold at least two resolutions"),
        ((4, 4, 4), r"^cells must be strictly increasing \(coarse to fine\), got \[4, 4, 4\]$"),
        ((16, 8), r"^cells must be strictly increasing"),
        ((8, 12, 16), r"^cells must each be twice the last for the observed order"),
        (("a", 8), r"^cells must hold integers >= 2, got 'a' in \['a', 8\]$"),
        ((8.0, 16.0), r"^cells must hold integers >= 2, got 8\.0"),
        ((1, 2), r"^cells must hold integers >= 2, got 1 in"),
        ((True, 4), r"^cells must hold integers >= 2, got True"),
        (8, r"^cells must be a sequence of resolutions \(integers >= 2\), got 8$"),
        ("816", r"^cells must be a sequence of resolutions"),
    ],
)
def test_surface_convergence_refuses_bad_resolutions_by_name(cells, match):
    _one_line(lambda: reference.reference_convergence(jm.GasSlab(**SLAB), [1e-4], cells=cells), match)
    _one_line(lambda: reference.radial_convergence([1e-4], cells=cells, **GAS, dim=2), match)


@pytest.mark.slow
def test_surface_convergence_takes_two_resolutions_of_any_ratio():
    rows = reference.reference_convergence(jm.GasSlab(**SLAB), [1e-4], cells=(np.int64(6), 9))
    assert [r["cells"] for r in rows] == [6, 9] and all("order" not in r for r in rows)
    assert rows[1]["x_free_max_diff"] == 0.0 and rows[0]["x_free_max_diff"] > 0.0


@pytest.mark.slow
def test_surface_convergence_at_t_0_has_no_order_to_measure():
    """All times at 0: every resolution agrees exactly, and the order is None, not log2(0 / 0)."""
    rows = reference.reference_convergence(jm.GasSlab(**SLAB), [0.0], cells=(4, 8, 16))
    assert [r["x_free_max_diff"] for r in rows] == [0.0, 0.0, 0.0] and rows[1]["order"] is None


@pytest.mark.parametrize(
    "cells, match",
    [
        (("a",), r"^cells must hold integers >= 2, got 'a' in \['a'\]$"),  # not "invalid literal for int()"
        ((8, 16.5, 32), r"^cells must hold integers >= 2, got 16\.5"),
        (None, r"^cells must be a sequence of resolutions"),
        ((8, 16), r"^cells must hold at least three resolutions"),
        ((8, 8, 16), r"^cells must each be an integer multiple of the last"),
    ],
)
def test_radial_profile_convergence_refuses_bad_resolutions_by_name(cells, match):
    _one_line(lambda: reference.radial_profile_convergence(**GAS, dim=2, ts=[1e-4], cells=cells), match)


# ---------------------------------------------------------------- RadialSolution.at and profile rel. errors


@pytest.fixture(scope="module")
def radial_small():
    return reference.gas_radial(**GAS, dim=2, ts=[0.0, 1e-4], cells=20)


_OUTSIDE = r"^R must lie in the charge, 0 <= R <= 0\.5, got values from "


@pytest.mark.parametrize(
    "R, match",
    [
        (np.array([-1.0, 0.25, 2.0]), _OUTSIDE + r"-1\.0 to 2\.0$"),
        (0.5 + 1e-9, _OUTSIDE + r"0\.500000001 to 0\.500000001$"),
        (-1e-300, _OUTSIDE + r"-1e-300 to -1e-300$"),
        (math.nan, r"^R must be finite, got nan$"),
        (np.array([0.1, math.inf]), r"^R must be finite, got \[0\.1 inf\]$"),
    ],
)
def test_radial_at_refuses_radii_outside_the_charge(radial_small, R, match):
    # not the end values, clamped, nor NaN
    _one_line(lambda: radial_small.at(R), match)


def test_radial_at_takes_the_ends_and_round_off_beyond_the_surface(radial_small):
    sol = radial_small
    ends = sol.at(np.array([0.0, GAS["radius"]]))
    np.testing.assert_array_equal(np.asarray(ends["r"]), np.asarray(sol.r)[:, [0, -1]])
    beyond = sol.at(GAS["radius"] * (1 + 1e-13))  # a radius computed with round-off
    np.testing.assert_array_equal(np.asarray(beyond["v"]), np.asarray(sol.v)[:, -1])
    # traced radii are not checked
    v = jax.jit(lambda R: sol.at(R)["v"])(2.0)
    np.testing.assert_array_equal(np.asarray(v), np.asarray(sol.v)[:, -1])


@pytest.mark.slow
def test_radial_profile_convergence_at_t_0_is_nan_without_a_warning():
    """At t = 0 the gas is at rest: v_l1 is 0 and its relative value is undefined (NaN), not 0 / 0 with a
    RuntimeWarning; the orders there are NaN too; later times are finite."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rows = reference.radial_profile_convergence(**GAS, dim=2, ts=[0.0, 1e-4], cells=(10, 20, 40))
    for row in rows:
        assert float(row["v_l1"][0]) == 0.0 and np.isnan(row["v_l1_rel"][0])
        assert float(row["rho_l1_rel"][0]) == 0.0
        assert np.isfinite(row["v_l1_rel"][1]) and row["v_l1_rel"][1] > 0.0
    assert np.isnan(rows[0]["v_order"][0]) and np.isfinite(rows[0]["v_order"][1])
