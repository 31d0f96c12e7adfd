"""Hashes of final states and derivatives over a matrix of float64 runs: does a change to the step move
any result, even in the last bit?

A run without ``devices`` stays bit for bit what it is, so a change made for speed is kept only if
every hash is unchanged. Hash the code as it is, make the change, hash again and compare:

    python experiments/state_hashes.py --out /tmp/before.json
    python experiments/state_hashes.py --out /tmp/after.json --compare /tmp/before.json

The matrix (216 runs, 5-10 minutes on 2 cores):

- the gas expansion in 1D, 2D and 3D with every interpolator and transfer, with and without an
  artificial cell, USL (and MUSL for FLIP with the artificial cell), 15 steps;
- in 2D and 3D, every interpolator with the nodal volume average (``volume_average="node"``);
- for every interpolator and dimension, the derivative in ``beta`` of a scalar of the final state,
  reverse mode (``jax.grad``) and forward mode (``jax.jacfwd``);
- the gas expansion with particle counts that are not multiples of 8 (14 in 1D, 100 in 2D, 125 in
  3D, which the run pads with inert copies), every interpolator, an artificial cell, 15 steps;
- six other scenes (the blast disk, the axis-aligned scene, Sod's shock tube, Noh's problem, the
  detonation and the Gurney slab) with SPQ, GIMP, CPDI and MPQ, CFL-limited steps to ``t_end = 1e-4``
  within at most 40 steps (the detonation and the slab stop at that limit, SPQ and MPQ break down in
  the blast disk: both are hashed as they return).

Each line gives a run's key, the first 16 hex digits of the sha1 of every array of its final state
(or of the derivative), and the run's status: a run that breaks down or stops at its step limit is
hashed as what it returns (its last good state), so a change to where it stops shows too. With
``--compare`` the script lists the runs whose hash differs and exits with status 1 if any does, or
if a run of the earlier file is not run here; a run the earlier file lacks (one added to the matrix
since) is listed as new and not compared.

Hashes depend on the CPU and on the versions of JAX and XLA: compare two files made on one machine
with one environment, never with a file made elsewhere.

An existing ``--out`` is refused, before anything is run, unless ``--overwrite``.
"""

import argparse
import hashlib
import json
import sys

import jax
import numpy as np
from _entry import refuse_existing

from jaxmpm.studies._output import write_text


def _read_hashes(parser: argparse.ArgumentParser, path: str) -> dict:
    """The hashes of ``path``, a JSON file of an earlier run; a usage error where it cannot be read or
    is not one."""
    try:
        with open(path) as f:
            hashes = json.load(f)
    except OSError as e:
        parser.error(f"argument --compare: cannot read {path}: {e.strerror or e}")
    except (ValueError, UnicodeDecodeError) as e:
        parser.error(f"argument --compare: {path} is not JSON: {e}")
    if not isinstance(hashes, dict) or not all(isinstance(v, str) for v in hashes.values()):
        parser.error(f"argument --compare: {path} is not a file of this script (run key: hash)")
    return hashes


def _hash(tree) -> str:
    h = hashlib.sha1()
    for leaf in jax.tree.leaves(tree):
        if isinstance(leaf, jax.Array | np.ndarray):
            h.update(np.asarray(leaf).tobytes())
    return h.hexdigest()[:16]


def _runs():
    """Yield ``(key, thunk)`` for every run of the matrix; a thunk returns ``(tree, status)``."""
    import jax.numpy as jnp

    import jaxmpm as jm

    def scene(dim, beta=None):
        if dim == 1:
            return jm.GasExpansion(beta=200.0 if beta is None else beta, cells=8, h=0.125, pad=10)
        return jm.GasExpansion(beta=5.0 if beta is None else beta, cells=6, h=1 / 6, pad=4, dim=dim)

    def dt(dim):
        return 2e-5 if dim == 1 else 1e-4

    def state(sol):
        return sol.state, int(sol.state.status)

    for dim in (1, 2, 3):
        for name, make in jm.INTERPOLATORS.items():
            for transfer, make_transfer in jm.TRANSFERS.items():
                for cells in (0, 1):
                    for order in ("usl", "musl") if transfer == "flip" and cells == 1 else ("usl",):
                        yield (
                            f"{dim}D {name} {transfer} artificial_cells={cells} {order}",
                            lambda dim=dim, make=make, t=make_transfer, c=cells, o=order: state(
                                jm.simulate(
                                    scene(dim),
                                    make(),
                                    dt=dt(dim),
                                    steps=15,
                                    transfer=t(),
                                    artificial_cells=c,
                                    ordering=o,
                                    throw=False,
                                )
                            ),
                        )
            if dim > 1:
                yield (
                    f"{dim}D {name} volume_average=node",
                    lambda dim=dim, make=make: state(
                        jm.simulate(
                            scene(dim), make(), dt=dt(dim), steps=15, volume_average="node", throw=False
                        )
                    ),
                )
            for mode, derivative in (("reverse", jax.grad), ("forward", jax.jacfwd)):

                def f(beta, dim=dim, make=make):
                    sol = jm.simulate(
                        scene(dim, beta), make(), dt=dt(dim), steps=10, artificial_cells=1, throw=False
                    )
                    return jnp.mean(sol.state.F) + jnp.mean(sol.state.x**2)

                yield (
                    f"{dim}D {name} d/dbeta {mode} mode",
                    lambda derivative=derivative, f=f, dim=dim: (
                        derivative(f)(jnp.asarray(200.0 if dim == 1 else 5.0)),
                        0,
                    ),
                )
    # Particle counts that are not multiples of 8: the drivers pad them (jaxmpm._step.pad_particles).
    odd = {
        1: dict(beta=200.0, cells=7, h=1 / 7, pad=10),
        2: dict(beta=5.0, cells=5, h=1 / 5, pad=4, dim=2),
        3: dict(beta=5.0, cells=5, h=1 / 5, pad=4, dim=3, ppc=1),
    }
    for dim, kw in odd.items():
        for name, make in jm.INTERPOLATORS.items():
            yield (
                f"{dim}D {name} padded artificial_cells=1",
                lambda dim=dim, make=make, kw=kw: state(
                    jm.simulate(
                        jm.GasExpansion(**kw), make(), dt=dt(dim), steps=15, artificial_cells=1, throw=False
                    )
                ),
            )
    for name in ("blast-disk", "axis-aligned", "shock-tube", "noh", "detonation", "gurney-slab"):
        for interpolator in ("spq", "gimp", "cpdi", "mpq"):
            yield (
                f"{name} {interpolator}",
                lambda name=name, i=interpolator: state(
                    jm.simulate(
                        jm.SCENES[name](),
                        jm.INTERPOLATORS[i](),
                        t_end=1e-4,
                        max_steps=40,
                        throw=False,
                    )
                ),
            )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="the JSON file to write the hashes to")
    parser.add_argument("--overwrite", action="store_true", help="replace --out where it exists")
    parser.add_argument("--compare", help="a JSON file of an earlier run of this script to compare with")
    args = parser.parse_args(argv)
    refuse_existing(parser, "--out", [args.out], args.overwrite)
    earlier = None if args.compare is None else _read_hashes(parser, args.compare)
    jax.config.update("jax_enable_x64", True)

    hashes = {}
    for key, run in _runs():
        tree, status = run()
        hashes[key] = _hash(tree)
        jax.clear_caches()  # each compiled program holds memory maps; a process may hold only so many
        print(f"{key}: {hashes[key]} (status {status})", flush=True)
    write_text(args.out, json.dumps(hashes, indent=1))
    if earlier is None:
        return 0
    differ = [k for k in hashes if k in earlier and earlier[k] != hashes[k]]
    missing = [k for k in earlier if k not in hashes]
    new = [k for k in hashes if k not in earlier]
    print(
        f"{len(hashes)} runs, {len(differ)} differ from {args.compare}"
        + (f", {len(missing)} missing" if missing else "")
        + (f", {len(new)} new (not in it, not compared)" if new else "")
    )
    for k in differ:
        print(f"  differs: {k}")
    for k in missing:
        print(f"  not run here: {k}")
    for k in new:
        print(f"  new: {k}")
    return 1 if differ or missing else 0


if __name__ == "__main__":
    sys.exit(main())
