"""The metrics under faults, continued: a group of particles (the boundary cells, the interior) that
``where`` leaves empty has no errors (``None``, not 0), and the centre of the radial measures is
checked to be finite real numbers."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raw

import jaxmpm as jm
from jaxmpm import metrics

GROUPS = {
    "boundary": ("F_max_rel_boundary", "F_rms_rel_boundary"),
    "interior": ("F_max_rel_interior", "F_rms_rel_interior"),
}


@pytest.fixture(scope="module")
def gas():
    scene = jm.GasExpansion(cells=4, ppc=1)  # two boundary cells and two interior cells
    sol = jm.simulate(scene, jm.SPQ(), dt=1e-5, steps=20)
    boundary = np.asarray(sol.body.boundary)
    assert boundary.any() and not boundary.all()
    return scene, sol, boundary


@pytest.mark.parametrize("keep", ["boundary", "interior"])
def test_errors_of_a_group_that_where_leaves_empty_are_none(gas, keep):
    scene, sol, boundary = gas
    where = boundary if keep == "boundary" else ~boundary
    empty = "interior" if keep == "boundary" else "boundary"
    full = jm.errors(scene, sol.state, sol.body)
    for given in (jnp.asarray(where), where, [bool(w) for w in where]):  # an array, a list of bools
        e = raw(jm.errors)(scene, sol.state, sol.body, where=given)
        assert all(e[k] is None for k in GROUPS[empty]), {k: e[k] for k in GROUPS[empty]}
        for k in GROUPS[keep]:  # the group kept is measured as without where
            assert float(e[k]) == float(full[k])
        assert float(e["F_max_rel"]) == float(full[GROUPS[keep][0]])


def test_errors_where_leaves_both_groups_some_particle_are_numbers(gas):
    scene, sol, boundary = gas
    where = np.zeros_like(boundary)
    where[[0, 1]] = True  # the first (boundary) and second particle (interior at ppc=1, cells=4)
    assert boundary[0] and not boundary[1]
    e = jm.errors(scene, sol.state, sol.body, where=jnp.asarray(where))
    assert all(np.isfinite(float(e[k])) for k in metrics.EXACT_ERRORS)


def test_traced_where_leaving_a_group_empty_gives_zero_not_nan(gas):
    """Under jit the emptiness of a group cannot be read: the group's errors are 0 (no particle, no
    error), never NaN, and their derivatives are finite."""
    scene, sol, boundary = gas
    e = jax.jit(lambda w: jm.errors(scene, sol.state, sol.body, where=w))(jnp.asarray(boundary))
    assert float(e["F_max_rel_interior"]) == 0.0 and float(e["F_rms_rel_interior"]) == 0.0
    assert float(e["F_max_rel_boundary"]) == float(
        jm.errors(scene, sol.state, sol.body)["F_max_rel_boundary"]
    )

    rms = jax.jit(jax.grad(lambda F, w: _boundary_rms(F, scene, sol, w)))
    g = rms(sol.state.F, jnp.asarray(~boundary))
    assert bool(jnp.all(jnp.isfinite(g)))


def _boundary_rms(F, scene, sol, where):
    """``F_rms_rel_boundary`` of the state with deformation gradients ``F``."""
    state = eqx.tree_at(lambda s: s.F, sol.state, F)
    return jm.errors(scene, state, sol.body, where=where)["F_rms_rel_boundary"]


# ---------------------------------------------------------------- the centre of the radial measures

NOT_FINITE = [
    (np.array([np.nan]), r"^centre must be 1 finite real number \(one per axis\), got \[nan\]$"),
    (np.array([np.inf]), r"^centre must be 1 finite real number \(one per axis\), got \[inf\]$"),
]
NOT_REAL = [
    (["a"], r"^centre must be 1 finite real number \(one per axis\), got \['a'\]$"),
    ("a", r"^centre must be 1 finite real number \(one per axis\), got 'a'$"),
    ([None], r"^centre must be 1 finite real number \(one per axis\), got \[None\]$"),
    ([1j], r"^centre must be 1 finite real number \(one per axis\), got \[1j\]$"),
    ([True], r"^centre must be 1 finite real number \(one per axis\), got \[True\]$"),
]


def _radial_calls(sol, centre, every: bool):
    """Each radial measure called with ``centre``, without the suite's type checks (what a user runs);
    ``radial_bin`` and ``angular_spread`` only with ``every`` (they pass the centre on to checked
    functions, which refuse a value that is not a float array before the library's own check)."""
    calls = {
        "reference_radius": lambda: raw(metrics.reference_radius)(sol.body, centre),
        "radial_velocity": lambda: raw(metrics.radial_velocity)(sol.state, sol.body, centre),
    }
    if every:
        calls["radial_bin"] = lambda: raw(metrics.radial_bin)(sol.body, centre, 2)
        calls["angular_spread"] = lambda: raw(metrics.angular_spread)(sol.state, sol.body, centre, 2)
    return calls


@pytest.mark.parametrize(
    "centre, match, every",
    [(c, m, True) for c, m in NOT_FINITE] + [(c, m, False) for c, m in NOT_REAL],
    ids=[repr(c) for c, _ in NOT_FINITE + NOT_REAL],
)
def test_radial_measures_name_a_centre_that_is_not_finite_real_numbers(gas, centre, match, every):
    _, sol, _ = gas
    for name, call in _radial_calls(sol, centre, every).items():
        with pytest.raises(ValueError, match=match) as info:
            call()
        assert "\n" not in str(info.value), name


def test_radial_measures_still_name_a_centre_of_the_wrong_length(gas):
    _, sol, _ = gas
    with pytest.raises(
        ValueError, match=r"^centre must have 1 components \(the dimension\), got shape \(2,\)$"
    ):
        metrics.reference_radius(sol.body, np.zeros(2))


def test_radial_measures_take_a_traced_centre(gas):
    _, sol, _ = gas
    want = metrics.radial_velocity(sol.state, sol.body, np.zeros(1))
    got = jax.jit(lambda c: metrics.radial_velocity(sol.state, sol.body, c))(jnp.zeros(1))
    np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    R = jax.jit(lambda c: raw(metrics.reference_radius)(sol.body, [c]))(jnp.asarray(0.0))
    np.testing.assert_array_equal(np.asarray(R), np.asarray(raw(metrics.reference_radius)(sol.body, [0.0])))
