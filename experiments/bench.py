"""Throughput of the 1D step: jaxmpm per interpolator against plain JAX and NumPy baselines (issue 6).

Million particle-steps per second of a whole ``simulate`` (compile time measured apart) for each
interpolator, at 1k to 1M particles, in float32 and float64, next to two baselines of the same
algorithm written directly (SPQ with linear hats, USL, FLIP, the gas model, no checks):

- ``plain JAX``: ``.at[].add`` scatters in one ``lax.scan``;
- ``NumPy``: ``np.bincount`` scatters in a Python loop.

Each dtype runs in its own process (float64 is switched on at start-up, never mid-run). Everything
in one invocation runs on the same machine, so compare ratios. Taichi and Warp are not measured here
yet (see the README).

    python experiments/bench.py [--sizes 1000,8000,64000,256000,1000000] [--steps 100] [--out FILE.csv]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import time

SCENE = dict(beta=200.0, P0=2.0e5, gamma=1.4, p_atm=1.0e5, rho0=1.0)


def _dt(cells: int) -> float:
    h = 1.0 / cells
    c0 = (SCENE["gamma"] * SCENE["P0"] / SCENE["rho0"]) ** 0.5
    return 0.2 * h / (c0 + SCENE["beta"])


def numpy_baseline(n: int, steps: int, dtype: str) -> float:
    """Seconds for ``steps`` SPQ steps of ``n`` particles, NumPy, bincount scatters."""
    import numpy as np

    f = np.float32 if dtype == "f32" else np.float64
    cells = n // 2
    h = f(1.0 / cells)
    pad = cells // 8 + 4
    nodes = cells + 2 * pad + 1
    x_min = f(-pad * h)
    X = ((np.arange(n) + 0.5) / 2 * h).astype(f)
    x, v, F = X.copy(), (SCENE["beta"] * X).astype(f), np.ones(n, f)
    m = np.full(n, h / 2 * SCENE["rho0"], f)
    V0 = np.full(n, h / 2, f)
    dt = f(_dt(cells))
    t0 = time.perf_counter()
    for _ in range(steps):
        s = (x - x_min) / h
        i = np.floor(s).astype(np.int64)
        w1 = (s - i).astype(f)
        w0 = 1 - w1
        sig = -(SCENE["P0"] * F ** -SCENE["gamma"] - SCENE["p_atm"]).astype(f)
        mass = np.bincount(i, w0 * m, nodes) + np.bincount(i + 1, w1 * m, nodes)
        mom = np.bincount(i, w0 * m * v, nodes) + np.bincount(i + 1, w1 * m * v, nodes)
        fi = sig * V0 * F / h
        force = np.bincount(i, fi, nodes) - np.bincount(i + 1, fi, nodes)
        active = mass > 0
        safe = np.where(active, mass, 1)
        vn = np.where(active, mom / safe, 0)
        a = np.where(active, force / safe, 0)
        vnew = vn + dt * a
        v = v + dt * (w0 * a[i] + w1 * a[i + 1])
        x = x + dt * (w0 * vnew[i] + w1 * vnew[i + 1])
        F = F * (1 + dt * (vnew[i + 1] - vnew[i]) / h)
    assert np.all(np.isfinite(F))
    return time.perf_counter() - t0


def plain_jax(n: int, steps: int) -> tuple[float, float]:
    """``(compile_s, run_s)`` of the same SPQ algorithm as one ``lax.scan`` with ``.at[].add``."""
    import jax
    import jax.numpy as jnp

    cells = n // 2
    h = 1.0 / cells
    pad = cells // 8 + 4
    nodes = cells + 2 * pad + 1
    x_min = -pad * h
    dt = _dt(cells)

    def run(X):
        m = jnp.full_like(X, h / 2 * SCENE["rho0"])
        V0 = jnp.full_like(X, h / 2)

        def step(c, _):
            x, v, F = c
            s = (x - x_min) / h
            i = jnp.floor(s).astype(jnp.int32)
            w1 = s - i
            w0 = 1 - w1
            sig = -(SCENE["P0"] * F ** -SCENE["gamma"] - SCENE["p_atm"])
            z = jnp.zeros(nodes, X.dtype)
            mass = z.at[i].add(w0 * m).at[i + 1].add(w1 * m)
            mom = z.at[i].add(w0 * m * v).at[i + 1].add(w1 * m * v)
            fi = sig * V0 * F / h
            force = z.at[i].add(fi).at[i + 1].add(-fi)
            active = mass > 0
            safe = jnp.where(active, mass, 1)
            vn = jnp.where(active, mom / safe, 0)
            a = jnp.where(active, force / safe, 0)
            vnew = vn + dt * a
            v = v + dt * (w0 * a[i] + w1 * a[i + 1])
            x = x + dt * (w0 * vnew[i] + w1 * vnew[i + 1])
            F = F * (1 + dt * (vnew[i + 1] - vnew[i]) / h)
            return (x, v, F), None

        return jax.lax.scan(step, (X, SCENE["beta"] * X, jnp.ones_like(X)), None, length=steps)[0]

    X = (jnp.arange(n) + 0.5) / 2 * h
    t0 = time.perf_counter()
    compiled = jax.jit(run).lower(X).compile()
    t1 = time.perf_counter()
    jax.block_until_ready(compiled(X))
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1


def jaxmpm_run(name: str, n: int, steps: int) -> tuple[float, float, int]:
    """``(compile_s, run_s, status)`` of ``jm.simulate`` with interpolator ``name`` (FLIP, USL)."""
    import jaxmpm as jm

    cells = n // 2
    sc = jm.GasExpansion(cells=cells, h=1.0 / cells, pad=cells // 8 + 4, **SCENE)
    interp = jm.INTERPOLATORS[name]()
    sol, compile_s, run_s = jm.simulate_timed(sc, interp, dt=_dt(cells), steps=steps, throw=False)
    return compile_s, run_s, int(sol.state.status)


def worker(dtype: str, sizes, steps: int) -> list[dict]:
    import jax

    jax.config.update("jax_enable_x64", dtype == "f64")
    rows = []
    for n in sizes:
        n_steps = steps if n < 500_000 else max(10, steps // 4)
        rows.append(
            dict(
                code="NumPy",
                dtype=dtype,
                particles=n,
                steps=n_steps,
                compile_s=0.0,
                run_s=numpy_baseline(n, n_steps, dtype),
                status=0,
            )
        )
        c, r = plain_jax(n, n_steps)
        rows.append(
            dict(code="plain JAX", dtype=dtype, particles=n, steps=n_steps, compile_s=c, run_s=r, status=0)
        )
        for name in ("spq", "gimp", "cpgimp", "cpdi", "mpq"):
            c, r, st = jaxmpm_run(name, n, n_steps)
            rows.append(
                dict(
                    code=f"jaxmpm {name}",
                    dtype=dtype,
                    particles=n,
                    steps=n_steps,
                    compile_s=c,
                    run_s=r,
                    status=st,
                )
            )
        jax.clear_caches()
    for r in rows:
        r["Mpsps"] = r["particles"] * r["steps"] / r["run_s"] / 1e6
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="1000,8000,64000,256000,1000000")
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--dtypes", default="f32,f64")
    p.add_argument("--out", default=None)
    p.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = p.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.worker:
        print(json.dumps(worker(args.worker, sizes, args.steps)))
        return
    rows = []
    for dtype in args.dtypes.split(","):
        cmd = [sys.executable, __file__, "--worker", dtype, "--sizes", args.sizes, "--steps", str(args.steps)]
        out = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ), check=True)
        rows.extend(json.loads(out.stdout.strip().splitlines()[-1]))
    codes = list(dict.fromkeys(r["code"] for r in rows))
    for dtype in args.dtypes.split(","):
        print(f"\n{dtype}: million particle-steps per second (compile s)")
        print("| code | " + " | ".join(f"{n:,}" for n in sizes) + " |")
        print("|---|" + "---|" * len(sizes))
        for code in codes:
            cells = []
            for n in sizes:
                r = next(r for r in rows if r["code"] == code and r["dtype"] == dtype and r["particles"] == n)
                flag = "" if r["status"] == 0 else f" (status {r['status']})"
                cells.append(f"{r['Mpsps']:.1f} ({r['compile_s']:.2f}){flag}")
            print(f"| {code} | " + " | ".join(cells) + " |")
    if args.out:
        with open(args.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
