"""Throughput of the step against NumPy, plain JAX, Taichi and Warp.

The same as ``jaxmpm bench`` (see ``benchmarks/bench.py`` for what is measured and how); Taichi and
Warp are measured when installed (``pip install -e ".[bench]"``).

    python experiments/bench.py [--sizes 1000,8000,64000,256000,1000000] [--steps 100]
                                [--dtypes f32,f64] [--codes numpy,jax,taichi,warp,jaxmpm]
                                [--no-extras] [--out docs/bench]
"""

import sys

from jaxmpm.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
