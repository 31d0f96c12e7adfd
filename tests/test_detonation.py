"""The detonation scene: a programmed burn against the exact CJ-Taylor wave, its command line and its
bad input. Float64 is on for the whole suite (``conftest.py``)."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import usage

import jaxmpm as jm
from jaxmpm.cli import main


def _run(scene, interp, t_end, **kw):
    return jm.simulate(
        scene,
        interp,
        t_end=t_end,
        cfl=0.3,
        max_steps=100_000,
        artificial_cells=1,
        viscosity=jm.ArtificialViscosity(),
        **kw,
    )


@pytest.mark.slow
@pytest.mark.parametrize("interp", [jm.CPDI(), jm.MPQ()], ids=["cpdi", "mpq"])
def test_gamma_3_wall_products_F_within_2_percent_and_wall_plateau_8_27(interp):
    """400 particles per 10 cm (one per cell), gamma = 3 against a wall, t = 10 us (the front at 8 cm):
    F within 2% of the exact F over the burnt particles 12 cells behind the front, and the pressure at
    rest against the wall 8/27 p_CJ and its F = 9/8 within 0.15% and 0.1% (measured 4.8e-4 and 1.8e-4
    for CPDI, 8.8e-5 and 4.9e-5 for MPQ)."""
    scene = jm.Detonation(L=0.1, cells=400, ppc=1)
    sol = _run(scene, interp, 1e-5)
    st, body = sol.state, sol.body
    assert int(st.status) == 0 and float(st.t) == pytest.approx(1e-5, rel=1e-12)
    where = jm.metrics.smooth_mask(scene, body, st.t)
    assert int(jnp.sum(where)) > 250
    err = jm.errors(scene, st, body, where=where)
    assert float(err["F_max_rel"]) < 0.02, float(err["F_max_rel"])
    # At rest against the wall: the particles the fan has left, x < D t / 2 (away from its edge).
    X = np.asarray(body.X[:, 0])
    rest = X < 0.4 * 8000.0 * 1e-5 * 8.0 / 9.0
    p_wall = float(np.mean(np.asarray(jm.pressure(st))[rest]))
    assert p_wall == pytest.approx(8.0 / 27.0 * 3e10, rel=1.5e-3)
    F_rest = np.asarray(st.F[:, 0, 0])[rest]
    np.testing.assert_allclose(np.mean(F_rest), 9.0 / 8.0, rtol=1e-3)
    # Every particle the front has passed is burnt; none ahead of it has started.
    lam = np.asarray(st.internal["lambda"])
    front = 8000.0 * 1e-5
    assert np.all(lam[X < front - 4 * float(scene.h)] == 1.0)
    assert np.all(lam[X > front + float(scene.h)] == 0.0)


@pytest.mark.slow
def test_burn_fraction_never_decreases_and_the_step_resolves_the_front():
    """The step is bounded by the front's speed (the unburnt explosive has no sound speed), and the
    burn fraction of every particle only grows from step to step."""
    scene = jm.Detonation(L=0.02, cells=40, ppc=1)
    model = jm.Model(scene, jm.CPDI(), jm.FLIP(), viscosity=jm.ArtificialViscosity())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    dt0 = jm._step.stable_dt(model, s, state, jnp.asarray(0.3))
    assert float(dt0) == pytest.approx(0.3 * float(scene.h) / 8000.0, rel=1e-14)
    saveat = jm.SaveAt(every=1, fields=("internal",))
    sol = jm.simulate(
        scene, jm.CPDI(), dt=float(dt0), steps=40, saveat=saveat, viscosity=jm.ArtificialViscosity()
    )
    lam = np.asarray(sol.history["internal.lambda"])
    assert np.all(np.diff(lam, axis=0) >= 0.0)
    assert lam[-1, 0] == 1.0 and lam[-1, -1] == 0.0


@pytest.mark.slow
def test_jwl_row_runs_against_its_quadrature_fan():
    """Comp B on its principal isentrope (implied D = 7979.85 m/s): the exact fan by quadrature, F
    within 2% over the burnt particles at 400 particles per 10 cm."""
    scene = jm.Detonation(L=0.05, cells=200, ppc=1, explosive="compb")
    cj = scene.cj()
    assert float(cj["D"]) == pytest.approx(7980.0, rel=2e-3)
    assert float(cj["P_CJ"]) == pytest.approx(29.5e9, rel=2e-3)
    sol = _run(scene, jm.MPQ(), 5e-6)
    where = jm.metrics.smooth_mask(scene, sol.body, sol.state.t)
    err = jm.errors(scene, sol.state, sol.body, where=where)
    assert float(err["F_max_rel"]) < 0.02, float(err["F_max_rel"])


def test_exact_solution_of_the_scene_is_the_closed_form():
    scene = jm.Detonation()
    t = 1e-5
    X = jnp.array([0.01, 0.05, 0.07, 0.09])
    ex = jax.vmap(scene.exact, in_axes=(0, None))(X[:, None], t)
    F = np.asarray(ex["F"][:, 0, 0])
    np.testing.assert_allclose(F[0], 9.0 / 8.0, rtol=1e-14)  # at rest against the wall
    np.testing.assert_allclose(F[2], 0.75 * (8000.0 * t / 0.07) ** 0.5, rtol=1e-14)  # in the fan
    assert F[3] == 1.0 and float(ex["sigma"][3, 0, 0]) == 0.0  # not yet lit
    np.testing.assert_allclose(-float(ex["sigma"][0, 0, 0]), 8.0 / 27.0 * 3e10, rtol=1e-14)
    assert float(scene.t_valid) == pytest.approx(0.1 / 8000.0, rel=1e-15)


@pytest.mark.slow
def test_cli_json_has_burn_fraction_pressure_errors_and_cj_state(capsys):
    argv = "run detonation D=8000 gamma=3 rho0=1875 L=0.01 cells=40 ends=wall burn=time smooth=true"
    argv += " --interpolator cpdi --viscosity --t-end 1e-6 --cfl 0.3 --max-steps 2000 --json"
    assert main(argv.split()) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == 0 and out["params"]["smooth_burn"] is True
    cj = out["params"]["cj"]
    assert cj["P_CJ"] == pytest.approx(1875.0 * 8000.0**2 / 4, rel=1e-14) and cj["J_CJ"] == 0.75
    part = out["particles"]
    assert {"lambda", "p", "rho", "e"} <= set(part)
    assert set(out["errors"]) >= {"F_max_rel", "F_rms_rel", "p_rms_rel", "v_rms_abs"}
    lam = np.asarray(part["lambda"])
    assert lam[0] == 1.0 and lam[-1] == 0.0 and np.all(np.diff(lam) <= 0.0)
    burn = out["regions"][0]
    assert burn["material"] == "ProgrammedBurn" and burn["products"]["material"] == "GammaLawIsentrope"


@pytest.mark.parametrize(
    "params, match",
    [
        (["explosive=rdx"], "explosive must be one of gamma-law, tnt, compb, petn, pbx9404, got 'rdx'"),
        (["D=0"], "D must be > 0"),
        (["D=-8000"], "D must be > 0"),
        (["burn_width=0.5"], "burn_width"),
        (["ends=open"], "ends must be one of wall, free"),
        (["burn=fast"], "burn must be one of"),
        (["products=gas"], "products must be one of isentrope, full"),
        (["smooth=maybe"], "smooth must be true or false"),
    ],
)
def test_cli_bad_input_is_one_line(capsys, params, match):
    usage(
        capsys, ["run", "detonation", *params, "--interpolator", "mpq", "--dt", "1e-8", "--steps", "1"], match
    )


def test_a_detonator_outside_the_body_is_refused():
    burn = jm.Detonation().material()
    outside = jm.explosives.ProgrammedBurn(
        reactant=None, products=burn.products, D=8000.0, points=[0.2], width=1e-3, J_CJ=0.75
    )
    scene = jm.Bodies(
        parts=(jm.Region(jm.geometry.Box(0.0, 10.0), outside, 1875.0, 0.0, 4e6),), cells=10, h=0.01
    )
    with pytest.raises(ValueError, match="detonator"):
        jm.simulate(scene, jm.MPQ(), dt=1e-8, steps=1)


class _Pull(jm.AbstractEOS):
    """Test products in tension: ``p = -1e9`` Pa whatever the state."""

    def pressure_terms(self, rho, z):
        return -1e9 * jnp.ones_like(rho), jnp.zeros_like(rho)

    def initial_internal(self, X):
        return None

    def update_internal(self, z, X, t, dt, J_old, J_new):
        return z

    def front_speed(self):
        return None

    def nonnegative_energy(self):
        return True


def test_products_in_tension_are_a_named_breakdown():
    """Products pulling at -1e9 Pa (below -1e-3 rho0 D^2 = -1.2e8 Pa) stop the run at the first burnt
    particle, named."""
    burn = jm.explosives.ProgrammedBurn(
        reactant=None, products=_Pull(), D=8000.0, points=[0.0], width=1e-3, J_CJ=0.75
    )
    scene = jm.Bodies(
        parts=(jm.Region(jm.geometry.Box(0.0, 10.0), burn, 1875.0, 0.0, 4e6),), cells=10, h=1e-3
    )
    sol = jm.simulate(scene, jm.CPDI(), dt=2e-8, steps=20, throw=False)
    assert int(sol.state.status) == jm.status.PRODUCTS_TENSION
    # particle 0 (X = 0.25 mm) is lit at t = 3.1e-8 s, in the second step of 2e-8 s
    assert int(sol.state.fail_particle) == 0 and int(sol.state.fail_step) == 2
    assert "products in tension" in sol.failure()["quantities"][0]


@pytest.mark.slow
@pytest.mark.parametrize("smooth", [False, True], ids=["linear", "smooth"])
def test_gradient_with_respect_to_D_and_gamma_matches_central_differences(smooth):
    """Reverse mode through a burn (fixed steps: a run to an end time changes its step count with D):
    d/dD and d/dgamma of the products' mean pressure equal central differences."""

    def mean_p(D, gamma):
        scene = jm.Detonation(D=D, gamma=gamma, L=0.01, cells=20, ppc=1, smooth_burn=smooth)
        sol = jm.simulate(scene, jm.CPDI(), dt=2e-8, steps=40, viscosity=jm.ArtificialViscosity())
        return jnp.mean(jm.pressure(sol.state)) / 1e9

    D, gamma = jnp.asarray(8000.0), jnp.asarray(3.0)
    g = jax.grad(mean_p, argnums=(0, 1))(D, gamma)
    for k, eps in ((0, 0.5), (1, 1e-4)):
        hi, lo = [D, gamma], [D, gamma]
        hi[k], lo[k] = hi[k] + eps, lo[k] - eps
        fd = (mean_p(*hi) - mean_p(*lo)) / (2 * eps)
        assert abs(float(g[k]) - float(fd)) < 1e-4 * abs(float(fd)), (k, float(g[k]), float(fd))


@pytest.mark.slow
def test_gradient_of_a_run_to_an_end_time_is_finite_and_right():
    """To an end time the step depends on D (the front bounds it) and on each particle's |v|, zero for
    the explosive at rest: the derivative is finite (|v|'s is taken as 0 at rest) and equals the central
    difference (smooth burn, 1 us, the step count constant near D)."""

    def mean_p(D):
        scene = jm.Detonation(D=D, L=0.01, cells=20, ppc=1, smooth_burn=True)
        sol = jm.simulate(
            scene, jm.CPDI(), t_end=1e-6, cfl=0.3, max_steps=400, viscosity=jm.ArtificialViscosity()
        )
        return jnp.mean(jm.pressure(sol.state)) / 1e9

    g = float(jax.grad(mean_p)(jnp.asarray(8000.0)))
    fd = float((mean_p(jnp.asarray(8000.01)) - mean_p(jnp.asarray(7999.99))) / 0.02)
    assert np.isfinite(g) and abs(g - fd) < 1e-4 * abs(fd), (g, fd)


@pytest.mark.slow
def test_a_plane_detonator_lights_a_2d_slab_as_a_plane_front():
    """A 2D slab lit by the plane x = 0 (Huygens' straight-line burn): the burn fraction depends on x
    alone, and the front has crossed the distance D t."""
    D, h = 8000.0, 1e-3
    products = jm.explosives.GammaLawIsentrope(rho0=1875.0, D=D, gamma=3.0)
    burn = jm.explosives.ProgrammedBurn(
        reactant=None,
        products=products,
        D=D,
        points=jnp.zeros((0, 2)),
        width=1.5e-3,
        J_CJ=0.75,
        planes=[[1.0, 0.0, 0.0]],
    )
    region = jm.Region(jm.geometry.Box((0.0, 0.0), (12.0, 12.0)), burn, 1875.0, (0.0, 0.0), 4e6)
    scene = jm.Bodies(parts=(region,), dim=2, cells=12, h=h, ppc=1, left="wall", right="free", pad=4)
    sol = jm.simulate(scene, jm.CPDI(), dt=2e-8, steps=30, viscosity=jm.ArtificialViscosity())
    lam = np.asarray(sol.state.internal["lambda"]).reshape(12, 12)  # particles by x, then y
    np.testing.assert_array_equal(lam, np.broadcast_to(lam[:, :1], lam.shape))
    x = (np.arange(12) + 0.5) * h
    front = D * 30 * 2e-8  # 4.8 mm
    assert np.all(lam[x < front - 1.5e-3, 0] == 1.0) and np.all(lam[x > front, 0] == 0.0)


def test_detonators_of_another_dimension_are_refused():
    products = jm.explosives.GammaLawIsentrope(rho0=1875.0, D=8000.0, gamma=3.0)
    burn = jm.explosives.ProgrammedBurn(
        reactant=None,
        products=products,
        D=8000.0,
        points=jnp.zeros((0, 2)),
        width=1e-3,
        J_CJ=0.75,
        planes=[[1.0, 0.0, 0.0]],
    )
    region = jm.Region(jm.geometry.Box(0.0, 10.0), burn, 1875.0, 0.0, 4e6)
    scene = jm.Bodies(parts=(region,), cells=10, h=0.01)
    with pytest.raises(ValueError, match="detonators are 2D points, the scene is 1D"):
        jm.simulate(scene, jm.MPQ(), dt=1e-8, steps=1)


@pytest.mark.slow
def test_a_line_detonator_lights_a_3d_block_as_a_cylindrical_front():
    """A 3D block lit by the line along z through (0, 0): the burn fraction depends on the distance from
    the line alone (equal for particles at equal distance, whatever their z), lit where the front has
    passed; a line whose point lies outside the box is refused."""
    D, h = 8000.0, 1e-3
    products = jm.explosives.GammaLawIsentrope(rho0=1875.0, D=D, gamma=3.0)

    def burn(lines):
        return jm.explosives.ProgrammedBurn(
            reactant=None,
            products=products,
            D=D,
            points=jnp.zeros((0, 3)),
            width=1e-3,
            J_CJ=0.75,
            lines=lines,
        )

    def scene(lines):
        region = jm.Region(jm.geometry.Box((0.0,) * 3, (6.0, 6.0, 3.0)), burn(lines), 1875.0, (0.0,) * 3, 4e6)
        return jm.Bodies(parts=(region,), dim=3, cells=6, h=h, ppc=1, left="symmetry", right="free", pad=3)

    steps, dt = 8, 5e-8
    sol = jm.simulate(scene([[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]]), jm.CPDI(), dt=dt, steps=steps)
    assert int(sol.state.status) == 0
    lam = np.asarray(sol.state.internal["lambda"])
    X = np.asarray(sol.body.X)
    rho = np.round(np.hypot(X[:, 0], X[:, 1]) / h, 9)
    for value in np.unique(rho):
        same = lam[rho == value]
        np.testing.assert_array_equal(same, np.full_like(same, same[0]))
    front = D * steps * dt  # 3.2 mm
    t_end = steps * dt
    expected = np.clip((t_end - rho * h / D) * D / 1e-3, 0.0, 1.0)
    np.testing.assert_allclose(lam, expected, atol=1e-12)
    assert lam[rho * h < front - 1e-3].min() == 1.0 and lam[rho * h > front].max() == 0.0
    with pytest.raises(ValueError, match=r"lines\[0\] = \[0.0, 7.0, 0.0\]"):
        jm.simulate(scene([[0.0, 7.0, 0.0, 0.0, 0.0, 1.0]]), jm.CPDI(), dt=dt, steps=1)
