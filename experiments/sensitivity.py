"""d(F error)/d(beta) and d(F error)/d(h) for every interpolator, with and without artificial cells.

Usage: python experiments/sensitivity.py [OUT_DIR] [--small] [--musl]   (default OUT_DIR: results/sensitivity)
"""

import sys

import jax

jax.config.update("jax_enable_x64", True)

from jaxmpm.studies import sensitivity  # noqa: E402

if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    sensitivity.main(
        out=args[0] if args else "results/sensitivity",
        small="--small" in sys.argv,
        ordering="musl" if "--musl" in sys.argv else "usl",
    )
