"""Scene and exact-solution faults: each bad value is named as the parameter the user gave, with what
is allowed, before anything is traced; tracers pass unchecked; a region's default velocity is the zero
vector of its shape's dimension."""

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raw

import jaxmpm as jm
from jaxmpm import exact
from jaxmpm.geometry import Ball, Box


def _one_line(make, match):
    with pytest.raises(ValueError, match=match) as info:
        make()
    assert "\n" not in str(info.value)
    return str(info.value)


# ---------------------------------------------------------------- Riemann


def test_riemann_names_P0_not_a_vacuum():
    # P0 = 0 makes every sound speed zero, which read as a vacuum between states at rest
    _one_line(lambda: jm.Riemann(P0=0), r"^P0 must be > 0, got 0\.0$")


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(P0=-1.0), r"^P0 must be > 0"),
        (dict(P0=math.inf), r"^P0 must be finite"),
        (dict(gamma=0.5), r"^gamma must be > 1"),  # gamma < 1 flips the sign of g = 2 / (gamma - 1)
        (dict(gamma=1.0), r"^gamma must be > 1"),
        (dict(rho0=math.inf), r"^rho0 must be finite"),  # c = 0 for rho0 = inf
        (dict(rho0=0.0), r"^rho0 must be > 0"),
        (dict(F_left=0.0), r"^F_left must be > 0"),
        (dict(F_right=-1.0), r"^F_right must be > 0"),
        (dict(v_left=math.nan), r"^v_left must be finite"),
        (dict(p_atm=-1.0), r"^p_atm must be >= 0"),
    ],
)
def test_riemann_names_each_bad_parameter(kw, match):
    _one_line(lambda: jm.Riemann(**kw), match)


@pytest.mark.parametrize(
    "kw, match",
    [
        # finite parameters whose states' pressure P0 F^-gamma overflows or underflows: NaN waves before
        (dict(gamma=1e300), r"^F_left=0\.5 with P0=1\.0, gamma=1e\+300 and rho0=1\.0 gives the left state"),
        (dict(F_left=1e-300), r"^F_left=1e-300 .* pressure P0 F_left\^-gamma = inf"),
        (dict(F_right=1e300), r"^F_right=1e\+300 .* pressure P0 F_right\^-gamma = 0\.0"),
        # states that collide at 1e300: no finite star state
        (dict(v_left=1e300), r"v_left=1e\+300.* give no finite star state"),
    ],
)
def test_riemann_refuses_parameters_that_give_no_finite_solution(kw, match):
    _one_line(lambda: jm.Riemann(**kw), match)


def test_riemann_still_refuses_a_vacuum_and_passes_tracers():
    _one_line(lambda: jm.Riemann(v_left=-10.0, v_right=10.0), "vacuum forms")
    t = jm.Riemann().t_valid
    assert np.isfinite(float(t)) and float(t) > 0
    dt = jax.grad(lambda p: jm.Riemann(P0=p).t_valid)(1.0)
    assert float(dt) == pytest.approx(-0.5 * float(t), rel=1e-12)  # t_valid scales as P0^-1/2
    ts = jax.vmap(lambda g: jm.Riemann(gamma=g).t_valid)(jnp.asarray([1.4, 1.6]))
    assert np.all(np.isfinite(np.asarray(ts)))


# ---------------------------------------------------------------- Detonation


def test_detonation_names_gamma_and_its_range():
    # gamma = 1e300 made J_CJ = gamma / (gamma + 1) round to 1, reported as "J_CJ must be < 1.0"
    msg = _one_line(lambda: jm.Detonation(gamma=1e300), r"^gamma must be in \(1, 4\.504e\+15\)")
    assert "J_CJ" in msg and msg.endswith("got 1e+300")
    _one_line(lambda: jm.Detonation(gamma=1e20), r"^gamma must be in \(1, ")
    assert float(jm.Detonation(gamma=1e15).cj()["J_CJ"]) < 1.0  # inside the range: a CJ state


@pytest.mark.parametrize(
    "kw, match",
    [
        # D^2 overflowed into the region's energy ("energy must be finite") or underflowed to P_CJ = 0
        (dict(D=1e160), r"^D must be in \(1\.492e-154, 1\.341e\+154\) .*got 1e\+160$"),
        (dict(D=1e-300), r"^D must be in \(1\.492e-154, 1\.341e\+154\) .*got 1e-300$"),
        (
            dict(rho0=1e308),
            r"^D=8000\.0, gamma=3\.0 and rho0=1e\+308 give the gamma law a CJ state .*P_CJ = inf",
        ),
        (dict(rho0=-1.0), r"^rho0 must be > 0"),
        (dict(gamma=1.0 + 1e-15, D=1e154), r"^D=1e\+154, gamma=1\.000000000000001 .*e0 = inf"),
        # L too small for a cell: "h must be > 0", a parameter Detonation does not have
        (dict(L=1e-320), r"^L=1e-320 gives a cell size h = L / cells = 0\.0"),
        (dict(L=1e300, burn_width=1e20), r"^burn_width=1e\+20 with L=1e\+300 gives the burn a length"),
        (
            dict(L=1e308, D=1e-100),
            r"^L=1e\+308 and the front's speed 1e-100 \(D\) give t_valid = L / D = inf",
        ),
    ],
)
def test_detonation_names_each_parameter_with_huge_or_tiny_values(kw, match):
    _one_line(lambda: jm.Detonation(**kw), match)


GURNEY_SIZES = dict(GurneySlab=dict(cells=4, ppc=1, pad=4), GurneyCylinder=dict(cells=10, ppc=1, pad=4))


@pytest.mark.parametrize("scene", sorted(GURNEY_SIZES))
@pytest.mark.parametrize(
    "kw, match",
    [
        # D^2 overflowed into the region's energy ("energy must be finite"), or underflowed to P_CJ = 0
        # and was taken; gamma = 1e300 gave "J_CJ must be < 1.0", a field of the programmed burn
        (dict(D=1e300), r"^D must be in \(1\.492e-154, 1\.341e\+154\) .*got 1e\+300$"),
        (dict(D=1e-300), r"^D must be in \(1\.492e-154, 1\.341e\+154\) .*got 1e-300$"),
        (dict(gamma=1e300), r"^gamma must be in \(1, 4\.504e\+15\) .*J_CJ.*got 1e\+300$"),
        (
            dict(rho0=1e308),
            r"^D=7980\.0, gamma=3\.0 and rho0=1e\+308 give the gamma law a CJ state .*P_CJ = inf",
        ),
        (dict(gamma=1.0 + 1e-15, D=1e154), r"^D=1e\+154, gamma=1\.000000000000001 .*e0 = inf"),
    ],
)
def test_gurney_gamma_law_runs_the_detonations_range_checks(scene, kw, match):
    make = getattr(jm, scene)
    _one_line(lambda: make(explosive="gamma-law", **kw, **GURNEY_SIZES[scene]), match)


def test_detonation_exact_takes_one_point_of_shape_1():
    """exact(X, t) is a scene's exact solution at one particle, X of shape (1,) like every 1D scene's;
    a number (0.05) failed with "'float' object is not subscriptable"."""
    scene = jm.Detonation()
    with pytest.raises(
        ValueError,
        match=r"^X must be one reference position of shape \(1,\), got shape \(\) "
        r"\(several: jax.vmap over them\)$",
    ):
        raw(jm.Detonation.exact)(scene, 0.05, 5e-6)
    with pytest.raises(
        ValueError,
        match=r"^X must be one reference position of shape \(1,\), got shape \(2,\) "
        r"\(several: jax.vmap over them\)$",
    ):
        raw(jm.Detonation.smooth)(scene, jnp.array([0.05, 0.06]), 5e-6)
    s = scene.exact(jnp.array([0.02]), 5e-6)
    exact_p = jm.exact_detonation.gamma_law_particles(0.02, 5e-6, 1875.0, 8000.0, 3.0)
    assert float(s["sigma"][0, 0]) == pytest.approx(-float(exact_p["p"]), rel=1e-14)
    assert float(s["sigma"][0, 0]) < 0.0


@pytest.mark.parametrize(
    "scene",
    [jm.Riemann(), jm.VacuumExpansion(), jm.VibratingBar(), jm.GasExpansion(), jm.GasExpansion(dim=2)],
    ids=["riemann", "vacuum-expansion", "vibrating-bar", "gas-expansion", "gas-expansion-2d"],
)
def test_every_exact_solution_takes_one_point_of_the_scenes_dimension(scene):
    """A number, or several positions in one array, is refused by name (a number failed with "'float'
    object is not subscriptable", and the vacuum expansion silently took the first of two positions);
    one position given as a list is that position."""
    dim = scene.dim
    t = 1e-4
    for X in (0.05, [0.05] * (dim + 1), np.full((1, dim), 0.05)):
        with pytest.raises(
            ValueError, match=rf"^X must be one reference position of shape \({dim},\), got shape"
        ):
            raw(type(scene).exact)(scene, X, t)
    one = scene.exact(jnp.full((dim,), 0.05), t)
    listed = raw(type(scene).exact)(scene, [0.05] * dim, t)
    for name in ("x", "v", "F", "sigma"):
        np.testing.assert_array_equal(listed[name], one[name])
    many = jax.vmap(lambda X: scene.exact(X, t))(jnp.full((3, dim), 0.05))
    np.testing.assert_array_equal(many["F"][0], one["F"])
    if callable(getattr(scene, "smooth", None)):
        with pytest.raises(ValueError, match=r"^X must be one reference position of shape \(1,\)"):
            raw(type(scene).smooth)(scene, [0.05, 0.06], t)


def test_detonation_defaults_rows_and_tracers_pass():
    assert float(jm.Detonation().cj()["P_CJ"]) == pytest.approx(1875.0 * 8000.0**2 / 4.0, rel=1e-14)
    assert float(jm.Detonation(explosive="tnt", products="full").t_valid) > 0
    dp = jax.grad(lambda g: jm.Detonation(gamma=g).cj()["P_CJ"])(3.0)
    assert float(dp) == pytest.approx(-1875.0 * 8000.0**2 / 16.0, rel=1e-12)


# ---------------------------------------------------------------- Region's default velocity


def test_a_2d_body_of_regions_takes_the_default_velocity():
    # the example of docs/shocks.md, with the velocities left out
    gas = jm.IdealGas(gamma=1.4)
    copper = jm.MieGruneisen(**jm.MIE_GRUNEISEN["copper"])
    charge = Ball((20.0, 20.0), 8.0)
    case = Box((0.0, 0.0), (40.0, 40.0)) - Ball((20.0, 20.0), 12.0)
    parts = dict(charge=(charge, gas, 1600.0, 4.0e6), case=(case, copper, 8930.0, 0.0))
    default = jm.Bodies(
        parts=tuple(jm.Region(s, m, rho0=r, energy=e) for s, m, r, e in parts.values()),
        dim=2,
        cells=40,
        h=1e-3,
    )
    given = jm.Bodies(
        parts=tuple(jm.Region(s, m, rho0=r, velocity=(0.0, 0.0), energy=e) for s, m, r, e in parts.values()),
        dim=2,
        cells=40,
        h=1e-3,
    )
    assert default.layout().counts == given.layout().counts
    for r in default.parts:
        np.testing.assert_array_equal(np.asarray(r.velocity), np.zeros(2))
        assert r.velocity.dtype == r.rho0.dtype
    np.testing.assert_array_equal(np.asarray(default.initial_velocity(jnp.asarray([0.02, 0.02]))), [0.0, 0.0])


def test_the_default_velocity_has_the_shape_dimension_in_1d_and_3d():
    gas = jm.IdealGas(gamma=1.4)
    assert jm.Region(Box(0.0, 4.0), gas, 1.0).velocity.shape == (1,)
    assert jm.Region(Box((0.0,) * 3, (2.0,) * 3), gas, 1.0).velocity.shape == (3,)
    _one_line(lambda: jm.Region(Ball((1.0, 1.0), 1.0), gas, 1.0, 0.5), "velocity must have 2 components")


def test_a_2d_body_of_regions_at_rest_runs():
    gas = jm.IdealGas(gamma=1.4)
    scene = jm.Bodies(
        parts=(jm.Region(Ball((3.0, 3.0), 2.0), gas, 1.0, energy=1.0),), dim=2, cells=6, h=0.1, ppc=1
    )
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-3, steps=1)
    assert int(sol.status) == 0
    assert np.all(np.isfinite(np.asarray(sol.state.v)))


# ---------------------------------------------------------------- jaxmpm.exact


@pytest.mark.parametrize(
    "args, match",
    [
        ((1.0, -1.0, 1.4, 1.0), r"^P0 must be >= 0, got -1\.0$"),  # not NaN
        ((-1.0, 1.0, 1.4, 1.0), r"^F must be > 0, got -1\.0$"),  # not a complex number
        ((1.0, 1.0, 0.5, 1.0), r"^gamma must be > 1"),
        ((1.0, 1.0, 1.4, 0.0), r"^rho0 must be > 0"),  # not ZeroDivisionError
        ((jnp.asarray([1.0, 0.0]), 1.0, 1.4, 1.0), r"^F must be > 0"),
    ],
)
def test_sound_speed_refuses_bad_input_by_name(args, match):
    _one_line(lambda: exact.sound_speed(*args), match)
    _one_line(lambda: exact.lagrangian_speed(*args), match)


def test_sound_speed_of_a_gas_without_pressure_is_zero():
    assert float(exact.sound_speed(1.0, 0.0, 1.4, 1.0)) == 0.0


STATES = (0.5, 0.0, 1.0, 0.0, 1.0, 1.4, 1.0)  # F_L, v_L, F_R, v_R, P0, gamma, rho0


@pytest.mark.parametrize(
    "index, value, match",
    [
        (4, -1.0, r"^P0 must be > 0, got -1\.0$"),  # not NaN
        (4, 0.0, r"^P0 must be > 0, got 0\.0$"),  # no wave curves: NaN
        (5, 0.9, r"^gamma must be > 1"),
        (6, -1.0, r"^rho0 must be > 0"),
        (0, -0.5, r"^F_L must be > 0"),
        (2, 0.0, r"^F_R must be > 0"),
        (1, math.nan, r"^v_L must be finite"),
        (3, math.inf, r"^v_R must be finite"),
    ],
)
def test_riemann_star_refuses_bad_input_by_name(index, value, match):
    args = list(STATES)
    args[index] = value
    for fn in (exact.riemann_star, exact.riemann_waves, exact.vacuum_forms):
        _one_line(lambda: fn(*args), match)
    _one_line(lambda: exact.riemann_solution(jnp.asarray(0.1), *args), match)


def test_riemann_star_refuses_a_bad_iteration_count():
    _one_line(lambda: exact.riemann_star(*STATES, iterations=0), r"^iterations must be an integer >= 1")


def test_vacuum_expansion_refuses_bad_input_by_name():
    _one_line(lambda: exact.vacuum_expansion(0.5, 0.1, 0.0, 1.0, 1.4, 1.0), r"^L must be > 0")
    _one_line(lambda: exact.vacuum_expansion(0.5, 0.1, 1.0, -1.0, 1.4, 1.0), r"^P0 must be > 0")
    _one_line(lambda: exact.vacuum_expansion(math.nan, 0.1, 1.0, 1.0, 1.4, 1.0), r"^X must be finite")


def test_exact_gas_functions_pass_tracers():
    # gradients and vmap reach the parameters: the checks pass tracers unchecked
    c = lambda P0: exact.sound_speed(2.0, P0, 1.4, 1.0)
    assert float(jax.grad(c)(1.0)) == pytest.approx(0.5 * float(c(1.0)), rel=1e-12)
    dF = jax.grad(lambda P0: exact.riemann_star(*STATES[:4], P0, 1.4, 1.0)[0])(1.0)
    assert float(dF) == pytest.approx(0.0, abs=1e-10)  # F* does not depend on P0 for states at rest
    F_s = jax.vmap(lambda g: exact.riemann_star(*STATES[:5], g, 1.0)[0])(jnp.asarray([1.4, 1.6]))
    assert np.all(np.isfinite(np.asarray(F_s)))
    # under jit the checks see tracers: bad values are the caller's, and give NaN
    assert math.isnan(float(jax.jit(exact.sound_speed)(1.0, -1.0, 1.4, 1.0)))


@pytest.mark.parametrize(
    "fn, got",
    [
        (lambda s, X, t: 1e-4 * t * jnp.sum(X), "float64[]"),
        (lambda s, X, t: jnp.zeros(2), "float64[2]"),
        (lambda s, X, t: jnp.zeros((1,), int), "int64[1]"),
        (lambda s, X, t: None, "NoneType"),
    ],
)
def test_a_displacement_field_of_the_wrong_shape_or_type_is_refused_when_the_scene_is_made(fn, got):
    with pytest.raises(
        ValueError, match=rf"displacement_fn\(scene, X, t\) must return .* got {re.escape(got)}$"
    ):
        jm.Manufactured(cells=4, displacement_fn=fn)
    good = jm.Manufactured(cells=4, displacement_fn=lambda s, X, t: 1e-4 * t * X)
    assert jm.simulate(good, jm.MPQ(), dt=1e-3, steps=1).failure() is None
