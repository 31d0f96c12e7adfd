"""Particle counts that are not a multiple of 8, or that the devices do not divide: how each layout runs.

The 1D gas slab (``--interpolator``, float64, ``--n`` particles), each layout in a process of its own
with ``--devices`` forced host devices (``XLA_FLAGS=--xla_force_host_platform_device_count``; the
one-device layouts without):

- ``one``: one device (``devices=None``), as ``simulate`` runs it, padded with inert particles to a
  multiple of ``jaxmpm._step.PAD_SHARE``;
- ``one-unpadded``: one device, not padded;
- ``aligned``: over the devices as ``simulate`` runs it, padded to an equal share a device that is a
  multiple of ``PAD_SHARE``;
- ``equal``: padded to an equal share only (``PAD_SHARE = 1``);
- ``xla``: not padded, the particle axis laid out over the devices all the same, so that XLA's
  partitioner splits an axis the devices do not divide in its own way.

For each it prints the time of one step (the difference of a 70-step and a 20-step run over 50, best
of three rounds each, compile time apart), the particles a device holds in the time loop, and the
collectives XLA runs in the loop each step.

::

    python experiments/uneven_shards.py [--n 500000,500001,500002,500008] [--devices 2]
        [--layouts one,one-unpadded,aligned,equal,xla] [--interpolator spq]
"""

import argparse
import json
import os
import re
import subprocess
import sys
import time

from _entry import interpolators, positive

LAYOUTS = ("one", "one-unpadded", "aligned", "equal", "xla")


def _counts(text: str) -> list[int]:
    return [positive(t, "particle counts, integers >= 1 separated by commas") for t in text.split(",")]


def _layouts(text: str) -> list[str]:
    names = text.split(",")
    bad = [n for n in names if n not in LAYOUTS]
    if bad or not text:
        raise argparse.ArgumentTypeError(f"layouts among {', '.join(LAYOUTS)}, got {text!r}")
    return names


def child(layout: str, n: int, devices: int, interpolator: str) -> dict:
    """Time one layout in this process (its forced device count set by the parent)."""
    import jax
    import numpy as np

    jax.config.update("jax_enable_x64", True)
    import jaxmpm as jm
    import jaxmpm._simulate as sim
    import jaxmpm._step as stp

    if layout == "equal":
        stp.PAD_SHARE = 1
    if layout == "one-unpadded":
        sim.pad_particles = lambda model, setup, state: (setup, state)
    if layout == "xla":

        def spread(model, tree, count):
            if model.devices is None:
                return tree
            mesh = jax.sharding.Mesh(np.asarray(model.devices, dtype=object), ("particles",))
            part = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("particles"))
            whole = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec())

            def lay(a):
                return jax.lax.with_sharding_constraint(a, part if a.ndim and a.shape[0] == count else whole)

            return jax.tree.map(lay, tree)

        sim.pad_particles = lambda model, setup, state: (setup, state)
        sim.shard_particles = spread
    on = None if layout.startswith("one") else devices
    make = jm.INTERPOLATORS[interpolator]
    scene = jm.GasSlab(cells=n, h=1.0 / n, ppc=1, pad=64)
    best = {}
    for steps in (20, 70):
        times = []
        for _ in range(3):
            sol, _, wall = jm.simulate_timed(scene, make(), dt=1e-9, steps=steps, devices=on, throw=False)
            times.append(wall)
        best[steps] = min(times)
    model, dt, count, saveat = sim.prepare(scene, make(), dt=1e-9, steps=20, devices=on)
    text = sim._run_scan_jit.lower(model, dt, count, saveat, None).compile().compiled.as_text()
    time_loop = 'op_name="jit(run_scan)/while"'
    loop = [line for line in text.splitlines() if " while(" in line and time_loop in line]
    held = re.search(r"f64\[(\d+),1\]", loop[0].split(" while(")[0]).group(1)
    per_step = []
    for line in text.splitlines():
        for kind in ("all-reduce", "all-gather", "collective-permute", "all-to-all"):
            if f" {kind}(" in line and "/while/body" in line:
                shape = line.split("=", 1)[1].split(f" {kind}(")[0].strip()
                per_step.append(f"{kind} {shape}")
    return dict(
        layout=layout,
        n=n,
        step_ms=1e3 * (best[70] - best[20]) / 50,
        held=int(held),
        per_step=per_step,
        status=int(sol.state.status),
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=_counts, default=[500_000, 500_001, 500_002, 500_008])
    parser.add_argument("--devices", type=positive, default=2, help="forced host devices (default 2)")
    parser.add_argument("--layouts", type=_layouts, default=list(LAYOUTS))
    parser.add_argument("--interpolator", type=interpolators, default=["spq"], help="one of INTERPOLATORS")
    parser.add_argument("--child", nargs=2, metavar=("LAYOUT", "N"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child[0], int(args.child[1]), args.devices, args.interpolator[0])))
        return
    if args.devices < 2:
        parser.error("--devices must be 2 or more")
    if len(args.interpolator) != 1:
        parser.error(f"--interpolator takes one name, got {','.join(args.interpolator)}")
    flags = os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={args.devices}"
    env = dict(os.environ, XLA_FLAGS=flags.strip())
    when = time.strftime("%Y-%m-%d %H:%M")
    print(f"1D gas slab, {args.interpolator[0]}, float64, {args.devices} forced host devices ({when})")
    print("| particles | layout | ms a step | particles a device in the loop | collectives each step |")
    print("|---|---|---|---|---|")
    for n in args.n:
        for layout in args.layouts:
            out = subprocess.run(
                [sys.executable, __file__, "--child", layout, str(n), "--devices", str(args.devices)]
                + ["--interpolator", args.interpolator[0]],
                env=os.environ if layout.startswith("one") else env,  # one device: XLA's own setup
                capture_output=True,
                text=True,
            )
            if out.returncode:
                sys.exit(out.stderr[-2000:])
            r = json.loads(out.stdout.strip().splitlines()[-1])
            note = "" if r["status"] == 0 else f" (status {r['status']})"
            print(
                f"| {n:,} | {layout} | {r['step_ms']:.1f}{note} | {r['held']:,} | "
                f"{'; '.join(r['per_step']) or 'none'} |"
            )


if __name__ == "__main__":
    main()
