"""USL (the talk's ordering) against MUSL: which runs break down, and when.

Gas expansion at beta = 20 /s (slow, so nothing but the numerics can break it), 400 steps, for 8, 50
and 500 cells and CFL numbers dt c0 / h of 0.5, 0.25 and 0.05, every interpolator with and without
artificial cells. Prints 'ok' or 'X@k' (broke down at step k, with the quantity in the run's status).
Usage: python experiments/ordering_stability.py [--small]
"""

import argparse

import jax

import jaxmpm as jm

C0 = (1.4 * 2.0e5 / 1.0) ** 0.5  # sound speed of the default gas at F = 1


def measure(small: bool = False) -> dict:
    """Run every case under USL and MUSL and print one line per ordering, size and CFL number (float64:
    ``main`` switches it on).

    Args:
        small: 8 cells only.

    Returns:
        ``{(ordering, cells, cfl, interpolator, artificial_cells): failed step (-1 if none)}``.
    """
    results = {}
    sizes = ((8, 0.125),) if small else ((8, 0.125), (50, 0.02), (500, 0.002))
    for ordering in ("usl", "musl"):
        for cells, h in sizes:
            for cfl in (0.5, 0.25, 0.05):
                scene = jm.GasExpansion(cells=cells, h=h, beta=20.0, pad=max(10, cells // 8))
                row = []
                for name, make in jm.INTERPOLATORS.items():
                    for ac in (0, 1):
                        sol = jm.simulate(
                            scene,
                            make(),
                            dt=cfl * h / C0,
                            steps=400,
                            artificial_cells=ac,
                            throw=False,
                            ordering=ordering,
                        )
                        step = int(sol.state.fail_step)
                        results[(ordering, cells, cfl, name, ac)] = step
                        row.append(f"{name}/{ac}:{'ok' if step < 0 else f'X@{step}'}")
                print(f"{ordering:4s} cells={cells:<4d} CFL={cfl:<5g} " + " ".join(row))
    return results


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--small", action="store_true", help="8 cells only")
    args = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    return measure(small=args.small)


if __name__ == "__main__":
    main()
