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
from helpers import monitored

import jaxmpm as jm
from benchmarks import _baselines, _baselines_2d, bench
from jaxmpm import cli
from jaxmpm import status as st_bits
from jaxmpm._step import fold_massless
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


@pytest.mark.parametrize("dim, n", [(2, 256), (3, 512)])
def test_reference_codes_nd_agree_with_jaxmpm_in_float64(dim, n):
    """In 2D and 3D the reference codes (NumPy, plain JAX; Taichi and Warp where installed) and
    ``jaxmpm spq`` run one method: their mean final F agree to round-off, and so do the NumPy code's
    two treatments of the traction points' force off the body's nodes (onto the nearest body node,
    and jaxmpm's fold). (Taichi runs one float type per process: this process's is float64.)"""
    steps = 20
    optional = [code for code in ("Taichi", "Warp") if importlib.util.find_spec(code.lower())]
    codes = ["NumPy", "plain JAX"] + optional
    results = {code: _baselines_2d.BASELINES_ND[code](n, steps, "f64", dim)[2] for code in codes}
    folded = _baselines_2d.numpy_spq_nd(n, steps, "f64", dim, fold=True)[2]
    _, _, mine, status = bench.jaxmpm_simulate("spq", n, steps, dim=dim)
    ref = results["NumPy"]
    assert status == 0
    assert abs(ref - 1.0 / dim) > 1e-4  # the mean of F = f I is f / dim: the body did expand
    for code, value in results.items():
        assert value == pytest.approx(ref, rel=1e-13), code
    assert folded == pytest.approx(ref, rel=1e-13)
    assert mine == pytest.approx(folded, rel=1e-13)


@pytest.mark.parametrize("dim", [2, 3])
def test_fold_port_is_jaxmpms_fold(dim):
    """``fold_massless_nd`` (NumPy) moves force off empty nodes exactly as jaxmpm's step does, on
    random masks (diagonal-only neighbours included), and on the box of nodes a body of cells fills
    it equals clamping each node into the box, which the reference codes do."""
    rng = np.random.default_rng(dim)
    axes = (7,) * dim
    f = rng.normal(size=(7**dim, dim))
    for density in (0.2, 0.5):
        mask = rng.random(7**dim) < density
        mine = _baselines_2d.fold_massless_nd(f, mask, axes)
        theirs = np.asarray(fold_massless(jnp.asarray(f), jnp.asarray(mask), axes))
        np.testing.assert_allclose(mine, theirs, rtol=1e-14, atol=1e-14)
        assert not np.allclose(mine, f)  # force did move
    lo, hi = 2, 4  # the body's nodes: 2..4 along each axis
    idx = _baselines_2d._lattice(axes)
    box = ((idx >= lo) & (idx <= hi)).all(1)
    ring = ((idx >= lo - 1) & (idx <= hi + 1)).all(1)  # force within one node of the box
    g = np.where(ring[:, None], f, 0.0)
    clamped = np.zeros_like(g)
    to = np.ravel_multi_index(tuple(np.clip(idx, lo, hi).T), axes)
    np.add.at(clamped, to, g)
    np.testing.assert_allclose(_baselines_2d.fold_massless_nd(g, box, axes), clamped, rtol=1e-13, atol=1e-13)


def test_layout_nd_and_cells_of():
    assert _baselines_2d.cells_of(102_400, 2) == 160
    assert _baselines_2d.cells_of(110_592, 3) == 24
    assert _baselines_2d.cells_of(100, 2) == 5
    assert _baselines_2d.cells_of(50, 2) is None
    assert _baselines_2d.cells_of(100, 3) is None
    L = _baselines_2d.layout_nd(256, 2)
    assert (L["cells"], L["axis_nodes"], L["nodes"]) == (8, 17, 17**2)
    X = _baselines_2d.initial_particles(L, np.float64)
    scene, dt = bench._scene(256, 2)
    body = scene.body()
    np.testing.assert_array_equal(X, np.asarray(body.X))
    assert (scene.cells, float(scene.h), float(scene.beta), dt) == (8, L["h"], 5.0, L["dt"])
    with pytest.raises(ValueError, match="not \\(2 k\\)"):
        _baselines_2d.layout_nd(50, 2)


def test_no_recompilation_across_parameter_values():
    scene = jm.GasExpansion(cells=16, h=1.0 / 16, pad=8)
    jm.simulate(scene, jm.CPDI(), dt=1e-6, steps=5)
    with monitored() as compiles:
        for beta, h, dt, P0 in ((100.0, 0.05, 2e-6, 3e5), (50.0, 0.07, 5e-7, 2.5e5)):
            other = jm.GasExpansion(cells=16, h=h, pad=8, beta=beta, P0=P0)
            jm.simulate(other, jm.CPDI(), dt=dt, steps=5)
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
        "NumPy 2D",
        "plain JAX 2D",
        "jaxmpm spq 2D",
        "jaxmpm mpq 2D",
    }
    for r in out["rows"]:
        sizes = (16, 64) if r["code"].endswith("2D") else (200, 400)
        assert r["dim"] == (2 if r["code"].endswith("2D") else 1)
        assert r["particles"] in sizes and r["steps"] == 5 and r["dtype"] == "f64"
        assert r["Mpsps"] > 0 and r["run_s"] > 0 and r["status"] == 0
        assert r["compile_s"] > 0 or r["code"].startswith("NumPy")
    assert out["agreement"]["f64"]["reference codes"] < 1e-13
    assert out["agreement"]["f64"]["jaxmpm spq vs NumPy with the fold"] < 1e-13
    assert out["agreement"]["f64"]["reference codes 2D"] < 1e-13
    assert out["agreement"]["f64"]["jaxmpm spq 2D vs NumPy 2D with the fold"] < 1e-13
    assert {(q["dim"], q["particles"]) for q in out["numpy_with_fold"]} == {
        (1, 200),
        (1, 400),
        (2, 16),
        (2, 64),
    }
    assert (tmp_path / "bench.csv").read_text().startswith("code,dtype,particles,steps")
    md = (tmp_path / "bench.md").read_text()
    assert "| plain JAX |" in md and "| plain JAX 2D |" in md and "f64, 2D: million" in md


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
        (["--sizes-3d", "100"], "--sizes-3d"),
        (["--sizes-3d", "64,8y"], "--sizes-3d"),
        (["--codes", "numpy,taichi2d"], "--codes"),
    ],
)
def test_bench_command_rejects_bad_input(argv, named, capsys):
    assert cli.main(["bench", *argv]) == 2
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1


def test_bench_out_is_checked_before_the_benchmark_runs(monkeypatch, capsys, tmp_path):
    ran = []
    monkeypatch.setattr(bench, "run", lambda *a, **k: ran.append(1))
    a_file = tmp_path / "a_file"
    a_file.write_text("mine")
    assert cli.main(["bench", "--sizes", "200", "--no-extras", "--out", str(a_file)]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "is a file, not a folder" in err and err.count("\n") == 1
    assert ran == [] and a_file.read_text() == "mine"


def test_bench_command_passes_codes_and_sizes_of_every_dim(monkeypatch, capsys):
    """``--codes`` names the codes for every dimension; ``--sizes-2d`` and ``--sizes-3d`` reach the
    benchmark as particle counts (the run itself replaced by a recorder)."""
    seen = {}

    def record(sizes, steps, dtypes, codes, interpolators, extras, sizes_2d, sizes_3d, rounds):
        seen.update(sizes=sizes, codes=codes, sizes_2d=sizes_2d, sizes_3d=sizes_3d, extras=extras)
        seen["rounds"] = rounds
        return dict(date="now", machine="here", versions={}, rows=[], agreement={})

    monkeypatch.setattr(bench, "run", record)
    argv = ["bench", "--sizes", "200", "--codes", "warp,numpy,jaxmpm", "--sizes-3d", "64,512", "--no-extras"]
    assert cli.main(argv) == 0
    assert seen.pop("rounds") == 1
    assert seen == dict(
        sizes=[200],
        codes=["warp", "numpy", "jaxmpm"],
        sizes_2d=[16384, 102400],
        sizes_3d=[64, 512],
        extras=False,
    )
    assert cli.main(["bench", "--sizes", "200", "--sizes-2d", "", "--no-extras", "--rounds", "3"]) == 0
    assert seen["codes"] == list(bench.CODES) and seen["sizes_2d"] == [] and seen["sizes_3d"] == []
    assert seen["rounds"] == 3
    capsys.readouterr()


def test_worker_runs_the_3d_codes_and_keeps_dims_apart():
    """The worker's 3D rows are the reference codes and jaxmpm in 3D, each with ``dim`` 3, and the
    agreement is reported per dimension (a 1D and a 3D run of the same particle count stay apart)."""
    out = bench.worker("f64", [64], 3, ["numpy", "jax", "jaxmpm"], ["spq"], extras=False, sizes_3d=[64])
    rows = {(r["code"], r["dim"]) for r in out["rows"]}
    assert {
        ("NumPy 3D", 3),
        ("plain JAX 3D", 3),
        ("jaxmpm spq 3D", 3),
        ("NumPy", 1),
        ("jaxmpm spq", 1),
    } <= rows
    assert all(r["status"] == 0 and r["particles"] == 64 for r in out["rows"])
    agree = bench.agreement(out["rows"], out["numpy_with_fold"])["f64"]
    assert set(agree) == {
        "reference codes",
        "jaxmpm spq vs NumPy with the fold",
        "reference codes 3D",
        "jaxmpm spq 3D vs NumPy 3D with the fold",
    }
    assert max(agree.values()) < 1e-13


def test_table_has_a_ratio_row_per_dimension():
    def row(code, dim, Mpsps, n=1024):
        return dict(
            code=code,
            dtype="f32",
            particles=n,
            steps=10,
            compile_s=0.5,
            run_s=1.0,
            Mpsps=Mpsps,
            F_mean=0.5,
            status=0,
            dim=dim,
        )

    result = dict(
        date="now",
        machine="here",
        versions={},
        copy_bandwidth_GBps=10.0,
        rows=[
            row("Taichi", 1, 10.0, 1000),
            row("jaxmpm spq", 1, 5.0, 1000),
            row("Taichi 2D", 2, 4.0),
            row("Warp 2D", 2, 8.0),
            row("jaxmpm spq 2D", 2, 6.0),
            row("jaxmpm mpq 2D", 2, 2.0),
        ],
        agreement={"f32": {"reference codes 2D": 1e-7}},
    )
    text = bench.table(result)
    one, two = text.split("f32, 2D: million particle-steps per second")
    assert "| jaxmpm spq / faster of Taichi, Warp | 0.50 |" in one
    assert "| jaxmpm spq / faster of Taichi, Warp | 0.75 |" in two  # 6 / max(4, 8)
    assert "| jaxmpm mpq 2D | 2.0 (0.50) |" in two and "Warp 2D" not in one
    assert "reference codes 2D 1.0e-07" in text


def test_table_says_why_nothing_was_compared():
    """An empty agreement names its reason: without the NumPy code there is no reference (not a
    breakdown); with it, no healthy pair of runs."""
    result = dict(
        date="now",
        machine="here",
        versions={},
        copy_bandwidth_GBps=10.0,
        rows=[_row("Warp", 0.01), _row("jaxmpm spq", 0.01)],
        agreement={"f32": {}},
    )
    text = bench.table(result)
    assert "f32: nothing compared (the NumPy code, the reference, was not among --codes)" in text
    assert "healthy" not in text
    broken = dict(_row("NumPy", float("nan")), status=3)
    text = bench.table(dict(result, rows=[*result["rows"], broken]))
    assert "f32: no healthy runs to compare" in text


def _row(code, run_s, n=1000, dim=1, steps=10):
    return dict(
        code=code,
        dtype="f32",
        particles=n,
        steps=steps,
        compile_s=0.5,
        run_s=run_s,
        Mpsps=n * steps / run_s / 1e6,
        F_mean=0.5,
        status=0,
        dim=dim,
    )


def test_best_of_keeps_each_codes_fastest_round():
    nan = float("nan")
    rounds = [
        [_row("Warp", 0.010), _row("jaxmpm spq", 0.020), _row("NumPy", nan), _row("Warp 2D", 0.4, dim=2)],
        [_row("Warp", 0.008), _row("jaxmpm spq", 0.025), _row("NumPy", 0.5), _row("Warp 2D", 0.5, dim=2)],
        [_row("Warp", 0.012), _row("jaxmpm spq", 0.005), _row("NumPy", nan), _row("Warp 2D", 0.2, dim=2)],
    ]
    best = bench.best_of(rounds)
    assert [r["code"] for r in best] == ["Warp", "jaxmpm spq", "NumPy", "Warp 2D"]
    assert [r["run_s"] for r in best] == [0.008, 0.005, 0.5, 0.2]
    assert all(r["rounds"] == 3 for r in best)
    assert best[0]["Mpsps_rounds"] == [1.0, 1.25, 1000 * 10 / 0.012 / 1e6]
    assert best[0]["Mpsps"] == 1.25 and best[1]["Mpsps"] == 2.0
    # every round broke down: the first round's row, its run time not finite
    assert np.isnan(bench.best_of([[_row("NumPy", nan)], [_row("NumPy", nan)]])[0]["run_s"])
    # one round: the row itself
    assert bench.best_of([[_row("Warp", 0.01)]]) == [dict(_row("Warp", 0.01), rounds=1, Mpsps_rounds=[1.0])]


def test_table_of_several_rounds_shows_the_spread_of_the_ratio():
    rounds = [
        [_row("Taichi", 0.02), _row("Warp", 0.01), _row("jaxmpm spq", 0.02)],  # 0.5
        [_row("Taichi", 0.02), _row("Warp", 0.02), _row("jaxmpm spq", 0.01)],  # 2.0
    ]
    result = dict(
        date="now",
        machine="here",
        versions={},
        copy_bandwidth_GBps=10.0,
        rounds=2,
        rows=bench.best_of(rounds),
        agreement={},
    )
    text = bench.table(result)
    assert "Each code's fastest of 2 rounds" in text
    assert "| jaxmpm spq / faster of Taichi, Warp | 1.00 |" in text  # 1.0 / max(0.5, 1.0)
    assert "| the same, round by round (lowest-highest) | 0.50-2.00 |" in text
    one = dict(result, rounds=1, rows=bench.best_of(rounds[:1]))
    assert "round by round" not in bench.table(one) and "rounds" not in bench.table(one).splitlines()[0]


def test_a_run_of_two_rounds_keeps_both(tmp_path):
    """Two real rounds of a tiny benchmark (two processes): every row is the best of both, and
    ``bench.csv`` has the ``rounds`` column."""
    result = bench.run([100], 2, ["f64"], ["numpy", "jax"], [], extras=False, rounds=2)
    assert result["rounds"] == 2
    assert [r["code"] for r in result["rows"]] == ["NumPy", "plain JAX"]
    for r in result["rows"]:
        assert r["rounds"] == 2 and len(r["Mpsps_rounds"]) == 2 and r["Mpsps"] == max(r["Mpsps_rounds"])
    bench.write(result, tmp_path)
    csv_rows = (tmp_path / "bench.csv").read_text().splitlines()
    assert csv_rows[0].endswith(",dim,rounds") and all(line.endswith(",1,2") for line in csv_rows[1:])
    assert "Each code's fastest of 2 rounds" in (tmp_path / "bench.md").read_text()
    with pytest.raises(ValueError, match="rounds must be an integer >= 1, got 0"):
        bench.run([100], 2, ["f64"], ["numpy"], [], extras=False, rounds=0)


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


def test_the_sharded_benchmark_records_the_command_that_wrote_its_files(monkeypatch, tmp_path):
    """``python -m benchmarks.sharded --out DIR`` records itself with its ``--out`` (the command that
    remakes the files), in ``sharded.json`` and above the table in ``sharded.md``."""
    import subprocess

    from benchmarks import sharded

    def timing_process(cmd, **kwargs):  # the timing process's rows, without running it
        return subprocess.CompletedProcess(cmd, 0, stdout="[]\n", stderr="")

    monkeypatch.setattr(sharded.subprocess, "run", timing_process)
    out = tmp_path / "scale"
    assert sharded.main(["--devices", "2", "--out", str(out)]) == 0
    command = f"python -m benchmarks.sharded --devices 2 --repeats 2 --out {out}"
    assert json.loads((out / "sharded.json").read_text())["command"] == command
    assert f"`{command}`" in (out / "sharded.md").read_text()
    assert sharded.run(2, 1)["command"] == "python -m benchmarks.sharded --devices 2 --repeats 1"


def test_the_gap_between_jaxmpm_and_the_timed_method_is_reported_not_judged():
    """The timed reference codes leave out jaxmpm's fold of force off nodes without mass (1D: dropped;
    2D and 3D: put on the body's box of nodes), so once a free end enters a new cell ``jaxmpm spq``
    computes a slightly different method from the rows it is timed beside. The benchmark reports that
    gap (``method_gap``, its own line) and does not count it as a disagreement."""
    rows = [
        dict(code="NumPy", dtype="f64", dim=1, particles=1000, F_mean=1.0, status=0),
        dict(code="jaxmpm spq", dtype="f64", dim=1, particles=1000, F_mean=1.0 + 6.3e-4, status=0),
        dict(code="NumPy 2D", dtype="f64", dim=2, particles=1024, F_mean=0.5, status=0),
        dict(code="jaxmpm spq 2D", dtype="f64", dim=2, particles=1024, F_mean=0.5, status=0),
        dict(code="NumPy", dtype="f64", dim=1, particles=8000, F_mean=1.0, status=0),
        dict(code="jaxmpm spq", dtype="f64", dim=1, particles=8000, F_mean=2.0, status=3),  # broke down
    ]
    gap = bench.method_gap(rows)
    assert gap == {"f64": {"1D": pytest.approx(6.3e-4, rel=1e-6), "2D": 0.0}}
    result = dict(rows=rows, agreement={"f64": {"reference codes": 0.0}}, method_gap=gap)
    lines = "\n".join(bench._agreement_lines(result))
    assert "jaxmpm spq against the NumPy code it is timed beside" in lines
    assert "f64: 1D 6.3e-04, 2D 0.0e+00" in lines
    assert "disagree" not in lines
