"""How far the 2D disk charge runs, and how smooth it stays, against its 1D radial reference.

Gas at 10 bar and 1.5 kg/m^3 against 1 bar, a disk of radius 0.5 m as a quarter with symmetry planes,
32 cells across the radius (2 particles per cell and axis unless told), `cfl = 0.3`, to two sound
transits of the radius. For each configuration: the status (and when it broke down, as a fraction of
two transits), and at the last good state the radial-velocity error (L1, relative) against the
reference at the particles' reference radii, the outer ring's radial position error, the angular
spread of the radial velocity (detrended, bins of one cell), the largest spurious rotation and the
folded domains. About 10 s a configuration on 2 cores.

    python experiments/blast_disk.py                  # the table of docs/multid.md
    python experiments/blast_disk.py cpdi flip node   # one configuration: interpolator transfer [options]

Options: `musl`, `visc` (artificial viscosity), `shear=C` (a shear viscosity of coefficient C), `cell`
or `node` (volume averaging), `ppc1`, `ratio=R`, `cells=N`, `pad=P` (grid beyond the charge, in radii),
`cutoff=K`: a nodal-mass cutoff, not an option of `simulate` (this script sets the run's round-off
floor of nodal mass, `Setup.tiny`, to K times the largest particle mass): a node with less mass gets
no velocity and no acceleration, and its force is folded onto its neighbours with mass.
"""

import argparse
import contextlib
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxmpm as jm
from jaxmpm import _simulate, metrics


@contextlib.contextmanager
def _mass_cutoff(k: float | None):
    """Within, runs count a node with less than ``k`` times the largest particle mass as empty (the
    driver's ``setup`` replaced; compiled runs dropped on entry and exit, so none is reused across)."""
    if k is None:
        yield
        return
    plain = _simulate.setup

    def setup(model):
        s = plain(model)
        return eqx.tree_at(lambda s: s.tiny, s, k * jnp.max(s.body.m))

    jax.clear_caches()
    _simulate.setup = setup
    try:
        yield
    finally:
        _simulate.setup = plain
        jax.clear_caches()


CONFIGS = [
    ("cpdi", "flip", ()),
    ("cpdi", "flip", ("ppc1",)),
    ("cpdi", "flip", ("musl",)),
    ("cpdi", "flip", ("node",)),
    ("cpdi", "flip", ("cell", "visc")),
    ("cpdi", "flip", ("visc",)),
    ("cpdi", "apic", ()),
    ("mpq", "flip", ()),
    ("mpq", "apic", ("musl",)),
]


def _viscosity(opts, kv):
    """``visc``: the bulk viscosity; ``shear=C``: a shear viscosity of coefficient C (bulk terms 0
    unless ``visc`` is given too)."""
    shear = float(kv["shear"]) if "shear" in kv else None
    if "visc" in opts:
        return jm.ArtificialViscosity(c_shear=shear)
    return None if shear is None else jm.ArtificialViscosity(c_quad=0.0, c_lin=0.0, c_shear=shear)


def run(interp: str, transfer: str, opts: tuple[str, ...]) -> str:
    kv = dict(o.split("=") for o in opts if "=" in o)
    ratio, cells = float(kv.get("ratio", 10.0)), int(kv.get("cells", 32))
    ppc = 1 if "ppc1" in opts else 2
    pad = float(kv.get("pad", 4.5 if ratio > 50 else 2.5))  # grid beyond the charge, in radii
    scene = jm.BlastDisk(P0=ratio * 1e5, cells=cells, ppc=ppc, pad=int(pad * cells))
    T = 2.0 * float(scene.transit_time)
    kwargs = dict(
        transfer=jm.TRANSFERS[transfer](),
        ordering="musl" if "musl" in opts else "usl",
        viscosity=_viscosity(opts, kv),
        volume_average=next((o for o in opts if o in ("cell", "node")), None),
    )
    with _mass_cutoff(float(kv["cutoff"]) if "cutoff" in kv else None):
        sol = jm.simulate(
            scene, jm.INTERPOLATORS[interp](), t_end=T, cfl=0.3, max_steps=20000, throw=False, **kwargs
        )
    st, body = sol.state, sol.body
    ref = scene.reference(np.array([float(st.t)]))
    R = np.asarray(metrics.reference_radius(body, scene.centre))
    at = ref.at(R)
    v_ref = np.asarray(at["v"][0])
    # a broken run's last good state is measured, and the row says it broke down
    v_r = np.asarray(metrics.radial_velocity(st, body, scene.centre, allow_broken=True))
    r = np.linalg.norm(np.asarray(st.x), axis=1)
    ring = R > float(scene.radius) - 0.6 * float(scene.h)
    spread = metrics.angular_spread(st, body, scene.centre, bins=cells, detrend=True, allow_broken=True)
    rotation = metrics.spurious_rotation(st, body, allow_broken=True)
    folded = int(metrics.folded_domains(metrics.domain_corners(st, body, allow_broken=True), body))
    status = int(st.status)
    what = (
        "ran through"
        if status == 0
        else f"broke down at {float(st.t) / T:.2f}: " + ", ".join(jm.status.describe(status))
    )
    return (
        f"{interp} {transfer} {' '.join(opts) or '-'}: {what}; v_r L1 "
        f"{np.sum(np.abs(v_r - v_ref)) / np.sum(np.abs(v_ref)):.3f}, outer ring radius "
        f"{np.max(np.abs(r[ring] / np.asarray(at['r'][0])[ring] - 1.0)):.3f}, spread "
        f"{float(spread['max']):.3f}, rotation {float(rotation['max']):.2f} rad, folded {folded}"
    )


FLAGS = ("musl", "visc", "cell", "node", "ppc1")
"""The options without a value."""
VALUES = {  # option: (its type, the least value, whether the least is allowed, what it is)
    "shear": (float, 0.0, True, "a number >= 0"),
    "ratio": (float, 1.0, False, "a number above 1"),
    "cells": (int, 1, True, "an integer >= 1"),
    "pad": (float, 0.0, True, "a number >= 0"),
    "cutoff": (float, 0.0, True, "a number >= 0"),
}
"""The options ``KEY=VALUE``."""


def _option(text: str) -> str:
    """``text``, once it is one of ``FLAGS`` or ``KEY=VALUE`` with ``KEY`` of ``VALUES`` and a value
    it allows."""
    if text in FLAGS:
        return text
    key, eq, value = text.partition("=")
    if not eq or key not in VALUES:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not an option: one of {', '.join(FLAGS)}, or "
            f"{', '.join(f'{k}=VALUE' for k in VALUES)}"
        )
    kind, least, inclusive, what = VALUES[key]
    try:
        number = kind(value)
    except ValueError:
        number = None
    if number is None or not math.isfinite(number) or number < least or (number == least and not inclusive):
        raise argparse.ArgumentTypeError(f"{key} is {what}, got {value!r}")
    return text


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "interpolator",
        nargs="?",
        choices=list(jm.INTERPOLATORS),
        metavar="INTERPOLATOR",
        help=f"one of {', '.join(jm.INTERPOLATORS)} (none: the table of docs/multid.md)",
    )
    parser.add_argument(
        "transfer", nargs="?", choices=list(jm.TRANSFERS), metavar="TRANSFER", help=", ".join(jm.TRANSFERS)
    )
    parser.add_argument("options", nargs="*", type=_option, metavar="OPTION", help="see above")
    args = parser.parse_args(argv)
    if args.interpolator is not None and args.transfer is None:
        parser.error(f"an interpolator is followed by a transfer: one of {', '.join(jm.TRANSFERS)}")
    if "cell" in args.options and "node" in args.options:
        parser.error("one volume averaging: cell or node, not both")
    jax.config.update("jax_enable_x64", True)
    if args.interpolator is not None:
        print(run(args.interpolator, args.transfer, tuple(args.options)))
    else:
        for interp, transfer, opts in CONFIGS:
            print(run(interp, transfer, opts), flush=True)


if __name__ == "__main__":
    main()
