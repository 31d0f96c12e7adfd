"""The background grid: uniform nodes along each axis, padded so that the body never leaves it."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, ArrayLike, Float, Int

from ._checks import any_traced, brief, check_int, check_positive, is_bool, is_real, python_int, show
from ._util import lattice

_X_MIN = "x_min must be the position of node 0, 1 to 3 finite real numbers (one per axis)"
_H = "h must be the node spacing, one finite number > 0 (not a bool)"


def _as_array(value):
    """A position or spacing as given (a list, a Python or NumPy number, an array of real numbers) as
    an array: a floating array as it is, anything else real in the default float dtype. A value that
    is not real numbers, or is bools, is left unchanged for ``Grid``'s check to name; a tracer too."""
    if any_traced(value):
        return value if isinstance(value, jax.Array) else jnp.asarray(value)
    if isinstance(value, jax.Array) and jnp.issubdtype(value.dtype, jnp.floating):
        return value
    if not is_real(value) or is_bool(value):
        return value
    arr = np.asarray(value)
    # A floating array keeps its dtype as JAX holds it (float64 only with float64 on, without a
    # warning); integers become the default float.
    return jnp.asarray(arr) if np.issubdtype(arr.dtype, np.floating) else jnp.asarray(arr, dtype=float)


def _check_x_min(x_min) -> None:
    """``x_min`` is 1 to 3 finite real numbers, not bools (its shape is checked under a trace too)."""
    if not any_traced(x_min) and (not is_real(x_min) or is_bool(x_min)):
        raise ValueError(f"{_X_MIN}, got {brief(x_min)}")
    if np.ndim(x_min) != 1 or not 1 <= np.shape(x_min)[0] <= 3:
        raise ValueError(f"{_X_MIN}, got an array of shape {np.shape(x_min)}")
    if not any_traced(x_min) and not np.all(np.isfinite(np.asarray(x_min))):
        raise ValueError(f"{_X_MIN}, got {show(np.asarray(x_min))}")


def _check_h(h) -> None:
    """``h`` is one finite number > 0, not a bool (its shape is checked under a trace too)."""
    if not any_traced(h) and (not is_real(h) or is_bool(h)):
        raise ValueError(f"{_H}, got {brief(h)}")
    if np.ndim(h) != 0:
        raise ValueError(f"{_H}, got an array of shape {np.shape(h)}")
    check_positive("h", h)


class Grid(eqx.Module):
    """A uniform grid of nodes ``x_i = x_min + i h`` along each axis, stored flat.

    A node's flat index is ``sum_a i_a stride_a`` with the last axis fastest (C order). Nodal fields
    are ``(n_nodes, ...)`` arrays in that order. ``x_min`` and ``h`` are arrays, so a gradient reaches
    the grid spacing; the node counts are structural (static).

    ``x_min`` and ``h`` may be given as a list or a Python or NumPy number: they are stored as arrays
    (a floating array keeps its dtype; anything else takes the default float dtype). Bools are refused.

    Attributes:
        x_min: position of node 0, shape ``(dim,)``: 1 to 3 finite real numbers.
        h: node spacing, one finite number > 0 (a scalar array; the same along every axis).
        n_nodes: total number of nodes, >= 2 (static).
        shape: nodes along each axis, each >= 2 (static); ``None`` for a 1D grid of ``n_nodes`` nodes
            (then ``x_min`` has one entry).
    """

    x_min: Float[Array, " dim"] = eqx.field(converter=_as_array)
    h: Float[Array, ""] = eqx.field(converter=_as_array)
    n_nodes: int = eqx.field(static=True)
    shape: tuple[int, ...] | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        """Check the node counts, the position and the spacing. Under a trace (a grid built inside
        ``jax.jit`` or ``jax.grad``, as inside a run) only the shapes of ``x_min`` and ``h`` are.

        Raises:
            ValueError: ``n_nodes`` or an entry of ``shape`` is not an integer >= 2 (a grid has at
                least one cell along each axis); ``x_min`` is not 1 to 3 finite real numbers (one
                per axis); ``h`` is not one finite number > 0 (a bool is refused); ``shape`` is
                ``None`` and ``x_min`` has more than one entry; ``shape`` does not match ``x_min``
                and ``n_nodes``.
        """
        check_int("n_nodes", self.n_nodes, 2)
        if self.shape is not None:
            for a, n in enumerate(self.shape):
                check_int(f"shape[{a}]", n, 2)
        _check_x_min(self.x_min)
        _check_h(self.h)
        if self.shape is None and np.shape(self.x_min)[0] != 1:
            raise ValueError(
                f"a Grid without shape is 1D: x_min must have 1 entry, got {np.shape(self.x_min)[0]} "
                "(Grid.box builds a 2D or 3D grid)"
            )
        if self.shape is not None and (
            len(self.shape) != self.x_min.shape[0] or math.prod(self.shape) != self.n_nodes
        ):
            raise ValueError(
                f"Grid.shape must give one node count per axis of x_min with product n_nodes; got "
                f"shape={self.shape}, x_min of {self.x_min.shape[0]} axes, n_nodes={self.n_nodes}"
            )

    @classmethod
    def box(cls, x_min: Float[ArrayLike, " dim"], h: Float[ArrayLike, ""], shape: tuple[int, ...]) -> "Grid":
        """A grid of ``shape[a]`` nodes along axis ``a``.

        Args:
            x_min: position of node 0: 1 to 3 finite real numbers, one per axis (an array or a list).
            h: node spacing: one finite number > 0 (an array or a Python or NumPy number; not a bool).
            shape: nodes along each axis: a tuple (or list) of integers >= 2, one per entry of
                ``x_min``.

        Returns:
            The ``Grid``.

        Raises:
            ValueError: ``shape`` is not a tuple of integers >= 2 with one per entry of ``x_min``, or
                ``x_min`` or ``h`` is not as above (``Grid``'s checks).
        """
        if not isinstance(shape, (tuple, list)):
            raise ValueError(
                f"shape must be a tuple of node counts, one per axis of x_min, got {brief(shape)}"
            )
        shape = tuple(python_int(s) for s in shape)
        for a, n in enumerate(shape):
            check_int(f"shape[{a}]", n, 2)
        x_min = _as_array(x_min)
        _check_x_min(x_min)
        if len(shape) != np.shape(x_min)[0]:
            raise ValueError(
                f"shape must give one node count per axis of x_min ({np.shape(x_min)[0]}), got {shape}"
            )
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
