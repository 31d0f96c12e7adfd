"""The Gurney cylinder (``gurney-cylinder``): a charge lit on its axis driving its metal tube, in 2D."""

import json

import equinox as eqx
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm.cli import main
from jaxmpm.scenes.gurney import gurney_cylinder

pytestmark = pytest.mark.slow  # 2D detonations

SMALL = dict(cells=8, pad=16)


@pytest.fixture(scope="module")
def short_run():
    """CPDI, APIC and the shear viscosity, 8 cells across R, to 8 us (the ring moving at ~600 m/s)."""
    scene = jm.GurneyCylinder(**SMALL)
    sol = jm.simulate(
        scene,
        jm.CPDI(),
        t_end=8e-6,
        cfl=0.3,
        max_steps=2000,
        transfer=jm.APIC(),
        viscosity=jm.ArtificialViscosity(c_shear=0.3),
        saveat=jm.SaveAt(every=4, fields=("x", "v")),
    )
    return scene, sol


def _moved(state, x, v):
    return eqx.tree_at(lambda s: (s.x, s.v), state, (x, v))


def test_gurney_cylinder_formula():
    # sqrt(2E) (M/C + 1/2)^(-1/2): the M/C = 2.565 gives about 1542 m/s
    assert float(gurney_cylinder(2700.0, 2.565)) == pytest.approx(2700.0 / np.sqrt(3.065), rel=1e-15)
    assert float(gurney_cylinder(2700.0, 2.565)) == pytest.approx(1542.2, abs=0.05)


def test_scene_mass_ratio_and_gurney_velocity():
    scene = jm.GurneyCylinder()
    # Comp B (JWL row, 1717 kg/m^3) of radius 4 cm in 4340 steel (7810 kg/m^3) to 5 cm
    mc = 7810.0 * (0.05**2 - 0.04**2) / (1717.0 * 0.04**2)
    assert float(scene.mass_ratio) == pytest.approx(mc, rel=1e-12)
    assert float(scene.gurney_velocity()) == pytest.approx(2700.0 / np.sqrt(mc + 0.5), rel=1e-12)
    assert float(scene.radius) == pytest.approx(0.04, rel=1e-15)
    assert float(scene.thickness) == pytest.approx(0.01, rel=1e-12)
    # the particles: charge inside radius 4 cm, ring between 4 and 5 cm (the lattice of the quarter)
    body = scene.body()
    r = np.linalg.norm(np.asarray(body.X), axis=1)
    region = np.asarray(body.region)
    assert r[region == 0].max() <= 0.04 and r[region == 1].min() > 0.04 and r.max() <= 0.05
    assert set(np.unique(region)) == {0, 1}


def test_run_is_symmetric_about_the_diagonal_and_drives_the_ring_out(short_run):
    scene, sol = short_run
    body, st = sol.body, sol.state
    assert sol.failure() is None
    X, x = np.asarray(body.X), np.asarray(st.x)
    # the quarter's lattice and its physics are symmetric under x <-> y: so is the run, to round-off
    index = {tuple(np.round(p / float(scene.h) * 1e6).astype(int)): i for i, p in enumerate(X)}
    mirror = np.array([index[tuple(np.round(p[::-1] / float(scene.h) * 1e6).astype(int))] for p in X])
    assert np.max(np.abs(x[mirror][:, ::-1] - x)) < 1e-13 * float(scene.R)
    # the ring moves outwards, faster at each frame, and stays below Gurney's terminal velocity
    ts = np.asarray(sol.ts)
    keep = np.concatenate([[True], np.diff(ts) > 0])
    frames = zip(np.asarray(sol.history["x"])[keep], np.asarray(sol.history["v"])[keep])
    v = [float(scene.ring_velocity(_moved(st, xk, vk), body)) for xk, vk in frames]
    v = np.asarray(v)
    assert abs(v[0]) < 1e-9  # at rest until the front reaches the ring at 5 us, then driven out
    moving = v > 10.0
    assert moving[-3:].all() and np.all(np.diff(v[moving]) > 0.0)
    assert 520.0 < v[-1] < 630.0 < float(scene.gurney_velocity())  # measured 575.3 m/s
    assert float(scene.ring_radius(st, body)) > float(scene.ring_radius(_moved(st, body.X, st.v), body))


def test_energy_is_kept_to_two_percent(short_run):
    # total energy (kinetic + internal, the detonation energy included from t = 0) over the run: APIC
    # and the grid's projections dissipate a little; nothing is created
    scene, sol = short_run
    start = jm.simulate(scene, jm.CPDI(), dt=1e-15, steps=1)
    e0 = float(jm.diagnostics(scene, start.state, start.body)["energy"])
    e1 = float(jm.diagnostics(scene, sol.state, sol.body)["energy"])
    assert 0.98 * e0 < e1 < e0  # measured 0.982


def test_bad_split_is_one_clear_error():
    with pytest.raises(ValueError, match="split"):
        jm.GurneyCylinder(split=1.2)
    with pytest.raises(ValueError, match=r"at least a cell across.*raise cells"):
        jm.GurneyCylinder(cells=4, split=0.1)


def test_cli_run_reports_the_ring(capsys):
    argv = "run gurney-cylinder cells=8 pad=16 --interpolator cpdi --transfer apic --viscosity 2,0.2,0.3 "
    argv += "--t-end 7e-6 --cfl 0.3 --max-steps 1000 --json"
    assert main(argv.split()) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["status"] == 0
    ring = data["ring"]
    assert ring["gurney"] == pytest.approx(float(jm.GurneyCylinder().gurney_velocity()), rel=1e-12)
    assert 0.0 < ring["velocity"] < ring["gurney"]
    assert ring["radius"] > 0.045
    assert data["params"]["cj"]["D"] == pytest.approx(7980.0, rel=2e-3)
    assert len(data["particles"]["region"]) == len(data["particles"]["x"])
