"""The background grid: uniform nodes along each axis, padded so that the body never leaves it."""

import math

import equinox as eqx
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, Float, Int

from ._checks import check_int, check_positive
from ._util import lattice


class Grid(eqx.Module):
    """A uniform grid of nodes ``x_i = x_min + i h`` along each axis, stored flat.

    A node's flat index is ``sum_a i_a stride_a`` with the last axis fastest (C order). Nodal fields
    are ``(n_nodes, ...)`` arrays in that order. ``x_min`` and ``h`` are arrays, so a gradient reaches
    the grid spacing; the node counts are structural (static).

    Attributes:
        x_min: position of node 0, shape ``(dim,)``.
        h: node spacing, > 0 (a scalar array; the same along every axis).
        n_nodes: total number of nodes, >= 2 (static).
        shape: nodes along each axis, each >= 2 (static); ``None`` for a 1D grid of ``n_nodes`` nodes.
    """

    x_min: Float[Array, " dim"]
    h: Float[Array, ""]
    n_nodes: int = eqx.field(static=True)
    shape: tuple[int, ...] | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        """Check the node counts and the spacing (a traced ``h``, as inside a run, is not checked).

        Raises:
            ValueError: ``n_nodes`` or an entry of ``shape`` is not an integer >= 2 (a grid has at
                least one cell along each axis); ``h`` is not finite and > 0; ``shape`` does not
                match ``x_min`` and ``n_nodes``.
        """
        check_int("n_nodes", self.n_nodes, 2)
        if self.shape is not None:
            for a, n in enumerate(self.shape):
                check_int(f"shape[{a}]", n, 2)
        check_positive("h", self.h)
        if self.shape is not None and (
            len(self.shape) != self.x_min.shape[0] or math.prod(self.shape) != self.n_nodes
        ):
            raise ValueError(
                f"Grid.shape must give one node count per axis of x_min with product n_nodes; got "
                f"shape={self.shape}, x_min of {self.x_min.shape[0]} axes, n_nodes={self.n_nodes}"
            )

    @classmethod
    def box(cls, x_min: Float[Array, " dim"], h: Float[Array, ""], shape: tuple[int, ...]) -> "Grid":
        """A grid of ``shape[a]`` nodes along axis ``a``.

        Args:
            x_min: position of node 0.
            h: node spacing.
            shape: nodes along each axis (length ``dim``).

        Returns:
            The ``Grid``.
        """
        shape = tuple(int(s) for s in shape)
        return cls(x_min=x_min, h=h, n_nodes=math.prod(shape), shape=None if len(shape) == 1 else shape)

    @property
    def dim(self) -> int:
        """Number of space dimensions."""
        return self.x_min.shape[0]

    @property
    def axes(self) -> tuple[int, ...]:
        """Nodes along each axis."""
        return (self.n_nodes,) if self.shape is None else self.shape

    @property
    def strides(self) -> tuple[int, ...]:
        """Flat-index stride of each axis (the last axis is contiguous)."""
        return tuple(math.prod(self.axes[a + 1 :]) for a in range(len(self.axes)))

    @property
    def x_max(self) -> Float[Array, " dim"]:
        """Position of the last node along each axis."""
        if self.shape is None:
            return self.x_min + (self.n_nodes - 1) * self.h
        return self.x_min + jnp.asarray([n - 1 for n in self.shape], dtype=self.h.dtype) * self.h

    def nodes(self) -> Float[Array, "n_nodes dim"]:
        """Node positions, shape ``(n_nodes, dim)``."""
        if self.shape is None:
            i = jnp.arange(self.n_nodes, dtype=self.h.dtype)
            return self.x_min[None, :] + i[:, None] * self.h
        i = jnp.asarray(lattice(self.axes), dtype=self.h.dtype)
        return self.x_min[None, :] + i * self.h

    def locate(self, x: Float[Array, "..."], axis: int = 0) -> tuple[Int[Array, "..."], Float[Array, "..."]]:
        """Cell index ``floor((x - x_min) / h)`` of a coordinate along ``axis`` and the fraction within it.

        The fraction carries the derivative with respect to ``x``, ``x_min`` and ``h``; the index
        is piecewise constant (its derivative is zero, so derivatives are one-sided at nodes).

        Args:
            x: coordinates along ``axis``.
            axis: the axis.

        Returns:
            ``(index, fraction)``.
        """
        xi = (x - self.x_min[axis]) / self.h
        base = jnp.floor(xi)
        return base.astype(jnp.int32), xi - base

    def flat_index(self, idx: list[Int[Array, "..."]]) -> Int[Array, "..."]:
        """The flat index of per-axis node indices (broadcast together).

        A node off the grid along any axis gets ``n_nodes``, which scatters drop and gathers read as
        zero (it must not alias a node of the next row).

        Args:
            idx: one array of node indices per axis.

        Returns:
            The flat indices.
        """
        if len(idx) == 1:
            return idx[0]
        flat, valid = 0, True
        for i, n, s in zip(idx, self.axes, self.strides):
            flat = flat + i * s
            valid = valid & (i >= 0) & (i < n)
        return jnp.where(valid, flat, self.n_nodes)

    def scatter(
        self, idx: Int[Array, "n k"], values: Float[Array, "n k ..."], base: Int[Array, "n g"] | None = None
    ) -> Float[Array, "n_nodes ..."]:
        """Sum ``values`` onto nodes ``idx``; indices outside the grid are dropped.

        A particle whose stencil leaves the grid is flagged by the step's status check, so a drop
        never passes silently.

        With ``base`` (1D: each particle's ``k`` nodes are ``g`` runs of ``k / g`` consecutive nodes,
        run ``r`` starting at ``base[:, r]``), each run's values are added as one window onto the
        field padded by ``k / g - 1`` nodes at each end, and the padding is dropped: the same sums in
        the same order, bit for bit, as ``k`` single-node updates, and faster inside the step on XLA's
        CPU backend (the performance docs, "1D windows").

        Args:
            idx: node indices.
            values: one value (scalar or array) per index.
            base: the first node of each run of consecutive nodes (1D), or ``None``.

        Returns:
            The nodal field.
        """
        tail = values.shape[2:]
        if base is not None:
            n, g = base.shape
            width = idx.shape[1] // g
            pad = width - 1  # a window reaching past an end puts those values on the padding
            out = jnp.zeros((self.n_nodes + 2 * pad,) + tail, dtype=values.dtype)
            dims = lax.ScatterDimensionNumbers(
                update_window_dims=tuple(range(1, 2 + len(tail))),
                inserted_window_dims=(),
                scatter_dims_to_operand_dims=(0,),
            )
            runs = values.reshape((n * g, width) + tail)
            starts = (base.reshape(-1) + pad)[:, None]
            out = lax.scatter_add(out, starts, runs, dims, mode=lax.GatherScatterMode.FILL_OR_DROP)
            return out[pad : pad + self.n_nodes]
        flat_idx = idx.reshape(-1)
        if self.dim == 1:  # a node past the low end is dropped too, not counted from the end
            flat_idx = jnp.where(flat_idx < 0, self.n_nodes, flat_idx)
        flat_val = values.reshape((-1,) + tail)
        out = jnp.zeros((self.n_nodes,) + tail, dtype=values.dtype)
        return out.at[flat_idx].add(flat_val, mode="drop")

    def gather(
        self,
        idx: Int[Array, "n k"],
        field: Float[Array, "n_nodes ..."],
        base: Int[Array, "n g"] | None = None,
    ) -> Float[Array, "n k ..."]:
        """Node values of ``field`` at ``idx`` (out-of-grid indices read zero).

        With ``base`` (1D, as for ``scatter``), each run of consecutive nodes is read as one window of
        the field padded by zeros at each end.

        Args:
            idx: node indices.
            field: a nodal field.
            base: the first node of each run of consecutive nodes (1D), or ``None``.

        Returns:
            ``field[idx]``.
        """
        if base is not None:
            n, g = base.shape
            width = idx.shape[1] // g
            tail = field.shape[1:]
            padded = jnp.pad(field, [(width - 1, width - 1)] + [(0, 0)] * len(tail))
            dims = lax.GatherDimensionNumbers(
                offset_dims=tuple(range(1, 1 + field.ndim)), collapsed_slice_dims=(), start_index_map=(0,)
            )
            runs = lax.gather(
                padded,
                (base.reshape(-1) + (width - 1))[:, None],
                dims,
                slice_sizes=(width,) + tail,
                mode=lax.GatherScatterMode.FILL_OR_DROP,
                fill_value=0.0,
            )
            return runs.reshape((n, g * width) + tail)
        if self.dim == 1:  # a node past the low end reads zero too, not counted from the end
            idx = jnp.where(idx < 0, self.n_nodes, idx)
        return field.at[idx].get(mode="fill", fill_value=0.0)
