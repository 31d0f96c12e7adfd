"""Throughput of the step: ``jaxmpm bench`` (from a source checkout) and ``experiments/bench.py``.

Million particle-steps per second of a whole ``simulate`` for each interpolator and of one jitted
``step`` called from Python, at 1k to 1M particles, in float32 and float64, compile time measured
apart, next to the same algorithm written directly in NumPy and plain JAX, and, when the packages
are installed (``pip install jaxmpm[bench]``), as Taichi and Warp kernels (``benchmarks._baselines``).
The same in 2D and 3D (``sizes_2d``, ``sizes_3d``): jaxmpm's interpolators on the gas expansion on a
square (cube), beside the same four reference codes of SPQ in 2D and 3D (``benchmarks._baselines_2d``,
whose ``PROBLEM_ND`` says why the 2D/3D problem has ``beta = 5 /s``). Every row carries its ``dim``.
Also the reverse-mode cost (``jax.grad`` through the checkpointed loop: time against the forward
run, XLA's buffer bytes against the step count) and ensemble throughput per member.

Each float type runs in its own process (``python -m benchmarks.bench --worker JSON``), which
switches x64 on or off at its start, never mid-run; everything in one invocation runs on the same
machine, so compare ratios. The problem is ``GasExpansion`` (``beta = 200 /s``, ``P0 = 2e5 Pa``,
two particles per cell on [0, 1], ``dt = 0.2 h / (c0 + beta)``) with FLIP and USL; jaxmpm runs with
all its checks on (CFL, F > 0, finite state, grid bounds).

Importing this module changes no JAX configuration; ``worker`` (the body of a benchmark process)
does.
"""

from __future__ import annotations

import csv
import datetime
import errno
import io
import json
import math
import os
import pathlib
import secrets
import signal
import subprocess
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxmpm as jm
from jaxmpm._json import dumps
from jaxmpm.status import NONFINITE
from jaxmpm.studies import machine

from ._baselines import BASELINES, PROBLEM, layout
from ._baselines_2d import (
    BASELINES_ND,
    PROBLEM_ND,
    cells_of,  # noqa: F401  (the command line checks --sizes-2d/3d with it)
    integer_root,
    layout_nd,
)

ROOT = pathlib.Path(__file__).resolve().parents[1]
"""The source checkout: ``benchmarks/`` and ``jaxmpm/`` beside each other."""

SIZES = (1_000, 8_000, 64_000, 256_000, 1_000_000)
CODES = ("numpy", "jax", "taichi", "warp", "jaxmpm")
_BASELINE_CODE = {"numpy": "NumPy", "jax": "plain JAX", "taichi": "Taichi", "warp": "Warp"}
PASSES = 4  # passes over the particle state (x, v, F) a step must make; see ``bandwidth_bound``

FILES = ("bench.csv", "bench.json", "bench.md")
"""What ``write`` writes into its folder."""

ROW_FIELDS = (
    "code",
    "dtype",
    "particles",
    "steps",
    "compile_s",
    "run_s",
    "Mpsps",
    "F_mean",
    "status",
    "dim",
    "rounds",
)
"""The keys of a row of ``rows``, in order: the columns of ``bench.csv``. A row of ``run`` also has
``Mpsps_rounds``, the throughput of each of its rounds (``best_of``), in ``bench.json`` only."""

MAX_STEPS = 2**31 - 1
"""The most steps a run takes: jaxmpm's step counter is a 32-bit integer."""

BYTES_PER_PARTICLE = {
    "numpy": {1: 160, 2: 940, 3: 2200},
    "jax": {1: 150, 2: 470, 3: 1250},
    "spq": {1: 400, 2: 1040, 3: 2400},
    "gimp": {1: 460, 2: 1560, 3: 6400},
    "cpgimp": {1: 470, 2: 1540, 3: 6400},
    "cpdi": {1: 490, 2: 2060, 3: 8200},
    "mpq": {1: 440, 2: 1510, 3: 3000},
    "cpdi2": {1: 520, 2: 1950, 3: 6100},
}
"""Peak memory of one run per particle in float64, bytes, by dimension: the NumPy and plain JAX
codes (``numpy``, ``jax``) and jaxmpm's interpolators (``simulate``; one step a call takes as much as
``spq``). The peak resident memory of a run on a CPU at 2M (1D), 1M (2D) and 512k (3D) particles,
less that of the process before it, rounded up by 10%; at two to four times as many particles a
particle takes less. Taichi and Warp hold the state and grid of the NumPy code without its
temporaries: counted as ``numpy``. Float32 takes less."""

PROCESS_BYTES = 300_000_000
"""Memory of a benchmark process before its first run (Python, NumPy and JAX imported): 270 MB
measured, rounded up."""


def steps_for(n: int, steps: int) -> int:
    """The steps of a run of ``n`` particles: a quarter from 500k particles up (at least 10), so that
    a NumPy run stays within seconds.

    Args:
        n: particles.
        steps: the steps asked for.

    Returns:
        The steps to run.
    """
    return steps if n < 500_000 else max(10, steps // 4)


def reach_cells(steps: int) -> float:
    """How far, in cells, the exact solution carries the 1D body's ends in ``steps`` steps: ``beta t``
    at ``t = steps dt``, ``dt = 0.2 h / (c0 + beta)`` (``layout``), whatever the size.

    Args:
        steps: the steps run.

    Returns:
        Cells.
    """
    c0 = math.sqrt(PROBLEM["gamma"] * PROBLEM["P0"] / PROBLEM["rho0"])
    return PROBLEM["beta"] * 0.2 * steps / (c0 + PROBLEM["beta"])


def stays_on_grid(n: int, steps: int) -> bool:
    """Whether the exact solution keeps the 1D body of ``n`` particles on its grid (``layout``'s
    ``pad`` cells beyond each end) for the steps a run of ``steps`` takes (``steps_for``). Where it
    does not, every code breaks down (a particle off the grid) and the run measures nothing.

    Args:
        n: particles (even).
        steps: the steps asked for.

    Returns:
        ``True`` when the body's ends stay short of the grid's last nodes.
    """
    return reach_cells(steps_for(n, steps)) < n // 2 // 8 + 4  # layout's pad, in integers (any n)


def smallest_size(steps: int) -> int:
    """The fewest particles (even) whose body stays on its grid for ``steps`` steps (``stays_on_grid``).

    Args:
        steps: the steps asked for.

    Returns:
        Particles.
    """
    need = math.floor(reach_cells(steps)) + 1  # pad = cells // 8 + 4 must reach this
    n = 2 * max(1, 8 * (need - 4))
    if n >= 500_000:  # a quarter of the steps from there on (steps_for)
        n = max(500_000, 2 * max(1, 8 * (math.floor(reach_cells(steps_for(500_000, steps))) + 1 - 4)))
    while not stays_on_grid(n, steps):  # (exact above; a guard against an off-by-one)
        n += 2
    return n


def available(code: str) -> bool:
    """Whether a code can run here: ``taichi`` and ``warp`` only when installed, the others always.

    Args:
        code: a name in ``CODES``.

    Returns:
        ``True`` when it can run.
    """
    if code not in ("taichi", "warp"):
        return True
    import importlib.util

    return importlib.util.find_spec(code) is not None


def bytes_per_particle(dim: int, codes, interpolators) -> int:
    """The most memory a particle takes in a run of one of ``codes`` (``BYTES_PER_PARTICLE``; the
    codes run one at a time).

    Args:
        dim: 1, 2 or 3.
        codes: among ``CODES``, at least one.
        interpolators: jaxmpm's interpolators (their names), at least one when ``codes`` has ``jaxmpm``.

    Returns:
        Bytes.
    """
    kinds = [c if c in ("numpy", "jax") else "numpy" for c in codes if c != "jaxmpm"]
    if "jaxmpm" in codes:
        kinds += interpolators
    largest = max(b[dim] for b in BYTES_PER_PARTICLE.values())  # for an interpolator not measured
    return max(BYTES_PER_PARTICLE[k][dim] if k in BYTES_PER_PARTICLE else largest for k in kinds)


def largest_size(dim: int, codes, interpolators, available: int) -> int:
    """The most particles a run of ``dim`` dimensions can have within ``available`` bytes of memory
    (``PROCESS_BYTES`` and ``bytes_per_particle`` each): even in 1D, ``(2 k)^dim`` in 2D and 3D.

    Args:
        dim: 1, 2 or 3.
        codes: among ``CODES``, at least one.
        interpolators: jaxmpm's interpolators (their names), at least one when ``codes`` has ``jaxmpm``.
        available: bytes.

    Returns:
        The particle count; 0 when not even the smallest run fits.
    """
    n = (available - PROCESS_BYTES) // bytes_per_particle(dim, codes, interpolators)
    if n < 2**dim:
        return 0
    if dim == 1:
        return n - n % 2
    side = integer_root(n, dim)
    side -= side % 2
    return side**dim


def available_memory() -> int | None:
    """Memory this machine can still give a new process, in bytes: ``MemAvailable`` of
    ``/proc/meminfo``, else the free pages; ``None`` where neither can be read. The host's memory,
    read without starting a JAX backend in this process (on a GPU that would take the device's memory
    from the benchmark's own processes).

    Returns:
        Bytes, or ``None``.
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _scene(n: int, dim: int = 1):
    """The benchmark's scene of ``n`` particles in ``dim`` dimensions and its time step."""
    if dim > 1:
        # The unit square (cube) of k^dim cells, 2^dim particles each, at beta = 5 /s and
        # dt = 0.1 h / (c0 + beta) (``_baselines_2d.PROBLEM_ND``): no particle enters a new cell
        # within 100 steps, so SPQ runs healthy. At the 1D problem's beta = 200 /s a face of particles
        # enters a new cell within 100 steps and SPQ breaks down (USL's small-mass breakdown).
        L = layout_nd(n, dim)
        scene = jm.GasExpansion(cells=L["cells"], h=L["h"], pad=L["pad"], dim=dim, **PROBLEM_ND)
        return scene, L["dt"]
    L = layout(n)
    return jm.GasExpansion(cells=L["cells"], h=L["h"], pad=L["pad"], **PROBLEM), L["dt"]


def jaxmpm_simulate(name: str, n: int, steps: int, dim: int = 1):
    """One ``jm.simulate_timed`` of the benchmark's problem (in 2D and 3D: the gas expansion on a
    unit square or cube at ``beta = 5 /s``, ``dt = 0.1 h / (c0 + beta)``; ``_baselines_2d.layout_nd``).

    Args:
        name: the interpolator (a key of ``jaxmpm.INTERPOLATORS``).
        n: particles (in 2D and 3D ``(2 k)^dim``).
        steps: steps.
        dim: 1, 2 or 3.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time, run time, the mean final ``F`` and the
        run's status bits.
    """
    scene, dt = _scene(n, dim)
    sol, compile_s, run_s = jm.simulate_timed(
        scene, jm.INTERPOLATORS[name](), dt=dt, steps=steps, throw=False
    )
    return compile_s, run_s, float(jnp.mean(sol.state.F)), int(sol.state.status)


def jaxmpm_step(name: str, n: int, steps: int):
    """``steps`` calls of one jitted ``jm.step`` from Python (what a user's own loop costs: one
    dispatch a step).

    Args:
        name: the interpolator (a key of ``jaxmpm.INTERPOLATORS``).
        n: particles.
        steps: steps.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time, run time, the mean final ``F`` and the
        run's status bits.
    """
    scene, dt = _scene(n)
    model = jm.Model(scene, jm.INTERPOLATORS[name](), jm.FLIP())
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    dt = jnp.asarray(dt, dtype=state.x.dtype)
    one = eqx.filter_jit(jm.step)
    t0 = time.perf_counter()
    compiled = one.lower(model, s, state, dt).compile()
    t1 = time.perf_counter()
    for _ in range(steps):
        state = compiled(model, s, state, dt)
    jax.block_until_ready(state)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, float(jnp.mean(state.F)), int(state.status)


def reverse_objective(steps: int, checkpoint):
    """The objective of the reverse-mode problem (also that of ``experiments/grad_memory.py``): the gas
    expansion with 1,000 particles (500 cells, ``h = 2 mm``), MPQ with artificial cells,
    ``dt = 0.1 h / c0``.

    Args:
        steps: steps of the run.
        checkpoint: ``simulate``'s ``checkpoint`` (``True``: bounded-memory reverse mode).

    Returns:
        ``beta -> the final RMS relative F error``.
    """
    h = 0.002
    dt = 0.1 * h / (1.4 * 2.0e5) ** 0.5

    def f(beta):
        scene = jm.GasExpansion(cells=500, ppc=2, h=h, beta=beta, pad=60)
        sol = jm.simulate(scene, jm.MPQ(), dt=dt, steps=steps, artificial_cells=1, checkpoint=checkpoint)
        return jm.errors(scene, sol.state, sol.body)["F_rms_rel"]

    return f


def xla_bytes(compiled) -> int:
    """XLA's buffer account of a compiled computation.

    Args:
        compiled: a compiled computation (``jax.jit(f).lower(...).compile()``).

    Returns:
        The bytes of its arguments, outputs and temporaries.
    """
    m = compiled.memory_analysis()
    return int(m.temp_size_in_bytes + m.argument_size_in_bytes + m.output_size_in_bytes)


def reverse_mode(step_counts=(250, 1_000, 4_000)) -> list[dict]:
    """Forward run against ``jax.grad`` through the checkpointed loop (``checkpoint=True``), on
    ``reverse_objective`` at ``beta = 2 /s``, differentiated in ``beta``. ``xla_bytes`` of each
    compiled computation measures memory; plain (uncheckpointed) reverse mode is compiled for its
    account only.

    Args:
        step_counts: the step counts to measure.

    Returns:
        One row per step count: compile time and ``xla_bytes`` of each mode, run times of the forward
        and checkpointed reverse runs, and their ratio ``reverse_over_forward``.
    """
    rows = []
    for steps in step_counts:
        beta = jnp.asarray(2.0)
        row = dict(particles=1_000, steps=steps, interpolator="mpq")
        for mode, fn in (
            ("forward", jax.jit(reverse_objective(steps, False))),
            ("reverse", jax.jit(jax.grad(reverse_objective(steps, True)))),
            ("plain_reverse", jax.jit(jax.grad(reverse_objective(steps, False)))),
        ):
            t0 = time.perf_counter()
            compiled = fn.lower(beta).compile()
            row[f"{mode}_compile_s"] = time.perf_counter() - t0
            row[f"{mode}_xla_bytes"] = xla_bytes(compiled)
            if mode != "plain_reverse":
                jax.block_until_ready(compiled(beta))  # a warm run, then the timed one
                t0 = time.perf_counter()
                jax.block_until_ready(compiled(beta))
                row[f"{mode}_s"] = time.perf_counter() - t0
        row["reverse_over_forward"] = row["reverse_s"] / row["forward_s"]
        rows.append(row)
    return rows


def ensemble_throughput(n: int = 1_000, members: int = 256, steps: int = 100, name: str = "mpq") -> dict:
    """One ``jm.ensemble`` of ``members`` values of ``beta`` against one ``jm.simulate``.

    Args:
        n: particles.
        members: ensemble members (``beta`` from half to all of the problem's).
        steps: steps.
        name: the interpolator.

    Returns:
        Times, particle-steps per second per member and of one run alone, and the failed members.
    """
    scene, dt = _scene(n)
    vary = {"beta": np.linspace(0.5, 1.0, members) * PROBLEM["beta"]}
    jax.block_until_ready(jm.ensemble(scene, jm.INTERPOLATORS[name](), vary, dt=dt, steps=steps).solution)
    t0 = time.perf_counter()
    ens = jm.ensemble(scene, jm.INTERPOLATORS[name](), vary, dt=dt, steps=steps)
    jax.block_until_ready(ens.solution)
    ens_s = time.perf_counter() - t0
    _, _, single_s = jm.simulate_timed(scene, jm.INTERPOLATORS[name](), dt=dt, steps=steps, throw=False)
    return dict(
        particles=n,
        members=members,
        steps=steps,
        interpolator=name,
        ensemble_s=ens_s,
        single_run_s=single_s,
        s_per_member=ens_s / members,
        Mpsps_per_member=n * steps / (ens_s / members) / 1e6,
        Mpsps_single=n * steps / single_s / 1e6,
        failed_members=int((~ens.ok).sum()),
    )


def copy_bandwidth(nbytes: int = 256 * 2**20) -> float:
    """Memory bandwidth of a large NumPy copy (read + write), best of 5.

    Args:
        nbytes: the size of the copied array.

    Returns:
        Bytes per second.
    """
    a = np.ones(nbytes // 8)
    b = np.empty_like(a)
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        np.copyto(b, a)
        best = min(best, time.perf_counter() - t0)
    return 2 * nbytes / best


def bandwidth_bound(bytes_per_s: float, dtype: str, dim: int = 1) -> float:
    """Million particle-steps per second a step cannot beat on this memory: ``PASSES`` passes over
    the particle state ``x, v, F`` (P2G reads it; G2P reads it again and writes it; the grid, about
    0.6 nodes per particle with five fields in 1D, fewer nodes per particle in 2D and 3D, moves about
    one more pass).

    Args:
        bytes_per_s: the memory bandwidth (``copy_bandwidth``).
        dtype: ``"f32"`` or ``"f64"``.
        dim: 1, 2 or 3: a particle's state is ``2 dim + dim^2`` numbers.

    Returns:
        The bound, million particle-steps per second.
    """
    item = 4 if dtype == "f32" else 8
    return bytes_per_s / (PASSES * (2 * dim + dim * dim) * item) / 1e6


def worker(
    dtype: str, sizes, steps: int, codes, interpolators, extras: bool, sizes_2d=(), sizes_3d=()
) -> dict:
    """The benchmark of one float type: the body of its own process (see ``run``).

    As the benchmark's entry point it sets JAX's configuration: x64 on exactly for ``"f64"``, and
    JAX's caches dropped after each size (every compiled XLA CPU program holds memory maps, of which
    a process has a bounded number).

    Args:
        dtype: ``"f32"`` or ``"f64"``.
        sizes: particle counts of the 1D runs.
        steps: steps per run (fewer from 500k particles up: ``steps_for``).
        codes: among ``CODES``.
        interpolators: jaxmpm's interpolators (names in ``jaxmpm.INTERPOLATORS``).
        extras: also the reverse-mode (float64 only) and ensemble measurements.
        sizes_2d: particle counts of the 2D runs (``4 k^2``), reference codes and jaxmpm alike.
        sizes_3d: particle counts of the 3D runs (``8 k^3``).

    Returns:
        ``rows`` (one per code, dimension and size, each with its ``dim``), ``numpy_with_fold``
        (float64, with jaxmpm and NumPy among ``codes``), and with ``extras`` ``reverse`` and
        ``ensemble``.
    """
    jax.config.update("jax_enable_x64", dtype == "f64")
    rows = []

    def add(code, n, n_steps, result, dim=1, error=None):
        compile_s, run_s, F_mean = result[:3]
        # every code's own health check (jaxmpm's status bits); a mean F that is not finite is one too
        status = (result[3] if len(result) > 3 else 0) | (0 if math.isfinite(F_mean) else NONFINITE)
        healthy = status == 0 and math.isfinite(run_s) and run_s > 0
        row = dict(
            code=code,
            dtype=dtype,
            particles=n,
            steps=n_steps,
            compile_s=compile_s,
            run_s=run_s,
            Mpsps=n * n_steps / run_s / 1e6 if healthy else None,  # a broken run has no throughput
            F_mean=F_mean,
            status=status,
            dim=dim,
        )
        if error is not None:
            row["error"] = error
        rows.append(row)

    def reference(code, n, n_steps, dim, fold=False):
        """A reference code's run: ``(result, error)``; one that raised is NONFINITE, its error kept."""
        try:
            if dim == 1:
                return BASELINES[code](n, n_steps, dtype, **({"fold": True} if fold else {})), None
            return BASELINES_ND[code](n, n_steps, dtype, dim, **({"fold": True} if fold else {})), None
        except (ValueError, IndexError) as e:  # NumPy's bincount meets the NaN of a breakdown
            return (0.0, float("nan"), float("nan"), NONFINITE), f"{type(e).__name__}: {e}"

    folded = {}
    for dim, dim_sizes in ((1, sizes), (2, sizes_2d), (3, sizes_3d)):
        x = _suffix(dim)
        for n in dim_sizes:
            n_steps = steps_for(n, steps)
            for code in ("numpy", "jax", "taichi", "warp"):
                if code in codes and available(code):
                    result, error = reference(_BASELINE_CODE[code], n, n_steps, dim)
                    add(_BASELINE_CODE[code] + x, n, n_steps, result, dim, error)
            # What jaxmpm spq must reproduce (see agreement): in float64, where round-off stays small;
            # float32 runs of this problem part ways at the 1e-3 level whatever the code (see README).
            # A fold run that breaks down is kept with its status (agreement names the size it leaves out).
            if "jaxmpm" in codes and "spq" in interpolators and "numpy" in codes and dtype == "f64":
                result, error = reference("NumPy", n, n_steps, dim, fold=True)
                status = result[3] | (0 if math.isfinite(result[2]) else NONFINITE)
                folded[(dim, n)] = dict(
                    F_mean=result[2], status=status, **({"error": error} if error else {})
                )
            if "jaxmpm" in codes:
                for name in interpolators:
                    add(f"jaxmpm {name}{x}", n, n_steps, jaxmpm_simulate(name, n, n_steps, dim=dim), dim)
                if dim == 1:
                    for name in interpolators:
                        add(f"jaxmpm {name}, one step a call", n, n_steps, jaxmpm_step(name, n, n_steps))
            jax.clear_caches()
    out = dict(
        rows=rows,
        numpy_with_fold=[dict(dtype=dtype, particles=n, dim=dim, **q) for (dim, n), q in folded.items()],
    )
    if extras and "jaxmpm" in codes:
        if dtype == "f64":
            out["reverse"] = reverse_mode()
        out["ensemble"] = [ensemble_throughput()]
        for r in out["ensemble"]:
            r["dtype"] = dtype
    return out


def run(
    sizes=SIZES,
    steps: int = 100,
    dtypes=("f32", "f64"),
    codes=CODES,
    interpolators=tuple(jm.INTERPOLATORS),
    extras: bool = True,
    sizes_2d=(),
    sizes_3d=(),
    rounds: int = 1,
) -> dict:
    """Run the benchmark, one process per float type and round.

    With ``rounds > 1`` every code runs that many times, each round in new processes, the rounds one
    after another (f32, f64, f32, f64, ...), and each row is the round of its code that ran fastest
    (``best_of``): a run slowed by another process on the machine does not decide a ratio. The
    reverse-mode and ensemble measurements run in the first round only.

    Args:
        sizes: particle counts of the 1D runs (even: two particles per cell).
        steps: steps per run.
        dtypes: ``"f32"``, ``"f64"`` or both.
        codes: among ``CODES``.
        interpolators: jaxmpm's interpolators (names in ``jaxmpm.INTERPOLATORS``).
        extras: also the reverse-mode and ensemble measurements.
        sizes_2d: particle counts of the 2D runs (``4 k^2``).
        sizes_3d: particle counts of the 3D runs (``8 k^3``).
        rounds: how many times each code runs (at least 1).

    Returns:
        The result: ``date``, ``machine``, ``versions``, ``copy_bandwidth_GBps``, the bandwidth
        bounds (``bandwidth_bound_Mpsps_<dtype>``, in 2D and 3D ``..._<dtype>_2d``, ``_3d``),
        ``rounds``, ``rows``, ``numpy_with_fold``, ``reverse``, ``ensemble``, ``agreement``,
        ``agreement_notes`` (what it could not compare), ``agreement_bound`` (``AGREEMENT_BOUND``) and
        ``disagreement`` (the groups beyond it; empty when the codes agree).

    Raises:
        WorkerError: a benchmark process failed.
    """
    result = dict(
        date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        machine=machine(),
        versions=_versions(),
        rows=[],
        numpy_with_fold=[],
        reverse=[],
        ensemble=[],
    )
    if isinstance(rounds, bool) or not isinstance(rounds, int) or rounds < 1:
        raise ValueError(f"rounds must be an integer >= 1, got {rounds!r}")
    result["rounds"] = rounds
    bw = copy_bandwidth()
    result["copy_bandwidth_GBps"] = bw / 1e9
    rows = {dtype: [] for dtype in dtypes}
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    env = dict(os.environ, PYTHONPATH=path)  # the worker imports benchmarks from the source tree
    for r in range(rounds):
        for k, dtype in enumerate(dtypes):
            which = f"{k + 1} of {len(dtypes)}" + (f", round {r + 1} of {rounds}" if rounds > 1 else "")
            print(f"jaxmpm bench: {dtype} ({which}), one process ...", file=sys.stderr, flush=True)
            spec = dict(
                dtype=dtype,
                sizes=list(sizes),
                steps=steps,
                codes=list(codes),
                interpolators=list(interpolators),
                extras=extras and r == 0,
                sizes_2d=list(sizes_2d),
                sizes_3d=list(sizes_3d),
            )
            cmd = [sys.executable, "-m", "benchmarks.bench", "--worker", json.dumps(spec)]
            proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
            if proc.returncode != 0:
                raise WorkerError(dtype, proc.returncode, proc.stderr)
            part = json.loads(proc.stdout.strip().splitlines()[-1])
            rows[dtype].append(part["rows"])
            if r == 0:
                for key in ("reverse", "ensemble", "numpy_with_fold"):
                    result[key].extend(part.get(key, []))
    for dtype in dtypes:
        result["rows"].extend(best_of(rows[dtype]))
        result[f"bandwidth_bound_Mpsps_{dtype}"] = bandwidth_bound(bw, dtype)
        for dim, dim_sizes in ((2, sizes_2d), (3, sizes_3d)):
            if dim_sizes:
                result[f"bandwidth_bound_Mpsps_{dtype}_{dim}d"] = bandwidth_bound(bw, dtype, dim)
    result["agreement"], result["agreement_notes"] = _agreement(result["rows"], result["numpy_with_fold"])
    result["agreement_bound"] = dict(AGREEMENT_BOUND)
    result["disagreement"] = disagreement(result["agreement"])
    result["method_gap"] = method_gap(result["rows"])
    return result


def best_of(rounds_rows: list[list[dict]]) -> list[dict]:
    """Each code's fastest healthy round: the rows of several rounds of one float type merged.

    Args:
        rounds_rows: the rows of each round (the same codes, dimensions and sizes in each).

    Returns:
        One row per code, dimension and size, in the first round's order: the row of the healthy
        round (``status`` 0, a finite run time) with the shortest ``run_s``; where no round is
        healthy, the first round's row (it broke down: no throughput). Each with ``rounds``, how many
        rounds it is the best of, and ``Mpsps_rounds``, every round's throughput in order (``None`` for
        a round that broke down).
    """
    key = lambda r: (r["code"], r.get("dim", 1), r["particles"])  # noqa: E731
    found = {}
    for rows in rounds_rows:
        for r in rows:
            found.setdefault(key(r), []).append(r)
    out = []
    for runs in found.values():
        healthy = [r for r in runs if r["status"] == 0 and math.isfinite(r["run_s"])]
        best = dict(min(healthy, key=lambda r: r["run_s"]) if healthy else runs[0])
        best["rounds"] = len(runs)
        best["Mpsps_rounds"] = [r["Mpsps"] for r in runs]
        out.append(best)
    return out


class WorkerError(RuntimeError):
    """A benchmark process (one float type's) failed.

    Its message is one line: the float type and how the process ended (the last line of its stderr,
    or the signal that killed it); ``stderr`` holds the whole of its stderr.

    Args:
        dtype: the process's float type.
        returncode: its exit status (negative: killed by that signal).
        stderr: what it wrote on stderr.
    """

    def __init__(self, dtype: str, returncode: int, stderr: str):
        lines = [line.strip() for line in stderr.splitlines() if line.strip()]
        if returncode < 0:
            try:
                name = signal.Signals(-returncode).name
            except ValueError:
                name = f"signal {-returncode}"
            why = f"killed by {name}" + (" (out of memory?)" if -returncode == signal.SIGKILL else "")
        else:
            why = lines[-1] if lines else f"exit status {returncode}, nothing on stderr"
        super().__init__(f"the {dtype} benchmark process failed: {why}")
        self.dtype, self.returncode, self.stderr = dtype, returncode, stderr


def _suffix(dim: int) -> str:
    """What follows a code's name in the rows of ``dim`` dimensions: nothing in 1D, `` 2D``, `` 3D``."""
    return "" if dim == 1 else f" {dim}D"


AGREEMENT_BOUND = {"f64": 1e-10}
"""The largest relative difference of the mean final F that counts as round-off, per float type: in
float64 the reference codes agree within 2.2e-16 to 1.6e-15 at 1k to 1M particles (``docs/bench*``;
the tests ask for 1e-13 at a few hundred particles and a few steps), and ``jaxmpm spq`` and the NumPy
code with the fold within 1.8e-15 there, 2.1e-13 in a run of 100 particles over 180 steps close to
its breakdown (the fold's threshold on a node's mass); a wrong kernel differs by 1e-6 or more. Float32
runs of this problem part ways at the 1e-3 level whatever the code: their differences are reported,
never judged (``disagreement``)."""


def _relative(a: float, b: float) -> float:
    """``|a - b| / |b|`` (0 where both are 0), ``inf`` where it is not a number."""
    diff = abs(a - b) / abs(b) if b != 0 else (0.0 if a == b else math.inf)
    return diff if math.isfinite(diff) else math.inf


def _agreement(rows, numpy_with_fold=()) -> tuple[dict, dict]:
    """``(agreement, agreement_notes)``: see ``agreement`` and ``agreement_notes``."""
    out, notes = {}, {}
    for dtype in sorted({r["dtype"] for r in rows}):
        worst, said = {}, {}
        for dim in sorted({r.get("dim", 1) for r in rows if r["dtype"] == dtype}):
            x = _suffix(dim)
            here = [r for r in rows if r["dtype"] == dtype and r.get("dim", 1) == dim]
            reference = {c + x for c in _BASELINE_CODE.values()}
            fold = {
                q["particles"]: dict(q, code=f"NumPy{x} with the fold")
                for q in numpy_with_fold
                if q["dtype"] == dtype and q.get("dim", 1) == dim
            }
            spq = [
                r
                for r in here
                if r["code"] == f"jaxmpm spq{x}" or (dim == 1 and r["code"].startswith("jaxmpm spq,"))
            ]
            groups = []
            if any(r["code"] in reference for r in here):
                numpy = {r["particles"]: r for r in here if r["code"] == "NumPy" + x}
                others = [r for r in here if r["code"] in reference and r["code"] != "NumPy" + x]
                groups.append((f"reference codes{x}", numpy, others, f"NumPy{x}"))
            if fold and spq:
                groups.append(
                    (f"jaxmpm spq{x} vs NumPy{x} with the fold", fold, spq, f"NumPy{x} with the fold")
                )
            for group, refs, others, ref_name in groups:
                diffs, lines = [], []
                for r in others:
                    ref = refs.get(r["particles"])
                    if ref is None:
                        continue
                    broken = [q for q in (ref, r) if q.get("status", 0) != 0]
                    if broken:
                        lines.append(
                            f"{r['code']} at {r['particles']:,} left out: "
                            + ", ".join(f"{q['code']} broke down (status {q['status']})" for q in broken)
                        )
                        continue
                    diffs.append(_relative(r["F_mean"], ref["F_mean"]))  # NaN: inf, a disagreement
                if diffs:
                    worst[group] = max(diffs)
                else:
                    why = (
                        "the NumPy code, the reference, was not among --codes"
                        if not refs
                        else f"fewer than two healthy codes (only {ref_name})"
                        if not others
                        else "no healthy pair of runs"
                    )
                    lines.insert(0, f"nothing to compare: {why}")
                if lines:
                    said[group] = lines
        out[dtype] = worst
        if said:
            notes[dtype] = said
    return out, notes


def agreement(rows, numpy_with_fold=()) -> dict:
    """Largest relative difference of the mean final F, per dtype: among the reference codes (one
    algorithm, so they agree to round-off and a wrong kernel shows), each against the NumPy code, and
    of ``jaxmpm spq`` from the NumPy code with jaxmpm's fold of force off empty nodes
    (``numpy_spq(fold=True)``: the same method exactly), each per dimension. In 1D, ``jaxmpm spq``
    against the reference codes' standard algorithm differs by that fold, a real difference while
    the free end enters a new cell. In 2D and 3D the reference codes put a traction point's force on
    the nearest of the body's nodes, which is what the fold does until a particle enters a new cell
    (``benchmarks._baselines_2d``). ``method_gap`` reports ``jaxmpm spq`` against the timed NumPy code.

    Only healthy runs (status 0) are compared, at the same size; a size where one side broke down is
    left out, and ``agreement_notes`` names it. A difference that is not a number (NaN) counts as
    ``inf``: a disagreement.

    Args:
        rows: the benchmark's rows (a row without ``dim`` is 1D).
        numpy_with_fold: the mean final F of the NumPy code with the fold, per dtype, size and
            dimension (without ``dim``: 1D), with its ``status`` (without: healthy).

    Returns:
        ``{dtype: {group: largest relative difference}}``, a group only where at least one pair of
        healthy runs was compared; the groups are ``reference codes`` and ``jaxmpm spq vs NumPy with
        the fold`` (1D), ``reference codes 2D`` and ``jaxmpm spq 2D vs NumPy 2D with the fold``, and
        the same for 3D.
    """
    return _agreement(rows, numpy_with_fold)[0]


def agreement_notes(rows, numpy_with_fold=()) -> dict:
    """What the agreement could not compare, per dtype and group (``agreement``).

    Args:
        rows: as for ``agreement``.
        numpy_with_fold: as for ``agreement``.

    Returns:
        ``{dtype: {group: [note, ...]}}``: ``nothing to compare: WHY`` for a group of which no pair of
        healthy runs was compared (no reference code but NumPy, NumPy not among the codes, or every
        pair with a side that broke down), and ``CODE at N left out: ... broke down (status S)`` for
        each size left out.
    """
    return _agreement(rows, numpy_with_fold)[1]


def method_gap(rows) -> dict:
    """Largest relative difference of the mean final F of ``jaxmpm spq`` from the NumPy code it is
    timed beside, per dtype and dimension (healthy runs at the same size): reported, never judged.

    The timed reference codes leave out jaxmpm's fold of force off nodes without mass: in 1D they
    drop such force, in 2D and 3D they put it on the nearest of the body's nodes (the fold does the
    same until a particle enters a new cell). So while a free end enters a new cell they compute a
    slightly different method; ``agreement`` checks ``jaxmpm spq`` against the NumPy code with the fold.

    Args:
        rows: the benchmark's rows (a row without ``dim`` is 1D).

    Returns:
        ``{dtype: {"1D" | "2D" | "3D": largest relative difference}}``, where a pair was compared.
    """
    out = {}
    for r in rows:
        dim = r.get("dim", 1)
        if r["code"] != f"jaxmpm spq{_suffix(dim)}" or r.get("status", 0) != 0:
            continue
        ref = [
            q
            for q in rows
            if q["code"] == f"NumPy{_suffix(dim)}"
            and q["dtype"] == r["dtype"]
            and q.get("dim", 1) == dim
            and q["particles"] == r["particles"]
            and q.get("status", 0) == 0
        ]
        if not ref:
            continue
        groups = out.setdefault(r["dtype"], {})
        key = f"{dim}D"
        groups[key] = max(groups.get(key, 0.0), _relative(r["F_mean"], ref[0]["F_mean"]))
    return {dtype: dict(sorted(g.items())) for dtype, g in out.items()}


def disagreement(agree: dict) -> dict:
    """The groups of ``agreement`` whose codes disagree beyond round-off (``AGREEMENT_BOUND``; float64
    only: float32 differences are reported, not judged).

    Args:
        agree: what ``agreement`` returns.

    Returns:
        ``{dtype: {group: largest relative difference}}``; empty when every group agrees.
    """
    out = {}
    for dtype, groups in agree.items():
        bound = AGREEMENT_BOUND.get(dtype)
        if bound is None:
            continue
        bad = {g: d for g, d in groups.items() if not d <= bound}  # NaN too
        if bad:
            out[dtype] = bad
    return out


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for pkg in ("jax", "numpy", "taichi", "warp-lang"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            pass
    return out


def _healthy(r: dict) -> bool:
    """A row of a run that finished healthy: status 0 and a throughput (never one that broke down)."""
    return r["status"] == 0 and r.get("Mpsps") is not None and math.isfinite(r["Mpsps"])


def _round_ratios(rows: list[dict], n: int, x: str) -> str:
    """The lowest and highest ratio of ``jaxmpm spq`` to the faster of Taichi and Warp over the
    rounds of a several-round run (each round's own runs, a round where a side broke down left out),
    at ``n`` particles; '' for one round."""
    at_n = [r for r in rows if r["particles"] == n and len(r.get("Mpsps_rounds", ())) > 1]
    mine = [r["Mpsps_rounds"] for r in at_n if r["code"] == "jaxmpm spq" + x]
    fast = [r["Mpsps_rounds"] for r in at_n if r["code"] in ("Taichi" + x, "Warp" + x)]
    if not mine or not fast:
        return ""

    def ok(value):
        return value is not None and math.isfinite(value)

    ratios = [
        m / max(f[i] for f in fast) for i, m in enumerate(mine[0]) if ok(m) and all(ok(f[i]) for f in fast)
    ]
    return f"{min(ratios):.2f}-{max(ratios):.2f}" if ratios else ""


def _throughput_table(result: dict, dtype: str, dim: int) -> list[str]:
    """The lines of the throughput table of one dtype and dimension (see ``table``)."""
    x = _suffix(dim)
    rows = [r for r in result["rows"] if r["dtype"] == dtype and r.get("dim", 1) == dim]
    sizes = sorted({r["particles"] for r in rows})
    title = dtype if dim == 1 else f"{dtype}, {dim}D"
    lines = ["", f"{title}: million particle-steps per second (compile s in brackets)", ""]
    lines.append("| code | " + " | ".join(f"{n:,}" for n in sizes) + " |")
    lines.append("|---|" + "---|" * len(sizes))
    for code in dict.fromkeys(r["code"] for r in rows):
        cells = []
        for n in sizes:
            r = next((r for r in rows if r["code"] == code and r["particles"] == n), None)
            if r is None:
                cells.append("")
            elif _healthy(r):
                cells.append(f"{r['Mpsps']:.1f} ({r['compile_s']:.2f})")
            else:  # no throughput for a run that broke down
                cells.append(f"broke down (status {r['status']})")
        lines.append(f"| {code} | " + " | ".join(cells) + " |")
    ratio, why = [], []
    for n in sizes:
        at_n = [r for r in rows if r["particles"] == n]
        fast = [r for r in at_n if r["code"] in ("Taichi" + x, "Warp" + x)]
        mine = [r for r in at_n if r["code"] == "jaxmpm spq" + x]
        broken = [r for r in fast + mine if not _healthy(r)]
        if not fast or not mine:
            ratio.append("")
        elif broken:  # a ratio never uses a run that broke down
            ratio.append("-")
            why.append(
                f"{n:,}: " + ", ".join(f"{r['code']} broke down (status {r['status']})" for r in broken)
            )
        else:
            ratio.append(f"{mine[0]['Mpsps'] / max(r['Mpsps'] for r in fast):.2f}")
    if any(ratio):
        lines.append("| jaxmpm spq / faster of Taichi, Warp | " + " | ".join(ratio) + " |")
        spread = [_round_ratios(rows, n, x) for n in sizes]
        if any(spread):
            lines.append("| the same, round by round (lowest-highest) | " + " | ".join(spread) + " |")
    bound = result.get(f"bandwidth_bound_Mpsps_{dtype}" + ("" if dim == 1 else f"_{dim}d"))
    if bound:
        lines.append(
            f"| bandwidth bound ({result['copy_bandwidth_GBps']:.1f} GB/s copy, "
            f"{PASSES} passes over x, v, F) | " + " | ".join(f"{bound:.0f}" for _ in sizes) + " |"
        )
    if why:
        lines += ["", "No ratio (`-`) where a run of it broke down: at " + "; ".join(why) + "."]
    return lines


def table(result: dict) -> str:
    """The result as markdown tables.

    Args:
        result: what ``run`` returns.

    Returns:
        Million particle-steps per second (compile s) per code and size, per dtype and dimension
        (1D, then 2D, 3D), then the reverse-mode, ensemble and agreement measurements.
    """
    rows = result["rows"]
    rounds = result.get("rounds", 1)
    lines = [
        f"Measured {result['date']} on {result['machine']}; "
        + ", ".join(f"{k} {v}" for k, v in result["versions"].items())
        + "."
        + (
            f" Each code's fastest of {rounds} rounds (every round in new processes, one after another)."
            if rounds > 1
            else ""
        )
    ]
    for dtype in dict.fromkeys(r["dtype"] for r in rows):
        for dim in sorted({r.get("dim", 1) for r in rows if r["dtype"] == dtype}):
            lines += _throughput_table(result, dtype, dim)
    if result.get("reverse"):
        lines += [
            "",
            "Reverse mode (jax.grad of the final F error in beta; float64; MPQ, artificial cells; "
            "checkpoint=True):",
            "",
        ]
        lines.append(
            "| particles | steps | forward s | reverse s | ratio | XLA MB forward | checkpointed | plain |"
        )
        lines.append("|---|---|---|---|---|---|---|---|")
        for r in result["reverse"]:
            lines.append(
                f"| {r['particles']:,} | {r['steps']:,} | {r['forward_s']:.3f} | {r['reverse_s']:.3f} | "
                f"{r['reverse_over_forward']:.2f} | {r['forward_xla_bytes'] / 1e6:.2f} | "
                f"{r['reverse_xla_bytes'] / 1e6:.2f} | {r['plain_reverse_xla_bytes'] / 1e6:.2f} |"
            )
    if result.get("ensemble"):
        lines += ["", "Ensembles (jm.ensemble over beta, one compiled call):", ""]
        lines.append(
            "| dtype | particles | members | steps | ensemble s | M p-steps/s per member | one run alone |"
        )
        lines.append("|---|---|---|---|---|---|---|")
        for r in result["ensemble"]:
            lines.append(
                f"| {r['dtype']} | {r['particles']:,} | {r['members']} | {r['steps']} | "
                f"{r['ensemble_s']:.2f} | "
                f"{r['Mpsps_per_member']:.1f} | {r['Mpsps_single']:.1f} |"
            )
    lines += _agreement_lines(result)
    return "\n".join(lines)


def _difference(value: float) -> str:
    return f"{value:.1e}" if math.isfinite(value) else "not a number"


def _agreement_lines(result: dict) -> list[str]:
    """The agreement line of ``table`` and, where float64 codes disagree beyond round-off, a line
    saying so."""
    rows = result["rows"]
    agree = result.get("agreement", {})
    if not agree:
        return []
    notes = result.get("agreement_notes", {})
    parts = []
    for dtype, groups in agree.items():
        said = [f"{g} {_difference(v)}" for g, v in groups.items()]
        said += [f"{g}: {'; '.join(n)}" for g, n in notes.get(dtype, {}).items()]
        parts.append(f"{dtype}: " + (", ".join(said) or _nothing_compared(rows, dtype)))
    lines = ["", "Mean final F, largest relative difference from NumPy's: " + "; ".join(parts)]
    gap = result.get("method_gap", {})
    if gap:
        lines += [
            "",
            "Mean final F of jaxmpm spq against the NumPy code it is timed beside, largest relative "
            "difference (the timed codes drop (1D) or put on the body's nodes (2D, 3D) the force that "
            "jaxmpm folds off nodes without mass, a different method once a free end enters a new "
            "cell; reported, not judged): "
            + "; ".join(
                f"{dtype}: " + ", ".join(f"{k} {_difference(v)}" for k, v in g.items())
                for dtype, g in gap.items()
            ),
        ]
    bad = result.get("disagreement", disagreement(agree))
    if bad:
        lines += [
            "",
            "**The codes disagree beyond round-off**: "
            + "; ".join(
                f"{dtype} {g} by {_difference(v)} (round-off is under {AGREEMENT_BOUND[dtype]:.0e})"
                for dtype, groups in bad.items()
                for g, v in groups.items()
            )
            + ". Their throughputs do not time one computation.",
        ]
    return lines


def _nothing_compared(rows: list[dict], dtype: str) -> str:
    """Why a dtype's agreement is empty: the NumPy code, the reference of every comparison, did not
    run, or none of the runs that would be compared finished healthy."""
    if not any(r["dtype"] == dtype and r["code"].startswith("NumPy") for r in rows):
        return "nothing compared (the NumPy code, the reference, was not among --codes)"
    return "no healthy runs to compare"


def write(result: dict, out_dir: str | os.PathLike, overwrite: bool = False) -> list[pathlib.Path]:
    """Write ``bench.csv`` (the throughput rows), ``bench.json`` (everything) and ``bench.md`` (the
    tables), all three or none: each is written whole to a new temporary file beside it first, and
    only once all three are written are they renamed into place. A write that fails (a full disk)
    removes the temporary files and raises, leaving the folder as it was.

    Args:
        result: what ``run`` returns.
        out_dir: the directory (created).
        overwrite: replace the files of an earlier benchmark there (else refused).

    Returns:
        The three paths (``FILES``).

    Raises:
        FileExistsError: without ``overwrite``, one of the files is there already (nothing written).
        OSError: a file cannot be written.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = io.StringIO(newline="")
    w = csv.DictWriter(rows, fieldnames=ROW_FIELDS, extrasaction="ignore")
    w.writeheader()
    w.writerows(result["rows"])
    texts = (rows.getvalue(), dumps(result, indent=1), table(result) + "\n")
    paths = [out / name for name in FILES]
    staged = []
    try:
        for path, text in zip(paths, texts):
            tmp = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp")
            with open(tmp, "xb") as f:  # a name of its own: no file is written over
                staged.append(tmp)
                f.write(text.encode())
        if not overwrite:
            for path in paths:
                if path.exists():
                    raise FileExistsError(errno.EEXIST, f"{path.name} is there already", str(path))
        for tmp, path in zip(staged, paths):
            os.replace(tmp, path)
    finally:
        for tmp in staged:
            tmp.unlink(missing_ok=True)
    return paths


if __name__ == "__main__":  # the per-dtype worker process of ``run``
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        spec = json.loads(sys.argv[2])
        print(
            json.dumps(
                worker(
                    spec["dtype"],
                    spec["sizes"],
                    spec["steps"],
                    spec["codes"],
                    spec["interpolators"],
                    spec["extras"],
                    spec.get("sizes_2d", ()),
                    spec.get("sizes_3d", ()),
                )
            )
        )
    else:
        sys.exit("usage: jaxmpm bench (see jaxmpm bench --help)")
