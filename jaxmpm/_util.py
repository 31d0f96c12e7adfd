"""Small helpers shared across modules."""

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
