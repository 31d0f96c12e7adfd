"""Small helpers shared across modules."""

import functools
import operator

import jax
import jax.numpy as jnp
from jaxtyping import Array


def as_float(x) -> Array:
    """``x`` as an array of the default float dtype (float64 once x64 is enabled)."""
    return jnp.asarray(x, dtype=jnp.result_type(float))


def tree_where(pred, on_true, on_false):
    """Leafwise ``jnp.where(pred, a, b)`` over two pytrees of the same structure."""
    return jax.tree.map(lambda a, b: jnp.where(pred, a, b), on_true, on_false)


def det(F):
    """``det F`` of each particle, ``F`` of shape ``(..., dim, dim)`` (the entry itself in 1D)."""
    return F[..., 0, 0] if F.shape[-1] == 1 else jnp.linalg.det(F)


def contract(spec: str, a: Array, b: Array) -> Array:
    """``jnp.einsum(spec, a, b)`` as a broadcast product and a sum, for the step's tiny per-particle
    contractions (stencil width by ``dim``).

    XLA turns an einsum into a ``dot_general`` and a sum into a ``reduce``; its CPU backend hands both
    to a library kernel that runs millions of length-2 products one by one, several times slower
    than unrolled elementwise adds, which fuse with their neighbours (measured on the 1D step, see
    experiments/bench.py). Two operands, no repeated letter within one operand.
    """
    ins, out = spec.replace(" ", "").split("->")
    sa, sb = ins.split(",")
    letters = sa + "".join(c for c in sb if c not in sa)

    def expand(x, s):
        perm = [s.index(c) for c in letters if c in s]
        x = jnp.transpose(x, perm) if perm != sorted(perm) else x
        shape = [x.shape[[c for c in letters if c in s].index(c)] if c in s else 1 for c in letters]
        return jnp.reshape(x, shape)

    prod = expand(a, sa) * expand(b, sb)
    summed = tuple(i for i, c in enumerate(letters) if c not in out)
    kept = [c for c in letters if c in out]
    for axis in reversed(summed):  # unrolled adds: a reduce op is again a slow custom fusion
        parts = [jax.lax.index_in_dim(prod, i, axis, keepdims=False) for i in range(prod.shape[axis])]
        prod = functools.reduce(operator.add, parts)
    perm = [kept.index(c) for c in out]
    return jnp.transpose(prod, perm) if perm != sorted(perm) else prod
