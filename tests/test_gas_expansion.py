"""The talk's exact numbers for the gas expansion u = beta t X, to round-off in float64."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm

BETA = 200.0
DT = 1e-5
TOL = 1e-12  # relative, in (F - 1)


def first_step(interpolator, transfer=None, artificial_cells=0, ordering="usl", **scene_kw):
    kw = dict(cells=3, ppc=2, beta=BETA) | scene_kw
    scene = jm.GasExpansion(**kw)
    sol = jm.simulate(
        scene,
        interpolator,
        dt=DT,
        steps=1,
        transfer=transfer,
        artificial_cells=artificial_cells,
        ordering=ordering,
    )
    return scene, sol


@pytest.mark.parametrize(
    "transfer, ordering",
    [(jm.FLIP(), "usl"), (jm.PIC(), "usl"), (jm.FLIP(), "musl")],
    ids=["flip-usl", "pic-usl", "flip-musl"],
)
def test_boundary_cells_five_eighths(interpolator, transfer, ordering):
    scene, sol = first_step(interpolator, transfer, ordering=ordering)
    growth = (np.asarray(sol.state.F[:, 0, 0]) - 1.0) / (BETA * DT)
    expected = np.array([5 / 8, 5 / 8, 1, 1, 5 / 8, 5 / 8])
    np.testing.assert_allclose(growth, expected, rtol=TOL, atol=0)
    # The talk's partition: boundary-cell particles are exactly those seeded in the first and last cell.
    np.testing.assert_array_equal(np.asarray(sol.body.boundary), expected != 1)


def test_musl_with_pic_smooths_twice(interpolator):
    """MUSL re-projects PIC's already projected velocity: on the bar of 3 cells the first step is
    exactly 59/128 of beta dt in the boundary cells and 55/64 in the middle cell (worked out from two
    hat-weighted averages of v = beta X)."""
    _, sol = first_step(interpolator, jm.PIC(), ordering="musl")
    growth = (np.asarray(sol.state.F[:, 0, 0]) - 1.0) / (BETA * DT)
    expected = np.array([59 / 128, 59 / 128, 55 / 64, 55 / 64, 59 / 128, 59 / 128])
    np.testing.assert_allclose(growth, expected, rtol=TOL, atol=0)


def test_musl_with_pic_is_exact_from_the_third_cell_in(interpolator):
    """On a longer bar the second projection reaches one cell further in than the first: 59/128 in
    the boundary cells, 119/128 in the cells next to them, and exactly beta dt from the third cell in.
    Checked in F itself, to 8 ulps of 1 (MPQ's sums over 16 particles' corners round to 6)."""
    _, sol = first_step(interpolator, jm.PIC(), ordering="musl", cells=8)
    growth = np.array([59, 59, 119, 119] + [128] * 8 + [119, 119, 59, 59]) / 128
    F = np.asarray(sol.state.F[:, 0, 0])
    np.testing.assert_allclose(F, 1.0 + growth * BETA * DT, rtol=0, atol=8 * np.finfo(np.float64).eps)


@pytest.mark.slow
@pytest.mark.parametrize("ordering", ["usl", "musl"])
@pytest.mark.parametrize("layers", [1, 2])
def test_artificial_cells_make_first_step_exact(interpolator, transfer, layers, ordering):
    _, sol = first_step(interpolator, transfer, artificial_cells=layers, ordering=ordering)
    growth = (np.asarray(sol.state.F[:, 0, 0]) - 1.0) / (BETA * DT)
    np.testing.assert_allclose(growth, np.ones(6), rtol=TOL, atol=0)


def test_apic_carries_the_linear_field_exactly(interpolator):
    """APIC's affine momentum reproduces v = beta X on every node: no 5/8 even without artificial cells."""
    _, sol = first_step(interpolator, jm.APIC())
    growth = (np.asarray(sol.state.F[:, 0, 0]) - 1.0) / (BETA * DT)
    np.testing.assert_allclose(growth, np.ones(6), rtol=TOL, atol=0)


@pytest.mark.parametrize("ppc", [1, 3, 4])
def test_artificial_cells_exact_for_other_ppc(interpolator, ppc):
    _, sol = first_step(interpolator, artificial_cells=1, ppc=ppc, cells=4)
    growth = (np.asarray(sol.state.F[:, 0, 0]) - 1.0) / (BETA * DT)
    np.testing.assert_allclose(growth, np.ones(4 * ppc), rtol=TOL, atol=0)


def test_first_step_velocity_and_position(interpolator):
    """a_i = 0 at t = 0 (the tractions balance the uniform stress), so v_p stays beta X."""
    scene, sol = first_step(interpolator)
    X = np.asarray(sol.body.X[:, 0])
    np.testing.assert_allclose(np.asarray(sol.state.v[:, 0]), BETA * X, rtol=1e-13, atol=1e-12)
    # With artificial cells the grid velocity is exact, so positions are exact too.
    _, sol = first_step(interpolator, artificial_cells=1)
    np.testing.assert_allclose(np.asarray(sol.state.x[:, 0]), (1 + BETA * DT) * X, rtol=1e-14, atol=0)


def test_spq_boundary_error_compounds():
    """SPQ: F_p^n = prod_k (1 + grad v^k dt); the boundary error after a few steps exceeds the first."""
    scene = jm.GasExpansion(cells=3, ppc=2, beta=BETA)
    sol = jm.simulate(scene, jm.SPQ(), dt=DT, steps=10, saveat=jm.SaveAt(every=1, fields=("F",)))
    F = np.asarray(sol.history["F"][:, 0, 0, 0])
    F_exact = 1 + BETA * np.asarray(sol.ts)
    err = np.abs(F - F_exact)
    assert np.all(np.diff(err[1:]) > 0)
    np.testing.assert_allclose(err[1], 3 / 8 * BETA * DT, rtol=1e-12)


def test_mpq_with_artificial_cells_beats_spq_at_talk_time():
    """The talk's conclusion at t = 0.00125 on the default scene."""
    scene = jm.GasExpansion()
    out = {}
    for name, interp, ac in (("spq", jm.SPQ(), 0), ("mpq+ac", jm.MPQ(), 1)):
        sol = jm.simulate(scene, interp, dt=DT, steps=125, artificial_cells=ac)
        out[name] = float(jm.errors(scene, sol.state, sol.body)["F_max_rel"])
    assert out["mpq+ac"] < 0.01 < out["spq"]
    assert out["mpq+ac"] < out["spq"] / 10


def test_exact_solution_fields():
    scene = jm.GasExpansion(beta=BETA)
    ex = scene.exact(jnp.array([0.5]), jnp.asarray(1e-3))
    F = 1 + BETA * 1e-3
    np.testing.assert_allclose(float(ex["F"][0, 0]), F, rtol=1e-15)
    np.testing.assert_allclose(float(ex["x"][0]), 0.5 * F, rtol=1e-15)
    np.testing.assert_allclose(float(ex["v"][0]), 0.5 * BETA, rtol=1e-15)
    P = 2.0e5 * F**-1.4 - 1.0e5
    np.testing.assert_allclose(float(ex["sigma"][0, 0]), -P, rtol=1e-14)
