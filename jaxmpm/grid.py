"""The background grid: uniform nodes, padded so that the body never leaves it."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, Int


class Grid(eqx.Module):
    """A uniform grid of ``n_nodes`` nodes ``x_i = x_min + i h`` along each axis.

    ``x_min`` and ``h`` are arrays, so a gradient reaches the grid spacing; the node count is
    structural (static).

    Attributes:
        x_min: position of node 0, shape ``(dim,)``.
        h: node spacing (a scalar array).
        n_nodes: number of nodes (static).
    """

    x_min: Float[Array, " dim"]
    h: Float[Array, ""]
    n_nodes: int = eqx.field(static=True)

    @property
    def dim(self) -> int:
        return self.x_min.shape[0]

    @property
    def x_max(self) -> Float[Array, " dim"]:
        return self.x_min + (self.n_nodes - 1) * self.h

    def nodes(self) -> Float[Array, "n_nodes dim"]:
        """Node positions, shape ``(n_nodes, dim)``."""
        i = jnp.arange(self.n_nodes, dtype=self.h.dtype)
        return self.x_min[None, :] + i[:, None] * self.h

    def locate(self, x: Float[Array, "..."]) -> tuple[Int[Array, "..."], Float[Array, "..."]]:
        """Cell index ``floor((x - x_min) / h)`` of a 1D coordinate and the fraction within it.

        The fraction carries the derivative with respect to ``x``, ``x_min`` and ``h``; the index
        is piecewise constant (its derivative is zero, so derivatives are one-sided at nodes).
        """
        xi = (x - self.x_min[0]) / self.h
        base = jnp.floor(xi)
        return base.astype(jnp.int32), xi - base

    def scatter(self, idx: Int[Array, "n k"], values: Float[Array, "n k ..."]) -> Float[Array, "n_nodes ..."]:
        """Sum ``values`` onto nodes ``idx``; indices outside the grid are dropped.

        A particle whose stencil leaves the grid is flagged by the step's status check, so a drop
        never passes silently.
        """
        tail = values.shape[2:]
        flat_idx = idx.reshape(-1)
        flat_val = values.reshape((-1,) + tail)
        out = jnp.zeros((self.n_nodes,) + tail, dtype=values.dtype)
        return out.at[flat_idx].add(flat_val, mode="drop")

    def gather(self, idx: Int[Array, "n k"], field: Float[Array, "n_nodes ..."]) -> Float[Array, "n k ..."]:
        """Node values of ``field`` at ``idx`` (out-of-grid indices read zero)."""
        return field.at[idx].get(mode="fill", fill_value=0.0)
