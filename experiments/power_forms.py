"""How XLA's CPU backend prices a power law ``J ** p`` against ``exp(p log J)`` (``jaxmpm._util.power``).

Each form is one jitted elementwise map over ``n`` volume ratios ``J`` in ``[0.9, 1.1]`` with a
traced exponent, timed best of 200 calls; a plain product is the floor. The largest difference of
the two forms is printed in ulps of the power.

In float64 XLA's ``log`` (like its ``power``) is one library call per element, while its ``exp`` is
a vectorised polynomial. ``log_vectorised`` is a float64 logarithm written in array operations (the
algorithm of fdlibm's ``__ieee754_log``: exponent and mantissa split by bit operations, a polynomial
in ``s = f / (2 + f)``), which XLA vectorises; ``exp(p log_vectorised(J))`` is the third form here,
with its largest error against NumPy's long-double ``log`` over ``[0.2, 5]`` (x86's 80-bit long
double; where long double is float64, the reference is only NumPy's own float64 ``log``).

    python experiments/power_forms.py [--n 102400]
"""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np
from _entry import positive

# fdlibm e_log.c: the coefficients of its polynomial in s^2, and ln 2 in two parts
_LG = (
    6.666666666666735130e-01,
    3.999999999940941908e-01,
    2.857142874366239149e-01,
    2.222219843214978396e-01,
    1.818357216161805012e-01,
    1.531383769920937332e-01,
    1.479819860511658591e-01,
)
_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10


def log_vectorised(x):
    """``log x`` of float64 ``x > 0`` (normal numbers) in array operations: within 1 ulp.

    Zero, negative, subnormal, infinite and NaN inputs are not handled (fdlibm's special cases are
    left out): what it returns for them means nothing."""
    bits = jax.lax.bitcast_convert_type(x, jnp.int64)
    high = (bits >> 32).astype(jnp.int32)
    k = (high >> 20) - 1023
    high = high & 0x000FFFFF
    # the mantissa m in [sqrt(2)/2, sqrt(2)): where m >= sqrt(2), halve it and raise the exponent
    up = (high + 0x95F64) & 0x100000
    m = jax.lax.bitcast_convert_type(
        ((high | (up ^ 0x3FF00000)).astype(jnp.int64) << 32) | (bits & 0xFFFFFFFF), jnp.float64
    )
    k = (k + (up >> 20)).astype(jnp.float64)
    f = m - 1.0
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    R = z * (_LG[0] + w * (_LG[2] + w * (_LG[4] + w * _LG[6]))) + w * (_LG[1] + w * (_LG[3] + w * _LG[5]))
    hfsq = 0.5 * f * f
    return k * _LN2_HI - ((hfsq - (s * (hfsq + R) + k * _LN2_LO)) - f)


def best_ms(f, *args, repeats: int = 200) -> float:
    jax.block_until_ready(f(*args))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(*args))
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=positive, default=102_400, help="volume ratios (default 102,400)")
    args = parser.parse_args(argv)
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
    J = jnp.asarray(rng.uniform(0.9, 1.1, args.n))
    p = jnp.asarray(-1.4)
    vec = jax.jit(lambda J, p: jnp.exp(p * log_vectorised(J)))
    print(f"float64  exp(p log_vectorised J) {best_ms(vec, J, p):7.3f} ms")
    a, b = forms["J ** p"](J, p), vec(J, p)
    ulps = float(jnp.max(jnp.abs(a - b) / jnp.spacing(a)))
    print(f"float64  largest difference from J ** p: {ulps:.1f} ulps, equal in {float(jnp.mean(a == b)):.1%}")
    x = rng.uniform(0.2, 5.0, 200_000)
    exact = np.log(x.astype(np.longdouble))
    got = np.asarray(jax.jit(log_vectorised)(jnp.asarray(x))).astype(np.longdouble)
    err = np.max(np.abs(got - exact) / np.spacing(np.abs(got.astype(np.float64))))
    print(f"float64  log_vectorised: largest error {float(err):.2f} ulps over [0.2, 5]")


if __name__ == "__main__":
    main()
