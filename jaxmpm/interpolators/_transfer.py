"""The pieces the interpolators have in common: tensor-product hat stencils, domain gradients,
velocity gradients.

In ``dim`` dimensions a node's shape function is the product of 1D hats, ``S_i(x) = prod_a
S_{i_a}(x_a)`` (Sulsky, Chen & Schreyer 1994); GIMP's weights are products of the 1D averages
(Bardenhagen & Kober 2004, for an axis-aligned domain). Every stencil here is built per axis and
combined by ``tensor``, so one code path serves 1D, 2D and 3D; in 1D ``tensor`` is the identity.
"""

import functools
import math
import operator

import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._util import adjugate, contract, corner_signs, det, materialise
from ..grid import Grid
from ..particles import Body
from ._base import Stencil


def point_stencil(
    grid: Grid, y: Float[Array, "..."], axis: int = 0
) -> tuple[Int[Array, "... 2"], Float[Array, "... 2"], Float[Array, "... 2"]]:
    """Nodes, hat values ``S_i(y)`` and hat slopes ``S_i'(y)`` of the two nodes around coordinates ``y``
    along ``axis`` (per-axis node indices).

    A point exactly on node ``j`` gets nodes ``(j, j + 1)`` with values ``(1, 0)`` and the slopes of
    the cell to its right: the one-sided derivative.

    Args:
        grid: the background grid.
        y: coordinates along ``axis``.
        axis: the axis.

    Returns:
        ``(idx, S, S')``, each with a last axis of the two nodes.
    """
    base, frac = grid.locate(y, axis)
    idx = jnp.stack([base, base + 1], axis=-1)
    w = jnp.stack([1.0 - frac, frac], axis=-1)
    inv_h = 1.0 / grid.h
    slope = jnp.stack([-inv_h * jnp.ones_like(frac), inv_h * jnp.ones_like(frac)], axis=-1)
    return idx, w, slope


def tensor(grid: Grid, parts, gradients: bool = True):
    """Combine per-axis stencils ``parts[a] = (idx_a, w_a, dw_a)``, each ``(..., k_a)``, into the
    tensor-product stencil ``(idx, w, dw)`` of ``prod_a k_a`` nodes (last axis fastest):
    ``w = prod_a w_a`` and ``dw[..., a] = dw_a prod_{b != a} w_b``.

    Args:
        grid: the background grid.
        parts: one ``(idx_a, w_a, dw_a)`` per axis.
        gradients: whether to form ``dw``.

    Returns:
        ``(idx, w, dw)``: flat node indices and weights ``(..., k)``, gradients ``(..., k, dim)`` (or
        ``None``).
    """
    if len(parts) == 1:
        idx, w, dw = parts[0]
        return idx, w, (dw[..., None] if gradients else None)
    lead = parts[0][0].shape[:-1]
    ks = [p[0].shape[-1] for p in parts]
    k = math.prod(ks)

    def expand(x, a):
        return x.reshape(lead + tuple(kb if b == a else 1 for b, kb in enumerate(ks)))

    def flat(x):
        return jnp.broadcast_to(x, lead + tuple(ks)).reshape(lead + (k,))

    idx = flat(grid.flat_index([expand(p[0], a) for a, p in enumerate(parts)]))
    ws = [expand(p[1], a) for a, p in enumerate(parts)]
    w = flat(functools.reduce(operator.mul, ws))
    if not gradients:
        return idx, w, None
    dws = []
    for a, p in enumerate(parts):
        factors = [expand(p[2], a) if b == a else ws[b] for b in range(len(parts))]
        dws.append(flat(functools.reduce(operator.mul, factors)))
    return idx, w, jnp.stack(dws, axis=-1)


def points_stencil(grid: Grid, y: Float[Array, "... dim"], gradients: bool = True):
    """The ``2^dim``-node hat stencil of points ``y``.

    Args:
        grid: the background grid.
        y: the points.
        gradients: whether to form ``grad S_i(y)``.

    Returns:
        ``(idx, S_i(y), grad S_i(y))`` with flat node indices (``tensor``).
    """
    parts = [point_stencil(grid, y[..., a], a) for a in range(y.shape[-1])]
    return tensor(grid, parts, gradients)


def corner_matrix(c: Float[Array, "n corners dim"]) -> Float[Array, "n dim dim"]:
    """``D = sum_c x_c s_c^T`` of each particle's ``2^dim`` corners ``x_c`` (signs ``s_c`` of
    ``corner_signs``): for a parallelogram ``x_c = x_p + J s_c`` it is ``2^dim J``, and in 1D the
    domain length ``x_c2 - x_c1``. Written as sums and differences (no products by +-1).

    Args:
        c: each particle's corners, in the order of ``corner_signs``.

    Returns:
        ``D`` of each particle.
    """
    d = c.shape[-1]
    signs = corner_signs(d)
    cols = []
    for j in range(d):
        plus = functools.reduce(operator.add, [c[:, i] for i in range(2**d) if signs[i, j] > 0])
        minus = functools.reduce(operator.add, [c[:, i] for i in range(2**d) if signs[i, j] < 0])
        cols.append(plus - minus)
    return jnp.stack(cols, axis=-1)


def domain_gradient(S: Float[Array, "n corners k"], D: Float[Array, "n dim dim"]) -> Float[Array, "n ck dim"]:
    """The domain-averaged gradient of each node's shape function from its values ``S`` at the
    particle's corners, ``dphi_ip = sum_c S_i(x_c) D^-T s_c`` with ``D`` of ``corner_matrix``.

    For a parallelogram this is the exact average of the gradient of the corner-interpolated shape
    function over the domain, ``2^-dim sum_c S_i(x_c) J^-T s_c`` (Sadeghirad, Brannon & Burghardt
    2011, CPDI1; in 2D their eq. 31). In 1D it is ``(S_i(c2) - S_i(c1)) / (c2 - c1)``. The entries
    are returned flat, ``(n, corners * k, dim)`` (corner-major); summing over corners is left to the
    scatter. In 2D and 3D each entry is ``S_i(x_c) g_c`` with ``g_c`` of ``corner_vectors``.

    Args:
        S: each node's hat value at each of the particle's corners.
        D: ``corner_matrix`` of the corners.

    Returns:
        ``dphi_ip`` per (corner, node) entry.
    """
    d = D.shape[-1]
    n, c, k = S.shape
    if d == 1:  # adj(D) = 1: signed hat values over the length, as flat rows (the fastest form)
        sign = jnp.repeat(jnp.asarray(corner_signs(1), dtype=D.dtype)[:, 0], k)  # per (corner, node) entry
        return ((sign[None, :] * S.reshape(n, c * k)) / D[:, :, 0])[..., None]
    return (S[..., None] * corner_vectors(D)[:, :, None, :]).reshape(n, c * k, d)


def corner_vectors(D: Float[Array, "n dim dim"]) -> Float[Array, "n corners dim"]:
    """``g_c = D^-T s_c = adj(D)^T s_c / det D`` for each of a particle's ``2^dim`` corners (signs
    ``s_c`` of ``corner_signs``), the factor of the domain form ``dphi_ip = sum_c S_i(x_c) g_c``.

    Args:
        D: ``corner_matrix`` of each particle's corners.

    Returns:
        ``g_c`` of each particle's corners.
    """
    signs = jnp.asarray(corner_signs(D.shape[-1]), dtype=D.dtype)
    return contract("nji,cj->nci", adjugate(D), signs) / det(D)[:, None, None]


def domain_stencil(
    idx: Int[Array, "n k"],
    w: Float[Array, "n k"],
    gidx: Int[Array, "n ck"],
    S: Float[Array, "n corners nodes"],
    D: Float[Array, "n dim dim"],
) -> Stencil:
    """The stencil of an interpolator whose ``dphi`` is the domain form (``domain_gradient``) on the
    nodes ``gidx`` of the corners' hat stencils ``S``; in 2D and 3D it carries the factors ``S_c`` and
    ``g_c`` as well.

    Args:
        idx: node indices of ``phi``.
        w: values of ``phi``.
        gidx: node indices of ``dphi``, corner-major.
        S: each node's hat value at each of the particle's corners.
        D: ``corner_matrix`` of the corners.

    Returns:
        The ``Stencil``.
    """
    if D.shape[-1] == 1:
        return Stencil(idx, w, gidx, domain_gradient(S, D), None)
    n, c, k = S.shape
    g = corner_vectors(D)
    dw = (S[..., None] * g[:, :, None, :]).reshape(n, c * k, D.shape[-1])
    return Stencil(idx, w, gidx, dw, None, S, g)


def gradient_forces(
    stencil: Stencil, sigma: Float[Array, "n dim dim"], V: Float[Array, " n"]
) -> Float[Array, "n kg dim"]:
    """``V_p sigma_p dphi_ip`` for every entry of the stencil's ``dphi`` (the internal force, before
    its sign): through the factors ``S_c``, ``g_c`` where the stencil has them, ``S_i(x_c) (V_p
    sigma_p g_c)``.

    Args:
        stencil: the particles' stencil (with gradients).
        sigma: the particles' stress.
        V: the particles' volume.

    Returns:
        ``V_p sigma_p dphi_ip`` per entry of ``gidx``.
    """
    if stencil.S_c is None:
        return contract("nab,nkb->nka", sigma, stencil.dw) * V[:, None, None]
    n, c, k = stencil.S_c.shape
    q = materialise(contract("nab,ncb->nca", sigma, stencil.g_c) * V[:, None, None])
    return (stencil.S_c[..., None] * q[:, :, None, :]).reshape(n, c * k, q.shape[-1])


def shared_corner_forces(
    grid: Grid,
    stencil: Stencil,
    sigma: Float[Array, "n dim dim"],
    V: Float[Array, " n"],
    corners: Float[Array, "nc dim"],
    corner_ids: Int[Array, "n corners"],
) -> Float[Array, "n_nodes dim"]:
    """The nodal internal force (before its sign) ``sum_p V_p sigma_p dphi_ip`` of particles whose
    domain corners are tracked and shared (MPQ, CPDI2 in 2D and 3D), summed corner by corner.

    With ``dphi_ip = sum_c S_i(x_c) g_pc`` (``domain_stencil``) the force is ``sum_corners S_i(x_c)
    Q_c`` with ``Q_c = sum_{p at c} V_p sigma_p g_pc``: each corner gathers its particles' share
    first (``2^dim`` entries a particle), then its own hat stencil takes it to the nodes (``2^dim``
    entries a corner), where the per-particle form scatters ``4^dim`` entries a particle. Equal to
    that form up to the order of the sums.

    Args:
        grid: the background grid.
        stencil: the particles' stencil (with the factors ``g_c``).
        sigma: the particles' stress.
        V: the particles' volume.
        corners: the body's tracked corners, one row per corner.
        corner_ids: each particle's corners (``Body.corner_ids``), in the order of ``g_c``.

    Returns:
        The nodal force.
    """
    q = contract("nab,ncb->nca", sigma, stencil.g_c) * V[:, None, None]
    q_corner = jnp.zeros(corners.shape, q.dtype).at[corner_ids].add(q)
    c_idx, c_s, _ = points_stencil(grid, corners, gradients=False)
    return grid.scatter(c_idx, c_s[..., None] * q_corner[:, None, :])


def gradient_outer(stencil: Stencil, values: Float[Array, "n kg dim"]) -> Float[Array, "n dim dim"]:
    """``sum_i values_ip (dphi_ip)^T`` over the stencil's ``dphi`` entries (a velocity gradient):
    through the factors where the stencil has them, ``sum_c (sum_i S_i(x_c) values_ip) g_c^T``.

    Args:
        stencil: the particles' stencil (with gradients).
        values: one vector per entry of ``gidx`` (nodal values gathered there).

    Returns:
        The sum of outer products, one matrix per particle.
    """
    if stencil.S_c is None:
        return contract("nka,nkb->nab", values, stencil.dw)
    n, c, k = stencil.S_c.shape
    at_corners = materialise(
        contract("nck,nckd->ncd", stencil.S_c, values.reshape(n, c, k, values.shape[-1]))
    )
    return contract("nca,ncb->nab", at_corners, stencil.g_c)


def velocity_gradient(
    grid: Grid, stencil: Stencil, v_nodes: Float[Array, "n_nodes dim"]
) -> Float[Array, "n dim dim"]:
    """``L_p = sum_i v_i (dphi_ip)^T``, the velocity gradient each particle sees.

    Args:
        grid: the background grid.
        stencil: the particles' stencil (with gradients).
        v_nodes: nodal velocities.

    Returns:
        ``L`` of each particle.
    """
    return gradient_outer(stencil, grid.gather(stencil.gidx, v_nodes, stencil.gbase))


def multiplicative_F_update(
    grid: Grid,
    stencil: Stencil,
    F: Float[Array, "n dim dim"],
    v_new: Float[Array, "n_nodes dim"],
    dt: Float[Array, ""],
) -> Float[Array, "n dim dim"]:
    """``F <- (I + dt L) F`` with ``L`` of ``velocity_gradient``, the update of SPQ (Sulsky, Chen &
    Schreyer 1994), GIMP (Bardenhagen & Kober 2004) and CPDI (Sadeghirad, Brannon & Burghardt 2011).

    Args:
        grid: the background grid.
        stencil: the particles' stencil (with gradients).
        F: deformation gradients at the start of the step.
        v_new: nodal velocities at the end of the step.
        dt: the time step.

    Returns:
        The new deformation gradients.
    """
    L = velocity_gradient(grid, stencil, v_new)
    return F + dt * contract("nab,nbc->nac", L, F)


def tracked_corner_update(
    grid: Grid,
    body: Body,
    F: Float[Array, "n dim dim"],
    corners: Float[Array, "nc dim"],
    v_new: Float[Array, "n_nodes dim"],
    dt: Float[Array, ""],
) -> tuple[Float[Array, "n dim dim"], Float[Array, "nc dim"]]:
    """Move the tracked domain corners with the grid velocity and read ``F`` off them, the update of
    MPQ (Bonifasi-Lista, Brannon & Wiskin 2013) and CPDI2 (Sadeghirad, Brannon & Guilkey 2013).

    Every corner, stored once for all the particles that meet at it, moves ``x_c += dt sum_i S_i(x_c)
    v_i``; then ``F = D diag(1 / (2^dim r0))`` with ``D`` of ``corner_matrix``, the mean gradient of
    the map from the reference cube ``x_p + diag(r0) [-1, 1]^dim`` to the corners (exact for a
    parallelogram; in 1D ``(x_c2 - x_c1) / (2 r0)``).

    In float64 ``F`` is read off the moved corners' positions, so it is the corners' geometry to the
    last bit. In float32 that reading would carry the positions' round-off, ``eps |x| / (2 r0)`` a
    step, which grows as the grid is refined (``F_max_rel`` 1.0e-3 at 256 cells of the manufactured
    bar, where float64 has 3.9e-7); there ``F`` takes the same update as an increment, ``F += dt
    corner_matrix(v_c) diag(1 / (2^dim r0))`` (``D`` is linear in the corners), equal in exact
    arithmetic and accurate to float32's own precision.

    Args:
        grid: the background grid.
        body: the reference configuration (its ``r0`` and ``particle_corners``).
        F: the deformation gradients at the start of the step (read in float32 only).
        corners: the body's tracked corners at the start of the step.
        v_new: nodal velocities at the end of the step.
        dt: the time step.

    Returns:
        ``(F_new, corners_new)``.
    """
    cidx, s, _ = points_stencil(grid, corners, gradients=False)
    if grid.dim == 2:
        # The corners' node indices written once (as ``jaxmpm._step._materialised`` does for the
        # particles' stencil): fused into the gather, XLA's CPU backend redoes their computation for
        # every component of every read. In 3D the copy saves nothing, and the fused form stays.
        # Measured in the Performance page of the docs.
        cidx = materialise(cidx)
    v_c = contract("ck,ckd->cd", s, grid.gather(cidx, v_new, cidx[:, :1] if grid.dim == 1 else None))
    corners = corners + dt * v_c
    scale = ((2.0**grid.dim) * body.r0)[:, None, :]
    if corners.dtype == jnp.float64:
        return corner_matrix(body.particle_corners(corners)) / scale, corners  # (n, dim, dim)
    return F + dt * corner_matrix(body.particle_corners(v_c)) / scale, corners


def any_axis(mask):
    """``mask.any(-1)`` as unrolled ORs (a short reduce is a slow library call on XLA's CPU backend).

    Args:
        mask: booleans with a short last axis.

    Returns:
        Whether any entry along the last axis is set.
    """
    return functools.reduce(operator.or_, [mask[..., a] for a in range(mask.shape[-1])])
