"""Particle state and seeding.

Arrays are shaped ``(n, dim)`` (vectors) and ``(n, dim, dim)`` (tensors) so that 2D and 3D follow
without a rewrite; this release seeds 1D bodies.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int


class Body(eqx.Module):
    """The reference configuration of the real particles: fixed through a run.

    Attributes:
        X: reference centres, ``(n, dim)``.
        r0: initial half-lengths of the particle domains, ``(n, dim)``.
        m: masses ``rho0 * V0``, ``(n,)``.
        V0: initial volumes ``2 r0`` (unit cross-section), ``(n,)``.
        X_corners: reference positions of the shared domain corners, ``(n + 1, dim)`` in 1D.
        corner_ids: the two corners of each particle (left, right), ``(n, 2)``.
        boundary: whether a particle was seeded in the first or last cell of the body, ``(n,)``.
    """

    X: Float[Array, "n dim"]
    r0: Float[Array, "n dim"]
    m: Float[Array, " n"]
    V0: Float[Array, " n"]
    X_corners: Float[Array, "nc dim"]
    corner_ids: Int[Array, "n 2"]
    boundary: Bool[Array, " n"]

    @property
    def n(self) -> int:
        return self.X.shape[0]

    def particle_corners(self, corners: Float[Array, "nc dim"]) -> Float[Array, "n 2 dim"]:
        """Each particle's two corners, ``corners[corner_ids]``.

        A 1D body is a chain (``seed_bar``: particle ``p`` has corners ``p`` and ``p + 1``), read as
        two shifted slices rather than a gather, which the step does several times a step.
        """
        if self.X.shape[1] == 1 and corners.shape[0] == self.n + 1:
            return jnp.stack([corners[:-1], corners[1:]], axis=1)
        return corners[self.corner_ids]


def seed_bar(cells: int, ppc: int, h: Array, rho0: Array) -> Body:
    """Seed ``ppc`` particles per cell on ``[0, cells h]``.

    Particles sit at the centres of ``ppc`` equal sub-intervals of each cell, so adjacent domains
    share corners (SPEC section 1).
    """
    n = cells * ppc
    frac = (np.arange(n) + 0.5) / ppc  # in cells, static
    X = (jnp.asarray(frac, dtype=h.dtype) * h)[:, None]
    r0 = jnp.full((n, 1), 0.5 / ppc, dtype=h.dtype) * h
    V0 = 2.0 * r0[:, 0]
    X_corners = (jnp.asarray(np.arange(n + 1) / ppc, dtype=h.dtype) * h)[:, None]
    ids = np.stack([np.arange(n), np.arange(1, n + 1)], axis=1).astype(np.int32)  # a chain (see Body)
    cell = np.arange(n) // ppc
    boundary = (cell == 0) | (cell == cells - 1)
    return Body(
        X=X,
        r0=r0,
        m=rho0 * V0,
        V0=V0,
        X_corners=X_corners,
        corner_ids=jnp.asarray(ids),
        boundary=jnp.asarray(boundary),
    )


class State(eqx.Module):
    """The evolving state of a run. Optional parts are ``None`` unless the run needs them.

    Attributes:
        t: time.
        step: number of steps taken.
        x: current centres ``(n, dim)``.
        v: velocities ``(n, dim)``.
        F: deformation gradients ``(n, dim, dim)``.
        sigma: Cauchy stresses ``(n, dim, dim)``.
        C: APIC affine velocity matrices ``(n, dim, dim)``; ``None`` unless the transfer is APIC.
        corners: MPQ's tracked domain corners ``(n + 1, dim)``; ``None`` unless the interpolator is MPQ.
        x_traction: material boundary points that carry a traction, ``(k, dim)``, moved with the
            grid velocity; ``None`` when the scene applies no traction.
        status: failure bitmask (see ``jaxmpm.status``); 0 while the run is healthy.
        fail_step: the step at which the first failure was detected (-1 if none).
        fail_particle: the real particle that failed first (-1 if none).
    """

    t: Float[Array, ""]
    step: Int[Array, ""]
    x: Float[Array, "n dim"]
    v: Float[Array, "n dim"]
    F: Float[Array, "n dim dim"]
    sigma: Float[Array, "n dim dim"]
    C: Float[Array, "n dim dim"] | None
    corners: Float[Array, "nc dim"] | None
    x_traction: Float[Array, "k dim"] | None
    status: Int[Array, ""]
    fail_step: Int[Array, ""]
    fail_particle: Int[Array, ""]
