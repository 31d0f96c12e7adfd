"""Two local processes (a coordinator on localhost, 2 forced host devices each, Gloo collectives on
CPU) run one sharded simulation over their 4 devices, an ensemble, a breakdown, a chunked run saved
and resumed, and a calibration's starts: the results equal one process's."""

import json
import os
import pathlib
import signal
import socket
import subprocess
import sys
import textwrap
import time

import jax
import numpy as np
import pytest
from helpers import calibration_case

import jaxmpm as jm

pytestmark = pytest.mark.slow

WORKER = textwrap.dedent(
    """
    import json, sys
    import jax
    process, port = int(sys.argv[1]), sys.argv[2]
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=f"localhost:{port}", num_processes=2, process_id=process)
    jax.config.update("jax_enable_x64", True)
    import numpy as np, jaxmpm as jm
    from jax.experimental import multihost_utils

    out = dict(process=jax.process_index(), processes=jax.process_count(), devices=len(jax.devices()),
               local=len(jax.local_devices()))
    slab = jm.GasSlab(cells=30, h=1 / 30, pad=60)
    sol = jm.simulate(slab, jm.MPQ(), dt=5e-6, steps=20, devices=jax.devices())
    out["own_particles"] = sum(s.data.shape[0] for s in sol.state.x.addressable_shards)
    out["x"] = np.asarray(multihost_utils.process_allgather(sol.state.x, tiled=True)).ravel().tolist()
    out["F"] = np.asarray(multihost_utils.process_allgather(sol.state.F, tiled=True)).ravel().tolist()
    out["status"] = int(sol.state.status)
    vary = {"gamma": np.linspace(1.2, 1.8, 6), "P0": np.linspace(2e5, 4e5, 6)}
    vary["P0"][4] = 5e7  # breaks down
    ens = jm.ensemble(slab, jm.CPDI(), vary, dt=2e-5, steps=50, devices=jax.devices())
    out["ens_devices"] = ens.devices
    out["ens_status"] = ens.status.tolist()
    out["ens_failures"] = [(f["member"], f["step"], f["particle"]) for f in ens.failures()]
    gather = lambda a: np.asarray(multihost_utils.process_allgather(a, tiled=True))
    out["ens_x"] = gather(ens.solution.state.x).ravel().tolist()
    # a breakdown of a run over both processes: the same message on each
    try:
        jm.simulate(slab, jm.SPQ(), dt=3e-4, steps=50, devices=jax.devices())
    except jm.SimulationError as e:
        out["error"] = str(e)
    # a chunked run over both processes, saved by the first and resumed: bit for bit
    from jaxmpm import long_run
    path = f"{sys.argv[3]}/run.npz"
    kw = dict(dt=5e-6, steps=30, chunk=4, progress=False, devices=jax.devices())
    full = long_run.run(slab, jm.MPQ(), **kw)
    long_run.run(slab, jm.MPQ(), out=path, checkpoint_every=2, **(kw | dict(steps=14)))
    if process == 0:  # extend the saved run's target, as a user continuing it would
        with np.load(path) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(str(arrays["meta"]))
        meta["steps"] = 30
        arrays["meta"] = np.asarray(json.dumps(meta))
        np.savez(path, **arrays)
    multihost_utils.sync_global_devices("extended")
    res = long_run.resume(path, progress=False)
    out["resume_identical"] = all(
        np.array_equal(multihost_utils.process_allgather(getattr(res.state, k), tiled=True),
                       multihost_utils.process_allgather(getattr(full.state, k), tiled=True))
        for k in ("x", "v", "F", "sigma", "corners"))
    out["resume_x"] = np.asarray(multihost_utils.process_allgather(res.state.x, tiled=True)).ravel().tolist()
    # 31 particles, which the 4 devices do not divide: padded, run over both, saved by the first
    odd = jm.GasSlab(cells=31, h=1 / 31, ppc=1, pad=40)
    sol = jm.simulate(odd, jm.CPDI(), dt=5e-6, steps=20, devices=jax.devices())
    out["odd_x"] = np.asarray(multihost_utils.process_allgather(sol.state.x, tiled=True)).ravel().tolist()
    long_run.run(odd, jm.CPDI(), out=f"{sys.argv[3]}/odd.npz", dt=5e-6, steps=8, chunk=4, progress=False,
                 devices=jax.devices())
    # a calibration's starts spread over both processes' devices (one start each)
    sys.path.insert(0, sys.argv[4])  # the tests' helpers
    from helpers import calibration_case
    model, t, data, starts, dt = calibration_case()
    fit = jm.calibrate.calibrate(model, jm.CPDI(), t, data, starts=starts, dt=dt, progress=False,
                                 devices=jax.devices())
    out["fit"] = dict(fitted=fit.fitted, starts={k: v.tolist() for k, v in fit.starts_fitted.items()},
                      failed=sorted(fit.failed_starts), iterations=fit.iterations, std=fit.std)
    print(json.dumps(out))
    """
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def _two_processes(command):
    """Run ``command(0)`` and ``command(1)`` together, 2 forced host devices each; no progress bars.

    Returns:
        The processes and their ``(stdout, stderr)``; a process still running at the end is killed.
    """
    flags = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2"
    env = dict(os.environ, XLA_FLAGS=flags.strip(), JAXMPM_PROGRESS="0")
    procs = [
        subprocess.Popen(command(i), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for i in range(2)
    ]
    try:
        outs = [p.communicate(timeout=600) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.communicate()
    return procs, outs


def _cli_over_two_processes(argv):
    """Run ``jaxmpm argv`` as two processes joined by ``--coordinator --processes --process-id`` (what
    ``--distributed`` reads from SLURM): both exit 0 and the second prints nothing.

    Returns:
        The first process's stdout (the report).
    """
    port = str(_free_port())
    procs, outs = _two_processes(
        lambda i: (
            [sys.executable, "-m", "jaxmpm.cli", *argv]
            + ["--coordinator", f"localhost:{port}", "--processes", "2", "--process-id", str(i)]
        )
    )
    assert [p.returncode for p in procs] == [0, 0], outs[0][1][-2000:] + outs[1][1][-2000:]
    assert outs[1] == ("", "")  # the second process says nothing
    return outs[0][0]


def test_two_processes_equal_one(tmp_path):
    script = tmp_path / "worker.py"
    script.write_text(WORKER)
    port = str(_free_port())
    tests = str(pathlib.Path(__file__).parent)
    procs, outs = _two_processes(lambda i: [sys.executable, str(script), str(i), port, str(tmp_path), tests])
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    a, b = (json.loads(out.strip().splitlines()[-1]) for out, _ in outs)
    assert (a["process"], b["process"]) == (0, 1)
    assert a["processes"] == 2 and a["devices"] == 4 and a["local"] == 2
    assert a["own_particles"] == b["own_particles"] == 30  # each process computes its half of 60
    # One process, one device, the same runs
    slab = jm.GasSlab(cells=30, h=1 / 30, pad=60)
    one = jm.simulate(slab, jm.MPQ(), dt=5e-6, steps=20)
    for key in ("x", "F"):
        assert a[key] == b[key]  # both processes gathered the same global state
        ref = np.asarray(getattr(one.state, key)).ravel()
        # the grid sums in another order: round-off (measured 1e-16 of the largest value)
        assert np.max(np.abs(np.asarray(a[key]) - ref)) <= 1e-13 * np.max(np.abs(ref)), key
    assert a["status"] == b["status"] == 0
    vary = {"gamma": np.linspace(1.2, 1.8, 6), "P0": np.linspace(2e5, 4e5, 6)}
    vary["P0"][4] = 5e7
    ens = jm.ensemble(slab, jm.CPDI(), vary, dt=2e-5, steps=50, devices=jax.devices()[:1])
    assert a["ens_devices"] == 4
    assert a["ens_status"] == b["ens_status"] == ens.status.tolist() and ens.status[4] != 0
    assert (
        a["ens_failures"]
        == b["ens_failures"]
        == [[f["member"], f["step"], f["particle"]] for f in ens.failures()]
    )
    # members are independent: each computed exactly as in one process
    assert a["ens_x"] == np.asarray(ens.solution.state.x).ravel().tolist()
    with pytest.raises(jm.SimulationError) as e:
        jm.simulate(slab, jm.SPQ(), dt=3e-4, steps=50)
    assert a["error"] == b["error"] == str(e.value)
    assert a["resume_identical"] and b["resume_identical"]
    x = np.asarray(jm.simulate(slab, jm.MPQ(), dt=5e-6, steps=30).state.x).ravel()
    assert np.max(np.abs(np.asarray(a["resume_x"]) - x)) <= 1e-13 * np.max(np.abs(x))
    odd = jm.GasSlab(cells=31, h=1 / 31, ppc=1, pad=40)
    x = np.asarray(jm.simulate(odd, jm.CPDI(), dt=5e-6, steps=20).state.x).ravel()
    assert a["odd_x"] == b["odd_x"] and len(x) == 31
    assert np.max(np.abs(np.asarray(a["odd_x"]) - x)) <= 1e-13 * np.max(np.abs(x))
    saved, meta = jm.long_run.load(tmp_path / "odd.npz")
    x = np.asarray(jm.simulate(odd, jm.CPDI(), dt=5e-6, steps=8).state.x)
    assert meta["devices"] == 4 and meta["step"] == 8 and saved.state.x.shape == (31, 1)
    assert np.max(np.abs(np.asarray(saved.state.x) - x)) <= 1e-13 * np.max(np.abs(x))
    # the calibration: every process has every start's fit; each start as fitted in one process (the
    # batch of one start per device is compiled apart from the batch of four: round-off, measured 1e-15)
    model, t, data, starts, dt = calibration_case()
    fit = jm.calibrate.calibrate(model, jm.CPDI(), t, data, starts=starts, dt=dt, progress=False)
    assert a["fit"] == b["fit"]
    assert a["fit"]["failed"] == sorted(fit.failed_starts) == [3]  # the start that breaks down
    assert a["fit"]["iterations"] == fit.iterations
    for k, v in fit.fitted.items():
        assert a["fit"]["fitted"][k] == pytest.approx(v, rel=1e-12)
        assert a["fit"]["std"][k] == pytest.approx(fit.std[k], rel=1e-9)
        np.testing.assert_allclose(a["fit"]["starts"][k], fit.starts_fitted[k], rtol=1e-12)


def test_command_line_run_over_two_processes(tmp_path, capsys):
    """``jaxmpm run ... --coordinator --processes --process-id`` (what ``--distributed`` reads from
    SLURM): the first process reports the run over all 4 devices and saves it; the other prints
    nothing; the report equals one process's to round-off."""
    from jaxmpm.cli import main

    run = ["run", "gas-slab", "cells=30", "h=0.0333333333", "pad=60", "--interpolator", "cpdi"]
    run += ["--dt", "5e-6", "--steps", "20", "--json"]
    many = json.loads(_cli_over_two_processes([*run, "--out", str(tmp_path / "run.npz"), "--chunk", "8"]))
    assert main(run) == 0
    one = json.loads(capsys.readouterr().out)
    assert many["devices"] == 4 and "devices" not in one and many["out"] == str(tmp_path / "run.npz")
    assert many["status"] == one["status"] == 0
    for key in ("x", "F"):
        a, b = np.asarray(many["particles"][key]), np.asarray(one["particles"][key])
        assert np.max(np.abs(a - b)) <= 1e-13 * np.max(np.abs(b)), key
    _, meta = jm.long_run.load(tmp_path / "run.npz")
    assert meta["devices"] == 4 and meta["complete"] and meta["step"] == 20


def test_command_line_calibration_over_two_processes(tmp_path, capsys):
    """``jaxmpm calibrate`` with four starts over two processes' four devices: the first process reports
    the fit, the second nothing; the fit equals one process's to round-off, the start that breaks
    down included."""
    from jaxmpm.cli import main

    _, t, data, starts, dt = calibration_case()
    path = tmp_path / "traj.csv"
    np.savetxt(path, np.c_[t, data], delimiter=",", header="t,x_free", comments="")
    cmd = ["calibrate", "gas-slab", "cells=16", "h=0.0625", "pad=96", "--data", str(path), "--dt", repr(dt)]
    for s in starts:
        cmd += ["--start", ",".join(f"{k}={v!r}" for k, v in s.items())]
    cmd += ["--json", "--no-progress"]
    many = json.loads(_cli_over_two_processes(cmd))
    assert main(cmd) == 0
    one = json.loads(capsys.readouterr().out)
    assert list(many["failed_starts"]) == list(one["failed_starts"]) == ["3"]
    assert many["best_start"] == one["best_start"] and many["iterations"] == one["iterations"]
    assert many["starts_fitted"][3] is one["starts_fitted"][3] is None
    for i in range(3):
        for k, v in one["starts_fitted"][i].items():
            assert many["starts_fitted"][i][k] == pytest.approx(v, rel=1e-12)
    for k, v in one["std"].items():
        assert many["std"][k] == pytest.approx(v, rel=1e-9)


def test_ctrl_c_in_one_process_stops_both_after_the_same_chunk(tmp_path):
    """A run over two processes' devices: Ctrl-C (SIGINT) to the second process alone. Its chunks'
    collectives need both, so the processes agree after each chunk: both stop after the same one, the
    first saves it and reports the step, and neither is left waiting for the other."""
    port = str(_free_port())
    path = tmp_path / "run.npz"
    run = ["run", "gas-expansion", "pad=4000", "beta=1", "--interpolator", "cpdi", "--dt", "1e-7"]
    run += ["--steps", "1000000000", "--out", str(path), "--chunk", "200", "--checkpoint-every", "1"]
    flags = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2"
    env = dict(os.environ, XLA_FLAGS=flags.strip(), JAXMPM_PROGRESS="0")
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "jaxmpm.cli", *run]
            + ["--coordinator", f"localhost:{port}", "--processes", "2", "--process-id", str(i)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for i in range(2)
    ]
    try:
        deadline = time.monotonic() + 120
        while not path.exists():  # past start-up and compilation: the first chunk is saved
            assert time.monotonic() < deadline and all(p.poll() is None for p in procs), [
                p.communicate() for p in procs if p.poll() is not None
            ]
            time.sleep(0.2)
        procs[1].send_signal(signal.SIGINT)
        outs = [p.communicate(timeout=60) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.communicate()
    assert [p.returncode for p in procs] == [130, 130], outs
    assert outs[1] == ("", "")  # the second process says nothing
    line = outs[0][1].strip().splitlines()[-1]
    assert line.startswith("jaxmpm: interrupted at step ") and f"saved in {path}" in line, outs[0][1]
    step = int(line.split("interrupted at step ")[1].split()[0])
    _, meta = jm.long_run.load(path)
    assert meta["step"] == step and step % 200 == 0 and step >= 200 and meta["devices"] == 4
