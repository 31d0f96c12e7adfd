"""cpGIMP with artificial cells at the stationary left end of the gas expansion: error against dt.

Prints the relative F error of the leftmost and rightmost particles at several times for three time
steps, at the scene defaults and at a softer gas (P0 = p_atm = 1e5 Pa, beta = 100 /s). An error that
halves with dt is a time-discretisation error; one that does not is a property of the semi-discrete
scheme. Usage: python experiments/cpgimp_boundary.py [--small]
"""

import argparse

import jax
import numpy as np

import jaxmpm as jm

TIMES = (2.5e-4, 5e-4, 7.5e-4, 1.0e-3, 1.25e-3)


def measure(small: bool = False) -> list[dict]:
    """Run both cases at each time step and print the end particles' errors (float64: ``main``
    switches it on).

    Args:
        small: two time steps instead of three.

    Returns:
        One row per case and time step: ``left`` and ``right`` errors at ``TIMES``, and the status.
    """
    rows = []
    cases = {
        "defaults": jm.GasExpansion(),
        "P0=p_atm=1e5, beta=100": jm.GasExpansion(P0=1e5, p_atm=1e5, beta=100.0),
    }
    for label, scene in cases.items():
        for dt in (1e-5, 5e-6) if small else (1e-5, 5e-6, 2.5e-6):
            steps = int(round(TIMES[-1] / dt))
            sol = jm.simulate(
                scene,
                jm.GIMP(contiguous=True),
                dt=dt,
                steps=steps,
                artificial_cells=1,
                saveat=jm.SaveAt(every=1, fields=("F",)),
                throw=False,
            )
            F_exact = 1 + float(scene.beta) * np.asarray(sol.ts)
            F = np.asarray(sol.history["F"][:, :, 0, 0])
            idx = [int(round(t / dt)) for t in TIMES]
            left = np.abs(F[idx, 0] / F_exact[idx] - 1)
            right = np.abs(F[idx, -1] / F_exact[idx] - 1)
            rows.append(
                dict(case=label, dt=dt, left=left.tolist(), right=right.tolist(), status=int(sol.status))
            )
            print(
                f"{label:24s} dt={dt:8.1e}  left  "
                + " ".join(f"{e:8.2e}" for e in left)
                + "   right "
                + " ".join(f"{e:8.2e}" for e in right)
                + f"   status={int(sol.status)}"
            )
    return rows


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--small", action="store_true", help="two time steps instead of three")
    args = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    print("relative F error of the end particles at t = " + ", ".join(f"{t:g}" for t in TIMES))
    return measure(small=args.small)


if __name__ == "__main__":
    main()
