"""One run spread over several devices (``simulate(..., devices=...)``): the particles sharded, the
grid replicated. Checked on 4 forced host devices (a subprocess: the device count is fixed when JAX
starts) against the one-device run, for every interpolator and transfer."""

import json
import os
import subprocess
import sys
import textwrap

import jax
import pytest

import jaxmpm as jm

SCRIPT = textwrap.dedent(
    """
    import json, pathlib, sys, tempfile
    import jax
    jax.config.update("jax_enable_x64", True)
    import numpy as np, jaxmpm as jm
    from jaxmpm import long_run

    def diff(a, b):
        out = {}
        for k in ("x", "v", "F", "sigma"):
            x, y = np.asarray(getattr(a.state, k)), np.asarray(getattr(b.state, k))
            out[k] = float(np.max(np.abs(x - y)) / np.max(np.abs(x)))
        return out

    def failure(sol):
        return [int(sol.state.status), int(sol.state.fail_step), int(sol.state.fail_particle)]

    r = {"devices": len(jax.devices()), "runs": {}}
    # 1D, a wall and a free end under the atmosphere's traction: 60 particles over 4 devices
    slab = jm.GasSlab(cells=30, h=1 / 30, pad=60)
    for i, make in jm.INTERPOLATORS.items():
        for t, transfer in jm.TRANSFERS.items():
            kw = dict(dt=5e-6, steps=20, transfer=transfer(), throw=False)
            a = jm.simulate(slab, make(), **kw)
            b = jm.simulate(slab, make(), devices=4, **kw)
            r["runs"][f"{i}-{t}"] = dict(diff=diff(a, b), a=failure(a), b=failure(b),
                                         spread=list(b.state.x.sharding.spec))
    # artificial cells at both free ends (the talk's gas expansion; 1D and 2D)
    for i in ("spq", "cpdi", "mpq"):
        for dim in (1, 2):
            sc = jm.GasExpansion(cells=8, pad=4, dim=dim)
            kw = dict(dt=1e-5, steps=25, artificial_cells=1)
            a = jm.simulate(sc, jm.INTERPOLATORS[i](), **kw)
            b = jm.simulate(sc, jm.INTERPOLATORS[i](), devices=4, **kw)
            r["runs"][f"artificial-{i}-{dim}d"] = dict(diff=diff(a, b), a=failure(a), b=failure(b))
    # 2D, symmetry planes and the atmosphere's traction, to an end time (CFL steps): 112 particles
    for i in ("spq", "cpdi", "mpq"):
        disk = jm.BlastDisk(cells=6, pad=8)
        kw = dict(t_end=0.5 * float(disk.transit_time), cfl=0.3, max_steps=400)
        a = jm.simulate(disk, jm.INTERPOLATORS[i](), **kw)
        b = jm.simulate(disk, jm.INTERPOLATORS[i](), devices=jax.devices(), **kw)
        r["runs"][f"disk-{i}"] = dict(diff=diff(a, b), a=failure(a), b=failure(b), steps=int(a.state.step),
                                      steps_b=int(b.state.step))
    # a history variable (the burn fraction) and the energy equation; 44 particles on 4 devices
    det = jm.Detonation(L=0.02, cells=44, ppc=1)
    kw = dict(dt=1e-8, steps=30, viscosity=jm.ArtificialViscosity())
    a, b = jm.simulate(det, jm.CPDI(), **kw), jm.simulate(det, jm.CPDI(), devices=4, **kw)
    lam = np.asarray(a.state.internal["lambda"]) - np.asarray(b.state.internal["lambda"])
    burnt = float(np.sum(b.state.internal["lambda"]))
    lam = float(np.max(np.abs(lam)))
    r["runs"]["detonation"] = dict(diff=diff(a, b), a=failure(a), b=failure(b), lam=lam, burnt=burnt)
    # the gradient through a sharded run
    def f(P0, devices):
        sc = jm.GasSlab(cells=30, h=1 / 30, pad=60, P0=P0)
        return jm.simulate(sc, jm.CPDI(), dt=5e-6, steps=20, devices=devices).state.x[-1, 0]
    ga, gb = jax.grad(f)(3e5, None), jax.grad(f)(3e5, 4)
    r["grad"] = [float(ga), float(gb)]
    # ... and in the time step, which jax.grad traces while the status stays known
    g = lambda dt, devices: jm.simulate(slab, jm.CPDI(), dt=dt, steps=20, devices=devices).state.x[-1, 0]
    r["grad_dt"] = [float(jax.grad(g)(5e-6, None)), float(jax.grad(g)(5e-6, 4))]
    # a chunked run on 4 devices, saved mid-way and resumed: bit for bit
    def chunked_and_resumed(scene):  # MPQ's whole run, the run saved at step 14 and resumed, its meta
        kw = dict(dt=5e-6, steps=30, chunk=4, progress=False, devices=4)
        full = long_run.run(scene, jm.MPQ(), **kw)
        path = pathlib.Path(tempfile.mkdtemp()) / "run.npz"
        long_run.run(scene, jm.MPQ(), out=path, checkpoint_every=2, **(kw | dict(steps=14)))
        _, meta = long_run.load(path)
        with np.load(path) as z:
            arrays = {k: z[k] for k in z.files}
        meta["steps"] = 30
        arrays["meta"] = np.asarray(json.dumps(meta))
        np.savez(path, **arrays)
        return full, long_run.resume(path, progress=False), meta

    def identical(a, b):
        return all(np.array_equal(np.asarray(getattr(a.state, k)), np.asarray(getattr(b.state, k)))
                   for k in ("x", "v", "F", "sigma", "corners"))

    full, res, meta = chunked_and_resumed(slab)
    r["resume"] = dict(saved_devices=meta["devices"], identical=identical(res, full))
    one = jm.simulate(slab, jm.MPQ(), dt=5e-6, steps=30, devices=4)
    r["resume"]["as_simulate"] = diff(one, full)
    # particles that the devices do not divide: padded with inert copies of the last one
    u = r["uneven"] = {}
    odd = jm.GasSlab(cells=31, h=1 / 31, ppc=1, pad=40)  # 31 particles over 4 devices
    for i, make in jm.INTERPOLATORS.items():
        kw = dict(dt=5e-6, steps=20, throw=False)
        a, b = jm.simulate(odd, make(), **kw), jm.simulate(odd, make(), devices=4, **kw)
        u[f"slab-{i}"] = dict(diff=diff(a, b), a=failure(a), b=failure(b), n=int(b.state.x.shape[0]))
    wide, cpgimp = jm.GasSlab(cells=31, h=1 / 31, pad=60), jm.INTERPOLATORS["cpgimp"]  # 62; the last breaks
    kw = dict(dt=5e-6, steps=20, transfer=jm.APIC(), throw=False)
    a, b = jm.simulate(wide, cpgimp(), **kw), jm.simulate(wide, cpgimp(), devices=4, **kw)
    u["slab-cpgimp-apic"] = dict(diff=diff(a, b), a=failure(a), b=failure(b), n=int(b.state.x.shape[0]))
    for i, dim, k in (("spq", 1, 4), ("mpq", 1, 4), ("mpq", 2, 3)):  # 14 over 4, 196 over 3
        sc = jm.GasExpansion(cells=7, pad=4, dim=dim)
        kw = dict(dt=1e-5, steps=25, artificial_cells=1)
        a = jm.simulate(sc, jm.INTERPOLATORS[i](), **kw)
        b = jm.simulate(sc, jm.INTERPOLATORS[i](), devices=k, **kw)
        u[f"artificial-{i}-{dim}d"] = dict(diff=diff(a, b), a=failure(a), b=failure(b),
                                           n=int(b.state.x.shape[0]))
    for i in ("cpdi", "mpq"):  # 79 particles over 4, symmetry planes, traction, CFL steps to an end time
        disk = jm.BlastDisk(cells=5, pad=8)
        kw = dict(t_end=0.5 * float(disk.transit_time), cfl=0.3, max_steps=400, saveat=jm.SaveAt(every=10))
        a = jm.simulate(disk, jm.INTERPOLATORS[i](), **kw)
        b = jm.simulate(disk, jm.INTERPOLATORS[i](), devices=4, **kw)
        u[f"disk-{i}"] = dict(diff=diff(a, b), a=failure(a), b=failure(b), n=int(b.state.x.shape[0]),
                              steps=[int(a.state.step), int(b.state.step)],
                              history=[list(a.history["x"].shape), list(b.history["x"].shape)],
                              history_diff=float(np.max(np.abs(np.asarray(a.history["x"]) -
                                                               np.asarray(b.history["x"])))))
    det = jm.Detonation(L=0.02, cells=43, ppc=1)  # two regions, energy and burn fraction: 43 over 4
    kw = dict(dt=1e-8, steps=30, viscosity=jm.ArtificialViscosity())
    a, b = jm.simulate(det, jm.CPDI(), **kw), jm.simulate(det, jm.CPDI(), devices=4, **kw)
    u["detonation"] = dict(diff=diff(a, b), a=failure(a), b=failure(b), n=int(b.state.x.shape[0]),
                           lam=float(np.max(np.abs(np.asarray(a.state.internal["lambda"]) -
                                                   np.asarray(b.state.internal["lambda"])))),
                           e=float(np.max(np.abs(np.asarray(a.state.e) - np.asarray(b.state.e)))
                                   / np.max(np.abs(np.asarray(a.state.e)))))
    g = lambda P0, devices: jm.simulate(jm.GasSlab(cells=31, h=1 / 31, ppc=1, pad=40, P0=P0), jm.CPDI(),
                                        dt=5e-6, steps=20, devices=devices).state.x[-1, 0]
    r["grad_uneven"] = [float(jax.grad(g)(3e5, None)), float(jax.grad(g)(3e5, 4))]
    # each device holds its share of the padded particles: 8 of 32 (31 and one inert copy)
    from jaxmpm._simulate import prepare, _run_scan_jit
    model, dt_a, n, saveat = prepare(odd, jm.SPQ(), dt=5e-6, steps=20, devices=4)
    text = _run_scan_jit.lower(model, dt_a, n, saveat, None).compile().compiled.as_text()
    loop = [line.split(" while(")[0] for line in text.splitlines()  # the time loop's carry
            if " while(" in line and 'op_name="jit(run_scan)/while"' in line]
    u["share"] = [len(loop), "f64[8,1,1]" in loop[0], "f64[32,1,1]" in loop[0] or "f64[31,1,1]" in loop[0]]
    full, res, _ = chunked_and_resumed(odd)
    u["resume"] = dict(identical=identical(res, full),
        as_simulate=diff(jm.simulate(odd, jm.MPQ(), dt=5e-6, steps=30, devices=4), full),
        one_device=diff(jm.simulate(odd, jm.MPQ(), dt=5e-6, steps=30), full))
    # refused: a breakdown raised from inside jax.jit or jax.vmap (the device that found it stopped
    # while the others waited for it in an all-reduce: the process aborted after 40 s), while the
    # run is traced
    def refusal(f):
        try:
            f()
        except ValueError as e:
            return str(e)
    r["refused"] = {}
    broken = lambda b: jm.simulate(jm.GasExpansion(cells=8, pad=1, beta=b), jm.CPDI(), dt=1e-4, steps=300,
                                   devices=4).state.x[-1, 0]
    r["refused"]["jit"] = refusal(lambda: jax.jit(broken)(200.0))
    r["refused"]["vmap"] = refusal(lambda: jax.vmap(broken)(np.array([1.0, 200.0])))
    quiet = lambda b: jm.simulate(jm.GasExpansion(cells=8, pad=1, beta=b), jm.CPDI(), dt=1e-4, steps=300,
                                  devices=4, throw=False).state.status
    r["refused"]["jit_status"] = int(jax.jit(quiet)(200.0))
    print(json.dumps(r))
    """
)


@pytest.fixture(scope="module")
def four_devices():
    flags = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
    env = dict(os.environ, XLA_FLAGS=flags.strip())
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


# The grid sums are added in another order on 4 devices: the states differ by round-off, measured
# at most 9e-16 of each field's largest value over these runs in 1D and 6e-15 in 2D (20 to 30 steps;
# MPQ and CPDI2 reach 3-6e-14 after 60 steps in 2D, docs/scale.md).
ROUND_OFF = 1e-13


@pytest.mark.slow
def test_every_interpolator_and_transfer_on_four_devices_equals_one(four_devices):
    r = four_devices
    assert r["devices"] == 4
    assert len(r["runs"]) == len(jm.INTERPOLATORS) * len(jm.TRANSFERS) + 6 + 4
    for name, run in r["runs"].items():
        assert max(run["diff"].values()) < ROUND_OFF, (name, run["diff"])
        assert run["a"] == run["b"], (name, run)  # the same status, failing step and particle
        if "spread" in run:
            assert run["spread"] == ["particles"], run
    # one 1D run breaks down (CPGIMP with APIC, its last particle): named the same on 4 devices
    broken = {k: v["b"] for k, v in r["runs"].items() if v["b"][0] != 0}
    assert broken == {"cpgimp-apic": [jm.status.STENCIL, 16, 59]}, broken
    assert r["runs"]["disk-mpq"]["steps"] == r["runs"]["disk-mpq"]["steps_b"] > 10
    det = r["runs"]["detonation"]
    assert det["lam"] < ROUND_OFF and det["burnt"] > 1.0  # the burn has begun, the same on 4 devices


@pytest.mark.slow
@pytest.mark.parametrize("key", ["grad", "grad_dt"], ids=["in-P0", "in-dt"])
def test_gradient_through_a_sharded_run_equals_the_unsharded(four_devices, key):
    ga, gb = four_devices[key]
    assert ga != 0.0 and abs(gb - ga) <= ROUND_OFF * abs(ga)


@pytest.mark.slow
def test_sharded_chunked_run_resumes_bit_for_bit(four_devices):
    res = four_devices["resume"]
    assert res["saved_devices"] == 4 and res["identical"]
    assert max(res["as_simulate"].values()) == 0.0  # chunks and one scan: the same compiled step


@pytest.mark.slow
def test_particles_the_devices_do_not_divide_run_spread_and_equal_one_device(four_devices):
    u = four_devices["uneven"]
    runs = {k: v for k, v in u.items() if "diff" in v}
    assert len(runs) == len(jm.INTERPOLATORS) + 1 + 3 + 2 + 1
    for name, run in runs.items():
        assert max(run["diff"].values()) < ROUND_OFF, (name, run["diff"])
        assert run["a"] == run["b"], (name, run)  # the same status, failing step and particle
    # the states hold the real particles only (the inert copies are dropped)
    assert {k: v["n"] for k, v in runs.items() if k.startswith("slab-")} == {
        **{f"slab-{i}": 31 for i in jm.INTERPOLATORS},
        "slab-cpgimp-apic": 62,
    }
    assert [u[f"artificial-{i}"]["n"] for i in ("spq-1d", "mpq-1d", "mpq-2d")] == [14, 14, 196]
    # the last of 62 particles breaks down, and not its copies: named the same on 4 devices
    assert u["slab-cpgimp-apic"]["b"][0] == jm.status.STENCIL and u["slab-cpgimp-apic"]["b"][2] == 61
    for i in ("cpdi", "mpq"):
        disk = u[f"disk-{i}"]
        assert disk["n"] == 79 and disk["steps"][0] == disk["steps"][1] > 10
        assert disk["history"][0] == disk["history"][1] and disk["history"][0][1] == 79
        assert disk["history_diff"] < ROUND_OFF
    det = u["detonation"]
    assert det["n"] == 43 and det["lam"] < ROUND_OFF and det["e"] < ROUND_OFF
    ga, gb = four_devices["grad_uneven"]
    assert ga != 0.0 and abs(gb - ga) <= ROUND_OFF * abs(ga)
    # spread, not whole on every device: the step's loop holds 8 particles a device, never all 32
    assert u["share"] == [1, True, False]
    assert u["resume"]["identical"] and max(u["resume"]["as_simulate"].values()) == 0.0
    assert max(u["resume"]["one_device"].values()) < ROUND_OFF


@pytest.mark.slow
def test_a_sharded_run_refuses_raising_inside_a_transformation(four_devices):
    r = four_devices["refused"]
    for how in ("jit", "vmap"):
        assert r[how] is not None and r[how].startswith(
            "a run over several devices cannot raise its breakdown from inside jax.jit or jax.vmap"
        ), r[how]
        assert "throw=False" in r[how]
    assert r["jit_status"] != 0  # with throw=False it runs, and the status says it broke down


@pytest.mark.parametrize(
    "devices, match",
    [
        (0, "devices must be a count from 1 to"),
        (10**6, "devices must be a count from 1 to"),
        ("cpu", "devices must be a non-empty sequence of distinct JAX devices"),
        ([], "devices must be a non-empty sequence"),
        (2.0, "devices must be a non-empty sequence"),
    ],
)
def test_bad_devices_are_refused_before_tracing(devices, match):
    with pytest.raises(ValueError, match=match):
        jm.simulate(jm.GasSlab(cells=4, h=0.25, pad=8), jm.SPQ(), dt=1e-6, steps=1, devices=devices)


def test_with_several_processes_the_devices_include_every_process(monkeypatch):
    # the other process, with no device in the run, failed to read its result ("non-addressable")
    monkeypatch.setattr(jax, "process_count", lambda: 2)
    match = (
        r"^devices must include devices of every process when several run \(2 processes; these are of "
        r"process 0 only\): pass devices=len\(jax.devices\(\)\) or jax.devices\(\)$"
    )
    with pytest.raises(ValueError, match=match):
        jm.simulate(jm.GasSlab(cells=4, h=0.25, pad=8), jm.SPQ(), dt=1e-6, steps=1, devices=1)


def test_the_same_device_twice_is_refused():
    d = jax.devices()[0]
    with pytest.raises(ValueError, match="devices must be distinct"):
        jm.simulate(jm.GasSlab(cells=4, h=0.25, pad=8), jm.SPQ(), dt=1e-6, steps=1, devices=[d, d])


def test_one_device_equals_the_default_run():
    sc = jm.GasSlab(cells=8, h=1 / 8, pad=16)
    a = jm.simulate(sc, jm.CPDI(), dt=5e-6, steps=10)
    b = jm.simulate(sc, jm.CPDI(), dt=5e-6, steps=10, devices=1)
    for k in ("x", "v", "F", "sigma"):
        assert jax.numpy.array_equal(getattr(a.state, k), getattr(b.state, k)), k
