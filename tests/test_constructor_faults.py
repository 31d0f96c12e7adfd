"""Constructor faults: scenes, materials, viscosities, explosives and grids name the parameter that is
wrong, with what is allowed, before anything is traced; tracers and batched values under jax.vmap pass.

(The suite's runtime type checks may refuse a wrongly typed argument first, with a TypeError; the
tests that accept one still ask for the parameter's name.)
"""

import inspect
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import float32

import jaxmpm as jm
from jaxmpm import explosives as ex

SMALL = dict(cells=4, ppc=1, pad=4)  # a cheap Gurney slab


def _one_line(make, match, errors=ValueError):
    """``make()`` raises ``errors`` matching ``match``; a ValueError (the library's own) in one line."""
    with pytest.raises(errors, match=match) as info:
        make()
    if isinstance(info.value, ValueError):
        assert "\n" not in str(info.value)
    return str(info.value)


def _raw(cls, **kw):
    """A scene's fields as given, before the converters and the checks: what ``__post_init__`` sees
    (the suite's runtime type checks would refuse a wrongly typed argument before it)."""
    obj = object.__new__(cls)
    for k, v in {**cls.parameters(), **kw}.items():
        object.__setattr__(obj, k, v)
    return obj


# -- Gurney: the JWL constants are checked whichever explosive runs ---------------------------------

JWL_BAD = [
    ("A", np.nan, r"^A must be finite, got nan$"),
    ("A", np.inf, r"^A must be finite, got inf$"),
    ("B", -np.inf, r"^B must be finite, got -inf$"),
    ("R1", -4.2, r"^R1 must be > 0, got -4\.2$"),
    ("R2", 0.0, r"^R2 must be > 0, got 0\.0$"),
    ("w", np.nan, r"^w must be finite, got nan$"),
    ("w", -0.3, r"^w must be > 0, got -0\.3$"),
]


@pytest.mark.parametrize("explosive", ["compb", "gamma-law", "jwl"])
@pytest.mark.parametrize("param, bad, match", JWL_BAD, ids=[f"{p}={b}" for p, b, _ in JWL_BAD])
@pytest.mark.parametrize("scene", ["GurneySlab", "GurneyCylinder"])
def test_gurney_refuses_bad_jwl_constants_whatever_the_explosive(scene, param, bad, match, explosive):
    kw = SMALL if scene == "GurneySlab" else dict(cells=10, ppc=1, pad=4)
    _one_line(lambda: getattr(jm, scene)(explosive=explosive, **{param: bad}, **kw), match)


def test_gurney_with_good_jwl_constants_and_another_explosive_still_builds():
    s = jm.GurneySlab(explosive="gamma-law", A=1e11, B=1e9, R1=5.0, R2=1.5, w=0.4, **SMALL)
    assert s.parameter_values()["R1"] == 5.0 and np.isfinite(float(s.gurney_velocity()))


def test_gurney_jwl_constants_pass_as_tracers():
    def f(A):
        return jm.GurneySlab(explosive="gamma-law", A=A, **SMALL).A * 2.0

    assert float(jax.jit(f)(3.0)) == 6.0


# -- scenes: a continuous parameter is one number, a structural one an integer ----------------------

SEVERAL = (
    r"must be one number, got an array of shape \(2,\): to run several values, jax\.vmap.*jaxmpm\.ensemble$"
)

LISTS = [
    ("GasSlab", "P0", [3e5, 4e5]),
    ("Blast", "p_atm", [1e5, 2e5]),
    ("BlastDisk", "P0", [1e6, 2e6]),
    ("Riemann", "F_left", [0.5, 0.6]),
    ("ShockTube", "p_l", [1.0, 2.0]),
    ("Detonation", "rho0", [1875.0, 1900.0]),
    ("Detonation", "D", [8000.0, 8100.0]),
    ("GasExpansion", "beta", np.array([100.0, 200.0])),
    ("GurneySlab", "sqrt_2E", jnp.array([2700.0, 2800.0])),
]


@pytest.mark.parametrize("scene, param, value", LISTS, ids=[f"{s}-{p}" for s, p, _ in LISTS])
def test_a_scene_parameter_with_a_shape_is_refused_by_name(scene, param, value):
    _one_line(lambda: getattr(jm, scene)(**{param: value}), f"^{param} {SEVERAL}", (ValueError, TypeError))


STATIC = [
    ("Interface", "x0", [0.5], r"^x0 must be one number, got an array of shape \(1,\) \(a static parameter"),
    ("ShockTube", "x0", np.array([0.5, 0.6]), r"^x0 must be one number, got an array of shape \(2,\)"),
    ("GurneySlab", "split", [0.8], r"^split must be one number, got an array of shape \(1,\)"),
    ("GurneyCylinder", "split", [0.8], r"^split must be one number, got an array of shape \(1,\)"),
    ("GurneySlab", "split", "0.8", r"^split must be a real number, got '0\.8'$"),
]


@pytest.mark.parametrize(
    "scene, param, value, match", STATIC, ids=[f"{s}-{p}={v!r}" for s, p, v, _ in STATIC]
)
def test_a_static_fraction_is_one_number(scene, param, value, match):
    _one_line(lambda: getattr(jm, scene)(**{param: value}), match)


SPLITS = [
    ("Interface", "x0", 0.001, dict(), "left", r"0\.1 cells.*\[0\.25, 99\.75\) cells"),
    ("ShockTube", "x0", 0.0001, dict(cells=100), "left", r"0\.01 cells.*\[0\.25, 99\.75\) cells"),
    ("Interface", "x0", 0.9975, dict(), "right", r"99\.75 cells.*\[0\.25, 99\.75\) cells"),
    ("GurneySlab", "split", 0.999, dict(), "right", r"199\.8 cells.*\[0\.25, 199\.75\) cells"),
    ("GurneySlab", "split", 0.01, dict(cells=10, ppc=1, pad=4), "left", r"0\.1 cells.*\[0\.5, 9\.5\) cells"),
]


@pytest.mark.parametrize(
    "scene, param, value, kw, side, where", SPLITS, ids=[f"{s}-{p}={v!r}" for s, p, v, *_ in SPLITS]
)
def test_a_split_leaving_a_side_without_particles_is_refused_by_name(scene, param, value, kw, side, where):
    msg = _one_line(
        lambda: getattr(jm, scene)(**{param: value}, **kw), f"^{param} = {value!r} leaves the {side}"
    )
    assert re.search(where, msg), msg


@pytest.mark.parametrize("scene, param, value", [("Interface", "x0", 0.0025), ("Interface", "x0", 0.9974)])
def test_a_split_one_particle_from_the_end_is_kept(scene, param, value):
    # the first centre (0.25 cells) on the split belongs to the left side; 99.74 cells leaves the right
    # side its last particle (99.75)
    s = getattr(jm, scene)(**{param: value})
    counts = jm.regions.layout((s.cells,), s.ppc, tuple(r.shape for r in s.regions()), s.pad).counts
    assert min(counts) == 1 and sum(counts) == s.cells * s.ppc


STRUCTURAL = [
    ("Detonation", "cells", "200", r"^cells must be an integer >= 1, got '200'$"),
    ("Detonation", "ppc", None, r"^ppc must be an integer >= 1, got None$"),
    ("Detonation", "cells", 0, r"^cells must be an integer >= 1, got 0$"),
    ("GurneyCylinder", "cells", None, r"^cells must be an integer >= 1, got None$"),
    ("GurneySlab", "pad", 2.5, r"^pad must be an integer >= 1, got 2\.5$"),
    ("BlastDisk", "cells", -3, r"^cells must be an integer >= 1, got -3$"),
    ("GasSlab", "ppc", True, r"^ppc must be an integer >= 1, got True$"),
]


@pytest.mark.parametrize(
    "scene, param, value, match", STRUCTURAL, ids=[f"{s}-{p}={v!r}" for s, p, v, _ in STRUCTURAL]
)
def test_a_structural_parameter_is_named_before_the_scene_computes_with_it(scene, param, value, match):
    cls = getattr(jm, scene)
    _one_line(lambda: cls(**{param: value}), param, (ValueError, TypeError))
    # without the suite's type checks: refused on the value as given, before any __check_init__ (a
    # scene's own runs first and divides by cells)
    _one_line(lambda: jm.scenes.AbstractScene.__post_init__(_raw(cls, **{param: value})), match)


def test_static_parameters_still_take_numbers_and_0d_arrays():
    assert jm.Interface(x0=np.float64(0.25)).x0 == 0.25
    assert jm.ShockTube(x0=np.asarray(0.75), cells=8, h=1 / 8).x0 == 0.75
    assert jm.GurneySlab(split=np.float32(0.5), **SMALL).split == 0.5


def test_scene_parameters_pass_as_tracers_and_batched_under_vmap():
    p0 = jnp.asarray([3e5, 4e5])
    np.testing.assert_array_equal(np.asarray(jax.vmap(lambda p: jm.GasSlab(P0=p).P0)(p0)), [3e5, 4e5])
    out = jax.vmap(lambda p: jm.Blast(P0=p).wave_speed)(jnp.asarray([2e5, 3e5]))
    one = [float(jm.Blast(P0=p).wave_speed) for p in (2e5, 3e5)]
    np.testing.assert_allclose(np.asarray(out), one, rtol=1e-15)
    assert one[0] != one[1]
    out = jax.vmap(lambda p: jm.ShockTube(p_l=p, cells=8, h=1 / 8).p_l)(jnp.asarray([1.0, 2.0]))
    np.testing.assert_array_equal(np.asarray(out), [1.0, 2.0])
    scene = jm.Detonation(D=8000.0, cells=20)  # t_valid = L / D: its derivative in D is -t_valid / D
    g = jax.grad(lambda d: jm.Detonation(D=d, cells=20).t_valid)(8000.0)
    assert float(g) == pytest.approx(-float(scene.t_valid) / 8000.0, rel=1e-14)


# -- materials and viscosities name the parameter --------------------------------------------------

MATERIALS = [
    (lambda: jm.AdiabaticGas(P0=None, gamma=1.4, p_atm=0.0), r"^P0 must be a real number, got None$"),
    (lambda: jm.AdiabaticGas(P0=1.0, gamma="a", p_atm=0.0), r"^gamma must be a real number, got 'a'$"),
    (lambda: jm.LinearElastic(E="a"), r"^E must be a real number, got 'a'$"),
    (lambda: jm.LinearElastic(E=1.0, nu=None), r"^nu must be a real number, got None$"),
    (lambda: jm.NeoHookean(lam=1.0, mu=None), r"^mu must be a real number, got None$"),
    (lambda: jm.NeoHookean(lam=1 + 2j, mu=1.0), r"^lam must be a real number, got \(1\+2j\)$"),
    (lambda: jm.IdealGas(gamma=None), r"^gamma must be a real number, got None$"),
    (lambda: jm.ArtificialViscosity(c_lin="x"), r"^c_lin must be a real number, got 'x'$"),
    (lambda: jm.ArtificialViscosity(c_quad=None), r"^c_quad must be a real number, got None$"),
    (lambda: jm.ArtificialViscosity(c_shear="x"), r"^c_shear must be a real number, got 'x'$"),
    (lambda: ex.JWL(1717.0, 5e11, 7e9, "4.2", 1.1, 0.34), r"^R1 must be a real number, got '4\.2'$"),
    (lambda: ex.Murnaghan(rho0=1.0, K=None, n=1.0), r"^K must be a real number, got None$"),
]


@pytest.mark.parametrize("make, match", MATERIALS, ids=[m for _, m in MATERIALS])
def test_materials_and_viscosity_name_a_parameter_that_is_not_a_number(make, match):
    _one_line(make, match, (ValueError, TypeError))


BOOLS = [
    (lambda: jm.GasExpansion(cells=4, h=True), "h"),
    (lambda: jm.GasExpansion(cells=4, beta=np.bool_(True)), "beta"),
    (lambda: jm.AdiabaticGas(P0=True, gamma=1.4, p_atm=0.0), "P0"),
    (lambda: jm.AdiabaticGas(P0=1.0, gamma=True, p_atm=0.0), "gamma"),
    (lambda: jm.ArtificialViscosity(c_quad=True), "c_quad"),
    (lambda: jm.ArtificialViscosity(c_shear=False), "c_shear"),
    (lambda: jm.LinearElastic(E=jnp.asarray(True)), "E"),
    (lambda: jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), t_end=True, cfl=0.5, max_steps=30), "t_end"),
    (lambda: jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), t_end=1e-5, cfl=True, max_steps=30), "cfl"),
    (lambda: jm.simulate(jm.GasExpansion(cells=4), jm.SPQ(), dt=1e-5, steps=1, cfl_limit=True), "cfl_limit"),
]


@pytest.mark.parametrize("make, name", BOOLS, ids=[n for _, n in BOOLS])
def test_a_bool_is_not_taken_for_a_number(make, name):
    # True was read as 1.0: h = 1 m, t_end = 1 s (a run that then ran out of max_steps)
    _one_line(
        make, rf"^{name} must be a real number, got (np\.)?(True|False|Array\(True)", (ValueError, TypeError)
    )


def test_materials_still_take_numbers_tracers_and_none_where_allowed():
    assert jm.ArtificialViscosity(c_shear=None).c_shear is None
    assert float(jm.ArtificialViscosity(c_shear=0.1).c_shear) == 0.1
    gammas = jax.vmap(lambda g: jm.IdealGas(gamma=g).gamma)(jnp.asarray([1.4, 1.5]))
    np.testing.assert_array_equal(np.asarray(gammas), [1.4, 1.5])
    assert float(jax.grad(lambda e: jm.LinearElastic(E=e).E * 3.0)(2.0)) == 3.0


# -- cj_energy: no CJ state of speed D is refused ----------------------------------------------------


@pytest.mark.parametrize("D", [10.0, 3000.0])
def test_cj_energy_refuses_a_speed_the_products_never_detonate_at(D):
    eos, _ = ex.jwl("compb", check=False)
    _one_line(
        lambda: ex.cj_energy(eos, 1717.0, D), rf"^D={D!r} is the CJ detonation speed of these products at no"
    )
    assert np.isnan(float(jax.jit(lambda d: ex.cj_energy(eos, 1717.0, d))(D)))  # traced: NaN, as documented


def test_cj_energy_refuses_a_barotropic_eos_whose_speed_is_another():
    iso = ex.GammaLawIsentrope(rho0=1600.0, D=8000.0, gamma=3.0)  # ignores e0: its CJ speed is 8000
    _one_line(lambda: ex.cj_energy(iso, 1600.0, 6000.0), r"^D=6000\.0 is the CJ detonation speed")


def test_cj_energy_below_the_zero_energy_speed_is_a_consistent_root():
    eos, _ = ex.jwl("compb", check=False)
    e0 = ex.cj_energy(eos, 1717.0, 5000.0)
    assert float(e0) < 0.0  # below the speed of the products at e0 = 0, yet a CJ state of speed D
    assert float(ex.cj_state(eos, 1717.0, e0)["D"]) == pytest.approx(5000.0, rel=1e-12)


def test_gurney_jwl_with_a_speed_of_no_cj_state_is_refused_naming_D():
    _one_line(lambda: jm.GurneySlab(explosive="jwl", D=10.0, **SMALL), r"^D=10\.0 is the CJ detonation speed")


# -- Grid -------------------------------------------------------------------------------------------

GRIDS = [
    (dict(h=-1.0, n_nodes=0), "n_nodes", r"^n_nodes must be an integer >= 2, got 0$"),
    (dict(h=0.5, n_nodes=1), "n_nodes", r"^n_nodes must be an integer >= 2, got 1$"),
    (dict(h=0.5, n_nodes=4.0), "n_nodes", r"^n_nodes must be an integer >= 2, got 4\.0$"),
    (dict(h=-1.0, n_nodes=5), "h", r"^h must be > 0, got -1\.0$"),
    (dict(h=0.0, n_nodes=5), "h", r"^h must be > 0, got 0\.0$"),
    (dict(h=np.nan, n_nodes=5), "h", r"^h must be finite, got nan$"),
]


@pytest.mark.parametrize("kw, name, match", GRIDS, ids=[m for _, _, m in GRIDS])
def test_grid_refuses_no_cells_and_a_spacing_not_above_zero(kw, name, match):
    arrays = {**kw, "h": jnp.asarray(kw["h"])}
    _one_line(lambda: jm.Grid(x_min=jnp.zeros(1), **arrays), name, (ValueError, TypeError))
    # the check itself, on the values as a user without the suite's type checks gives them
    grid = object.__new__(jm.Grid)
    for k, v in dict(x_min=jnp.zeros(1), shape=None, **kw).items():
        object.__setattr__(grid, k, v)
    _one_line(lambda: jm.Grid.__check_init__(grid), match)


def test_grid_box_refuses_an_axis_of_one_node():
    _one_line(
        lambda: jm.Grid.box(jnp.zeros(2), jnp.asarray(0.5), (3, 1)), r"^shape\[1\] must be an integer >= 2"
    )


def test_grid_takes_a_traced_spacing():
    x_max = jax.jit(lambda h: jm.Grid(x_min=jnp.zeros(1), h=h, n_nodes=4).x_max)(jnp.asarray(0.5))
    assert float(x_max[0]) == 1.5
    assert jm.GasExpansion(cells=2, pad=1).grid().n_nodes == 5


GAS = dict(P0=3e5, gamma=1.4, p_atm=1e5)
ONE_NUMBER = r"must be one number, got an array of shape \(2,\): to run several values, jax.vmap"


@pytest.mark.parametrize(
    "name, make",
    [
        ("P0", lambda: jm.AdiabaticGas(**{**GAS, "P0": [3e5, 4e5]})),
        ("E", lambda: jm.LinearElastic(E=[1.0, 2.0])),
        ("lam", lambda: jm.NeoHookean(lam=[1.0, 2.0], mu=1.0)),
        ("gamma", lambda: jm.IdealGas(gamma=[1.4, 1.5])),
        ("c_quad", lambda: jm.ArtificialViscosity(c_quad=[1.0, 2.0])),
        ("c_shear", lambda: jm.ArtificialViscosity(c_shear=[1.0, 2.0])),
        ("rho0", lambda: jm.Region(jm.geometry.Box((0, 0), (4, 4)), jm.AdiabaticGas(**GAS), rho0=[1.0, 2.0])),
    ],
)
def test_a_material_parameter_is_one_number(name, make):
    """An array where a material, a viscosity or a region takes one number is refused by name: a gas
    given two P0s would otherwise run with an anisotropic stress, status 0."""
    assert _one_line(make, rf"^{name} {ONE_NUMBER}")


def test_a_region_names_its_parameter_that_is_not_a_number():
    box, gas = jm.geometry.Box((0, 0), (4, 4)), jm.AdiabaticGas(**GAS)
    _one_line(
        lambda: jm.Region(box, gas, rho0="a"),
        r"^rho0 must be a real number, got 'a'",
        (ValueError, TypeError),
    )
    _one_line(
        lambda: jm.Region(box, gas, rho0=1.0, velocity="a"),
        r"velocity must be a real number",
        (ValueError, TypeError),
    )


def test_material_parameters_under_vmap_pass():
    """Tracers pass the check: a material built inside jax.vmap takes one value per member."""
    P = jax.vmap(lambda P0: jm.AdiabaticGas(P0=P0, gamma=1.4, p_atm=1e5).pressure(jnp.asarray(1.0)))(
        jnp.array([3e5, 4e5])
    )
    np.testing.assert_allclose(np.asarray(P), [2e5, 3e5], rtol=1e-15)


@pytest.mark.parametrize(
    "make, sizes",
    [
        (lambda: jm.ShockTube(cells=10**14), "cells=100000000000000, ppc=2"),
        (lambda: jm.BlastDisk(cells=10**20), "cells=100000000000000000000"),
        (lambda: jm.BlastDisk(pad=10**20), "pad=100000000000000000000"),
        (lambda: jm.GurneyCylinder(ppc=10**9), "ppc=1000000000"),
    ],
)
def test_a_scene_of_regions_too_large_to_lay_out_is_refused_by_its_sizes(make, sizes):
    """A body of regions is laid out on the host when the scene is made: sizes beyond the host's
    memory are refused by name before that (they raised NumPy's MemoryError or an OverflowError, or
    the process was killed)."""
    msg = _one_line(
        make, r"needs about .* of memory to lay out, more than the .* available; reduce cells, ppc or pad"
    )
    assert sizes in msg


def test_particles_beyond_float64s_range_are_refused_by_h_and_rho0():
    """A particle volume or mass that overflows (h = 1e200 in 2D) ran with NaN and infinite
    diagnostics and a healthy status; it is refused naming h and rho0."""
    msg = _one_line(
        lambda: jm.AxisAligned(cells=4, h=1e200), r"^h=1e\+200 and rho0=1 give particles of volume inf"
    )
    assert "beyond float64's range" in msg
    _one_line(
        lambda: jm.GasExpansion(h=1e-200, rho0=1e-200), r"^h=1e-200 and rho0=1e-200 give particles of volume"
    )
    jm.GasExpansion(h=1e-100)  # small, in range


def test_a_manufactured_field_must_be_a_function():
    with pytest.raises(
        ValueError, match=r"displacement_fn must be a function u\(scene, X, t\) -> u, or None, got int 3"
    ):
        _raw(jm.Manufactured, displacement_fn=3).__check_init__()


@pytest.mark.parametrize("kind", [np.uint8, np.int8, np.int32, np.int64])
def test_numpy_integers_are_the_python_integers_they_hold(kind):
    """A scene's static integers given as NumPy integers are kept as Python ints: the grid's sizes
    then never wrap around in the NumPy type (200 + 2 * 40 + 1 nodes in uint8 would be 25)."""
    scene = jm.GasExpansion(cells=kind(100), ppc=kind(2), pad=kind(40))
    assert all(type(getattr(scene, k)) is int for k in ("cells", "ppc", "pad", "dim"))
    assert scene.grid().n_nodes == 181 and scene == jm.GasExpansion(cells=100, ppc=2, pad=40)
    slab = jm.GurneySlab(cells=kind(4), ppc=kind(1), pad=kind(4), strength=np.bool_(True))
    assert type(slab.cells) is int and type(slab.strength) is bool
    saveat = jm.SaveAt(every=kind(2))
    assert type(saveat.every) is int and saveat == jm.SaveAt(every=2)
    # the memory estimate of a 3D run of 1000^3 cells, in int32 too: 81 TB, refused
    big = jm.Model(jm.GasExpansion(dim=3, cells=np.int32(1000)), jm.MPQ(), jm.FLIP())
    with pytest.raises(ValueError, match="memory"):
        jm._memory.check_run(big, 1, jm.SaveAt())


def test_saved_fields_without_every_are_refused():
    """SaveAt(fields=...) without every would keep nothing: the fields are refused, not ignored."""
    _one_line(
        lambda: jm.SaveAt(fields=("x", "F")), r"SaveAt.fields=\('x', 'F'\) without every keeps no history"
    )
    assert jm.SaveAt().every is None  # the default: no history


def test_a_jwl_rows_check_is_a_switch():
    for bad in ("yes", 1, None):
        with pytest.raises(ValueError, match="check must be True or False"):
            inspect.unwrap(ex.jwl)("tnt", check=bad)  # without the suite's type checks: what a user runs
    assert ex.jwl("tnt", check=False)[0] == ex.jwl("tnt")[0]


def test_a_bound_that_float32_rounds_a_value_onto_says_so():
    """With float64 off a scene's numbers are float32: gamma = 1 + 1e-8 reads as 1.0, and the refusal
    says that the value was rounded, not that 1.0 was given."""
    with float32():
        with pytest.raises(ValueError, match=r"gamma must be > 1\.0, got 1\.0 \(float32") as caught:
            jm.GasExpansion(gamma=1 + 1e-8)
        assert "jax_enable_x64" in str(caught.value)
        with pytest.raises(ValueError, match=r"gamma must be > 1\.0, got 0\.5$"):
            jm.GasExpansion(gamma=0.5)
    with pytest.raises(ValueError, match=r"gamma must be > 1\.0, got 1\.0$"):  # float64: as given
        jm.GasExpansion(gamma=1.0)
