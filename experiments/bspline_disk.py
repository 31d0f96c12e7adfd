"""Quadratic B-spline shape functions on the round gas charge: measured, and not kept in the library.

Runs the 2D disk of `jaxmpm study blast` (32 cells across the radius, two sound transits) at 1.5, 10
and 100 to 1 with `BSpline` (`experiments/bspline.py`: standard MPM on quadratic B-splines, Steffen,
Kirby & Berzins 2008) under each remedy of the study, measured as the study measures its rows, and
prints one line per run. About 2 minutes on 2 cores.

    python experiments/bspline_disk.py

What it found (docs/multid.md): B-splines never fail with F <= 0 in the disk, but they are far less
accurate than CPDI (at 10:1 with APIC and the shear viscosity, `v_r` L1 0.195 and the outer ring 7.7%
off, against CPDI's 0.039 and 0.8%), and three pieces of the library assume hats: walls and symmetry
planes hold the node beyond the face at rest rather than mirroring it, face tractions are loaded with
hats, and one layer of artificial cells is too few for a stencil of a cell and a half.
"""

import argparse
import pathlib
import sys

import jax

import jaxmpm as jm
from jaxmpm.studies import blast


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from bspline import BSpline

    # this script's own registry entry, so that the study's runner can make the interpolator by name
    jm.INTERPOLATORS["bspline"] = BSpline
    refs = blast.References()
    for ratio in (1.5, 10.0, 100.0):
        for remedy in blast.REMEDIES:
            r = blast.run_row("disk", ratio, 32, "bspline", remedy, refs)
            measures = "  ".join(f"{k} {r[k]:.3g}" for k in blast.MEASURES)
            print(f"{ratio:g}:1 {remedy}: {blast.status_cell(r)}; {measures}; {r['steps']} steps", flush=True)


if __name__ == "__main__":
    main()
