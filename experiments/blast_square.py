"""The quarter square blast of `jaxmpm study multid` with remedies: CPDI's largest corner gap and MPQ's
folded quadrilaterals at the end.

1.5 bar in 1 bar, 8 cells per side of the charge, 300 steps of `0.25 h / c` (12.5 ms). For each
interpolator and configuration (transfer, ordering, shear viscosity `c_shear` with the bulk terms
off): the time reached, the status, the largest corner gap over `r0` and the folded domains.

    python experiments/blast_square.py
"""

import argparse

import jax
import numpy as np

import jaxmpm as jm
from jaxmpm import metrics

CONFIGS = (  # transfer, ordering, c_shear
    ("flip", "musl", None),
    ("flip", "musl", 0.5),
    ("apic", "usl", 0.5),
    ("apic", "musl", 0.5),
    ("flip", "usl", 0.5),
)


def run(name: str, transfer: str, ordering: str, shear: float | None) -> str:
    scene = jm.Blast(cells=8, h=0.5 / 8, pad=24)
    dt = 0.25 * float(scene.h) / float(scene.wave_speed)
    visc = None if shear is None else jm.ArtificialViscosity(c_quad=0.0, c_lin=0.0, c_shear=shear)
    sol = jm.simulate(
        scene,
        jm.INTERPOLATORS[name](),
        dt=dt,
        steps=300,
        ordering=ordering,
        transfer=jm.TRANSFERS[transfer](),
        viscosity=visc,
        throw=False,
    )
    corners = jm.domain_corners(sol.state, sol.body, allow_broken=True)  # the line gives the status
    gap = float(np.max(jm.corner_gap(corners, sol.body)))
    folded = int(metrics.folded_domains(corners, sol.body))
    return (
        f"{name} {transfer} {ordering} shear={shear}: t = {float(sol.state.t) * 1e3:.2f} ms, status "
        f"{int(sol.state.status)}, corner gap {gap:.3f} r0, folded {folded}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    for name in ("cpdi", "mpq"):
        for config in CONFIGS:
            print(run(name, *config), flush=True)


if __name__ == "__main__":
    main()
