"""The talk's study (same as `jaxmpm study talk`).

Usage: python experiments/talk.py OUT_DIR [--small] [--overwrite]

Writes the study's files (``jaxmpm.studies.talk.OUTPUTS``) to OUT_DIR (default ``results/talk``);
where one of them is already there, it is refused, before anything is computed, unless
``--overwrite``.
"""

import argparse

import jax
from _entry import refuse_existing_in

from jaxmpm.studies import talk


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("out", nargs="?", default="results/talk", metavar="OUT_DIR", help="the folder")
    parser.add_argument("--small", action="store_true", help="one beta and 4 cells instead of three and 8")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace the study's files already in OUT_DIR"
    )
    args = parser.parse_args(argv)
    refuse_existing_in(parser, args.out, talk.OUTPUTS.names, args.overwrite)
    jax.config.update("jax_enable_x64", True)
    return talk.main(out=args.out, small=args.small)


if __name__ == "__main__":
    main()
