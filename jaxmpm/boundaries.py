"""Boundary conditions: tractions at moving material points, walls, and artificial cells.

Artificial cells (SPEC section 4, the talk's fix for boundary cells), stated precisely:

- *Where*: ``layers`` cells outside each free (non-wall) end of the body, each holding ``ppc``
  artificial particles at the reference positions real particles would have there.
- *What*: each artificial particle's current position ``x``, velocity ``v``, deformation gradient
  ``F`` and, with APIC, affine matrix ``C``; its mass and half-length are those of a real particle.
- *How*: ``x`` and ``v`` by a linear least-squares fit in the reference coordinate ``X`` to the
  ``ppc`` real particles of the boundary cell (the two outermost real particles when ``ppc == 1``),
  evaluated at the artificial particle's ``X``. Their gradients ``F = dx/dX`` and ``C = dv/dx`` are
  the one order lower: the mean over the same particles. A linear motion (the talk's
  ``u = beta t X``) is extrapolated exactly; extrapolating ``F`` linearly as well would multiply
  particle-to-particle noise in ``F`` by up to ``2 layers + 1`` and destabilise cpGIMP.
- *When*: at the start of every step, before particle-to-grid, from the current real particles.
  The talk extrapolates "at time 0"; doing it every step keeps the layer consistent with a body
  that has moved.
- *What they do*: they add mass and momentum to the particle-to-grid transfer that defines the nodal
  velocity ``v_i^n``, so that the boundary node sees a symmetric stencil. They carry no stress and
  exert no force: nodal forces come from the real particles and the tractions, and the nodal
  acceleration is ``a_i = f_i / m_i`` with the real particles' mass ``m_i``. The boundary traction
  still acts at the real material boundary point. They are never part of the state, results or
  errors.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .particles import Body


class ArtificialLayer(eqx.Module):
    """Static recipe for the artificial particles of a body: sources and extrapolation weights.

    Attributes:
        src: ``(n_art, n_src)`` indices of the real particles each artificial particle is fitted to.
        weights: ``(n_art, n_src)`` linear least-squares extrapolation weights (rows sum to one).
    """

    src: Int[Array, "n_art n_src"]
    weights: Float[Array, "n_art n_src"]

    def extrapolate(self, field: Float[Array, "n ..."]) -> Float[Array, "n_art ..."]:
        """Linear extrapolation (for ``x`` and ``v``): ``sum_s weights[a, s] field[src[a, s]]``."""
        vals = field[self.src]  # (n_art, n_src, *tail)
        w = self.weights.astype(field.dtype).reshape(self.weights.shape + (1,) * (field.ndim - 1))
        return jnp.sum(w * vals, axis=1)

    def mean(self, field: Float[Array, "n ..."]) -> Float[Array, "n_art ..."]:
        """Constant extrapolation (for the gradients ``F`` and ``C``): the mean over the sources."""
        return jnp.mean(field[self.src], axis=1)


def artificial_layer(cells: int, ppc: int, layers: int, sides: tuple[bool, bool]) -> ArtificialLayer | None:
    """The artificial particles of a ``cells x ppc`` bar with ``layers`` cells at each free side.

    ``sides`` says whether the left and right ends are free. Weights are computed in cell units:
    a linear least-squares fit is invariant under scaling of ``X``, so they do not depend on ``h``.
    Returns ``None`` when there is nothing to add.
    """
    if layers == 0 or not any(sides):
        return None
    n = cells * ppc
    n_src = max(ppc, 2)
    if n < n_src:
        raise ValueError(
            f"artificial cells need at least 2 real particles to extrapolate from, got cells*ppc = {n}"
        )
    X = (np.arange(n) + 0.5) / ppc
    srcs, weights = [], []
    for side, free in zip(("left", "right"), sides):
        if not free:
            continue
        if side == "left":
            src = np.arange(n_src)
            X_art = -(np.arange(layers * ppc)[::-1] + 0.5) / ppc
        else:
            src = np.arange(n - n_src, n)
            X_art = cells + (np.arange(layers * ppc) + 0.5) / ppc
        Xs = X[src]
        d = Xs - Xs.mean()
        w = 1.0 / n_src + np.outer(X_art - Xs.mean(), d) / np.sum(d * d)
        srcs.append(np.broadcast_to(src, (X_art.size, n_src)))
        weights.append(w)
    return ArtificialLayer(
        src=jnp.asarray(np.concatenate(srcs), dtype=jnp.int32),
        weights=jnp.asarray(np.concatenate(weights)),
    )


def traction_points(body: Body, cells: int, h, sides: tuple[bool, bool]) -> Float[Array, "k dim"] | None:
    """Initial positions of the material boundary points that carry a traction (left, right)."""
    del body
    pts = [x for x, on in zip((0.0, float(cells)), sides) if on]
    if not pts:
        return None
    return (jnp.asarray(pts, dtype=h.dtype) * h)[:, None]


def wall_mask(n_nodes: int, pad: int, cells: int, left: str, right: str) -> np.ndarray | None:
    """Static mask of the nodes held at zero velocity: the wall node and every node beyond it."""
    mask = np.zeros(n_nodes, dtype=bool)
    if left == "wall":
        mask[: pad + 1] = True
    if right == "wall":
        mask[pad + cells :] = True
    return mask if mask.any() else None
