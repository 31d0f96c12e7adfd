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

import sys

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxmpm as jm  # noqa: E402
from jaxmpm.studies import blast  # noqa: E402

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


def main(argv: list[str]) -> None:
    ratios = [float(argv[0])] if argv else [10.0, 100.0]
    cells = int(argv[1]) if len(argv) > 1 else 32
    interpolator = argv[2] if len(argv) > 2 else "cpdi"
    for ratio in ratios:
        for transfer in ("flip", "apic"):
            print(f"slab at {ratio:g}:1, {cells} cells, {interpolator.upper()}, {transfer.upper()}")
            print("\n".join(history(ratio, cells, transfer, interpolator)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
