"""Failure bits recorded in the loop state (a bitmask, as jax-md's neighbour lists do)."""

import functools
import operator

import jax
import jax.numpy as jnp
import numpy as np

NONFINITE = 1
NONPOSITIVE_F = 2
LEFT_GRID = 4
CFL = 8
STENCIL = 16
SCENE_DATA = 32
MAX_STEPS = 64
NEGATIVE_ENERGY = 128
PRODUCTS_TENSION = 256

QUANTITY = {
    NONFINITE: "non-finite state (x, v, F or sigma is NaN or inf)",
    NONPOSITIVE_F: "F <= 0 (the particle's domain inverted)",
    LEFT_GRID: "particle left the grid (its query points reach past the padded grid; raise pad)",
    CFL: "time step beyond the stable limit (dt > cfl_limit * h / (c + |v|))",
    STENCIL: "GIMP domain wider than its stencil (raise GIMP.max_span, or use CPDI or MPQ)",
    SCENE_DATA: "the scene's traction or body force is not finite (past the end of its solution?)",
    MAX_STEPS: "max_steps steps were taken before t_end was reached (raise max_steps)",
    NEGATIVE_ENERGY: "negative specific internal energy e (the step took more energy than the particle had)",
    PRODUCTS_TENSION: "detonation products in tension (their pressure below -1e-3 rho0 D^2)",
}


_KNOWN = functools.reduce(operator.or_, QUANTITY)
"""Every bit a check sets."""


def describe(status: int | np.integer | jax.Array) -> list[str]:
    """The failures set in a status bitmask, in words.

    Args:
        status: one run's bitmask: an integer >= 0 whose bits are among ``QUANTITY``'s (a Python or
            NumPy integer, or a 0-d integer array such as ``Solution.status``).

    Returns:
        The description (``QUANTITY``) of each bit set (empty for 0).

    Raises:
        ValueError: ``status`` is not one such integer (an ensemble's array of statuses: describe each
            member's, ``[describe(int(s)) for s in ensemble.status]``), or sets a bit no check sets.
    """
    shape = getattr(status, "shape", ())
    dtype = getattr(status, "dtype", None)
    whole = isinstance(status, int) if dtype is None else np.issubdtype(dtype, np.integer)
    if shape != () or isinstance(status, bool) or not whole:
        raise ValueError(
            f"status must be one run's status, an integer >= 0, got {status!r}"
            + (
                " (for an ensemble, describe each member's: [describe(int(s)) for s in ens.status])"
                if shape
                else ""
            )
        )
    status = int(status)
    if status < 0 or status & ~_KNOWN:
        raise ValueError(f"status must be an integer >= 0 of the bits {sorted(QUANTITY)}, got {status}")
    return [text for bit, text in QUANTITY.items() if status & bit]


def combine(checks, sharded: bool = False):
    """Fold ``[(bit, mask (n,)), ...]`` into ``(status, first particle of the lowest set bit)``.

    One pass builds each particle's bits and one reduction ORs them; the particle is searched for
    only when a bit is set (``lax.cond``), so a healthy step pays for no ``argmax``.

    Args:
        checks: pairs of a status bit and a boolean per particle (where the check failed).
        sharded: the particles are sharded over several devices. Cross-device reductions are then
            ones every backend's collectives have (max and min): each bit by a max over the
            particles, the particle by a min over the indices that fail. Same results.

    Returns:
        ``(status, particle)``, ``particle`` -1 when no bit is set.
    """
    if not checks:
        return jnp.zeros((), dtype=jnp.int32), jnp.full((), -1, dtype=jnp.int32)
    if sharded:
        status = sum(jnp.max(jnp.where(mask, jnp.int32(bit), jnp.int32(0))) for bit, mask in _by_bit(checks))
        lowest = status & -status
        n = checks[0][1].shape[0]
        hit = functools.reduce(operator.or_, (mask & ((lowest & bit) != 0) for bit, mask in checks))
        first = jnp.min(jnp.where(hit, jnp.arange(n, dtype=jnp.int32), jnp.int32(n)))
        return status, jnp.where(status != 0, first, jnp.int32(-1))
    per = None
    for bit, mask in checks:
        term = jnp.where(mask, jnp.int32(bit), jnp.int32(0))
        per = term if per is None else per | term
    status = jax.lax.reduce(per, jnp.int32(0), jax.lax.bitwise_or, (0,))
    lowest = status & -status

    def first(per):
        return jnp.argmax((per & lowest) != 0).astype(jnp.int32)

    particle = jax.lax.cond(status != 0, first, lambda per: jnp.full((), -1, dtype=jnp.int32), per)
    return status, particle


def _by_bit(checks):
    """``checks`` with the masks of the same bit ORed together: one ``(bit, mask)`` per bit."""
    merged = {}
    for bit, mask in checks:
        merged[bit] = mask if bit not in merged else merged[bit] | mask
    return merged.items()
