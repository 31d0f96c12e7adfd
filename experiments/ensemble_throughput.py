"""Ensemble throughput: one vmap-ed, compiled call against separate jitted runs.

For the gas slab (CPDI, FLIP, 16 and 32 cells, 1,000 steps), members per second of

- ``jm.ensemble`` (one compiled call over all members; compile time reported apart), and
- a Python loop of ``jm.simulate`` calls (compiled once; each member is a new call of the same
  compiled run, as a user would write it).

Both in one process, on the same machine; the ratio is what to compare. Also the sharded ensemble
on 4 forced host devices when run with ``XLA_FLAGS=--xla_force_host_platform_device_count=4``.

    python experiments/ensemble_throughput.py [--out docs/ensemble_throughput.csv [--overwrite]]

An existing ``--out`` is refused, before anything is computed, unless ``--overwrite``.
"""

import argparse
import time

import jax
import numpy as np
from _entry import refuse_existing

import jaxmpm as jm
from jaxmpm.studies._output import csv_text, write_text


def measure(cells: int, members: int, steps: int = 1000) -> dict:
    """Members per second of one ensemble call and of separate runs of the gas slab.

    Args:
        cells: cells of the slab (two particles each).
        members: ensemble members (``gamma`` and ``P0`` uniform in a range).
        steps: steps of each run.

    Returns:
        The times, members per second each way and their ratio ``speedup``.
    """
    scene = jm.GasSlab(cells=cells, h=1.0 / cells, pad=6 * cells)
    rng = np.random.default_rng(0)
    vary = {"gamma": rng.uniform(1.33, 1.47, members), "P0": rng.uniform(2.7e5, 3.3e5, members)}
    dt = 0.2 * float(scene.h) / float(np.sqrt(1.47 * 3.3e5))
    t0 = time.perf_counter()
    jax.block_until_ready(jm.ensemble(scene, jm.CPDI(), vary, dt=dt, steps=steps).solution)  # compile + run
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(jm.ensemble(scene, jm.CPDI(), vary, dt=dt, steps=steps).solution)
    ens_s = time.perf_counter() - t0
    loop_n = min(members, 64)  # separate runs: time a sample of members, scale per member
    s0 = jm.GasSlab(cells=cells, h=1.0 / cells, pad=6 * cells, gamma=vary["gamma"][0], P0=vary["P0"][0])
    jax.block_until_ready(jm.simulate(s0, jm.CPDI(), dt=dt, steps=steps, throw=False))  # compile once
    t0 = time.perf_counter()
    for i in range(loop_n):
        s = jm.GasSlab(cells=cells, h=1.0 / cells, pad=6 * cells, gamma=vary["gamma"][i], P0=vary["P0"][i])
        jax.block_until_ready(jm.simulate(s, jm.CPDI(), dt=dt, steps=steps, throw=False).state.x)
    loop_s = (time.perf_counter() - t0) / loop_n * members
    return dict(
        cells=cells,
        particles=2 * cells,
        members=members,
        steps=steps,
        devices=len(jax.local_devices()),
        ensemble_s=ens_s,
        ensemble_compile_and_first_s=first,
        separate_s=loop_s,
        members_per_s_ensemble=members / ens_s,
        members_per_s_separate=members / loop_s,
        speedup=loop_s / ens_s,
    )


def main(argv: list[str] | None = None):
    """Measure 16 and 32 cells at 64, 256 and 1,024 members; print a table, optionally write a CSV."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=None, help="the CSV file to write")
    p.add_argument("--overwrite", action="store_true", help="replace --out where it exists")
    args = p.parse_args(argv)
    if args.out:
        refuse_existing(p, "--out", [args.out], args.overwrite)
    jax.config.update("jax_enable_x64", True)
    rows = [measure(c, m) for c in (16, 32) for m in (64, 256, 1024)]
    print("| cells | members | devices | ensemble (s) | compile+first (s) | separate runs (s) | speedup |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['cells']} | {r['members']} | {r['devices']} | {r['ensemble_s']:.2f} | "
            f"{r['ensemble_compile_and_first_s']:.2f} | {r['separate_s']:.2f} | {r['speedup']:.1f}x |"
        )
    if args.out:
        write_text(args.out, csv_text(rows, list(rows[0])))


if __name__ == "__main__":
    main()
