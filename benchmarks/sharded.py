"""Speed-up of one run spread over several devices (``simulate(..., devices=k)``) against one device.

``python -m benchmarks.sharded --out docs/scale`` (from a source checkout) times the same runs on 1
and on ``k`` devices in one process started with ``k`` forced host devices
(``XLA_FLAGS=--xla_force_host_platform_device_count=k``: on a CPU each such device computes on its
own thread, so ``k`` devices can use ``k`` cores). The problems are the benchmark's gas expansion
(``benchmarks._baselines.layout``): 1D at 1M particles (two per cell) and 2D on a square at 250k
particles (2 x 2 per cell), FLIP and USL, float64, each run once to compile and then timed (the best
of ``repeats``). It writes ``sharded.json`` and ``sharded.md`` (the table the performance page shows).

Importing this module changes no JAX configuration; ``worker`` (the body of the timing process)
does.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import pathlib
import shlex
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]

CASES = (  # (dim, particles, interpolator, steps)
    (1, 1_000_000, "spq", 40),
    (1, 1_000_000, "cpdi", 40),
    (1, 1_000_000, "mpq", 40),
    (2, 250_000, "cpdi", 20),
    (2, 250_000, "mpq", 20),
)


def scene(dim: int, n: int):
    """The gas expansion of ``n`` particles and its step.

    Args:
        dim: 1 (two particles per cell on [0, 1]) or 2 (a square of k x k cells, 2 x 2 particles each).
        n: particles.

    Returns:
        ``(scene, dt)``, ``dt`` a CFL number of 0.2 (1D) or 0.1 (2D).
    """
    import jaxmpm as jm

    from ._baselines import PROBLEM, layout

    if dim == 1:
        L = layout(n)
        return jm.GasExpansion(cells=L["cells"], h=L["h"], pad=L["pad"], **PROBLEM), L["dt"]
    k = round(math.sqrt(n // 4))
    c0 = math.sqrt(PROBLEM["gamma"] * PROBLEM["P0"] / PROBLEM["rho0"])
    return jm.GasExpansion(cells=k, h=1.0 / k, pad=4, dim=2, **PROBLEM), 0.1 / (k * (c0 + PROBLEM["beta"]))


def worker(devices: int, repeats: int) -> list[dict]:
    """Time every case on 1 and on ``devices`` devices: the body of the timing process.

    As an entry point it switches float64 on.

    Args:
        devices: the devices to spread a run over (the process has at least this many).
        repeats: timed runs of each case after the one that compiles; the best is kept.

    Returns:
        One row per case: ``dim``, ``particles``, ``interpolator``, ``steps``, the compile and run
        seconds on 1 and on ``devices`` devices, ``speedup`` (run time on 1 / on ``devices``), the
        largest relative difference of the final ``F``, and both runs' status.
    """
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import jaxmpm as jm

    rows = []
    for dim, n, name, steps in CASES:
        sc, dt = scene(dim, n)
        row = dict(dim=dim, particles=n, interpolator=name, steps=steps, devices=devices)
        F = {}
        for k in (1, devices):
            kw = dict(dt=dt, steps=steps, throw=False, devices=None if k == 1 else k)
            sol, compile_s, _ = jm.simulate_timed(sc, jm.INTERPOLATORS[name](), **kw)
            best = math.inf
            for _ in range(repeats):
                t0 = time.perf_counter()
                sol = jax.block_until_ready(jm.simulate(sc, jm.INTERPOLATORS[name](), **kw))
                best = min(best, time.perf_counter() - t0)
            tag = "one" if k == 1 else "many"
            row[f"compile_s_{tag}"] = compile_s
            row[f"run_s_{tag}"] = best
            row[f"status_{tag}"] = int(sol.state.status)
            F[tag] = sol.state.F
        row["speedup"] = row["run_s_one"] / row["run_s_many"]
        row["F_rel_diff"] = float(jnp.max(jnp.abs(F["one"] - F["many"])) / jnp.max(jnp.abs(F["one"])))
        rows.append(row)
        jax.clear_caches()
        print(json.dumps(row), file=sys.stderr, flush=True)
    return rows


def run(devices: int = 2, repeats: int = 2, out: str | None = None) -> dict:
    """Start the timing process with ``devices`` forced host devices and collect its rows.

    Args:
        devices: devices to spread each run over.
        repeats: timed runs per case.
        out: the folder the result is written to (``--out``), for the command it records.

    Returns:
        ``date``, ``machine``, ``command`` and ``rows``.

    Raises:
        RuntimeError: the timing process failed (with the end of its stderr).
    """
    from jaxmpm.studies import machine

    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={devices}".strip()
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    cmd = [sys.executable, "-m", "benchmarks.sharded", "--worker", json.dumps([devices, repeats])]
    proc = subprocess.run(
        cmd, capture_output=True, text=True, env=dict(os.environ, XLA_FLAGS=flags, PYTHONPATH=path)
    )
    if proc.returncode != 0:
        raise RuntimeError(f"the timing process failed:\n{proc.stderr[-4000:]}")
    return dict(
        date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        machine=machine(),
        command=f"python -m benchmarks.sharded --devices {devices} --repeats {repeats}"
        + ("" if out is None else f" --out {shlex.quote(str(out))}"),
        rows=json.loads(proc.stdout.strip().splitlines()[-1]),
    )


def table(result: dict) -> str:
    """The result as a Markdown table.

    Args:
        result: what ``run`` returns.

    Returns:
        The table, with the machine, date and command above it.
    """
    k = result["rows"][0]["devices"] if result["rows"] else 2
    lines = [
        f"{result['machine']}; {result['date']}; `{result['command']}`",
        "",
        f"| dim | particles | interpolator | steps | run s, 1 device | run s, {k} devices | speed-up | "
        f"compile s, 1 / {k} | F, largest relative difference | status |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        cells = [
            str(r["dim"]),
            f"{r['particles']:,}",
            r["interpolator"],
            str(r["steps"]),
            f"{r['run_s_one']:.2f}",
            f"{r['run_s_many']:.2f}",
            f"{r['speedup']:.2f}x",
            f"{r['compile_s_one']:.2f} / {r['compile_s_many']:.2f}",
            f"{r['F_rel_diff']:.1e}",
            f"{r['status_one']} / {r['status_many']}",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``python -m benchmarks.sharded [--devices K] [--repeats R] [--out DIR]``.

    Args:
        argv: the arguments (default: the command line's).

    Returns:
        The exit status.
    """
    p = argparse.ArgumentParser(prog="python -m benchmarks.sharded", description=__doc__.splitlines()[0])
    p.add_argument("--devices", type=int, default=2, help="devices to spread each run over (default 2)")
    p.add_argument("--repeats", type=int, default=2, help="timed runs per case (default 2)")
    p.add_argument("--out", help="a folder to write sharded.json and sharded.md to")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker is not None:
        devices, repeats = json.loads(args.worker)
        print(json.dumps(worker(devices, repeats)))
        return 0
    if args.devices < 2 or args.repeats < 1:
        p.error("--devices must be >= 2 and --repeats >= 1")
    out = pathlib.Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():  # before the runs, not after
        p.error(f"--out {args.out} is a file, not a folder")
    result = run(args.devices, args.repeats, args.out)
    text = table(result)
    print(text)
    if out is not None:
        from jaxmpm._files import write_whole
        from jaxmpm._json import dumps

        out.mkdir(parents=True, exist_ok=True)
        for name, content in (("sharded.json", dumps(result, indent=1) + "\n"), ("sharded.md", text)):
            write_whole(out / name, lambda f, content=content: f.write(content.encode()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
