"""How XLA's CPU backend prices a power law ``J ** p`` against ``exp(p log J)`` (``jaxmpm._util.power``).

Each form is one jitted elementwise map over ``n`` volume ratios ``J`` in ``[0.9, 1.1]`` with a
traced exponent, timed best of 200 calls; a plain product is the floor. The largest difference of
the two forms is printed in ulps of the power.

    python experiments/power_forms.py [--n 102400]
"""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np


def best_ms(f, *args, repeats: int = 200) -> float:
    jax.block_until_ready(f(*args))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(*args))
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=102_400)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    forms = {
        "J ** p": jax.jit(lambda J, p: J**p),
        "exp(p log J)": jax.jit(lambda J, p: jnp.exp(p * jnp.log(J))),
        "J * p (floor)": jax.jit(lambda J, p: J * p),
    }
    rng = np.random.default_rng(0)
    for dtype in (jnp.float32, jnp.float64):
        J = jnp.asarray(rng.uniform(0.9, 1.1, args.n), dtype=dtype)
        p = jnp.asarray(-1.4, dtype=dtype)
        for name, f in forms.items():
            print(f"{jnp.dtype(dtype).name:8s} {name:14s} {best_ms(f, J, p):7.3f} ms")
        a, b = forms["J ** p"](J, p), forms["exp(p log J)"](J, p)
        ulps = float(jnp.max(jnp.abs(a - b) / jnp.spacing(a)))
        print(f"{jnp.dtype(dtype).name:8s} largest difference of the two forms: {ulps:.1f} ulps")


if __name__ == "__main__":
    main()
