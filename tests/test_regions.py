"""Bodies made of regions: layouts, several materials in one step, history variables, energy, faults."""

import json
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jaxtyping import Array, Float

import jaxmpm as jm
from jaxmpm.geometry import Ball, Box, Shell

GAS = jm.AdiabaticGas(P0=2.0, gamma=1.4, p_atm=1.0)
SOLID = jm.LinearElastic(E=100.0)


class Tension(jm.AbstractEOS):
    """A test EOS: a constant tension ``p = -1`` (no energy dependence), so compression takes energy."""

    def pressure_terms(self, rho, z):
        del z
        return -jnp.ones_like(rho), jnp.zeros_like(rho)

    def initial_internal(self, X):
        return None

    def update_internal(self, z, X, t, dt, J_old, J_new):
        return z

    def front_speed(self):
        return None

    def nonnegative_energy(self):
        return True


class Peak(jm.AbstractEOS):
    """A test EOS with a history variable: an ideal gas that records each particle's smallest ``J``."""

    gamma: jax.Array = eqx.field(converter=jnp.asarray, default=1.4)

    def pressure_terms(self, rho, z):
        del z
        return jnp.zeros_like(rho), (self.gamma - 1.0) * rho

    def initial_internal(self, X):
        return {"J_min": jnp.ones((), dtype=X.dtype)}

    def update_internal(self, z, X, t, dt, J_old, J_new):
        return {"J_min": jnp.minimum(z["J_min"], J_new)}

    def front_speed(self):
        return None

    def nonnegative_energy(self):
        return True


class PeakTube(jm.AbstractScene):
    """A registered-by-name test scene of two regions of ``Peak`` gas colliding in a box with walls."""

    name = "peak-tube"
    description = "two Peak gases colliding between walls"
    dim = 1
    left = "wall"
    right = "wall"
    body_force = None
    traction = None
    exact = None
    initial_position = None
    smooth = None
    u: jax.Array = eqx.field(converter=jnp.asarray, default=0.5)
    h: jax.Array = eqx.field(converter=jnp.asarray, default=0.05)
    rho0: jax.Array = eqx.field(converter=jnp.asarray, default=1.0)
    cells: int = eqx.field(static=True, default=20)
    ppc: int = eqx.field(static=True, default=2)
    pad: int = eqx.field(static=True, default=4)

    def material(self):
        return Peak()

    def regions(self):
        half = Box(0.0, 10.0)
        return (
            jm.Region(half, Peak(), self.rho0, self.u, 1.0),
            jm.Region(Box(10.0, 20.0) - half, Peak(), 2.0 * self.rho0, -self.u, 1.0),
        )

    def initial_velocity(self, X):
        return jnp.where(X < 0.5, self.u, -self.u) * jnp.ones_like(X)


def test_layout_assigns_each_particle_to_the_one_region_holding_it():
    ring, core = Shell((5.0, 5.0), 2.0, 4.0), Ball((5.0, 5.0), 2.0) - Box((0.0, 0.0), (0.1, 0.1))
    scene = jm.Bodies(
        parts=(jm.Region(core, GAS, 1.0, (0.0, 0.0)), jm.Region(ring - core, SOLID, 3.0, (0.0, 0.0))),
        dim=2,
        cells=10,
        ppc=2,
    )
    lay = scene.layout()
    centres = (np.indices((20, 20)).reshape(2, -1).T + 0.5) / 2
    d = np.linalg.norm(centres - 5.0, axis=1)
    assert lay.counts == (int(np.sum(d <= 2.0)), int(np.sum((d > 2.0) & (d <= 4.0))))
    assert not lay.box
    body = scene.body()
    assert body.n == sum(lay.counts)
    # masses: rho0 of each particle's region times its volume (h = 1: V0 = 0.25)
    np.testing.assert_array_equal(np.asarray(body.m), np.where(lay.region == 0, 1.0, 3.0) * 0.25)
    # every particle has its 4 corners, the lattice corners around its centre
    corners = np.asarray(body.X_corners)[np.asarray(body.corner_ids)]
    np.testing.assert_allclose(corners.mean(axis=1), np.asarray(body.X), atol=1e-15)


@pytest.mark.slow
def test_a_one_box_region_runs_as_the_scene_of_one_body():
    """A gas slab built from one Box region equals GasSlab to round-off."""
    slab = jm.GasSlab(P0=3.0, gamma=1.4, p_atm=1.0, rho0=1.0, h=0.1, cells=10, ppc=2, pad=20)
    mat = slab.material()
    bodies = jm.Bodies(
        parts=(jm.Region(Box(0.0, 10.0), mat, 1.0),),
        cells=10,
        ppc=2,
        pad=20,
        h=0.1,
        left="wall",
        right="free",
    )
    for interp in (jm.CPDI(), jm.MPQ()):
        a = jm.simulate(slab, interp, dt=0.01, steps=60)
        b = jm.simulate(bodies, interp, dt=0.01, steps=60)
        np.testing.assert_allclose(np.asarray(b.state.x), np.asarray(a.state.x), rtol=0, atol=1e-15)
        np.testing.assert_allclose(np.asarray(b.state.F), np.asarray(a.state.F), rtol=1e-14)
        assert b.state.e is None and b.state.internal is None  # a model of F alone carries no energy


@pytest.mark.slow
def test_two_blocks_collide_with_exact_momentum_and_the_impedance_weighted_interface_velocity():
    """Elastic blocks of density 1 and 4 (same E) meet at 0.5: the interface moves at
    ``(Z_a v_a + Z_b v_b) / (Z_a + Z_b)``, ``Z = sqrt(E rho)``, until a wave returns from an end."""
    E, rho_a, rho_b, va, vb = 100.0, 1.0, 4.0, 0.1, -0.1
    cells = 200
    h = 1.0 / cells
    mat = jm.LinearElastic(E=E)
    scene = jm.Bodies(
        parts=(
            jm.Region(Box(0.0, 100.0), mat, rho_a, va),
            jm.Region(Box(100.0, 200.0) - Box(0.0, 100.0), mat, rho_b, vb),
        ),
        cells=cells,
        ppc=2,
        h=h,
        pad=4,
    )
    za, zb = np.sqrt(E * rho_a), np.sqrt(E * rho_b)
    v_star = (za * va + zb * vb) / (za + zb)
    t_end = 0.8 * 0.5 / np.sqrt(E / rho_a)  # before the faster wave (in block a) returns from its end
    dt = 0.2 * h / np.sqrt(E / rho_a)
    steps = int(round(t_end / dt))
    p0 = rho_a * 0.5 * va + rho_b * 0.5 * vb
    last_a = scene.layout().counts[0] - 1
    for interp in (jm.CPDI(), jm.MPQ(), jm.GIMP()):
        sol = jm.simulate(scene, interp, dt=dt, steps=steps, saveat=jm.SaveAt(every=10, fields=("x",)))
        assert int(sol.status) == 0
        p = float(jnp.sum(sol.body.m * sol.state.v[:, 0]))
        assert abs(p - p0) < 1e-14 * abs(p0)
        # The interface (midway between the last particle of a and the first of b) moves at v*,
        # measured as the slope of its position after the first quarter of the run: within 0.2%.
        x_i = np.asarray(sol.history["x"][:, last_a : last_a + 2, 0]).mean(axis=1)
        ts = np.asarray(sol.ts)
        k = len(ts) // 4
        slope = np.polyfit(ts[k:], x_i[k:], 1)[0]
        # measured 3.8e-4 (CPDI), 6.4e-4 (MPQ), 4.5e-4 (GIMP)
        assert abs(slope / v_star - 1) < 1e-3, (type(interp).__name__, slope, v_star)
        assert np.all(np.diff(np.asarray(sol.state.x[:, 0])) > 0)  # the blocks stick; nothing crosses


@pytest.mark.slow
def test_history_variables_live_in_the_state_history_and_gradient():
    scene = jm.Bodies(
        parts=(jm.Region(Box(0.0, 20.0), Peak(), 1.0, -0.5, 1.0),), cells=20, h=0.05, left="wall"
    )
    saveat = jm.SaveAt(every=10, fields=("x", "e", "internal"))
    sol = jm.simulate(scene, jm.MPQ(), dt=1e-3, steps=40, saveat=saveat)
    assert int(sol.status) == 0
    J = np.asarray(jax.vmap(jnp.linalg.det)(sol.state.F))
    J_min = np.asarray(sol.state.internal["J_min"])
    assert np.all(J_min <= J + 1e-15) and J_min.min() < 0.99  # the gas at the wall was compressed
    hist = np.asarray(sol.history["internal.J_min"])
    assert hist.shape == (5, 40) and np.all(np.diff(hist, axis=0) <= 0)  # it never grows
    np.testing.assert_array_equal(hist[-1], J_min)

    def loss(v0):
        sc = eqx.tree_at(lambda s: s.parts[0].velocity, scene, jnp.reshape(v0, (1,)))
        return jnp.sum(jm.simulate(sc, jm.MPQ(), dt=1e-3, steps=40).state.internal["J_min"])

    g = jax.grad(loss)(jnp.asarray(-0.5))
    eps = 1e-5
    fd = (loss(jnp.asarray(-0.5 + eps)) - loss(jnp.asarray(-0.5 - eps))) / (2 * eps)
    assert np.isfinite(float(g)) and abs(float(g) - float(fd)) < 3e-9 * abs(float(fd))  # measured 3.0e-10


def test_negative_energy_is_a_named_breakdown():
    scene = jm.Bodies(
        parts=(jm.Region(Box(0.0, 10.0), Tension(), 1.0, -1.0, 0.0),), cells=10, h=0.1, left="wall"
    )
    sol = jm.simulate(scene, jm.CPDI(), dt=1e-3, steps=20, throw=False)
    fail = sol.failure()
    assert fail is not None and fail["status"] & jm.status.NEGATIVE_ENERGY
    assert fail["step"] == 1 and 0 <= fail["particle"] < 20
    assert np.all(np.asarray(sol.state.e) == 0.0)  # the failing step was not taken
    with pytest.raises(jm.SimulationError, match="negative specific internal energy"):
        jm.simulate(scene, jm.CPDI(), dt=1e-3, steps=20)


def test_a_step_failing_two_checks_names_only_the_first_of_them_on_its_particle():
    """A linear-elastic bar inverts at its wall (F <= 0, bit 2) in the step in which the gas beside it
    takes more energy than it has (bit 128). The particle named is the bar's; the gas's breakdown is
    said to be the step's, not that particle's (which carries no energy)."""
    solid, gas = jm.LinearElastic(E=1.0), jm.IdealGas(gamma=3.0)
    parts = (
        jm.Region(Box(0.0, 3.0), solid, rho0=1.0, velocity=-3.0),
        jm.Region(Box(6.0, 10.0), gas, rho0=1.0, energy=1.0),
    )
    scene = jm.Bodies(parts=parts, cells=10, h=1.0, ppc=2, pad=20, left="wall")
    with pytest.raises(jm.SimulationError) as info:
        jm.simulate(scene, jm.CPDI(), dt=1.0, steps=2, cfl_limit=None)
    f = info.value.solution.failure()
    assert f["status"] == jm.status.NONPOSITIVE_F | jm.status.NEGATIVE_ENERGY and f["particle"] == 0
    message = str(info.value)
    named, rest = message.split(": F <= 0 (the particle's domain inverted)")
    assert "particle 0 (X = 0.25" in named and "region 0" in named and "negative" not in named
    assert ", e = " not in named  # a linear-elastic particle carries no internal energy
    gas_alone = jm.Bodies(parts=parts[1:], cells=10, h=1.0, ppc=2, pad=20, left="wall")
    with pytest.raises(jm.SimulationError, match=r"particle 0 \(X = 6.25, .*, e = -?[0-9.e+-]+ at step 0\)"):
        jm.simulate(gas_alone, jm.CPDI(), dt=1.0, steps=2, cfl_limit=None)
    assert rest.startswith(
        "; in the same step, at this particle or others: negative specific internal energy e"
    )


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: jm.Region(Box(0.0, 1.0), GAS, -1.0), "rho0 must be > 0"),
        (lambda: jm.Region(Box(0.0, 1.0), jm.IdealGas(gamma=1.4), 1.0, 0.0, -2.0), "energy must be >= 0"),
        (
            lambda: jm.Region(
                Box(0.0, 1.0), jm.MieGruneisen(**jm.MIE_GRUNEISEN["copper"]), 8930.0, 0.0, np.inf
            ),
            "energy must be finite, got inf",
        ),
        (lambda: jm.IdealGas(gamma=1.0), "gamma must be > 1"),
        (lambda: jm.Region(Box(0.0, 1.0), GAS, 1.0, 0.0, 1.0), "energy applies to an AbstractEOS"),
        (lambda: jm.Region(Box(0.0, 1.0), GAS, 1.0, (0.0, 1.0)), "velocity must have 1 components"),
        (
            lambda: jm.Bodies(parts=(jm.Region(Box(0.0, 0.2), GAS, 1.0),), cells=4),
            "region 0 holds no particle",
        ),
        (
            lambda: jm.Bodies(
                parts=(jm.Region(Box(0.0, 3.0), GAS, 1.0), jm.Region(Box(2.0, 4.0), GAS, 1.0)), cells=4
            ),
            r"regions \[0, 1\] overlap",
        ),
        (
            lambda: jm.Bodies(
                parts=(jm.Region(Box(0.0, 4.0), GAS, 1.0), jm.Region(Box(20.0, 30.0), GAS, 1.0)), cells=4
            ),
            "region 1 lies outside the grid",
        ),
        (lambda: jm.ShockTube(p_r=-0.1), r"^p_r must be > 0, got -0\.1$"),
        (lambda: jm.ShockTube(p_r=0.0), r"^p_r must be > 0, got 0\.0$"),  # vacuum: not a state of the tube
        (lambda: jm.ShockTube(p_l=0.0), r"^p_l must be > 0, got 0\.0$"),
        (lambda: jm.ShockTube(rho_l=0.0), "rho_l must be > 0"),
        (lambda: jm.ShockTube(gamma=0.9), "gamma must be > 1"),
        (lambda: jm.ShockTube(x0=1.0), "x0 must be a fraction"),
        (lambda: jm.Noh(u0=-1.0), "u0 must be > 0"),
    ],
)
def test_bad_regions_are_one_line_errors(make, match):
    with pytest.raises(ValueError, match=match) as info:
        make()
    assert "\n" not in str(info.value)


def test_artificial_cells_and_tractions_need_a_box():
    disk = jm.Bodies(parts=(jm.Region(Ball(5.0, 3.0), GAS, 1.0),), cells=10, h=0.1)
    with pytest.raises(
        ValueError, match="artificial_cells is supported only where the body is a box"
    ) as info:
        jm.simulate(disk, jm.MPQ(), dt=1e-3, steps=2, artificial_cells=1)
    assert "\n" not in str(info.value)  # raised before tracing, one line
    box = jm.Bodies(
        parts=(jm.Region(Box(0.0, 5.0), GAS, 1.0), jm.Region(Box(5.0, 10.0) - Box(0.0, 5.0), GAS, 2.0)),
        cells=10,
        h=0.1,
    )
    sol = jm.simulate(box, jm.MPQ(), dt=1e-3, steps=2, artificial_cells=1)  # a box of two regions may
    assert int(sol.status) == 0


class LoadedBlock(jm.AbstractScene):
    """A 2D elastic block at rest with a traction on one face (``face``: 0, 1 the low and high face of
    axis 0, then 2, 3 of axis 1), its faces ``left`` and ``right`` as given."""

    name: ClassVar[str] = "loaded-block"
    description: ClassVar[str] = "a 2D block with a traction on one face"
    dim: ClassVar[int] = 2
    body_force: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None
    regions: ClassVar[None] = None

    face: int = eqx.field(static=True, default=0)
    left: str = eqx.field(static=True, default="free")
    right: str = eqx.field(static=True, default="free")
    h: Float[Array, ""] = eqx.field(converter=jnp.asarray, default=0.25)
    rho0: Float[Array, ""] = eqx.field(converter=jnp.asarray, default=1000.0)
    cells: int = eqx.field(static=True, default=4)
    ppc: int = eqx.field(static=True, default=2)
    pad: int = eqx.field(static=True, default=4)

    def material(self):
        return jm.NeoHookean(lam=1e3, mu=1e3)

    def initial_velocity(self, X):
        return jnp.zeros_like(X)

    def traction(self, t):
        faces = [None] * 4
        faces[self.face] = jnp.asarray([7.0, 3.0], self.h.dtype)
        return tuple(faces)


@pytest.mark.parametrize(
    "face, left, right", [(0, "wall", "free"), (3, "free", "wall"), (1, "symmetry", "wall")]
)
def test_a_traction_on_a_wall_is_refused(face, left, right):
    """A wall holds its nodes at rest: a traction there would be dropped without a trace (the run
    stayed at rest, status 0). Refused before the run is traced, naming the face."""
    scene = LoadedBlock(face=face, left=left, right=right)
    side = ("low", "high")[face % 2]
    with pytest.raises(
        ValueError, match=rf"^LoadedBlock.traction loads the {side} face of axis {face // 2}, which is a wall"
    ) as info:
        jm.simulate(scene, jm.MPQ(), dt=1e-4, steps=2)
    assert "\n" not in str(info.value)


def test_a_traction_on_a_free_face_gives_the_body_its_force():
    """The momentum a traction gives a free body is the force on its face: the traction times the
    face's length (1 m) times the time."""
    steps, dt = 5, 1e-4
    scene = LoadedBlock(face=0)
    sol = jm.simulate(scene, jm.MPQ(), dt=dt, steps=steps)
    p = np.asarray(jm.diagnostics(scene, sol.state, sol.body)["momentum"])
    np.testing.assert_allclose(p, np.array([7.0, 3.0]) * steps * dt, rtol=1e-12)


@pytest.mark.parametrize(
    "make",
    [
        lambda: jm.Interface(),
        lambda: jm.Manufactured(ends="wall"),
        lambda: jm.Bodies(
            parts=(jm.Region(Box(0.0, 10.0), GAS, 1.0),), cells=10, h=0.1, left="symmetry", right="wall"
        ),
    ],
    ids=["interface", "manufactured-walls", "bodies-symmetry-wall"],
)
def test_artificial_cells_need_a_free_face(make):
    """The artificial layer goes outside the body's free faces: on a scene with none it would add
    nothing, and a run asked for with it ran as without. Refused before anything is traced."""
    scene = make()
    with pytest.raises(
        ValueError, match=r"^artificial_cells adds cells outside the body's free faces, and "
    ) as info:
        jm.simulate(scene, jm.MPQ(), dt=1e-4, steps=1, artificial_cells=1)
    assert f"left={scene.left!r}, right={scene.right!r}" in str(info.value)
    assert "use artificial_cells=0" in str(info.value)
    with pytest.raises(ValueError, match=r"^artificial_cells adds cells outside the body's free faces"):
        jm.Model(scene, jm.MPQ(), jm.FLIP(), artificial_cells=2)


def test_energy_scene_with_one_region_material_needs_regions():
    class GasOnly(jm.AbstractScene):
        name = "x"
        description = "x"
        dim = 1
        left = "free"
        right = "free"
        body_force = None
        traction = None
        exact = None
        initial_position = None
        smooth = None
        regions = None
        h: jax.Array = eqx.field(converter=jnp.asarray, default=0.1)
        rho0: jax.Array = eqx.field(converter=jnp.asarray, default=1.0)
        cells: int = eqx.field(static=True, default=4)
        ppc: int = eqx.field(static=True, default=1)
        pad: int = eqx.field(static=True, default=2)

        def material(self):
            return jm.IdealGas(gamma=1.4)

        def initial_velocity(self, X):
            return jnp.zeros_like(X)

    with pytest.raises(ValueError, match="needs the scene's regions"):
        jm.simulate(GasOnly(), jm.SPQ(), dt=1e-3, steps=1)


def test_resume_of_a_run_with_energy_and_history_variables_is_bit_exact(tmp_path, monkeypatch):
    """A run of regions saved at step 30 and resumed to 60 equals the 60-step run bit for bit, its
    energies and internal variables included (a test scene registered for the saved run's name)."""
    scene = PeakTube()
    monkeypatch.setitem(jm.SCENES, PeakTube.name, PeakTube)
    kw = dict(dt=0.002, chunk=10, viscosity=jm.ArtificialViscosity(), progress=False)
    saveat = jm.SaveAt(every=10, fields=("x", "e", "internal"))
    full = jm.long_run.run(scene, jm.CPDI(), steps=60, saveat=saveat, **kw)
    path = tmp_path / "run.npz"
    jm.long_run.run(scene, jm.CPDI(), steps=30, saveat=saveat, out=path, **kw)
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    assert "state.e" in arrays and "state.internal.J_min" in arrays and "history.internal.J_min" in arrays
    meta = json.loads(str(arrays["meta"]))
    meta["steps"] = 60
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(path, **arrays)
    resumed = jm.long_run.resume(path, progress=False)
    for name in ("x", "v", "F", "sigma", "e"):
        np.testing.assert_array_equal(
            np.asarray(getattr(resumed.state, name)), np.asarray(getattr(full.state, name))
        )
    np.testing.assert_array_equal(
        np.asarray(resumed.state.internal["J_min"]), np.asarray(full.state.internal["J_min"])
    )
    for name in ("e", "internal.J_min"):
        np.testing.assert_array_equal(np.asarray(resumed.history[name]), np.asarray(full.history[name]))
    assert float(np.min(full.state.internal["J_min"])) < 1.0


@pytest.mark.slow
def test_cli_json_carries_density_pressure_energy_and_region(capsys):
    from jaxmpm.cli import main

    assert (
        main(
            [
                "run",
                "shock-tube",
                "cells=20",
                "h=0.05",
                "--interpolator",
                "mpq",
                "--viscosity",
                "--t-end",
                "0.05",
                "--cfl",
                "0.4",
                "--max-steps",
                "1000",
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    part = out["particles"]
    assert part["region"] == [0] * 20 + [1] * 20
    assert [r["rho0"] for r in out["regions"]] == [1.0, 0.125]
    assert out["params"]["p_l"] == 1.0 and out["params"]["rho_r"] == 0.125
    rho, p, e = (np.asarray(part[k]) for k in ("rho", "p", "e"))
    np.testing.assert_allclose(p[:3], 0.4 * rho[:3] * e[:3], rtol=1e-12)  # p = (gamma - 1) rho e far left
    assert set(out["errors"]) >= {"rho_L1", "u_L1", "p_L1", "e_L1"}


@pytest.mark.slow
def test_vtk_frames_carry_region_energy_and_internal_variables(tmp_path):
    scene = jm.Bodies(
        parts=(
            jm.Region(Box(0.0, 10.0), Peak(), 1.0, 0.5, 1.0),
            jm.Region(Box(10.0, 20.0) - Box(0.0, 10.0), Peak(), 2.0, -0.5, 1.0),
        ),
        cells=20,
        h=0.05,
        left="wall",
        right="wall",
    )
    saveat = jm.SaveAt(every=10, fields=("x", "v", "F", "sigma", "e", "internal"))
    model = jm.Model(scene, jm.CPDI(), jm.FLIP())
    sol = jm.simulate(scene, jm.CPDI(), dt=1e-3, steps=30, saveat=saveat)
    paths = jm.vtk.write_series(tmp_path, model, sol)
    frame = [p for p in paths if p.name == "particles_00003.vtk"][0].read_bytes()
    for name in (b"SCALARS region", b"SCALARS e ", b"SCALARS internal.J_min", b"SCALARS rho", b"SCALARS p "):
        assert name in frame
    fields = jm.vtk.particle_fields(sol.state, sol.body)
    np.testing.assert_array_equal(fields["region"], [0] * 20 + [1] * 20)
    np.testing.assert_array_equal(fields["internal.J_min"], np.asarray(sol.state.internal["J_min"]))
    with pytest.raises(ValueError, match="lacks"):  # a history without the energy cannot be written
        bare = jm.simulate(scene, jm.CPDI(), dt=1e-3, steps=30, saveat=jm.SaveAt(every=10))
        jm.vtk.write_series(tmp_path / "bare", model, bare)


def test_every_regions_density_is_checked_for_particle_masses_float64_cannot_hold():
    """Only the first region's density was checked: a second region of rho0 = 1e306 ran with infinite
    masses, a NaN energy and status 0."""
    gas = jm.IdealGas(gamma=1.4)

    def bodies(rho_first, rho_second):
        first = jm.Region(Box(0, 5), gas, rho0=rho_first, energy=1.0)
        return jm.Bodies(parts=(first, jm.Region(Box(5, 10), gas, rho0=rho_second, energy=1.0)), h=1e3, ppc=1)

    for first, second, who in ((1e306, 1.0, ""), (1.0, 1e306, "region 1's ")):
        with pytest.raises(ValueError, match=rf"^h=1000 and {who}rho0=1e\+306 give particles of volume"):
            bodies(first, second)


def test_bodies_take_a_list_of_parts_and_name_what_is_not_one():
    gas = jm.IdealGas(gamma=1.4)
    a, b = (jm.Region(Box(lo, lo + 5), gas, rho0=1.0, energy=1.0) for lo in (0, 5))
    assert jm.Bodies(parts=[a, b]).parts == (a, b)
    with pytest.raises(
        ValueError,
        match=r"^parts must be a non-empty tuple \(or list\) .*, got tuple of \['Region', 'int'\]$",
    ):
        jm.Bodies(parts=(a, 3))
    with pytest.raises(
        ValueError, match=r"got a Region \(a single region goes in a tuple: parts=\(region,\)\)$"
    ):
        jm.Bodies(parts=a)


def test_wave_speed_of_an_elastic_plastic_region_is_the_longitudinal_wave_the_step_checks():
    """``wave_speed`` is the speed the step's stability check uses: for copper with strength
    sqrt(c_eos^2 + 4 G / (3 rho0)) = sqrt(3940^2 + 4 46e9 / (3 8930)), so a step at CFL 0.9 of it runs
    (with the EOS's 3940 m/s alone it failed its stability check at step 1)."""
    cu = jm.ElasticPlastic(jm.MieGruneisen(**jm.MIE_GRUNEISEN["copper"]), **jm.STRENGTH["copper"])
    scene = jm.Bodies(parts=(jm.Region(Box(0, 10), cu, rho0=8930.0, velocity=10.0),), cells=10, h=1e-3)
    c = float(np.sqrt(3940.0**2 + 4 * 46e9 / (3 * 8930.0)))
    assert float(scene.wave_speed) == pytest.approx(c, rel=1e-12)
    sol = jm.simulate(scene, jm.CPDI(), dt=0.9 * 1e-3 / (c + 10.0), steps=2)
    assert sol.failure() is None


def test_a_region_starts_below_zero_energy_where_its_material_allows_it():
    """Mie-Grueneisen measures e from its reference state (nonnegative_energy() is False): a region of
    copper may start at e = -100 J/kg (it was refused, "energy must be >= 0"), at the pressure its EOS
    gives there; an ideal gas may not."""
    copper = jm.MieGruneisen(**jm.MIE_GRUNEISEN["copper"])
    region = jm.Region(Box(0.0, 1.0), copper, 8930.0, 0.0, -100.0)
    assert float(region.energy) == -100.0
    p = float(copper.pressure(region.rho0, region.energy))
    assert p == pytest.approx(2.02 * 8930.0 * -100.0, rel=1e-12)  # Gamma0 rho_ref e at rho_ref
    strong = jm.ElasticPlastic(copper, **jm.STRENGTH["copper"])
    assert float(jm.Region(Box(0.0, 1.0), strong, 8930.0, 0.0, -100.0).energy) == -100.0
    with pytest.raises(ValueError, match=r"^energy must be >= 0, got -2\.0$"):
        jm.Region(Box(0.0, 1.0), jm.IdealGas(gamma=1.4), 1.0, 0.0, -2.0)


def test_a_mie_gruneisen_energy_below_its_reference_is_no_breakdown():
    """Copper started 0.3% below its reference density is compressed (p0 = 115 MPa at 8900 kg/m^3) and
    expands, its e going below 0 at once: a state of the solid, not a breakdown (it broke down at step
    1 as 'negative specific internal energy'). A material that holds e >= 0 next to it (``Tension``,
    which the copper compresses) is still checked, and named."""
    cu = jm.MieGruneisen(**jm.MIE_GRUNEISEN["copper"])
    assert not cu.nonnegative_energy() and jm.IdealGas(gamma=1.4).nonnegative_energy()
    plate = jm.Region(Box(0, 10), cu, rho0=8900.0)
    dt = 0.3 * 1e-4 / 5000.0
    sol = jm.simulate(jm.Bodies(parts=(plate,), cells=10, h=1e-4, pad=4), jm.CPDI(), dt=dt, steps=20)
    assert sol.failure() is None and float(jnp.min(sol.state.e)) < 0.0
    soft = jm.Region(Box(10, 20), Tension(), rho0=8900.0, energy=0.0)
    both = jm.Bodies(parts=(plate, soft), cells=20, h=1e-4, pad=4)
    sol = jm.simulate(both, jm.CPDI(), dt=dt, steps=20, throw=False)
    fail = sol.failure()
    assert fail is not None and fail["quantities"] == [jm.status.QUANTITY[jm.status.NEGATIVE_ENERGY]]
    assert int(sol.body.region[int(sol.state.fail_particle)]) == 1


def _seeded_regions(scene):
    body = jm.setup(jm.Model(scene, jm.CPDI(), jm.FLIP())).body
    return np.asarray(body.X[:, 0]), np.asarray(body.region), np.asarray(body.m)


def test_a_split_inside_a_particles_domain_is_reported_where_the_seeded_regions_meet():
    """The regions meet at a particle domain's edge; a split given inside a domain moves to the edge
    after the last particle at or before it, and the scene's reference values describe the body
    seeded: the shock tube's X0 (its exact solution and initial velocity) and the Gurney slab's
    charge, plate and mass ratio. A split on an edge is kept as given, to the bit."""
    tube = jm.ShockTube(cells=10, h=0.1, ppc=1, x0=0.51, u_l=0.5)
    X, region, _ = _seeded_regions(tube)
    edge = X[region == 0].max() + 0.05  # the last left particle's domain ends half a spacing on
    assert float(tube.X0) == pytest.approx(edge, rel=1e-14) and abs(float(tube.X0) - 0.5) < 1e-14
    on = jm.ShockTube(cells=10, h=0.1, ppc=1, x0=0.45, u_l=0.5)  # a particle centre on the split: left
    X, region, _ = _seeded_regions(on)
    v0 = np.asarray(on.initial_velocity(jnp.asarray(X)))
    np.testing.assert_array_equal(v0, np.where(region == 0, 0.5, 0.0))
    assert float(jm.ShockTube().X0) == 0.5 * float(jm.ShockTube().length)  # on an edge: as given

    slab = jm.GurneySlab(cells=10, split=0.81, pad=40)
    X, region, m = _seeded_regions(slab)
    aligned = jm.GurneySlab(cells=10, split=0.8, pad=40)
    assert float(slab.charge) == pytest.approx(0.8 * float(slab.L), rel=1e-14)
    assert float(slab.mass_ratio) == pytest.approx(m[region == 1].sum() / m[region == 0].sum(), rel=1e-12)
    assert float(slab.gurney_velocity()) == pytest.approx(float(aligned.gurney_velocity()), rel=1e-14)
    default = jm.GurneySlab()
    assert float(default.charge) == default.split * float(default.L)
    assert float(default.plate) == (1.0 - default.split) * float(default.L)


def test_a_region_velocity_given_as_numbers_may_be_traced():
    """velocity=(u, 0.0) with u under jax.grad is real numbers, as a traced array is: its derivative
    is that of the array's."""
    gas = jm.AdiabaticGas(P0=1.0, gamma=1.4, p_atm=0.0)

    def kinetic(u, as_tuple):
        velocity = (u, 0.0) if as_tuple else jnp.stack([u, 0.0 * u])
        return jnp.sum(jm.Region(Box((0.0, 0.0), (1.0, 1.0)), gas, 1.0, velocity).velocity ** 2)

    assert float(jax.grad(kinetic)(0.3, True)) == float(jax.grad(kinetic)(0.3, False)) == pytest.approx(0.6)
    with pytest.raises(ValueError, match="velocity must be a real number"):
        jm.Region(Box((0.0, 0.0), (1.0, 1.0)), gas, 1.0, ("fast", 0.0))
