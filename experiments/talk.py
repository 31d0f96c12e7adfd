"""The talk's study (same as `jaxmpm study talk`). Usage: python experiments/talk.py OUT_DIR [--small]"""

import sys

import jax

jax.config.update("jax_enable_x64", True)

from jaxmpm.studies import talk  # noqa: E402

if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    talk.main(out=args[0] if args else "results/talk", small="--small" in sys.argv)
