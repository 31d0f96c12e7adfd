"""d(F error)/d(beta) and d(F error)/d(h) for every interpolator, with and without artificial cells.

Usage: python experiments/sensitivity.py [OUT_DIR] [--small] [--musl] [--overwrite]
(default OUT_DIR: results/sensitivity)

Writes ``sensitivity.csv``, ``sensitivity_beta.png`` and ``sensitivity_h.png`` to OUT_DIR (with
``--musl``: ``sensitivity_musl.csv``, ...), through ``jaxmpm.studies.sensitivity.main``. Where one of
them is already there, it is refused, before anything is computed, unless ``--overwrite``.
"""

import argparse

import jax
from _entry import refuse_existing_in

from jaxmpm.studies import sensitivity


def files(ordering: str) -> tuple[str, ...]:
    """The files ``jaxmpm.studies.sensitivity.main`` writes for ``ordering``."""
    tag = "" if ordering == "usl" else f"_{ordering}"
    return (f"sensitivity{tag}.csv", f"sensitivity_beta{tag}.png", f"sensitivity_h{tag}.png")


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("out", nargs="?", default="results/sensitivity", metavar="OUT_DIR", help="the folder")
    parser.add_argument(
        "--small", action="store_true", help="fewer values of beta and h, 4 cells instead of 8"
    )
    parser.add_argument("--musl", action="store_true", help="MUSL instead of USL")
    parser.add_argument("--overwrite", action="store_true", help="replace the files already in OUT_DIR")
    args = parser.parse_args(argv)
    ordering = "musl" if args.musl else "usl"
    refuse_existing_in(parser, args.out, files(ordering), args.overwrite)
    jax.config.update("jax_enable_x64", True)
    return sensitivity.main(out=args.out, small=args.small, ordering=ordering)


if __name__ == "__main__":
    main()
