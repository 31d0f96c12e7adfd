"""Which runs of the 2D blast break down, beside the 1D gas slab at the same pressure ratio.

Gas at P0 (2 or 1.2 bar, density P0 / 1e5 kg/m^3) against 1 bar; a charge of half-width 0.5 m as a
quarter with symmetry planes (2D) and the slab of the same half-width with a wall (1D); h = 1/16,
8 cells, pad 60, dt = h / (4 c), 300 steps; every interpolator, with and without artificial cells,
USL and MUSL. Prints one line per case. About 30 s on 2 cores.

    python experiments/blast_robustness.py
"""

import argparse

import jax

import jaxmpm as jm


def verdict(sol):
    """``"ok"``, or ``"fail@STEP (quantity)"`` for a run that broke down.

    Args:
        sol: a ``Solution`` (run with ``throw=False``).

    Returns:
        The verdict, one word or a short phrase.
    """
    f = sol.failure()
    return "ok" if f is None else f"fail@{f['step']} ({f['quantities'][0].split(' (')[0]})"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    for P0 in (2e5, 1.2e5):
        for name in ("mpq", "cpdi", "spq", "gimp"):
            for ac in (0, 1):
                for ordering in ("usl", "musl"):
                    kw = dict(P0=P0, rho0=P0 / 1e5, h=1 / 16, cells=8, pad=60)
                    slab, charge = jm.GasSlab(**kw), jm.Blast(**kw)
                    dt = 0.25 * float(slab.h) / float(slab.wave_speed)
                    run = dict(dt=dt, steps=300, artificial_cells=ac, throw=False, ordering=ordering)
                    s1 = jm.simulate(slab, jm.INTERPOLATORS[name](), **run)
                    s2 = jm.simulate(charge, jm.INTERPOLATORS[name](), **run)
                    print(
                        f"P0={P0:g} {name:5} ac={ac} {ordering:4}  "
                        f"1D slab: {verdict(s1):40} 2D blast: {verdict(s2)}"
                    )


if __name__ == "__main__":
    main()
