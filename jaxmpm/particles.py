"""Particle state, seeding and domain geometry.

Arrays are shaped ``(n, dim)`` (vectors) and ``(n, dim, dim)`` (tensors) in 1D, 2D and 3D alike.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ._util import contract, corner_signs, lattice


class Body(eqx.Module):
    """The reference configuration of the real particles: fixed through a run.

    Attributes:
        X: reference centres, ``(n, dim)``.
        r0: initial half-lengths of the particle domains, ``(n, dim)``.
        m: masses ``rho0 * V0``, ``(n,)``.
        V0: initial volumes ``prod_a 2 r0_a`` (in 1D the length ``2 r0``, unit cross-section), ``(n,)``.
        X_corners: reference positions of the domain corners, each stored once for every particle
            that meets there, ``(nc, dim)`` (``n + 1`` in 1D).
        corner_ids: the ``2^dim`` corners of each particle, ``(n, 2^dim)``, in the order of
            ``_util.corner_signs`` (in 1D: left, right).
        boundary: whether a particle was seeded in the first or last cell of the body along any
            axis, ``(n,)``.
        region: the region of each particle (``jaxmpm.regions``), ``(n,)``; ``None`` for a body of
            one region.
        inert: how many of the particles, the last ones, are inert copies that pad the run
            (``jaxmpm._step.pad_particles``; static): 0 for a body as seeded.
        chain: the body is a 1D chain in order, particle ``p`` having corners ``p`` and ``p + 1``
            (static; ``seed_bar`` and ``seed_box`` in 1D set it): its corners are read as slices.
            ``False`` (the default) reads them through ``corner_ids``, for any order.
    """

    X: Float[Array, "n dim"]
    r0: Float[Array, "n dim"]
    m: Float[Array, " n"]
    V0: Float[Array, " n"]
    X_corners: Float[Array, "nc dim"]
    corner_ids: Int[Array, "n corners"]
    boundary: Bool[Array, " n"]
    region: Int[Array, " n"] | None = None
    inert: int = eqx.field(static=True, default=0)
    chain: bool = eqx.field(static=True, default=False)

    @property
    def n(self) -> int:
        """Number of particles."""
        return self.X.shape[0]

    def particle_corners(self, corners: Float[Array, "nc dim"]) -> Float[Array, "n corners dim"]:
        """Each particle's ``2^dim`` corners, ``corners[corner_ids]``.

        A 1D chain (``chain``: particle ``p`` has corners ``p`` and ``p + 1``, ``n + 1`` corners) is
        read as two shifted slices rather than a gather, which the step does several times a step.
        Any other body (several pieces, another order of the particles, inert copies) is gathered.

        Args:
            corners: the body's corners, one row per corner of ``X_corners``.

        Returns:
            The corners of each particle, in the order of ``_util.corner_signs``.
        """
        if self.chain and self.inert == 0 and corners.shape[0] == self.n + 1:
            return jnp.stack([corners[:-1], corners[1:]], axis=1)
        return corners[self.corner_ids]


def seed_bar(cells: int, ppc: int, h: Float[Array, ""], rho0: Float[Array, ""]) -> Body:
    """Seed ``ppc`` particles per cell on ``[0, cells h]`` (``seed_box`` in 1D).

    Args:
        cells: cells the bar fills.
        ppc: particles per cell.
        h: cell size.
        rho0: initial density.

    Returns:
        The ``Body``.
    """
    return seed_box((cells,), ppc, h, rho0)


def seed_box(cells: tuple[int, ...], ppc: int, h: Float[Array, ""], rho0: Float[Array, ""]) -> Body:
    """Seed ``ppc`` particles per cell along each axis (``ppc^dim`` per cell) on ``[0, cells_a h]``.

    Particles sit at the centres of ``ppc`` equal sub-intervals of each cell along every axis, so
    adjacent domains meet at common corners (the usual MPM seeding; Sulsky, Chen & Schreyer 1994).
    They are ordered by initial position with the last axis fastest. A particle is in a boundary
    cell when its cell is the first or last along any axis. Corners form the lattice of
    ``cells_a ppc + 1`` points per axis, in the same order.

    Args:
        cells: cells the body fills along each axis.
        ppc: particles per cell along each axis.
        h: cell size (the same along every axis).
        rho0: initial density.

    Returns:
        The ``Body``.
    """
    d = len(cells)
    counts = [c * ppc for c in cells]
    ip = lattice(counts)  # (n, dim) particle multi-indices
    n = ip.shape[0]
    X = jnp.asarray((ip + 0.5) / ppc, dtype=h.dtype) * h  # in cells, static, times h
    r0 = jnp.full((n, d), 0.5 / ppc, dtype=h.dtype) * h
    V0 = 2.0 * r0[:, 0]
    for a in range(1, d):
        V0 = V0 * (2.0 * r0[:, a])
    X_corners = jnp.asarray(lattice([c + 1 for c in counts]) / ppc, dtype=h.dtype) * h
    cstride = [int(np.prod([c + 1 for c in counts[a + 1 :]])) for a in range(d)]
    bits = (corner_signs(d) > 0).astype(np.int64)  # corner c of a particle: +1 along axis a
    ids = ((ip[:, None, :] + bits[None, :, :]) * np.asarray(cstride)[None, None, :]).sum(-1).astype(np.int32)
    cell = ip // ppc
    boundary = np.any((cell == 0) | (cell == np.asarray(cells)[None, :] - 1), axis=1)
    return Body(
        X=X,
        r0=r0,
        m=rho0 * V0,
        V0=V0,
        X_corners=X_corners,
        corner_ids=jnp.asarray(ids),
        boundary=jnp.asarray(boundary),
        chain=d == 1,
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
        corners: the tracked domain corners ``(nc, dim)``; ``None`` unless the interpolator tracks
            them (``tracks_corners``: MPQ and CPDI2).
        x_traction: material boundary points that carry a traction, ``(k, dim)``, moved with the
            grid velocity; ``None`` when the scene applies no traction.
        status: failure bitmask (see ``jaxmpm.status``); 0 while the run is healthy.
        fail_step: the step at which the first failure was detected (-1 if none).
        fail_particle: the real particle that failed first (-1 if none).
        e: specific internal energies ``(n,)``; ``None`` unless a material has an energy equation
            (``AbstractEOS``; zero on the particles of the other materials).
        internal: the materials' internal variables, a dict of per-particle arrays ``(n,)``;
            ``None`` unless a material declares some. A region without a variable holds zeros.
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
    e: Float[Array, " n"] | None = None
    internal: dict[str, Float[Array, " n"]] | None = None


def parallelogram_corners(
    r0: Float[Array, "n dim"], x: Float[Array, "n dim"], F: Float[Array, "n dim dim"]
) -> Float[Array, "n corners dim"]:
    """The ``2^dim`` corners ``x_p + F diag(r0) s_c`` of each particle's parallelogram domain.

    The domain of a particle that deforms homogeneously with its own ``F``, the convected domain of
    CPDI (Sadeghirad, Brannon & Burghardt 2011; in 1D their eq. 31, ``x_p -/+ F r0``). ``s_c`` are
    the corners of the reference cube ``[-1, 1]^dim`` (``_util.corner_signs``).

    Args:
        r0: initial half-lengths of the domains.
        x: current centres.
        F: deformation gradients.

    Returns:
        The corners of each particle, in the order of ``_util.corner_signs``.
    """
    J = F * r0[:, None, :]  # J_ij = F_ij r0_j
    if x.shape[1] == 1:  # x_p -/+ F r0
        return jnp.stack([x - J[:, :, 0], x + J[:, :, 0]], axis=1)
    signs = jnp.asarray(corner_signs(x.shape[1]), dtype=x.dtype)
    return x[:, None, :] + contract("nij,cj->nci", J, signs)
