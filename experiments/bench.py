"""Throughput of the step against NumPy, plain JAX, Taichi and Warp.

The same as ``jaxmpm bench`` (see ``benchmarks/bench.py`` for what is measured and how); Taichi and
Warp are measured when installed (``pip install -e ".[bench]"``).

    python experiments/bench.py [--sizes 1000,8000,64000,256000,1000000] [--steps 100]
                                [--dtypes f32,f64] [--codes numpy,jax,taichi,warp,jaxmpm]
                                [--no-extras] [--out docs/bench [--overwrite]]
"""

import sys

from jaxmpm import cli


def main(argv: list[str] | None = None) -> None:
    """Run ``jaxmpm bench`` with ``argv`` (default: ``sys.argv[1:]``) and exit with its status (its
    options, their checks and ``--out``'s refusal of files already there without ``--overwrite``)."""
    sys.exit(cli.main(["bench", *(sys.argv[1:] if argv is None else argv)]))


if __name__ == "__main__":
    main()
