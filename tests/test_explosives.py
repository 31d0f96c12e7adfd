"""Explosives: the JWL rows' CJ states, the CJ solver, the isentropes, Murnaghan and the programmed burn."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raw

import jaxmpm as jm
from jaxmpm import explosives as ex

TNT = ex.EXPLOSIVES["tnt"]
ZERO, ONE = jnp.asarray(0.0), jnp.asarray(1.0)


def _tnt():
    eos = ex.JWL(*(TNT[k] for k in ("rho0", "A", "B", "R1", "R2", "w")))
    return eos, TNT["E0"] / TNT["rho0"]


@pytest.mark.parametrize("name", sorted(ex.EXPLOSIVES))
def test_rows_imply_their_tabulated_cj_state(name):
    row = ex.EXPLOSIVES[name]
    eos, e0 = ex.jwl(name)
    cj = ex.cj_state(eos, row["rho0"], e0)
    np.testing.assert_allclose(float(cj["D"]), row["D"], rtol=2e-3)
    np.testing.assert_allclose(float(cj["P_CJ"]), row["P_CJ"], rtol=2e-3)
    assert 0.7 < float(cj["J_CJ"]) < 0.76
    # The CJ condition: the products' own sound speed at the CJ point is D - u_CJ.
    c = eos.sound_speed(cj["rho_CJ"], cj["e_CJ"])
    np.testing.assert_allclose(float(c), float(cj["D"] - cj["u_CJ"]), rtol=1e-8)
    np.testing.assert_allclose(float(cj["c_CJ"]), float(c), rtol=1e-8)
    # On the Hugoniot and on the Rayleigh line, with the products' pressure.
    rho0 = row["rho0"]
    dv = 1.0 / rho0 - 1.0 / float(cj["rho_CJ"])
    np.testing.assert_allclose(float(cj["e_CJ"]), float(e0) + 0.5 * float(cj["P_CJ"]) * dv, rtol=1e-12)
    np.testing.assert_allclose(float(eos.pressure(cj["rho_CJ"], cj["e_CJ"])), float(cj["P_CJ"]), rtol=1e-12)
    np.testing.assert_allclose(float(cj["P_CJ"]), rho0 * float(cj["D"] * cj["u_CJ"]), rtol=1e-12)
    np.testing.assert_allclose(float(cj["J_CJ"]), rho0 / float(cj["rho_CJ"]), rtol=1e-14)


def test_measured_cj_of_the_rows():
    expected = {"tnt": (6929.35, 20.9997e9), "compb": (7979.85, 29.4988e9), "petn": (8300.79, 33.5086e9)}
    expected["pbx9404"] = (8800.05, 37.0007e9)
    for name, (D, P) in expected.items():
        eos, e0 = ex.jwl(name, check=False)
        cj = ex.cj_state(eos, eos.rho0, e0)
        np.testing.assert_allclose(float(cj["D"]), D, rtol=1e-5)
        np.testing.assert_allclose(float(cj["P_CJ"]), P, rtol=1e-4)


def test_a_row_with_transposed_digits_is_rejected():
    eos, e0 = _tnt()
    bad = ex.JWL(TNT["rho0"], 317.2e9, TNT["B"], TNT["R1"], TNT["R2"], TNT["w"])
    with pytest.raises(ValueError, match=r"CJ D = 6508.* but D = 6930 .*relative miss 0\.06"):
        ex.check_cj_consistency(bad, TNT["rho0"], e0, TNT["D"], TNT["P_CJ"])
    cj = ex.check_cj_consistency(eos, TNT["rho0"], e0, TNT["D"], TNT["P_CJ"], rtol=2e-3)
    assert abs(float(cj["D"]) / TNT["D"] - 1) < 2e-3
    with pytest.raises(ValueError, match="P_CJ"):  # the right D, a wrong pressure
        ex.check_cj_consistency(eos, TNT["rho0"], e0, TNT["D"], 1.1 * TNT["P_CJ"])


def test_unknown_explosive_lists_the_known_names():
    with pytest.raises(ValueError, match="'hmx'.*compb, pbx9404, petn, tnt"):
        ex.jwl("hmx")
    # a name that is not a string (a list is not even hashable) gets the same message
    with pytest.raises(ValueError, match=r"^unknown explosive \['tnt'\]; known: compb, pbx9404, petn, tnt$"):
        raw(ex.jwl)(["tnt"])


@pytest.mark.parametrize("name", ["rho0", "e0", "p0"])
def test_cj_state_is_one_state_and_names_an_array_of_several(name):
    """One CJ state per call: an array for e0 (or rho0, p0) is refused by name, with the way to run
    several (it broadcast into the solver, or failed in its gradient); jax.vmap solves several."""
    args = dict(rho0=1.0, e0=1.0, p0=0.0) | {name: np.array([1.0, 2.0])}
    with pytest.raises(
        ValueError,
        match=rf"^{name} must be one number, got an array of shape \(2,\); .*jax\.vmap over cj_state",
    ):
        ex.cj_state(jm.IdealGas(1.4), **args)
    D = jax.vmap(lambda e0: ex.cj_state(jm.IdealGas(1.4), 1.0, e0)["D"])(jnp.array([1.0, 2.0]))
    np.testing.assert_allclose(D, np.sqrt(2.0 * (1.4**2 - 1.0) * np.array([1.0, 2.0])), rtol=1e-10)


def test_cj_state_and_its_check_name_products_and_rtol():
    eos, e0 = _tnt()
    with pytest.raises(ValueError, match=r"^products must be an AbstractEOS .*got str$"):
        raw(ex.cj_state)("tnt", 1630.0, 4.3e6)
    for rtol, match in (
        ("1%", r"^rtol must be a real number, got '1%'$"),
        (-1.0, r"^rtol must be > 0, got -1\.0$"),
        (0.0, r"^rtol must be > 0, got 0\.0$"),
        (float("nan"), r"^rtol must be finite, got nan$"),
        (np.array([0.01, 0.02]), r"^rtol must be one number, got an array of shape \(2,\)"),
    ):
        with pytest.raises(ValueError, match=match):
            raw(ex.check_cj_consistency)(eos, eos.rho0, e0, 6930.0, rtol=rtol)
    with pytest.raises(ValueError, match=r"^D must be one number, got an array of shape \(2,\)"):
        ex.check_cj_consistency(eos, eos.rho0, e0, np.array([6930.0, 7000.0]))


@pytest.mark.parametrize("iterations", [0, -1, None, 2.5, True])
def test_cj_energy_names_iterations(iterations):
    # 0 and -1 blamed D (no Newton step leaves the start, whose speed is another), None was JAX's error
    # and 2.5 was taken
    with pytest.raises(ValueError, match=r"^iterations must be an integer >= 1, got "):
        raw(ex.cj_energy)(jm.IdealGas(1.4), 1.0, 2.0, iterations=iterations)


def test_ideal_gas_cj_is_the_gamma_law_closed_form():
    for gamma, D, rho0 in ((1.4, 2000.0, 1.2), (3.0, 7000.0, 1600.0)):
        e0 = D**2 / (2.0 * (gamma**2 - 1.0))
        cj = ex.cj_state(jm.IdealGas(gamma), rho0, e0)
        closed = ex.GammaLawIsentrope(rho0, D, gamma).cj()
        for k in ("D", "P_CJ", "J_CJ", "u_CJ", "c_CJ", "rho_CJ", "e_CJ"):
            np.testing.assert_allclose(float(cj[k]), float(closed[k]), rtol=1e-10, err_msg=k)
        np.testing.assert_allclose(float(cj["P_CJ"]), rho0 * D**2 / (gamma + 1.0), rtol=1e-10)
        np.testing.assert_allclose(float(cj["J_CJ"]), gamma / (gamma + 1.0), rtol=1e-10)


@pytest.mark.parametrize("q", [1e-1, 1e-3, 1e-5, 1e-6, 1e-8, 1e-10])
def test_cj_of_a_weak_detonation_with_ambient_pressure_is_the_closed_form(q):
    """A gamma-law gas detonating from ``(rho0, p0)`` with heat release ``q`` (per unit mass, here in
    units of ``c0^2``): ``D = sqrt(H + c0^2) + sqrt(H)``, ``H = (gamma^2 - 1) q / 2``, and ``J_CJ =
    (gamma + c0^2 / D^2) / (gamma + 1)``. The weakest (``q = 1e-6 c0^2`` and below) have ``1 - J_CJ``
    under 1e-3, closer to 1 than the scan's even grid reaches. ``D^2`` divides by ``1 - J``, so the
    state is as precise as ``eps / (1 - J_CJ)`` (measured: within it at every ``q`` here)."""
    gamma, rho0, p0 = 1.4, 1.0, 1.0
    c0sq = gamma * p0 / rho0
    q = q * c0sq
    H = (gamma**2 - 1.0) * q / 2.0
    D = np.sqrt(H + c0sq) + np.sqrt(H)
    J = (gamma + c0sq / D**2) / (gamma + 1.0)
    cj = ex.cj_state(jm.IdealGas(gamma), rho0, q + p0 / ((gamma - 1.0) * rho0), p0)
    rtol = 2.0 * np.finfo(float).eps / (1.0 - J)
    np.testing.assert_allclose(float(cj["D"]), D, rtol=rtol)
    np.testing.assert_allclose(float(cj["J_CJ"]), J, rtol=rtol)
    np.testing.assert_allclose(float(cj["P_CJ"]), p0 + rho0 * D**2 * (1.0 - J), rtol=rtol)


def test_no_heat_release_has_no_cj_state():
    """Without heat release the Hugoniot is the shock adiabat through the initial state, and ``D^2``
    falls toward the sound speed as ``J -> 1``: a sound wave, no CJ point (NaN)."""
    gamma, rho0, p0 = 1.4, 1.0, 1.0
    cj = ex.cj_state(jm.IdealGas(gamma), rho0, p0 / ((gamma - 1.0) * rho0), p0)
    assert all(np.isnan(float(v)) for v in cj.values())


def test_cj_with_ambient_pressure_stays_on_hugoniot_and_rayleigh_line():
    eos, e0 = _tnt()
    p0 = 1e8
    cj = ex.cj_state(eos, TNT["rho0"], e0, p0)
    rho0, D, P, J = TNT["rho0"], float(cj["D"]), float(cj["P_CJ"]), float(cj["J_CJ"])
    np.testing.assert_allclose(P - p0, rho0 * D**2 * (1.0 - J), rtol=1e-12)
    np.testing.assert_allclose(float(cj["e_CJ"]), float(e0) + 0.5 * (P + p0) * (1.0 - J) / rho0, rtol=1e-12)
    c = float(eos.sound_speed(cj["rho_CJ"], cj["e_CJ"]))
    np.testing.assert_allclose(c, D * J, rtol=1e-8)


@pytest.mark.slow
def test_cj_gradients_match_central_differences():
    rho0 = TNT["rho0"]

    def state(A, E0):
        eos = ex.JWL(rho0, A, TNT["B"], TNT["R1"], TNT["R2"], TNT["w"])
        cj = ex.cj_state(eos, rho0, E0 / rho0)
        return jnp.stack([cj["D"], cj["P_CJ"], cj["J_CJ"]])

    A, E0 = jnp.asarray(TNT["A"]), jnp.asarray(TNT["E0"])
    jac = jax.jacfwd(state, argnums=(0, 1))(A, E0)
    grads = jax.jacrev(state, argnums=(0, 1))(A, E0)
    for i, x in enumerate((A, E0)):
        h = 1e-4 * x
        args_p = [A, E0]
        args_m = [A, E0]
        args_p[i], args_m[i] = x + h, x - h
        fd = (state(*args_p) - state(*args_m)) / (2.0 * h)
        np.testing.assert_allclose(np.asarray(jac[i]), np.asarray(fd), rtol=1e-6)
        np.testing.assert_allclose(np.asarray(grads[i]), np.asarray(fd), rtol=1e-6)
    assert float(jac[1][0]) > 0  # more energy, a faster detonation


def test_jwl_isentrope_passes_through_the_cj_point():
    eos, e0 = _tnt()
    cj = ex.cj_state(eos, eos.rho0, e0)
    iso = ex.JWLIsentrope.from_jwl(eos, e0)
    np.testing.assert_allclose(float(iso.pressure(cj["rho_CJ"], ZERO)), float(cj["P_CJ"]), rtol=1e-12)
    # A JWL isentrope: tangent to the Rayleigh line there too.
    np.testing.assert_allclose(float(iso.sound_speed(cj["rho_CJ"], ZERO)), float(cj["c_CJ"]), rtol=1e-8)
    a, b = iso.pressure_terms(jnp.asarray(2000.0), None)
    assert float(b) == 0.0
    V = TNT["rho0"] / 2000.0
    ref = TNT["A"] * np.exp(-TNT["R1"] * V) + TNT["B"] * np.exp(-TNT["R2"] * V) + float(iso.C) * V**-1.3
    np.testing.assert_allclose(float(a), ref, rtol=1e-12)


def test_gamma_law_isentrope():
    rho0, D, gamma = 1600.0, 7000.0, 3.0
    iso = ex.GammaLawIsentrope(rho0, D, gamma)
    cj = iso.cj()
    np.testing.assert_allclose(float(cj["P_CJ"]), rho0 * D**2 / 4.0, rtol=1e-14)
    np.testing.assert_allclose(float(cj["J_CJ"]), 0.75, rtol=1e-14)
    np.testing.assert_allclose(float(cj["c_CJ"]), 0.75 * D, rtol=1e-14)
    np.testing.assert_allclose(float(cj["u_CJ"]), 0.25 * D, rtol=1e-14)
    np.testing.assert_allclose(float(iso.pressure(cj["rho_CJ"], ZERO)), float(cj["P_CJ"]), rtol=1e-12)
    np.testing.assert_allclose(float(iso.sound_speed(cj["rho_CJ"], ZERO)), float(cj["c_CJ"]), rtol=1e-12)
    rho = 1.2 * rho0  # V = 1 / 1.2
    np.testing.assert_allclose(
        float(iso.pressure(jnp.asarray(rho), ZERO)), float(cj["P_CJ"]) * (0.75 * 1.2) ** 3.0, rtol=1e-12
    )


def test_barotropic_cj():
    iso = ex.GammaLawIsentrope(1600.0, 7000.0, 3.0)
    cj, closed = ex.cj_state(iso, 1600.0), iso.cj()
    for k in ("D", "P_CJ", "J_CJ", "u_CJ", "c_CJ"):
        np.testing.assert_allclose(float(cj[k]), float(closed[k]), rtol=1e-10, err_msg=k)
    eos, e0 = _tnt()
    D = ex.cj_state(ex.JWLIsentrope.from_jwl(eos, e0), TNT["rho0"])["D"]
    np.testing.assert_allclose(float(D), float(ex.cj_state(eos, TNT["rho0"], e0)["D"]), rtol=1e-10)
    sound = ex.cj_state(ex.Murnaghan(1600.0, 1.0 / 9e9, 7.4), 1600.0)  # no interior minimum
    assert all(np.isnan(float(v)) for v in sound.values())


def test_murnaghan_values():
    rho0, K, n = 1630.0, 1.0 / 9.0e9, 7.4
    m = ex.Murnaghan(rho0, K, n)
    for ratio in (0.9, 1.0, 1.1, 1.3):
        a, b = m.pressure_terms(jnp.asarray(ratio * rho0), None)
        np.testing.assert_allclose(float(a), (ratio**n - 1.0) / (n * K), rtol=1e-12, atol=1e-3)
        assert float(b) == 0.0
    np.testing.assert_allclose(
        float(m.sound_speed(jnp.asarray(rho0), ZERO)), np.sqrt(9.0e9 / rho0), rtol=1e-12
    )
    bulk = ex.Murnaghan.from_bulk_modulus(rho0, 9.0e9, n)
    np.testing.assert_allclose(float(bulk.K), K, rtol=1e-15)
    assert m.initial_internal(jnp.zeros(1)) is None


def _burn(**kw):
    eos, _ = _tnt()
    args = dict(
        reactant=ex.Murnaghan(TNT["rho0"], 1.0 / 9.0e9, 7.4),
        products=eos,
        D=TNT["D"],
        points=[[0.0]],
        width=0.003,
        J_CJ=0.73,
    )
    args.update(kw)
    return ex.ProgrammedBurn(**args)


def test_time_burn_ramps_linearly_and_never_decreases():
    pb = _burn(t_d=1e-6)
    X = jnp.asarray([0.02])
    tb = 1e-6 + 0.02 / TNT["D"]
    np.testing.assert_allclose(float(pb.lighting_time(X)), tb, rtol=1e-14)
    dt_burn = 0.003 / TNT["D"]
    z = pb.initial_internal(X)
    assert z["lambda"].shape == () and z["lambda"].dtype == X.dtype and float(z["lambda"]) == 0.0
    dt = 0.1 * dt_burn
    lams = []
    t = tb - 3 * dt
    for _ in range(16):
        z = pb.update_internal(z, X, jnp.asarray(t), jnp.asarray(dt), jnp.asarray(1.0), jnp.asarray(1.0))
        t += dt
        lams.append(float(z["lambda"]))
    expected = np.clip((tb - 3 * dt + dt * np.arange(1, 17) - tb) / dt_burn, 0.0, 1.0)
    np.testing.assert_allclose(lams, expected, atol=1e-10)
    assert lams[0] == 0.0 and lams[-1] == 1.0
    # Never decreases: an old lambda above the criterion stays.
    z = pb.update_internal({"lambda": jnp.asarray(0.8)}, X, jnp.asarray(tb), jnp.asarray(dt), ONE, ONE)
    assert float(z["lambda"]) == 0.8
    # As the step calls it: vmapped over particles.
    Xs = jnp.asarray([[0.0], [0.01], [0.05]])
    zs = jax.vmap(pb.initial_internal)(Xs)
    J = jnp.ones(3)
    out = jax.vmap(pb.update_internal, in_axes=(0, 0, None, None, 0, 0))(
        zs, Xs, jnp.asarray(1e-6 + 0.01 / TNT["D"]), jnp.asarray(0.5 * dt_burn), J, J
    )
    np.testing.assert_allclose(np.asarray(out["lambda"]), [1.0, 0.5, 0.0], atol=1e-12)


def test_volume_and_max_burns():
    X, t, dt = jnp.asarray([0.1]), jnp.asarray(0.0), jnp.asarray(1e-9)  # the front is far away
    half = jnp.asarray(1.0 - 0.5 * (1.0 - 0.73))
    z0 = {"lambda": jnp.asarray(0.0)}
    vol = _burn(burn="volume")
    assert float(vol.update_internal(z0, X, t, dt, ONE, half)["lambda"]) == pytest.approx(0.5)
    assert float(vol.update_internal(z0, X, t, dt, ONE, jnp.asarray(0.6))["lambda"]) == 1.0
    assert float(vol.update_internal(z0, X, t, dt, ONE, jnp.asarray(1.1))["lambda"]) == 0.0
    tim = _burn(burn="time")
    assert float(tim.update_internal(z0, X, t, dt, ONE, half)["lambda"]) == 0.0
    mx = _burn(burn="max")
    assert float(mx.update_internal(z0, X, t, dt, ONE, half)["lambda"]) == pytest.approx(0.5)
    # Later the front arrives: the time criterion, larger, wins.
    tb = float(mx.lighting_time(X))
    late = mx.update_internal(z0, X, jnp.asarray(tb), jnp.asarray(0.8 * 0.003 / TNT["D"]), ONE, half)
    assert float(late["lambda"]) == pytest.approx(0.8)


def test_smooth_ramp_is_c1():
    X = jnp.asarray([0.0])
    dt_burn = 0.003 / TNT["D"]
    one = ONE

    def lam(pb, s):  # lambda at the new time t + dt = s dt_burn after lighting
        z = pb.update_internal({"lambda": jnp.asarray(0.0)}, X, s * dt_burn, jnp.asarray(0.0), one, one)
        return z["lambda"]

    smooth, linear = _burn(smooth=True), _burn()
    dsmooth = jax.grad(lambda s: lam(smooth, s))
    dlinear = jax.grad(lambda s: lam(linear, s))
    for end in (0.0, 1.0):
        for s in (end - 1e-6, end + 1e-6):
            assert abs(float(dsmooth(jnp.asarray(s)))) < 1e-5
    np.testing.assert_allclose(float(dsmooth(jnp.asarray(0.5))), 1.5, rtol=1e-12)
    np.testing.assert_allclose(float(lam(smooth, jnp.asarray(0.25))), 3 * 0.25**2 - 2 * 0.25**3, rtol=1e-12)
    # The linear ramp's slope jumps from 1 to 0 at the end.
    assert float(dlinear(jnp.asarray(1.0 - 1e-6))) == pytest.approx(1.0)
    assert float(dlinear(jnp.asarray(1.0 + 1e-6))) == 0.0


def test_lighting_time_is_the_earliest_detonator():
    pb = _burn(points=[[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]], t_d=2e-6)
    X = jnp.asarray([0.7, 0.4])
    d = min(np.hypot(0.7, 0.4), np.hypot(0.3, 0.4), np.hypot(0.7, 1.6))
    np.testing.assert_allclose(float(pb.lighting_time(X)), 2e-6 + d / TNT["D"], rtol=1e-14)
    assert float(pb.lighting_time(jnp.asarray([1.0, 0.0]))) == pytest.approx(2e-6)
    g = jax.grad(lambda p: p.lighting_time(jnp.asarray([1.0, 0.0])))(pb)  # on a detonator: finite
    assert np.all(np.isfinite(np.asarray(g.points)))
    one = _burn(points=[0.5, 0.5])  # one point as a vector
    assert one.points.shape == (1, 2)
    assert _burn(points=0.25).points.shape == (1, 1)


def test_lighting_time_refuses_a_position_of_another_dimension():
    """X is one position of the detonators' dimension: a 2-vector against a 1D detonator broadcast to
    a time (7.215e-4 s), here and under jax.jit (the check is on the shape)."""
    pb = _burn(points=0.0)
    lighting_time = raw(ex.ProgrammedBurn.lighting_time)  # past the suite's type checks of X's rank
    for X, shape in ((jnp.array([3.0, 4.0]), r"\(2,\)"), (jnp.array([[3.0]]), r"\(1, 1\)"), (ONE, r"\(\)")):
        match = rf"^X must be one position of shape \(1,\) \(the detonators' dimension\), got shape {shape}$"
        with pytest.raises(ValueError, match=match):
            lighting_time(pb, X)
        with pytest.raises(ValueError, match=match.rstrip("$")):  # JAX appends a note on its traceback
            jax.jit(lambda X: lighting_time(pb, X))(X)
    assert float(pb.lighting_time(jnp.array([3.0]))) == pytest.approx(3.0 / TNT["D"], rel=1e-15)
    plane = _burn(points=np.zeros((0, 2)), planes=[[1.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"^X must be one position of shape \(2,\)"):
        plane.burn_fraction(jnp.array([1.0, 2.0, 3.0]), ONE, ONE)


def test_mixture_pressure_terms():
    pb = _burn()
    rho = jnp.asarray(1.2 * TNT["rho0"])
    ar, br = pb.reactant.pressure_terms(rho, None)
    ap, bp = pb.products.pressure_terms(rho, None)
    a, b = pb.pressure_terms(rho, {"lambda": jnp.asarray(0.3)})
    np.testing.assert_allclose(float(a), 0.7 * float(ar) + 0.3 * float(ap), rtol=1e-12)
    np.testing.assert_allclose(float(b), 0.7 * float(br) + 0.3 * float(bp), rtol=1e-12)
    inert = _burn(reactant=None)
    a, b = inert.pressure_terms(rho, {"lambda": jnp.asarray(0.3)})
    np.testing.assert_allclose([float(a), float(b)], [0.3 * float(ap), 0.3 * float(bp)], rtol=1e-12)
    c = inert.sound_speed(rho, jnp.asarray(4e6), {"lambda": jnp.asarray(1.0)})
    np.testing.assert_allclose(float(c), float(pb.products.sound_speed(rho, jnp.asarray(4e6))), rtol=1e-12)


def test_lambda_is_differentiable_in_the_burn_parameters():
    X = jnp.asarray([0.02])
    one = jnp.asarray(1.0)

    def lam(D):
        pb = _burn(D=D)
        t = 0.02 / TNT["D"] + 0.5 * 0.003 / TNT["D"]
        return pb.update_internal(
            {"lambda": jnp.asarray(0.0)}, X, jnp.asarray(t), jnp.asarray(0.0), one, one
        )["lambda"]

    D = jnp.asarray(TNT["D"])
    h = 1e-3
    fd = (lam(D + h) - lam(D - h)) / (2 * h)
    np.testing.assert_allclose(float(jax.grad(lam)(D)), float(fd), rtol=1e-6)


@pytest.mark.parametrize(
    "build, name",
    [
        (lambda: _burn(D=0.0), "D"),
        (lambda: _burn(width=-1.0), "width"),
        (lambda: _burn(J_CJ=1.0), "J_CJ"),
        (lambda: _burn(J_CJ=0.0), "J_CJ"),
        (lambda: _burn(t_d=float("nan")), "t_d"),
        (lambda: _burn(points=[[0.0, float("inf")]]), "points"),
        (lambda: _burn(burn="fast"), "burn"),
        (lambda: ex.JWL(1630.0, 1e11, 1e9, 4.0, 1.0, 0.0), "w"),
        (lambda: ex.JWL(-1.0, 1e11, 1e9, 4.0, 1.0, 0.3), "rho0"),
        (lambda: ex.JWL(1630.0, 1e11, 1e9, 0.0, 1.0, 0.3), "R1"),
        (lambda: ex.JWLIsentrope(1630.0, 1e11, 1e9, 4.0, 1.0, 0.3, float("nan")), "C"),
        (lambda: ex.GammaLawIsentrope(1630.0, 7000.0, 1.0), "gamma"),
        (lambda: ex.GammaLawIsentrope(1630.0, -1.0, 3.0), "D"),
        (lambda: ex.Murnaghan(1630.0, 1e-10, 0.0), "n"),
        (lambda: ex.Murnaghan(1630.0, 0.0, 7.4), "K"),
        (lambda: ex.Murnaghan.from_bulk_modulus(1630.0, -9e9, 7.4), "K_bulk"),
        (lambda: ex.cj_state(_tnt()[0], 0.0, 1e6), "rho0"),
    ],
)
def test_bad_inputs_name_the_parameter(build, name):
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        build()


@pytest.mark.parametrize("points", [[], [[]], np.zeros((1, 4))], ids=["empty", "empty-row", "4d"])
def test_points_without_a_dimension_of_1_to_3_are_refused(points):
    # an empty list gives no dimension: it is not one point of dimension 0
    with pytest.raises(ValueError, match=r"^points must be an array \(k, dim\) with dim 1, 2 or 3 .*shape"):
        _burn(points=points)
    assert _burn(points=np.zeros((0, 1)), planes=[[1.0, 0.0]]).points.shape == (0, 1)


def test_bad_burn_lists_the_allowed_values():
    with pytest.raises(ValueError, match="'time', 'volume', 'max'"):
        _burn(burn="fast")


def test_plane_detonators_light_by_distance_the_earliest_winning():
    """A plane n . X = c lights X at t_d + |n . X - c| / (|n| D) (Huygens' straight-line burn); with a
    point as well, the earlier of the two."""
    products = ex.GammaLawIsentrope(rho0=1.0, D=2.0, gamma=3.0)
    plane = ex.ProgrammedBurn(
        reactant=None,
        products=products,
        D=2.0,
        points=jnp.zeros((0, 2)),
        width=0.1,
        J_CJ=0.75,
        t_d=0.5,
        planes=[[3.0, 4.0, 1.0]],  # 3 x + 4 y = 1, |n| = 5
    )
    X = jnp.array([0.6, 0.2])
    assert float(plane.lighting_time(X)) == pytest.approx(0.5 + abs(1.8 + 0.8 - 1.0) / 5.0 / 2.0, rel=1e-15)
    both = ex.ProgrammedBurn(
        reactant=None, products=products, D=2.0, points=[[0.6, 0.3]], width=0.1, J_CJ=0.75, planes=[3, 4, 1]
    )
    assert float(both.lighting_time(X)) == pytest.approx(0.1 / 2.0, rel=1e-14)  # the point, 0.1 away
    far = jnp.array([-2.0, 0.0])
    assert float(both.lighting_time(far)) == pytest.approx(7.0 / 5.0 / 2.0, rel=1e-15)  # the plane
    g = jax.grad(lambda x: plane.lighting_time(x))(X)
    np.testing.assert_allclose(g, np.array([3.0, 4.0]) / 5.0 / 2.0, rtol=1e-15)
    for kwargs, match in (
        (dict(points=jnp.zeros((0, 2))), "at least one detonator"),
        (dict(points=jnp.zeros((0, 2)), planes=[[0.0, 0.0, 1.0]]), "normal n must not be zero"),
        (dict(points=[[0.0, 0.0]], planes=[[1.0, 0.0]]), "planes must be an array"),
    ):
        with pytest.raises(ValueError, match=match):
            ex.ProgrammedBurn(reactant=None, products=products, D=2.0, width=0.1, J_CJ=0.75, **kwargs)


def test_line_detonators_light_by_the_distance_to_the_line():
    """A line through a along d lights X at t_d + |(X - a) - ((X - a) . d) d / |d|^2| / D (a
    detonating cord in 3D); with a point as well, the earlier; on the line the derivative is 0, not NaN;
    in 2D a line lights as the plane through it."""
    products = ex.GammaLawIsentrope(rho0=1.0, D=2.0, gamma=3.0)
    a, d = np.array([0.1, 0.2, 0.3]), np.array([1.0, 2.0, 2.0])  # |d| = 3
    cord = ex.ProgrammedBurn(
        reactant=None,
        products=products,
        D=2.0,
        points=jnp.zeros((0, 3)),
        width=0.1,
        J_CJ=0.75,
        t_d=0.25,
        lines=np.concatenate([a, d]),
    )
    rng = np.random.default_rng(0)
    for X in rng.uniform(-1.0, 1.0, (5, 3)):
        r = X - a
        dist = np.linalg.norm(r - (r @ d) / 9.0 * d)
        assert float(cord.lighting_time(jnp.asarray(X))) == pytest.approx(0.25 + dist / 2.0, rel=1e-14)
    on_line = jnp.asarray(a + 0.5 * d)
    assert float(cord.lighting_time(on_line)) == pytest.approx(0.25, abs=1e-15)
    np.testing.assert_array_equal(jax.grad(cord.lighting_time)(on_line), np.zeros(3))
    X = jnp.array([0.6, -0.4, 0.2])
    r = np.asarray(X) - a
    normal = r - (r @ d) / 9.0 * d
    np.testing.assert_allclose(
        jax.grad(cord.lighting_time)(X), normal / np.linalg.norm(normal) / 2.0, rtol=1e-13
    )
    both = ex.ProgrammedBurn(
        reactant=None,
        products=products,
        D=2.0,
        points=[[0.6, -0.4, 0.3]],
        width=0.1,
        J_CJ=0.75,
        lines=np.concatenate([a, d]),
    )
    assert float(both.lighting_time(X)) == pytest.approx(0.1 / 2.0, rel=1e-13)  # the point, 0.1 away
    line_2d = ex.ProgrammedBurn(
        reactant=None,
        products=products,
        D=2.0,
        points=jnp.zeros((0, 2)),
        width=0.1,
        J_CJ=0.75,
        lines=[[0.0, 0.25, 4.0, -3.0]],  # through (0, 1/4) along (4, -3): 3 x + 4 y = 1
    )
    plane_2d = ex.ProgrammedBurn(
        reactant=None,
        products=products,
        D=2.0,
        points=jnp.zeros((0, 2)),
        width=0.1,
        J_CJ=0.75,
        planes=[[3.0, 4.0, 1.0]],
    )
    for X2 in rng.uniform(-1.0, 1.0, (5, 2)):
        assert float(line_2d.lighting_time(jnp.asarray(X2))) == pytest.approx(
            float(plane_2d.lighting_time(jnp.asarray(X2))), rel=1e-14
        )
    for kwargs, match in (
        (
            dict(points=jnp.zeros((0, 3)), lines=[[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]),
            "direction d must not be zero",
        ),
        (dict(points=[[0.0, 0.0, 0.0]], lines=[[0.0, 0.0, 1.0, 0.0]]), "lines must be an array"),
        (dict(points=[0.5], lines=[[0.0, 1.0]]), "lines must be an array"),
    ):
        with pytest.raises(ValueError, match=match):
            ex.ProgrammedBurn(reactant=None, products=products, D=2.0, width=0.1, J_CJ=0.75, **kwargs)


@pytest.mark.slow
def test_cj_energy_implies_the_given_detonation_speed_and_is_differentiable():
    """cj_energy(products, rho0, D) is the e0 at which the products imply D: for each handbook row at its
    tabulated D it returns the row's E0 to the row's own consistency (0.2%), the CJ state it implies has
    speed D to round-off, and its derivatives (implicit function) match central differences."""
    for name, row in ex.EXPLOSIVES.items():
        eos, _ = ex.jwl(name)
        e0 = ex.cj_energy(eos, eos.rho0, row["D"])
        assert float(e0) * row["rho0"] == pytest.approx(row["E0"], rel=2e-3), name  # measured <= 1.8e-3
        assert float(ex.cj_state(eos, eos.rho0, e0)["D"]) == pytest.approx(row["D"], rel=1e-13), name
    gamma_law = jm.IdealGas(gamma=3.0)  # D^2 = 2 (gamma^2 - 1) e0 in closed form
    assert float(ex.cj_energy(gamma_law, 1600.0, 8000.0)) == pytest.approx(8000.0**2 / 16.0, rel=1e-12)
    eos, _ = ex.jwl("compb")

    def e0_of(A, D):
        return ex.cj_energy(ex.JWL(eos.rho0, A, eos.B, eos.R1, eos.R2, eos.w), eos.rho0, D)

    A, D = float(eos.A), 7980.0
    gA, gD = jax.grad(e0_of, argnums=(0, 1))(jnp.asarray(A), jnp.asarray(D))
    fdA = (e0_of(A * (1 + 1e-5), D) - e0_of(A * (1 - 1e-5), D)) / (2e-5 * A)
    fdD = (e0_of(A, D + 0.1) - e0_of(A, D - 0.1)) / 0.2
    assert float(gA) == pytest.approx(float(fdA), rel=1e-6) and float(gD) == pytest.approx(
        float(fdD), rel=1e-6
    )
    with pytest.raises(ValueError, match="D must be"):
        ex.cj_energy(eos, eos.rho0, -1.0)
