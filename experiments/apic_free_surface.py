"""APIC at a free surface expanding into near vacuum: where the energy of the 1D slab goes.

The planar analogue of the blast study's disk (``jaxmpm.studies.blast.make_slab``: gas at ``ratio`` bar
and 1.5 kg/m^3 against 1 bar, 0.5 m thick, a wall at 0, 32 cells, 2 particles per cell), with CPDI (or
another interpolator) under FLIP and APIC, to fractions of two sound transits of the thickness
(``cfl = 0.3``). For each: the change of the total energy (kinetic plus stored,
``jaxmpm.metrics.diagnostics``; the stored energy of the gas includes the work against the atmosphere
and is zero at rest, so the exact motion keeps the total at zero) as a fraction of the kinetic energy
then, and the velocities of the outermost particle and of the one inside it. About 10 s on 2 cores.

    python experiments/apic_free_surface.py            # ratios 10 and 100
    python experiments/apic_free_surface.py 100 64     # one ratio, and the cells across the slab
    python experiments/apic_free_surface.py 100 32 mpq # another interpolator (default cpdi)
"""

import argparse

import jax
import numpy as np
from _entry import positive

import jaxmpm as jm
from jaxmpm.studies import blast

FRACTIONS = (0.05, 0.1, 0.2, 0.3, 0.5, 1.0)


def history(ratio: float, cells: int, transfer: str, interpolator: str = "cpdi") -> list[str]:
    slab, disk = blast.make_slab(ratio, cells)
    T = blast.TRANSITS * float(disk.transit_time)
    lines = []
    for frac in FRACTIONS:
        sol = jm.simulate(
            slab,
            jm.INTERPOLATORS[interpolator](),
            transfer=jm.TRANSFERS[transfer](),
            t_end=max(frac, 1e-9) * T,
            cfl=blast.CFL,
            max_steps=blast.max_steps(cells),
            throw=False,
        )
        d = jm.metrics.diagnostics(slab, sol.state, sol.body)
        e, kinetic = float(d["energy"]), float(d["energy_kinetic"])  # the total starts at 0
        v = np.asarray(sol.state.v)[:, 0]
        fail = sol.failure()
        t = float(sol.state.t) / T
        status = "ok" if fail is None else f"broke down at {t:.2f}: {', '.join(fail['quantities'])}"
        lines.append(
            f"  t = {frac:4.2f} of two transits: energy gained {e / kinetic:+8.2%} "
            f"of the kinetic energy ({kinetic:.3g} J/m^2), outermost particle "
            f"{v[-1]:8.0f} m/s, the next {v[-2]:8.0f} m/s; {status}"
        )
        if fail is not None:
            break
    return lines


def _ratio(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a pressure ratio is a number above 1, got {text!r}") from None
    if not 1.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"a pressure ratio is a number above 1, got {text!r}")
    return value


def _cells(text: str) -> int:
    return positive(text, "the cells across the slab are an integer >= 1")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "ratio",
        metavar="RATIO",
        type=_ratio,
        nargs="?",
        default=None,
        help="the pressure ratio (default: 10 and 100)",
    )
    parser.add_argument(
        "cells",
        metavar="CELLS",
        type=_cells,
        nargs="?",
        default=32,
        help="cells across the slab (default 32)",
    )
    parser.add_argument(
        "interpolator",
        nargs="?",
        default="cpdi",
        choices=list(jm.INTERPOLATORS),
        metavar="INTERPOLATOR",
        help=f"one of {', '.join(jm.INTERPOLATORS)} (default cpdi)",
    )
    args = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    ratios = [args.ratio] if args.ratio is not None else [10.0, 100.0]
    cells, interpolator = args.cells, args.interpolator
    for ratio in ratios:
        for transfer in ("flip", "apic"):
            print(f"slab at {ratio:g}:1, {cells} cells, {interpolator.upper()}, {transfer.upper()}")
            print("\n".join(history(ratio, cells, transfer, interpolator)), flush=True)


if __name__ == "__main__":
    main()
