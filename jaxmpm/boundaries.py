"""Boundary conditions: tractions at moving material points, walls, and artificial cells.

Artificial cells (the fix for boundary cells of Bonifasi-Lista, Brannon & Wiskin 2013), stated
precisely:

- *Where*: ``layers`` cells outside each free (non-wall, non-symmetry) end of the body, each holding
  ``ppc`` artificial particles at the reference positions real particles would have there. In 2D
  and 3D: the body's box grown by ``layers`` cells at each free face, less the body (face, edge and
  corner cells; see ``artificial_layer``).
- *What*: each artificial particle's current position ``x``, velocity ``v``, deformation gradient
  ``F`` and, with APIC, affine matrix ``C``; its mass and half-length are those of a real particle.
- *How*: ``x`` and ``v`` by a linear least-squares fit in the reference coordinate ``X`` to the
  ``ppc`` real particles of the boundary cell (the two outermost real particles when ``ppc == 1``),
  evaluated at the artificial particle's ``X``. Their gradients ``F = dx/dX`` and ``C = dv/dx`` are
  the one order lower: the mean over the same particles. A linear motion (the manufactured
  ``u = beta t X``) is extrapolated exactly; extrapolating ``F`` linearly as well would multiply
  particle-to-particle noise in ``F`` by up to ``2 layers + 1`` and destabilise cpGIMP.
- *When*: at the start of every step, before particle-to-grid, from the current real particles.
  Bonifasi-Lista et al. extrapolate "at time 0"; doing it every step keeps the layer consistent
  with a body that has moved.
- *What they do*: they add mass and momentum to the particle-to-grid transfer that defines the nodal
  velocity ``v_i^n``, so that the boundary node sees a symmetric stencil. They carry no stress and
  exert no force: nodal forces come from the real particles and the tractions, and the nodal
  acceleration is ``a_i = f_i / m_i`` with the real particles' mass ``m_i``. The boundary traction
  still acts at the real material boundary point. With FLIP the body's momentum is unchanged by them;
  PIC and APIC give the particles the nodal velocity, which holds their momentum too, so there the
  body's momentum changes. They are never part of the state, results or errors.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._util import lattice


class ArtificialLayer(eqx.Module):
    """Static recipe for the artificial particles of a body: sources and extrapolation weights.

    Attributes:
        src: ``(n_art, n_src)`` indices of the real particles each artificial particle is fitted to.
        weights: ``(n_art, n_src)`` linear least-squares extrapolation weights (rows sum to one).
        mean_weights: ``(n_art, n_src)`` weights of the mean over the sources (for ``F`` and ``C``),
            or ``None`` when every row has ``n_src`` sources (1D), and the mean is the plain mean.
    """

    src: Int[Array, "n_art n_src"]
    weights: Float[Array, "n_art n_src"]
    mean_weights: Float[Array, "n_art n_src"] | None = None

    def extrapolate(self, field: Float[Array, "n ..."]) -> Float[Array, "n_art ..."]:
        """Linear extrapolation (for ``x`` and ``v``): ``sum_s weights[a, s] field[src[a, s]]``.

        Args:
            field: a field of the real particles.

        Returns:
            Its values at the artificial particles.
        """
        vals = field[self.src]  # (n_art, n_src, *tail)
        w = self.weights.astype(field.dtype).reshape(self.weights.shape + (1,) * (field.ndim - 1))
        return jnp.sum(w * vals, axis=1)

    def mean(self, field: Float[Array, "n ..."]) -> Float[Array, "n_art ..."]:
        """Constant extrapolation (for the gradients ``F`` and ``C``): the mean over the sources.

        Args:
            field: a field of the real particles.

        Returns:
            Its values at the artificial particles.
        """
        if self.mean_weights is None:
            return jnp.mean(field[self.src], axis=1)
        w = self.mean_weights.astype(field.dtype).reshape(self.mean_weights.shape + (1,) * (field.ndim - 1))
        return jnp.sum(w * field[self.src], axis=1)


def _axis_rows(n: int, ppc: int, layers: int, sides: tuple[bool, bool]):
    """Along one axis of ``n`` particles (``ppc`` per cell): for every index of the extended range
    (``layers ppc`` more at each free side), the ``(sources, weights)`` of its linear least-squares
    extrapolation from the boundary cell (the identity inside). Weights are in cell units: a linear
    fit is invariant under scaling of ``X``, so they do not depend on ``h``."""
    n_src = max(ppc, 2)
    if n < n_src:
        raise ValueError(
            f"artificial cells need at least 2 real particles to extrapolate from, got cells*ppc = {n}"
        )
    X = (np.arange(n) + 0.5) / ppc
    rows = {}
    for side, free in zip(("left", "right"), sides):
        if not free:
            continue
        if side == "left":
            src = np.arange(n_src)
            idx = -np.arange(layers * ppc)[::-1] - 1
        else:
            src = np.arange(n - n_src, n)
            idx = n + np.arange(layers * ppc)
        X_art = (idx + 0.5) / ppc
        Xs = X[src]
        d = Xs - Xs.mean()
        w = 1.0 / n_src + np.outer(X_art - Xs.mean(), d) / np.sum(d * d)
        for i, wi in zip(idx, w):
            rows[int(i)] = (src, wi)
    return rows


def artificial_layer(
    cells: int, ppc: int, layers: int, sides: tuple[bool, bool], dim: int = 1
) -> ArtificialLayer | None:
    """The artificial particles of a body of ``cells^dim`` cells, ``ppc`` particles per cell and axis,
    with ``layers`` cells outside each free face.

    ``sides`` says whether the low and high faces (of every axis) are free. In 2D and 3D the
    artificial region is the body's box grown by ``layers`` cells at each free face, less the body:
    face, edge and corner cells, so a node at the body's edge or corner also sees a full stencil.
    Each artificial particle is the tensor product of the 1D extrapolations along the axes where it
    lies outside the body (a multilinear fit, exact for the linear ``v = beta X``); its ``F`` is the
    mean over the same sources.

    Args:
        cells: cells of the body along each axis.
        ppc: particles per cell along each axis.
        layers: artificial cells outside each free face.
        sides: whether the low and high faces are free.
        dim: number of space dimensions.

    Returns:
        The ``ArtificialLayer``, or ``None`` when there is nothing to add.

    Raises:
        ValueError: fewer than 2 real particles along an axis to extrapolate from.
    """
    if layers == 0 or not any(sides):
        return None
    n = cells * ppc
    rows = _axis_rows(n, ppc, layers, sides)
    if dim == 1:
        order = sorted(rows, key=lambda i: (i >= 0, i))  # left layer, then right
        return ArtificialLayer(
            src=jnp.asarray(np.stack([rows[i][0] for i in order]), dtype=jnp.int32),
            weights=jnp.asarray(np.stack([rows[i][1] for i in order])),
        )
    axis_range = sorted(rows) + list(range(n))
    axis_range = sorted(set(axis_range))
    srcs, weights, means = [], [], []
    stride = [n ** (dim - 1 - a) for a in range(dim)]
    for multi in np.ndindex(*(len(axis_range),) * dim):
        idx = [axis_range[k] for k in multi]
        if all(0 <= i < n for i in idx):
            continue
        per_axis = [
            (np.array([i]), np.array([1.0]), np.array([1.0]))
            if 0 <= i < n
            else (rows[i][0], rows[i][1], np.full(len(rows[i][0]), 1.0 / len(rows[i][0])))
            for i in idx
        ]
        src, w, m = np.zeros(1, dtype=np.int64), np.ones(1), np.ones(1)
        for a, (s_a, w_a, m_a) in enumerate(per_axis):
            src = (src[:, None] + stride[a] * s_a[None, :]).reshape(-1)
            w = (w[:, None] * w_a[None, :]).reshape(-1)
            m = (m[:, None] * m_a[None, :]).reshape(-1)
        srcs.append(src)
        weights.append(w)
        means.append(m)
    width = max(len(s) for s in srcs)

    def pad(rows_, fill):
        return np.stack([np.concatenate([r, np.full(width - len(r), fill)]) for r in rows_])

    return ArtificialLayer(
        src=jnp.asarray(pad(srcs, 0), dtype=jnp.int32),
        weights=jnp.asarray(pad(weights, 0.0)),
        mean_weights=jnp.asarray(pad(means, 0.0)),
    )


class TractionPoints(eqx.Module):
    """The material boundary points that carry a traction, with what the step needs to load them.

    Attributes:
        X: initial positions ``(k, dim)``, moved with the grid velocity through the run.
        area: reference area each point carries ``(k,)`` (unit in 1D: ``None``).
        counts: points per loaded face, in the order of ``scene.traction``'s non-``None`` entries (static).
        report: the real particle next to each loaded face, on which bad traction data is reported (static).
        owner: the real particle whose domain corner each point is ``(k,)``, on which a point that
            leaves the grid or is not finite is reported.
    """

    X: Float[Array, "k dim"]
    area: Float[Array, " k"] | None
    owner: Int[Array, " k"]
    counts: tuple[int, ...] = eqx.field(static=True)
    report: tuple[int, ...] = eqx.field(static=True)


def traction_points(
    cells: int, ppc: int, h: Float[Array, ""], faces: tuple[bool, ...]
) -> TractionPoints | None:
    """The traction points of a ``cells^dim`` body: on each loaded face (``faces``: low and high face
    of axis 0, then of axis 1, ...), the particle-domain corners on that face, each carrying its share
    of the face area by the trapezoid rule (``(h / ppc)^(dim - 1)``, halved on an edge of the face
    per axis); in 1D the end point itself.

    The trapezoid rule on the domain corners is the face integral of the corner-interpolated shape
    functions that CPDI's and MPQ's domain gradients integrate by parts, so under a uniform stress
    their internal and boundary forces balance node by node, as in 1D; a midpoint rule would not
    once the face has moved off the grid lines.

    Args:
        cells: cells of the body along each axis.
        ppc: particles per cell along each axis.
        h: cell size.
        faces: whether each face is loaded.

    Returns:
        The ``TractionPoints``, or ``None`` when no face is loaded.
    """
    dim = len(faces) // 2
    n = cells * ppc
    pts, areas, counts, report, owner = [], [], [], [], []
    along = np.arange(n + 1) / ppc  # the corners along a face
    share = np.ones(n + 1)
    share[[0, -1]] = 0.5
    for f, on in enumerate(faces):
        if not on:
            continue
        a, high = divmod(f, 2)
        coords = [along] * dim
        coords[a] = np.array([float(cells) if high else 0.0])
        weights = [share] * dim
        weights[a] = np.ones(1)
        L = lattice([len(c) for c in coords])
        P = np.stack([coords[b][L[:, b]] for b in range(dim)], axis=1)
        W = np.prod(np.stack([weights[b][L[:, b]] for b in range(dim)], axis=1), axis=1)
        pts.append(P)
        areas.append(W * (1.0 / ppc) ** (dim - 1))
        counts.append(P.shape[0])
        first = np.zeros(dim, dtype=int)
        first[a] = n - 1 if high else 0
        report.append(int(np.ravel_multi_index(tuple(first), (n,) * dim)))
        index = np.minimum(L, n - 1)  # corner j along a face borders particle min(j, n - 1)
        index[:, a] = first[a]
        owner.append(np.ravel_multi_index(tuple(index.T), (n,) * dim))
    if not pts:
        return None
    X = jnp.asarray(np.concatenate(pts), dtype=h.dtype) * h
    area = None if dim == 1 else jnp.asarray(np.concatenate(areas), dtype=h.dtype) * h ** (dim - 1)
    return TractionPoints(
        X=X,
        area=area,
        owner=jnp.asarray(np.concatenate(owner), dtype=jnp.int32),
        counts=tuple(counts),
        report=tuple(report),
    )


def fixed_mask(axes: tuple[int, ...], pad: int, cells: int, low: str, high: str) -> np.ndarray | None:
    """Static ``(n_nodes, dim)`` mask of the nodal velocity components held at zero.

    At a ``"wall"`` face the node on the face and every node beyond it hold every component; at a
    ``"symmetry"`` plane (a roller) they hold the component normal to the face only, so the body
    slides along it. The same face types apply to every axis. In 1D a symmetry plane is a wall.

    Args:
        axes: nodes along each axis.
        pad: nodes of padding before the body along each axis.
        cells: cells of the body along each axis.
        low: the type of the low faces (``"free"``, ``"wall"`` or ``"symmetry"``).
        high: the type of the high faces.

    Returns:
        The mask, or ``None`` when nothing is held.
    """
    dim = len(axes)
    idx = lattice(axes)
    mask = np.zeros((idx.shape[0], dim), dtype=bool)
    for a in range(dim):
        for kind, beyond in ((low, idx[:, a] <= pad), (high, idx[:, a] >= pad + cells)):
            if kind == "wall":
                mask[beyond, :] = True
            elif kind == "symmetry":
                mask[beyond, a] = True
    return mask if mask.any() else None
