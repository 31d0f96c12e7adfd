"""Faults of `jaxmpm ensemble` and `jaxmpm calibrate`: the measures of members that broke down are
withheld, static parameters (x0, split) and constants a run does not use are refused by name, the
calibration's --viscosity takes QUAD,LIN and is reported, and Ctrl-C is answered at once (status 130,
one line naming the iteration)."""

import json
import os
import signal
import sys
import threading
import time

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import usage

import jaxmpm as jm
import jaxmpm.calibrate as cal
from jaxmpm.cli import main

ensemble_module = sys.modules["jaxmpm.ensemble"]  # jm.ensemble is the function

# gas-slab: dt = 1e-4 on h = 0.25 is beyond the stable limit where c = sqrt(1.4 P0) > 2500 (P0 > 4.5e6)
SLAB = ["gas-slab", "cells=4", "h=0.25", "pad=8"]
SHORT = ["--dt", "1e-4", "--steps", "3"]


def _json_run(capsys, argv, status=0):
    rc = main(argv + ["--json"])
    captured = capsys.readouterr()
    assert rc == status, captured.err
    assert "Traceback" not in captured.err
    return json.loads(captured.out)


# -- ensemble: the measures of a member that broke down are withheld ---------------------------------


@pytest.mark.slow
def test_ensemble_withholds_x_free_of_members_that_broke_down(capsys):
    argv = ["ensemble", *SLAB, "--vary", "P0=2e5:1.2e7", "--members", "6", *SHORT]
    out = _json_run(capsys, argv)
    broke = [r for r in out["results"] if r["status"] != 0]
    ran = [r for r in out["results"] if r["status"] == 0]
    assert broke and ran  # both kinds in the sample
    assert any(r["steps"] > 0 for r in broke)  # one broke after steps that moved its free surface
    for r in broke:
        assert "failure" in r and "x_free" in r and r["x_free"] is None
    for r in ran:
        assert r["x_free"] > 1.0  # the slab's free surface, past its start at x = 1
    assert main(argv) == 0  # the table marks the withheld measure
    lines = capsys.readouterr().out.splitlines()[1:]
    assert len(lines) == 6
    for line, r in zip(lines, out["results"]):
        assert ("x_free=withheld" in line) == (r["status"] != 0)
        assert ("FAILED" in line) == (r["status"] != 0)


@pytest.mark.slow
def test_ensemble_table_says_the_run_itself_failed_not_particle_minus_one(capsys):
    """Members that ran out of steps (--max-steps) failed as a whole: the table says "the run"."""
    argv = ["ensemble", "shock-tube", "cells=21", "ppc=1", "--interpolator", "cpdi", "--vary", "p_l=0.5:2"]
    argv += ["--members", "2", "--t-end", "0.2", "--max-steps", "20"]
    assert main(argv) == 3
    lines = capsys.readouterr().out.splitlines()[1:]
    assert len(lines) == 2
    for line in lines:
        assert "FAILED at step 21, the run: max_steps steps were taken before t_end" in line, line
        assert "particle" not in line


@pytest.mark.slow
def test_ensemble_withholds_f_max_rel_of_members_that_broke_down_and_keeps_the_key(capsys):
    argv = ["ensemble", "gas-expansion", "cells=2", "--vary", "beta=100:20000", "--members", "4"]
    out = _json_run(capsys, argv + ["--dt", "1e-4", "--steps", "10"])
    statuses = [r["status"] for r in out["results"]]
    assert 0 in statuses and any(statuses)
    for r in out["results"]:
        assert "F_max_rel" in r
        assert (r["F_max_rel"] is None) == (r["status"] != 0)


@pytest.mark.slow
def test_ensemble_past_t_valid_reports_f_max_rel_null_not_a_traceback(capsys):
    # t_valid of this vacuum expansion is 0.106; the run goes to 0.15
    argv = ["ensemble", "vacuum-expansion", "cells=4", "--vary", "gamma=1.3:1.5", "--members", "2"]
    argv += ["--dt", "0.005", "--steps", "30"]
    out = _json_run(capsys, argv)
    assert out["ok"] == 2 and [r["F_max_rel"] for r in out["results"]] == [None, None]
    assert main(argv) == 0
    assert capsys.readouterr().out.count("F_max_rel=none (past t_valid") == 2


# -- ensemble: what --vary may name ------------------------------------------------------------------


@pytest.mark.parametrize(
    "scene, name, params",
    [
        ("shock-tube", "x0", ["cells=20"]),
        ("interface", "x0", ["cells=20"]),
        ("gurney-slab", "split", ["cells=20", "pad=80"]),
    ],
)
def test_ensemble_refuses_a_static_parameter_by_name_and_lists_what_can_vary(capsys, scene, name, params):
    argv = ["ensemble", scene, *params, "--vary", f"{name}=0.4:0.6", "--members", "2", *SHORT]
    line = usage(capsys, argv, f"--vary: {name} is static in {scene}")
    listed = line.split("parameters that can vary: ")[1].split(", ")
    assert name not in listed
    values = dict(p.split("=") for p in params)  # the scene of the command line (gurney-slab: compb)
    sc = jm.SCENES[scene](**{k: int(v) for k, v in values.items()})
    assert set(listed) == set(ensemble_module.variable_parameters(sc))
    with pytest.raises(ValueError, match=rf"vary names '{name}', a static parameter of {scene}"):
        jm.ensemble(jm.SCENES[scene](cells=20), jm.CPDI(), {name: [0.4, 0.6]}, dt=1e-8, steps=1)


@pytest.mark.parametrize(
    "explosive, name, why",
    [
        ("gamma-law", "A", "the run of explosive=gamma-law does not use it"),
        ("compb", "D", "the run of explosive=compb does not use it"),
        ("jwl", "sqrt_2E", "it is the constant of Gurney's formula"),
    ],
)
def test_ensemble_refuses_a_constant_the_run_does_not_use(capsys, explosive, name, why):
    """Every member would run the same: the run does not read the constant (calibrate refuses to fit
    it for the same reason)."""
    argv = ["ensemble", "gurney-slab", "cells=20", "pad=80", f"explosive={explosive}"]
    line = usage(capsys, [*argv, "--vary", f"{name}=1:2", "--members", "2", *SHORT], f"--vary: {name}")
    assert why in line
    listed = line.split("parameters that can vary: ")[1].split(", ")
    scene = jm.GurneySlab(cells=20, pad=80, explosive=explosive)
    assert set(listed) == set(ensemble_module.variable_parameters(scene))
    assert not set(listed) & {"split", *cal.unused(scene)} and "L" in listed
    with pytest.raises(ValueError, match=rf"vary names '{name}', which the run does not use: {why}"):
        jm.ensemble(scene, jm.CPDI(), {name: [1.0, 2.0]}, dt=1e-9, steps=1)


def test_a_volume_burn_does_not_use_the_burn_width():
    """The beta burn lights a particle by its compression alone: burn_width (the time burn's length) is
    not read, so an ensemble refuses to vary it; the time and max burns read it."""
    why = "the run of burn=volume does not use it"
    for scene in (jm.Detonation(cells=8, burn="volume"), jm.GurneySlab(cells=5, ppc=1, pad=4, burn="volume")):
        assert why in cal.unused(scene)["burn_width"]
        assert "burn_width" not in ensemble_module.variable_parameters(scene)
    named = cal.unused(jm.Detonation(explosive="tnt", cells=8, burn="volume"))
    assert set(named) == {"D", "gamma", "rho0", "burn_width"}
    for burn in ("time", "max"):
        assert "burn_width" not in cal.unused(jm.Detonation(cells=8, burn=burn))
    with pytest.raises(ValueError, match=f"vary names 'burn_width', which the run does not use: {why}"):
        jm.ensemble(
            jm.Detonation(cells=8, burn="volume"), jm.MPQ(), {"burn_width": [1.5, 2.0]}, dt=1e-8, steps=2
        )


def test_a_manufactured_run_does_not_use_the_other_models_constants():
    """The neo-Hookean bar never reads the gas constants, the gas bar never the neo-Hookean ones, and
    a field of the user's that does not read the amplitude A leaves A unused: an ensemble refuses to
    vary them (every member would run the same), and they are not fittable. A field that reads them
    uses them."""
    solid, gas = jm.Manufactured(cells=4), jm.Manufactured(cells=4, model="gas")
    assert set(cal.unused(solid)) == {"P0", "gamma", "p_atm"} and set(cal.unused(gas)) == {"lam", "mu"}
    assert "the run of model=neo-hookean does not use it" in cal.unused(solid)["P0"]
    assert {"A", "lam", "mu"} <= set(ensemble_module.variable_parameters(solid))
    with pytest.raises(ValueError, match="vary names 'P0', which the run does not use: the run of model"):
        jm.ensemble(solid, jm.CPDI(), {"P0": [1.0, 100.0]}, dt=1e-3, steps=2)
    with pytest.raises(ValueError, match="vary names 'mu', which the run does not use: the run of model=gas"):
        jm.ensemble(gas, jm.CPDI(), {"mu": [1.0, 2.0]}, dt=1e-3, steps=2)

    def stretch(scene, X, t):  # reads neither A nor the gas constants
        return 0.01 * X * t

    def wave(scene, X, t):  # reads A, and P0 though the bar is neo-Hookean
        return scene.A * jnp.sin(X) * t + 1e-9 * scene.P0 * X

    own = jm.Manufactured(cells=4, ends="traction", displacement_fn=stretch)
    assert set(cal.unused(own)) == {"A", "P0", "gamma", "p_atm"}
    assert "displacement_fn does not read it" in cal.unused(own)["A"]
    read = jm.Manufactured(cells=4, ends="traction", displacement_fn=wave)
    assert set(cal.unused(read)) == {"gamma", "p_atm"}
    ens = jm.ensemble(read, jm.CPDI(), {"A": [1e-4, 2e-4], "P0": [1.0, 2.0]}, dt=1e-3, steps=2)
    x = np.asarray(ens.solution.state.x)
    assert list(ens.status) == [0, 0] and not np.array_equal(x[0], x[1])
    assert "A" not in cal.fittable(own) and "A" in cal.fittable(read)


def test_a_detonation_of_a_named_explosive_does_not_use_the_gamma_laws_constants():
    """A JWL row brings its own detonation speed, density and products: D, gamma and rho0 do not
    change the run, so an ensemble refuses them (the gamma law's scene varies them)."""
    row = jm.Detonation(explosive="tnt", cells=8)
    assert set(cal.unused(row)) == {"D", "gamma", "rho0"} and cal.unused(jm.Detonation(cells=8)) == {}
    assert set(ensemble_module.variable_parameters(row)) == {"L", "burn_width"}
    with pytest.raises(
        ValueError, match="vary names 'D', which the run does not use: the run of explosive=tnt"
    ):
        jm.ensemble(row, jm.MPQ(), {"D": [5000.0, 9000.0]}, dt=1e-8, steps=3)
    ens = jm.ensemble(jm.Detonation(cells=8), jm.MPQ(), {"D": [7000.0, 9000.0]}, dt=2e-7, steps=20)
    assert ens.status.tolist() == [0, 0]
    assert float(jnp.max(jnp.abs(ens.solution.state.sigma[0] - ens.solution.state.sigma[1]))) > 0


def test_ensemble_from_a_fit_refuses_a_constant_the_run_does_not_use(capsys, tmp_path):
    fit = tmp_path / "fit.json"  # a fit of the JWL products' A, drawn from for compb's own products
    one = {"A": 1.0}
    fit.write_text(
        json.dumps(dict(scene="gurney-slab", fitted=one, offsets=one, covariance_theta={"A": one}))
    )
    argv = [
        "ensemble",
        "gurney-slab",
        "cells=20",
        "pad=80",
        "explosive=compb",
        "--from-fit",
        str(fit),
        "--members",
        "2",
    ]
    usage(capsys, argv, f"--from-fit: {fit} fits A, which cannot vary this run: the run of explosive=compb")


def test_ensemble_lists_no_static_parameter_for_an_unknown_name(capsys):
    line = usage(capsys, ["ensemble", "shock-tube", "--vary", "foo=1:2", "--members", "2"], "'foo'")
    assert "x0" not in line.split("allowed: ")[1].split(", ")
    with pytest.raises(ValueError, match="unknown parameter 'foo'.*can vary: rho_l") as info:
        jm.ensemble(jm.ShockTube(cells=20), jm.CPDI(), {"foo": [1.0, 2.0]}, dt=1e-8, steps=1)
    assert "x0" not in str(info.value)
    with pytest.raises(ValueError, match="'cells', a structural parameter of shock-tube"):
        jm.ensemble(jm.ShockTube(cells=20), jm.CPDI(), {"cells": [1.0, 2.0]}, dt=1e-8, steps=1)


def test_static_parameters_are_the_static_float_fields():
    assert jm.sensitivity.static_parameters(jm.ShockTube) == ("x0",)
    assert jm.sensitivity.static_parameters(jm.GurneySlab()) == ("split",)
    assert jm.sensitivity.static_parameters(jm.GasSlab) == ()
    assert "split" not in ensemble_module.variable_parameters(jm.GurneyCylinder)


def test_a_gradient_refuses_a_static_parameter_by_name():
    with pytest.raises(ValueError, match="x0 is static in shock-tube .* so it has no gradient") as info:
        jm.gradient(jm.ShockTube(cells=20), jm.CPDI(), ["x0"], dt=1e-5, steps=2, error="separation_max")
    assert str(info.value).endswith(
        "differentiable parameters of shock-tube: rho_l, u_l, p_l, rho_r, u_r, p_r, gamma, h, dt"
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "scene, kw", [("shock-tube", dict(cells=8)), ("gurney-slab", dict(cells=20, pad=20))]
)
def test_every_parameter_the_ensemble_lists_can_vary(scene, kw):
    """Every name of variable_parameters varied at once, by 1%, in one ensemble: it runs."""
    sc = jm.SCENES[scene](**kw)
    names = ensemble_module.variable_parameters(sc)
    vary = {n: [float(getattr(sc, n)), 1.01 * float(getattr(sc, n))] for n in names}
    dt = 0.01 * float(sc.h) / float(sc.wave_speed)
    ens = jm.ensemble(sc, jm.CPDI(), vary, dt=dt, steps=2)
    assert ens.status.tolist() == [0, 0] and set(ens.params) == set(names)


# -- calibrate: what --fit may name, --viscosity ----------------------------------------------------


@pytest.fixture
def plate_data(tmp_path):
    path = tmp_path / "pdv.csv"
    path.write_text("t,v_plate\n0,0\n2e-6,500\n4e-6,900\n6e-6,1100\n")
    return str(path)


GURNEY = ["calibrate", "gurney-slab", "cells=20", "pad=80", "--no-progress", "--iterations", "1"]


@pytest.mark.parametrize(
    "explosive, fit, match",
    [
        ("gamma-law", "split", "--fit: split is static (it places the particles when the run is compiled)"),
        ("gamma-law", "D,A", "--fit: A cannot be fitted: the run of explosive=gamma-law does not use it"),
        ("gamma-law", "sqrt_2E", "--fit: sqrt_2E cannot be fitted: it is the constant of Gurney's formula"),
        ("jwl", "A,gamma", "--fit: gamma cannot be fitted: the run of explosive=jwl does not use it"),
        ("compb", "D", "--fit: D cannot be fitted: the run of explosive=compb does not use it"),
    ],
)
def test_calibrate_refuses_what_the_gurney_run_cannot_fit(capsys, plate_data, explosive, fit, match):
    argv = [*GURNEY, f"explosive={explosive}", "--data", plate_data, "--viscosity", "--fit", fit]
    line = usage(capsys, argv, match)
    fittable = line.split("fittable: ")[1].split(", ")
    assert fittable == list(cal.fittable(jm.GurneySlab(explosive=explosive)))
    assert "split" not in fittable and "sqrt_2E" not in fittable
    with pytest.raises(ValueError, match=fit.split(",")[-1] + " (is static|cannot be fitted)"):
        cal.calibrate(
            jm.GurneySlab(explosive=explosive),
            jm.CPDI(),
            [0.0, 1e-6],
            [0.0, 1.0],
            fit=fit.split(","),
            dt=1e-8,
        )


def test_fittable_names_only_constants_the_run_uses():
    assert cal.fittable(jm.GurneySlab(explosive="gamma-law")) == ("D", "gamma", "rho0", "burn_width", "L")
    assert cal.fittable(jm.GurneySlab(explosive="jwl")) == (
        "D",
        "rho0",
        "burn_width",
        "A",
        "B",
        "R1",
        "R2",
        "w",
        "L",
    )
    assert cal.fittable(jm.GurneySlab()) == ("burn_width", "L")  # Comp B's row has its own constants
    assert "split" not in cal.fittable(jm.GurneySlab) and "sqrt_2E" not in cal.fittable(jm.GurneySlab)
    assert cal.fittable(jm.GasSlab()) == ("P0", "gamma", "p_atm", "rho0")


@pytest.mark.slow
def test_calibrate_gurney_slab_without_viscosity_runs_with_a_note(capsys, plate_data):
    argv = [*GURNEY, "explosive=gamma-law", "--data", plate_data, "--fit", "D", "--json"]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "jaxmpm: note: calibrate gurney-slab runs without artificial viscosity" in err
    assert json.loads(out)["viscosity"] is None
    with pytest.raises(SystemExit) as info:  # argparse's --help
        main(["calibrate", "--help"])
    assert info.value.code == 0
    assert "gurney-slab's detonation front is a shock" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize(
    "value, match",
    [
        ("2,0.2,5", "--viscosity takes QUAD,LIN, got 3 numbers '2,0.2,5': a third, SHEAR"),
        ("2", "--viscosity must be QUAD,LIN (two numbers >= 0), got '2': 1 number"),
        ("2,-1", "--viscosity must be QUAD,LIN (two numbers >= 0), got '2,-1': c_lin must be >= 0"),
        ("2,x", "--viscosity must be QUAD,LIN (two numbers >= 0), got '2,x'"),
    ],
)
def test_calibrate_viscosity_takes_quad_and_lin(capsys, tmp_path, value, match):
    data = tmp_path / "traj.csv"
    data.write_text("t,x_free\n0,1\n2e-4,1.1\n4e-4,1.2\n")
    usage(capsys, ["calibrate", *SLAB, "--data", str(data), "--viscosity", value], match)


@pytest.fixture
def slab_data(tmp_path):
    path = tmp_path / "traj.csv"
    path.write_text("t,x_free\n0,1\n2e-4,1.1\n4e-4,1.2\n6e-4,1.3\n")
    return str(path)


SLAB_FIT = ["calibrate", *SLAB, "--dt", "5e-5", "--no-progress"]


@pytest.mark.slow
def test_calibrate_json_reports_the_viscosity(capsys, slab_data):
    argv = [*SLAB_FIT, "--data", slab_data, "--fit", "gamma", "--iterations", "1"]
    out = _json_run(capsys, [*argv, "--viscosity", "1.5,0.1"])
    assert out["viscosity"] == [1.5, 0.1]
    out = _json_run(capsys, argv)
    assert "viscosity" in out and out["viscosity"] is None


# -- Ctrl-C ------------------------------------------------------------------------------------------


@pytest.fixture
def main_thread():
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers can only be set in the main thread")


def _interrupt_and_block(real, on_call: int):
    """``real``, wrapped: its ``on_call``-th call sends SIGINT to this process and then blocks (up to
    60 s, until ``release`` is set) as a long compiled call does, deaf to the signal (a compiled call
    runs in C; a KeyboardInterrupt raised in this thread meanwhile is dropped, as Python would only
    raise it after the call); the others pass through."""
    release = threading.Event()
    calls = {"n": 0, "sent": None}

    def wrapped(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == on_call:
            deadline = time.perf_counter() + 60.0
            while not release.is_set() and time.perf_counter() < deadline:
                try:
                    if calls["sent"] is None:
                        calls["sent"] = time.perf_counter()
                        os.kill(os.getpid(), signal.SIGINT)
                    release.wait(0.05)
                except KeyboardInterrupt:
                    pass
        return real(*args, **kwargs)

    return wrapped, release, calls


@pytest.mark.slow
@pytest.mark.usefixtures("main_thread")
def test_ctrl_c_during_a_fit_is_answered_at_once_naming_the_iteration(capsys, monkeypatch, slab_data):
    """The second residual-and-Jacobian call (iteration 1's trial) gets SIGINT and does not return
    for 60 s: the command answers at once, with one line, status 130."""
    released = []
    init = cal._Model.__init__

    def patched(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self._rj, release, calls = _interrupt_and_block(self._rj, on_call=2)
        released.append((release, calls))

    monkeypatch.setattr(cal._Model, "__init__", patched)
    try:
        rc = main([*SLAB_FIT, "--data", slab_data, "--iterations", "3", "--fit", "gamma,P0", "--json"])
        answered = time.perf_counter()
    finally:
        for release, _ in released:
            release.set()
    captured = capsys.readouterr()
    ((_, calls),) = released
    assert rc == 130 and captured.out == ""
    assert answered - calls["sent"] < 10.0  # not the 60 s the call blocks for
    (line,) = captured.err.strip().splitlines()
    assert line.startswith("jaxmpm: interrupted at iteration 1 of 3 (the lowest loss so far ")
    assert line.endswith("the fit did not finish, and no fit is reported")


@pytest.mark.slow
def test_a_library_fit_interrupted_between_iterations_says_where(monkeypatch):
    init = cal._Model.__init__

    def patched(self, *args, **kwargs):
        init(self, *args, **kwargs)
        real, calls = self._rj, {"n": 0}

        def rj(*a):
            calls["n"] += 1
            if calls["n"] == 3:
                raise KeyboardInterrupt
            return real(*a)

        self._rj = rj

    monkeypatch.setattr(cal._Model, "__init__", patched)
    ts = np.array([0.0, 2e-4, 4e-4, 6e-4])
    xs = np.array([1.0, 1.1, 1.2, 1.3])
    sc = jm.GasSlab(cells=4, h=0.25, pad=8)
    with pytest.raises(KeyboardInterrupt, match=r"^interrupted at iteration 2 of 5 \(the lowest loss so far"):
        cal.calibrate(sc, jm.CPDI(), ts, xs, fit=("gamma", "P0"), dt=5e-5, iterations=5, progress=False)


@pytest.mark.slow
@pytest.mark.usefixtures("main_thread")
def test_ctrl_c_during_an_ensemble_is_answered_at_once(capsys, monkeypatch):
    wrapped, release, calls = _interrupt_and_block(ensemble_module._run_batch, on_call=1)
    monkeypatch.setattr(ensemble_module, "_run_batch", wrapped)
    try:
        rc = main(["ensemble", *SLAB, "--vary", "P0=2e5:3e5", "--members", "3", *SHORT])
        answered = time.perf_counter()
    finally:
        release.set()
    captured = capsys.readouterr()
    assert rc == 130 and captured.out == "" and answered - calls["sent"] < 10.0
    assert captured.err.strip().splitlines() == [
        "jaxmpm: interrupted while the ensemble's 3 members ran (one compiled call): no member is reported"
    ]


def test_data_beyond_the_grid_name_the_column_and_a_pad_that_exists(capsys, tmp_path):
    """Data past the grid's end are named as the file's column; a pad no memory could hold is not
    printed as a 300-digit count but as a hint at the data's units."""
    far = tmp_path / "far.csv"
    far.write_text("t,x_free\n0,1\n0.002,9\n")
    argv = ["calibrate", "gas-slab", "--data", str(far), "--fit", "gamma", "pad=10", "--no-progress"]
    line = usage(capsys, argv, "--data: x_free reaches x = 9, but the grid ends at x = 1.3125 (pad = 10")
    assert line.endswith("the model cannot follow the data; use pad >= 332")
    huge = tmp_path / "huge.csv"
    huge.write_text("t,x_free\n0,1\n0.002,1e300\n")
    line = usage(capsys, [*argv[:3], str(huge), *argv[4:]], "--data: x_free reaches x = 1e+300")
    assert line.endswith(
        "a grid holding them needs pad = 4e+301 cells, beyond any memory: check the data's units"
    )


def test_a_member_is_measured_with_its_own_scene():
    """``Ensemble.member_scene`` gives member i's scene (the varied values put in), so that its errors
    are against its own exact solution, not the base scene's."""
    scene = jm.GasExpansion(cells=4)
    kw = dict(dt=1e-5, steps=5, artificial_cells=1)
    ens = jm.ensemble(scene, jm.MPQ(), {"beta": [150.0, 250.0]}, **kw)
    for i, beta in enumerate((150.0, 250.0)):
        own = ens.member_scene(scene, i)
        assert float(own.beta) == beta and own.cells == scene.cells
        alone = jm.GasExpansion(cells=4, beta=beta)
        one = jm.simulate(alone, jm.MPQ(), **kw)
        got = float(jm.errors(own, ens.member(i).state, ens.member(i).body)["F_max_rel"])
        np.testing.assert_allclose(got, float(jm.errors(alone, one.state, one.body)["F_max_rel"]), rtol=1e-9)
        # the base scene's beta (200) measures the member against another solution
        base = float(jm.errors(scene, ens.member(i).state, ens.member(i).body)["F_max_rel"])
        assert base > 10 * got
    with pytest.raises(ValueError, match=r"scene must be the ensemble's, and vibrating-bar has no beta"):
        ens.member_scene(jm.VibratingBar(), 0)
    with pytest.raises(ValueError, match="i must be a member's index"):
        ens.member_scene(scene, 2)


def test_calibrate_gurney_slab_needs_fit_and_names_what_can_be_fitted(capsys, plate_data):
    """gas-slab's default --fit (gamma,P0) is not the Gurney slab's: without --fit the command says
    what can be fitted, not that P0 (which the user never typed) is unknown."""
    usage(
        capsys,
        [*GURNEY, "--data", plate_data],
        "--fit: name the constants to fit for gurney-slab; fittable with these parameters: burn_width, L",
    )


def test_a_fit_of_an_unknown_name_lists_what_can_be_fitted():
    """The list is of the fittable constants, not of every differentiable parameter (h and dt cannot
    be fitted)."""
    slab = jm.GasSlab(cells=8, h=1 / 8, pad=24)
    with pytest.raises(
        ValueError, match=r"^unknown parameter 'beta' for a fit; fittable: P0, gamma, p_atm, rho0$"
    ):
        cal.calibrate(slab, jm.CPDI(), [0.0, 1e-4], [1.0, 1.0], fit=("beta",), dt=1e-5)


@pytest.mark.slow
def test_ensemble_measures_the_detonation_where_run_does(capsys):
    """A detonation member's F_max_rel is measured away from the burn front, as ``jaxmpm run`` measures
    it (over every particle, front included, it read 0.207 where the run reads 0.074 at 600 steps), and
    is null before any particle is far enough behind the front."""
    for steps, measured in (("60", False), ("600", True)):
        argv = ["ensemble", "detonation", "cells=100", "--vary", "D=8000:8000.000001", "--members", "1"]
        member = _json_run(capsys, argv + ["--dt", "5e-9", "--steps", steps])["results"][0]
        assert member["status"] == 0
        D = repr(member["params"]["D"])
        run = ["run", "detonation", "cells=100", f"D={D}", "--interpolator", "cpdi", "--dt", "5e-9"]
        assert main(run + ["--steps", steps, "--json"]) == 0
        expected = json.loads(capsys.readouterr().out)["errors"]["F_max_rel"]
        assert (expected is not None) == measured
        # (the members run vmapped, one compiled program for all: round-off apart from the run)
        assert member["F_max_rel"] == (None if expected is None else pytest.approx(expected, rel=1e-9))


def _fit_file(tmp_path, **fixed):
    """A fit of gamma and P0 of the gas slab as ``jaxmpm calibrate --json`` writes it, with the scene's
    other parameters as the fit ran them (``fixed``)."""
    fit = dict(
        scene="gas-slab",
        interpolator="cpdi",
        fitted={"gamma": 1.4, "P0": 3.0e5},
        offsets={"gamma": 1.0, "P0": fixed["p_atm"]},
        covariance_theta={"gamma": {"gamma": 1e-4, "P0": 0.0}, "P0": {"gamma": 0.0, "P0": 1e-4}},
        fixed=fixed,
    )
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(fit))
    return str(path)


@pytest.mark.slow
def test_ensemble_from_a_fit_runs_the_scene_the_fit_ran(capsys, tmp_path):
    """``--from-fit`` runs the members in the fit's scene (its ``fixed``: here ``p_atm = 8e4``,
    ``rho0 = 1.1`` and 8 cells; they ran at the defaults, 1e5, 1 and 32 cells); the grid's ``pad`` is
    the ensemble's own, sized for the draws."""
    fixed = dict(p_atm=8.0e4, h=0.125, rho0=1.1, cells=8, ppc=2, pad=48)
    fit = _fit_file(tmp_path, **fixed)
    timing = ["--dt", "2e-5", "--steps", "50"]
    out = _json_run(capsys, ["ensemble", "gas-slab", "--from-fit", fit, "--members", "2"] + timing)
    assert out["ok"] == 2
    for r in out["results"]:
        scene = jm.GasSlab(**{**fixed, "pad": out["pad"], **r["params"]})
        sol = jm.simulate(scene, jm.CPDI(), dt=2e-5, steps=50)
        x = jm.scenes.gas_slab.free_surface(sol.state.x, sol.state.F, sol.state.corners, sol.body)
        assert r["x_free"] == pytest.approx(float(x), rel=1e-12)
    # the same values given again are taken; another value is refused, naming both
    again = ["ensemble", "gas-slab", "p_atm=8e4", "cells=8", "--from-fit", fit, "--members", "2"] + timing
    assert _json_run(capsys, again)["ok"] == 2
    other = ["ensemble", "gas-slab", "p_atm=1e5", "--from-fit", fit, "--members", "2"] + timing
    line = usage(capsys, other, "--from-fit")
    assert "the fit ran gas-slab with p_atm=80000.0, and the command line gives p_atm=100000.0" in line
