"""Performance: the fast paths compute what the plain ones did, the benchmark's reference codes
(``benchmarks/``) compute the same thing, nothing recompiles across parameter values, and the
``jaxmpm bench`` command keeps its contract. Speed itself is measured by ``jaxmpm bench``, never
here."""

import importlib.util
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from benchmarks import _baselines, bench
from jaxmpm import cli
from jaxmpm import status as st_bits
from jaxmpm._util import contract

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(
    "spec, a, b",
    [
        ("nk,nkd->nd", (7, 4), (7, 4, 3)),
        ("nab,nkb->nka", (7, 3, 3), (7, 4, 3)),
        ("nka,nkb->nab", (7, 4, 2), (7, 4, 2)),
        ("nab,nbc->nac", (7, 3, 3), (7, 3, 3)),
        ("kj,kjd->kd", (2, 2), (2, 2, 1)),
        ("ab,bc->ca", (2, 3), (3, 4)),
    ],
)
def test_contract_is_einsum(spec, a, b):
    rng = np.random.default_rng(0)
    A, B = rng.normal(size=a), rng.normal(size=b)
    got = np.asarray(contract(spec, jnp.asarray(A), jnp.asarray(B)))
    np.testing.assert_allclose(got, np.einsum(spec, A, B), rtol=1e-14, atol=1e-14)


def test_combine_reports_the_first_particle_of_the_lowest_bit():
    n = 6
    left = jnp.zeros(n, dtype=bool).at[4].set(True)
    nonfinite = jnp.zeros(n, dtype=bool).at[jnp.asarray([2, 5])].set(True)
    status, particle = st_bits.combine([(st_bits.LEFT_GRID, left), (st_bits.NONFINITE, nonfinite)])
    assert int(status) == st_bits.LEFT_GRID | st_bits.NONFINITE
    assert int(particle) == 2  # NONFINITE is the lower bit; its first particle
    status, particle = st_bits.combine([(st_bits.CFL, jnp.zeros(n, dtype=bool))])
    assert (int(status), int(particle)) == (0, -1)
    status, particle = jax.jit(lambda m: st_bits.combine([(st_bits.CFL, m)]))(left)
    assert (int(status), int(particle)) == (st_bits.CFL, 4)


def test_gas_sound_speed_from_its_stress_is_its_sound_speed():
    gas = jm.AdiabaticGas(P0=2.0e5, gamma=1.4, p_atm=1.0e5)
    for f in (0.3, 0.9, 1.0, 1.7, 12.0):
        F = jnp.full((1, 1), f)
        direct = float(gas.sound_speed(F, jnp.asarray(1.3)))
        reused = float(gas.sound_speed_from_stress(F, gas.stress(F), jnp.asarray(1.3)))
        assert reused == pytest.approx(direct, rel=1e-14)


def test_reference_codes_agree_in_float64():
    """The hand-written codes run one algorithm; their results agree to round-off, so a fast but
    wrong kernel cannot enter the table. (Warp only where installed, as the optional ``bench`` extra;
    Taichi keeps one float type per process, so ``jaxmpm bench`` checks it, in its own process.)"""
    n, steps = 400, 30
    codes = ["NumPy", "plain JAX"] + (["Warp"] if importlib.util.find_spec("warp") else [])
    results = {code: _baselines.BASELINES[code](n, steps, "f64")[2] for code in codes}
    ref = results["NumPy"]
    assert ref != pytest.approx(1.0, abs=1e-4)  # the body did expand
    for code, value in results.items():
        assert value == pytest.approx(ref, rel=1e-13), code


def test_jaxmpm_runs_the_reference_codes_problem():
    """``jaxmpm spq`` on the benchmark's problem is the NumPy code plus jaxmpm's fold of force off
    nodes without mass, to round-off; the fold is the whole difference from the standard
    algorithm the reference codes time (it acts while the free end enters a new cell)."""
    n, steps = 400, 30
    folded = _baselines.numpy_spq(n, steps, "f64", fold=True)[2]
    standard = _baselines.numpy_spq(n, steps, "f64")[2]
    _, _, mine, status = bench.jaxmpm_simulate("spq", n, steps)
    assert status == 0
    assert mine == pytest.approx(folded, rel=1e-13)
    assert abs(standard - folded) > 1e-6  # so the check above can tell the two apart


def test_no_recompilation_across_parameter_values():
    scene = jm.GasExpansion(cells=16, h=1.0 / 16, pad=8)
    jm.simulate(scene, jm.CPDI(), dt=1e-6, steps=5)
    compiles = []

    def listen(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            compiles.append(event)

    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        for beta, h, dt, P0 in ((100.0, 0.05, 2e-6, 3e5), (50.0, 0.07, 5e-7, 2.5e5)):
            other = jm.GasExpansion(cells=16, h=h, pad=8, beta=beta, P0=P0)
            jm.simulate(other, jm.CPDI(), dt=dt, steps=5)
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)
    assert compiles == []


def test_bench_command_json_and_files(tmp_path, capsys):
    code = cli.main(
        [
            "bench",
            "--sizes",
            "200,400",
            "--steps",
            "5",
            "--dtypes",
            "f64",
            "--codes",
            "numpy,jax,jaxmpm",
            "--interpolators",
            "spq,mpq",
            "--sizes-2d",
            "16,64",
            "--no-extras",
            "--json",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert {"date", "machine", "rows", "copy_bandwidth_GBps", "agreement"} <= set(out)
    codes = {r["code"] for r in out["rows"]}
    assert codes == {
        "NumPy",
        "plain JAX",
        "jaxmpm spq",
        "jaxmpm mpq",
        "jaxmpm spq, one step a call",
        "jaxmpm mpq, one step a call",
        "jaxmpm spq 2D",
        "jaxmpm mpq 2D",
    }
    for r in out["rows"]:
        sizes = (16, 64) if r["code"].endswith("2D") else (200, 400)
        assert r["particles"] in sizes and r["steps"] == 5 and r["dtype"] == "f64"
        assert r["Mpsps"] > 0 and r["run_s"] > 0 and r["status"] == 0
    assert out["agreement"]["f64"]["reference codes"] < 1e-13
    assert out["agreement"]["f64"]["jaxmpm spq vs NumPy with the fold"] < 1e-13
    assert (tmp_path / "bench.csv").read_text().startswith("code,dtype,particles,steps")
    assert "| plain JAX |" in (tmp_path / "bench.md").read_text()


@pytest.mark.parametrize(
    "argv, named",
    [
        (["--codes", "numpy,fortran"], "--codes"),
        (["--dtypes", "f16"], "--dtypes"),
        (["--sizes", "1k"], "--sizes"),
        (["--sizes", "1001"], "--sizes"),
        (["--steps", "1"], "--steps"),
        (["--interpolators", "sph"], "--interpolators"),
        (["--sizes-2d", "50"], "--sizes-2d"),
        (["--sizes-2d", "4x"], "--sizes-2d"),
    ],
)
def test_bench_command_rejects_bad_input(argv, named, capsys):
    assert cli.main(["bench", *argv]) == 2
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1


def test_a_reference_code_that_breaks_down_is_reported(monkeypatch):
    """A reference code has no checks; its breakdown shows as a non-finite F, and NumPy's bincount
    raises on the NaN index. Either way the row says status NONFINITE rather than a speed."""

    def broken(n, steps, dtype, fold=False):
        raise ValueError("'list' argument must have no negative elements")

    monkeypatch.setitem(_baselines.BASELINES, "NumPy", broken)
    monkeypatch.setitem(_baselines.BASELINES, "plain JAX", lambda n, s, d: (0.1, 0.2, float("nan")))
    out = bench.worker("f64", [200], 5, ["numpy", "jax"], [], extras=False)
    assert [(r["code"], r["status"]) for r in out["rows"]] == [
        ("NumPy", st_bits.NONFINITE),
        ("plain JAX", st_bits.NONFINITE),
    ]


def test_reverse_mode_measurement_small():
    rows = bench.reverse_mode(step_counts=(16, 64))
    for r in rows:
        assert r["reverse_s"] > 0 and r["forward_s"] > 0
        assert r["reverse_xla_bytes"] < r["plain_reverse_xla_bytes"]
    # checkpointed memory grows slower than the step count; plain reverse mode grows with it
    grow_ckpt = rows[1]["reverse_xla_bytes"] / rows[0]["reverse_xla_bytes"]
    grow_plain = rows[1]["plain_reverse_xla_bytes"] / rows[0]["plain_reverse_xla_bytes"]
    assert grow_ckpt < 0.6 * grow_plain
