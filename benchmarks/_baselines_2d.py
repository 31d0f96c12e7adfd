"""The benchmark's reference codes in 2D and 3D: the algorithm of ``jm.SPQ()`` with FLIP and USL on
``jm.GasExpansion(dim=2 or 3)``, written directly in NumPy, plain JAX, Taichi and Warp.

Every code here takes the dimension as an argument (2 or 3) and runs the same method as jaxmpm's
step on that scene: tensor-product linear hats (``2^dim`` nodes a particle), the adiabatic gas
``sigma = -(P0 J^-gamma - p_atm) I``, internal force ``-sum_p sigma_p grad S_i(x_p) V0 J_p``, the
exact traction on every face (``f^(dim - 1) sigma(f I) N`` per reference area, ``f = 1 + beta t``)
applied at the traction points of ``jaxmpm.boundaries.traction_points`` (the particle-domain corners
on each face, trapezoid areas) which move with the grid velocity, FLIP, ``F <- (I + dt L) F``, no
artificial cells and no checks.

A traction point that has moved off the body's nodes (the box of nodes ``pad .. pad + k`` along each
axis, the nodes with mass) puts its force on the nearest node of that box: its stencil's node indices
are clamped to the box. That is what jaxmpm's fold of force off nodes without mass
(``jaxmpm._step.fold_massless``) does while the nodes with mass form that box, as they do here until a
particle enters a new cell (``PROBLEM_ND``); after that the two differ (``bench.method_gap``).
``numpy_spq_nd(fold=True)`` runs the fold itself instead, the check that ``jaxmpm spq`` computes that
method. (The 1D reference codes drop such
force. In 2D that loses part of the traction on every high face from the first step, the faces
accelerate outward, and the run breaks down: at step 68 of 100 at 102,400 particles.)

Each function returns ``(compile_s, run_s, F_mean, status)``, ``F_mean`` the mean over every entry of
the final ``(n, dim, dim)`` F (what the benchmark reports for jaxmpm's rows), so that the benchmark can
compare the codes and a wrong kernel cannot pass as a fast one, and ``status`` the final state's
health in jaxmpm's status bits (``_baselines.health``, with ``det F`` for F > 0), checked after the
timed steps. Taichi and Warp are optional
(``pip install jaxmpm[bench]``); each function imports its package when called.

(No ``from __future__ import annotations`` here: Taichi and Warp read the kernels' annotations.)
"""

import itertools
import math
import time

import numpy as np

from ._baselines import PROBLEM, grid_span, health, scatter_sum

PROBLEM_ND = dict(PROBLEM, beta=5.0)
"""The 2D and 3D problem: the 1D benchmark's gas, with ``beta = 5 /s`` instead of 200.

Standard MPM with USL breaks down (``status 3``: non-finite, ``det F <= 0``) a few steps after the
first particles enter a new cell: that node gets a sliver of mass but a finite force through
``grad S_i``. In 2D and 3D a whole face of particles enters at once, and at ``beta = 200 /s``
jaxmpm's SPQ breaks down within 100 steps (at step 70 with ``dt = 0.1 h / 600``, at 16k and 100k
particles). At ``beta = 5 /s`` and ``dt = 0.1 h / (c0 + beta)`` the faces move about ``0.09 h`` in 100
steps, whatever ``h``, and no particle enters a new cell: SPQ runs healthy in float32 and float64
(measured, float64: the breakdown comes at steps 205-206 in 2D at 16k and 100k particles, at step 170 in
3D at 33k). A compression (``beta < 0``) is no better: from the corners where a low face meets a high
face, SPQ's error grows to ``|F - F_exact| = 0.5`` within 100 steps at ``beta = -10 /s``."""

CFL = 0.1
"""``dt = CFL h / (c0 + beta)``, ``c0`` the gas's sound speed at ``F = 1``."""

PAD = 4
"""Empty cells on each side of the body along each axis."""


def cells_of(n: int, dim: int) -> int | None:
    """The cells ``k`` per axis of an ``n``-particle body of ``k^dim`` cells with ``2^dim`` particles each.

    Args:
        n: particles.
        dim: 2 or 3.

    Returns:
        ``k``, or ``None`` when ``n`` is not ``(2 k)^dim`` for an integer ``k >= 1`` (exactly, in integer
        arithmetic, for any integer ``n``).
    """
    if n < 2**dim:
        return None
    side = integer_root(n, dim)
    return side // 2 if side % 2 == 0 and side**dim == n else None


def integer_root(n: int, dim: int) -> int:
    """The largest integer ``r`` with ``r^dim <= n`` (Newton's method on integers: exact for any size).

    Args:
        n: an integer >= 0.
        dim: the root's degree, >= 1.

    Returns:
        ``r``.
    """
    if n < 2:
        return n
    r = 1 << -(-n.bit_length() // dim)  # 2^ceil(bits / dim) > the root
    while True:
        s = ((dim - 1) * r + n // r ** (dim - 1)) // dim
        if s >= r:
            return r
        r = s


def layout_nd(n: int, dim: int) -> dict:
    """Grid, particles and step of the ``n``-particle problem on the unit square (cube).

    Args:
        n: particles, ``(2 k)^dim``: ``k^dim`` cells of ``2^dim`` particles.
        dim: 2 or 3.

    Returns:
        ``dim``, ``cells`` (``k``), ``h``, ``pad``, ``axis_nodes`` (nodes along each axis), ``nodes``
        (all of them), ``x_min`` (the first node along each axis), ``dt``, ``m`` and ``V0`` (each
        particle's mass and volume), ``c0``.

    Raises:
        ValueError: ``n`` is not ``(2 k)^dim``.
    """
    k = cells_of(n, dim)
    if k is None:
        raise ValueError(f"{n} particles is not (2 k)^{dim}: k^{dim} cells of 2^{dim} particles")
    h = 1.0 / k
    P = PROBLEM_ND
    c0 = math.sqrt(P["gamma"] * P["P0"] / P["rho0"])
    axis_nodes = k + 2 * PAD + 1
    V0 = (h / 2) ** dim
    return dict(
        dim=dim,
        cells=k,
        h=h,
        pad=PAD,
        axis_nodes=axis_nodes,
        nodes=axis_nodes**dim,
        x_min=-PAD * h,
        dt=CFL * h / (c0 + P["beta"]),
        m=P["rho0"] * V0,
        V0=V0,
        c0=c0,
    )


def _lattice(counts) -> np.ndarray:
    """Integer multi-indices of a lattice, last axis fastest (jaxmpm's particle and node order)."""
    return np.indices(tuple(counts)).reshape(len(counts), -1).T


def initial_particles(L: dict, dtype) -> np.ndarray:
    """Reference positions of the particles, ``(n, dim)``: two per cell along each axis at the
    centres of the half cells, in jaxmpm's order (``particles.seed_box``).

    Args:
        L: ``layout_nd``.
        dtype: a NumPy float type.

    Returns:
        ``X``.
    """
    ip = _lattice([2 * L["cells"]] * L["dim"])
    return ((ip + 0.5) / 2 * L["h"]).astype(dtype)


def traction_layout(L: dict, dtype):
    """The traction points of every face (``jaxmpm.boundaries.traction_points``, two particles per
    cell) and the traction each carries per unit of ``T(t)`` (``face_stress``).

    Faces in jaxmpm's order (low and high face of axis 0, then of axis 1, ...), on each the
    particle-domain corners of the face (``2 k + 1`` per axis, last axis fastest) with their
    trapezoid areas ``(h / 2)^(dim - 1)``, halved per axis on an edge of the face.

    Args:
        L: ``layout_nd``.
        dtype: a NumPy float type.

    Returns:
        ``(X_tr, t_vec)``, each ``(points, dim)``: the points' reference positions, and ``N area``
        (the outward normal times the point's area), so a point's traction is ``t_vec T(t)``.
    """
    dim, k, h = L["dim"], L["cells"], L["h"]
    along = np.arange(2 * k + 1) / 2
    share = np.ones(2 * k + 1)
    share[[0, -1]] = 0.5
    pts, vecs = [], []
    for a, high in itertools.product(range(dim), (False, True)):
        coords = [along] * dim
        coords[a] = np.array([float(k) if high else 0.0])
        weights = [share] * dim
        weights[a] = np.ones(1)
        idx = _lattice([len(c) for c in coords])
        P = np.stack([coords[b][idx[:, b]] for b in range(dim)], axis=1) * h
        area = np.prod(np.stack([weights[b][idx[:, b]] for b in range(dim)], axis=1), axis=1)
        area = area * (h / 2) ** (dim - 1)
        vec = np.zeros_like(P)
        vec[:, a] = area if high else -area
        pts.append(P)
        vecs.append(vec)
    return np.concatenate(pts).astype(dtype), np.concatenate(vecs).astype(dtype)


def face_stress(t: float, dim: int) -> float:
    """``T(t) = f^(dim - 1) sigma(f I)`` with ``f = 1 + beta t``: the normal component of the exact
    solution's first Piola stress, so a face with outward normal ``N`` carries ``T(t) N`` per unit
    reference area (``GasExpansion.traction``).

    Args:
        t: time (s).
        dim: 2 or 3.

    Returns:
        ``-(f^(dim - 1)) (P0 f^(-gamma dim) - p_atm)``.
    """
    P = PROBLEM_ND
    f = 1.0 + P["beta"] * t
    return -(f ** (dim - 1)) * (P["P0"] * (f**dim) ** -P["gamma"] - P["p_atm"])


def _corners(dim: int) -> np.ndarray:
    """The ``2^dim`` stencil nodes of a cell as offsets ``(2^dim, dim)``, last axis fastest."""
    return _lattice([2] * dim)


def _det(F: np.ndarray) -> np.ndarray:
    if F.shape[-1] == 2:
        return F[:, 0, 0] * F[:, 1, 1] - F[:, 0, 1] * F[:, 1, 0]
    a, b, c = F[:, 0, 0], F[:, 0, 1], F[:, 0, 2]
    return (
        a * (F[:, 1, 1] * F[:, 2, 2] - F[:, 1, 2] * F[:, 2, 1])
        - b * (F[:, 1, 0] * F[:, 2, 2] - F[:, 1, 2] * F[:, 2, 0])
        + c * (F[:, 1, 0] * F[:, 2, 1] - F[:, 1, 1] * F[:, 2, 0])
    )


def _stencil(y: np.ndarray, L: dict, f, gradients: bool = True, box: bool = False):
    """Flat node indices ``(m, 2^dim)``, hat values and (optionally) hat gradients ``(m, 2^dim, dim)``
    of points ``y`` (``(m, dim)``); with ``box``, node indices clamped to the body's nodes (``BOX``)."""
    dim, h = L["dim"], f(L["h"])
    s = (y - f(L["x_min"])) / h
    base = np.floor(s)
    fr = (s - base).astype(f)
    base = base.astype(np.int64)
    W = (1 - fr, fr)
    strides = [L["axis_nodes"] ** (dim - 1 - a) for a in range(dim)]
    slope = (-1 / h, 1 / h)
    idx, w, dw = [], [], []
    for c in _corners(dim):
        node = [base[:, a] + int(c[a]) for a in range(dim)]
        if box:
            node = [np.clip(i, L["pad"], L["pad"] + L["cells"]) for i in node]
        idx.append(sum(node[a] * strides[a] for a in range(dim)))
        ws = [W[c[a]][:, a] for a in range(dim)]
        w.append(math.prod(ws))
        if gradients:
            dw.append([slope[c[a]] * math.prod(ws[:a] + ws[a + 1 :]) for a in range(dim)])
    idx, w = np.stack(idx, axis=1), np.stack(w, axis=1)
    if not gradients:
        return idx, w, None
    return idx, w, np.stack([np.stack(g, axis=1) for g in dw], axis=1).astype(f)


def _shift(x: np.ndarray, by: int, a: int) -> np.ndarray:
    """``x[i - by]`` along axis ``a`` (``by`` = +-1), zero-filled."""
    out = np.zeros_like(x)
    dst, src = [slice(None)] * x.ndim, [slice(None)] * x.ndim
    if by > 0:
        dst[a], src[a] = slice(1, None), slice(None, -1)
    else:
        dst[a], src[a] = slice(None, -1), slice(1, None)
    out[tuple(dst)] = x[tuple(src)]
    return out


def fold_massless_nd(f: np.ndarray, has_mass: np.ndarray, axes: tuple[int, ...]) -> np.ndarray:
    """jaxmpm's fold of force off nodes without mass on a 2D or 3D grid (``_step.fold_massless``).

    Force on an empty node with massive neighbours along several axes is split equally among those
    axes, going to the lower neighbour with mass first along each; force whose only massive
    neighbours are diagonal moves one axis at a time, axis 0 first, towards a node from which mass
    is within reach along the later axes; what has no mass within one node is dropped.

    Args:
        f: nodal forces ``(nodes, dim)``.
        has_mass: which nodes count as having mass.
        axes: nodes along each axis.

    Returns:
        The folded forces.
    """
    d = len(axes)
    m = has_mass.reshape(axes)
    reach = [m] * d
    for a in range(d - 2, -1, -1):
        r = reach[a + 1]
        reach[a] = r | _shift(r, 1, a + 1) | _shift(r, -1, a + 1)
    f = f.reshape(axes + f.shape[1:])
    M = m[..., None]
    kept = np.where(M, f, 0)
    stray = np.where(M, 0, f)
    near = [_shift(m, 1, a) | _shift(m, -1, a) for a in range(d)]
    count = sum(np.where(n_a, 1, 0) for n_a in near).astype(f.dtype)
    for a in range(d):
        part = stray * (np.where(near[a], 1, 0) / np.maximum(count, 1))[..., None].astype(f.dtype)
        left_m = _shift(m, 1, a)
        kept = kept + _shift(np.where(left_m[..., None], part, 0), -1, a)
        kept = kept + _shift(np.where((~left_m & _shift(m, -1, a))[..., None], part, 0), 1, a)
    stray = np.where((count > 0)[..., None], 0, stray)
    for a in range(d):
        T = reach[a]
        left_m, right_m = _shift(m, 1, a), _shift(m, -1, a)
        left_T, right_T = _shift(T, 1, a), _shift(T, -1, a)
        stays = ~left_m & ~right_m & T
        go_left = left_m | (~right_m & ~stays & left_T)
        go_right = ~go_left & (right_m | (~stays & right_T))
        moved = (
            np.where((~go_left & ~go_right)[..., None], stray, 0)
            + _shift(np.where(go_left[..., None], stray, 0), -1, a)
            + _shift(np.where(go_right[..., None], stray, 0), 1, a)
        )
        kept = kept + np.where(M, moved, 0)
        stray = np.where(M, 0, moved)
    return kept.reshape((-1,) + f.shape[d:]).astype(f.dtype)


def numpy_spq_nd(n: int, steps: int, dtype: str, dim: int = 2, fold: bool = False):
    """A Python loop of NumPy steps, ``np.bincount`` scatters of the ``2^dim`` stencil nodes (which sum
    in float64: in float32 each nodal sum is rounded to float32, and the step goes on in float32).

    With ``fold``, the traction points' force is scattered to their own stencil nodes and then moved
    off nodes without mass as jaxmpm's step does (node masses under ``256 eps m`` count as empty;
    ``fold_massless_nd``), instead of going to the nearest of the body's nodes directly. The
    benchmark times ``fold=False``; ``fold=True`` is the check that ``jaxmpm spq`` computes this
    method.

    Args:
        n: particles, ``(2 k)^dim``.
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``.
        dim: 2 or 3.
        fold: move force off empty nodes as jaxmpm does, instead of clamping to the body's nodes.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time (0: nothing compiles), run time, the mean
        of the final F and the final state's ``health`` (``_baselines.health``). A step that cannot
        run (a ``bincount`` meets an index off the grid) ends the run with the state before it. With
        ``fold`` the state is checked after every step, as jaxmpm does, and the run stops at the
        first unhealthy one, ``F_mean`` NaN.
    """
    f = np.float32 if dtype == "f32" else np.float64
    L = layout_nd(n, dim)
    P = PROBLEM_ND
    X = initial_particles(L, f)
    x, v = X.copy(), (P["beta"] * X).astype(f)
    F = np.broadcast_to(np.eye(dim, dtype=f), (n, dim, dim)).copy()
    x_tr, t_vec = traction_layout(L, f)
    nodes, dt = L["nodes"], f(L["dt"])
    m, V0 = f(L["m"]), f(L["V0"])
    P0, gamma, p_atm = f(P["P0"]), f(P["gamma"]), f(P["p_atm"])
    tiny = 256 * np.finfo(f).eps * m
    lo, hi = grid_span(L)
    error = None

    def scatter(idx, values):
        return scatter_sum(idx, values, nodes, f)

    t0 = time.perf_counter()
    try:
        for k in range(steps):
            T = f(face_stress(k * L["dt"], dim))
            idx, w, dw = _stencil(x, L, f)
            t_idx, t_w, _ = _stencil(x_tr, L, f, gradients=False)
            t_to = t_idx if fold else _stencil(x_tr, L, f, gradients=False, box=True)[0]
            J = _det(F)
            fi = -(P0 * J**-gamma - p_atm) * V0 * J  # sigma_p V_p, sigma = that times I
            flat, t_flat = idx.ravel(), t_to.ravel()
            mass = scatter(flat, (w * m).ravel())
            mom = np.stack([scatter(flat, (w * (m * v[:, a])[:, None]).ravel()) for a in range(dim)], 1)
            tr = t_vec * T
            force = np.stack(
                [
                    scatter(t_flat, (t_w * tr[:, a][:, None]).ravel())
                    - scatter(flat, (dw[:, :, a] * fi[:, None]).ravel())
                    for a in range(dim)
                ],
                1,
            )
            active = mass > (tiny if fold else 0)
            if fold:
                force = fold_massless_nd(force, active, (L["axis_nodes"],) * dim)
            safe = np.where(active, mass, 1)[:, None]
            vn = np.where(active[:, None], mom / safe, 0)
            acc = np.where(active[:, None], force / safe, 0).astype(f)
            vnew = (vn + dt * acc).astype(f)
            vg, ag = vnew[idx], acc[idx]  # (n, 2^dim, dim)
            v = v + dt * np.einsum("nk,nkd->nd", w, ag)
            x = x + dt * np.einsum("nk,nkd->nd", w, vg)
            grad_v = np.einsum("nka,nkb->nab", vg, dw)
            F = F + dt * np.matmul(grad_v, F)
            x_tr = x_tr + dt * np.einsum("nk,nkd->nd", t_w, vnew[t_idx])
            if fold and health(x, v, F, x_tr, lo, hi, _det(F)):  # checked every step, as jaxmpm does
                break
    except (ValueError, IndexError) as e:  # a bincount met an index off the grid
        error = e  # x, v, F, x_tr: the state before the step
    run_s = time.perf_counter() - t0
    status = health(x, v, F, x_tr, lo, hi, _det(F))
    if error is not None and status == 0:
        raise error
    return 0.0, run_s, float("nan") if fold and status else float(np.mean(F)), status


def plain_jax_spq_nd(n: int, steps: int, dtype: str, dim: int = 2):
    """The same algorithm as one ``lax.scan`` with ``.at[].add`` scatters.

    Args:
        n: particles, ``(2 k)^dim``.
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``; not read: the float type is the process's (float64 exactly
            when x64 is on).
        dim: 2 or 3.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time, run time, the mean of the final F and
        the final state's ``health`` (checked after the timed run).
    """
    import jax
    import jax.numpy as jnp

    del dtype  # float64 exactly when the process enabled x64
    L = layout_nd(n, dim)
    P = PROBLEM_ND
    h, nodes, x_min, dt, m, V0 = (L[k] for k in ("h", "nodes", "x_min", "dt", "m", "V0"))
    strides = [L["axis_nodes"] ** (dim - 1 - a) for a in range(dim)]
    corners = [tuple(int(b) for b in c) for c in _corners(dim)]
    K = len(corners)

    def stencil(y, gradients=True, box=False):
        s = (y - x_min) / h
        base = jnp.floor(s)
        fr = s - base
        base = base.astype(jnp.int32)
        W = (1 - fr, fr)
        idx, w, dw = [], [], []
        for c in corners:
            node = [base[:, a] + c[a] for a in range(dim)]
            if box:  # onto the body's nodes (see the module's docstring)
                node = [jnp.clip(i, L["pad"], L["pad"] + L["cells"]) for i in node]
            idx.append(sum(node[a] * strides[a] for a in range(dim)))
            ws = [W[c[a]][:, a] for a in range(dim)]
            w.append(math.prod(ws))
            if gradients:
                slope = [(1 / h if c[a] else -1 / h) for a in range(dim)]
                dw.append(jnp.stack([slope[a] * math.prod(ws[:a] + ws[a + 1 :]) for a in range(dim)], 1))
        return jnp.stack(idx, 1), jnp.stack(w, 1), jnp.stack(dw, 1) if gradients else None

    def det(F):
        if dim == 2:
            return F[:, 0, 0] * F[:, 1, 1] - F[:, 0, 1] * F[:, 1, 0]
        a, b, c = F[:, 0, 0], F[:, 0, 1], F[:, 0, 2]
        return (
            a * (F[:, 1, 1] * F[:, 2, 2] - F[:, 1, 2] * F[:, 2, 1])
            - b * (F[:, 1, 0] * F[:, 2, 2] - F[:, 1, 2] * F[:, 2, 0])
            + c * (F[:, 1, 0] * F[:, 2, 1] - F[:, 1, 1] * F[:, 2, 0])
        )

    def run(X, x_tr, t_vec):
        def step(carry, k):
            x, v, F, x_tr = carry
            fac = 1.0 + P["beta"] * (k * dt)
            T = -(fac ** (dim - 1)) * (P["P0"] * (fac**dim) ** -P["gamma"] - P["p_atm"])
            idx, w, dw = stencil(x)
            t_idx, t_w, _ = stencil(x_tr, gradients=False)
            t_to = stencil(x_tr, gradients=False, box=True)[0]
            J = det(F)
            fi = -(P["P0"] * J ** -P["gamma"] - P["p_atm"]) * V0 * J
            flat, t_flat = idx.reshape(-1), t_to.reshape(-1)
            z = jnp.zeros(nodes, X.dtype)
            zv = jnp.zeros((nodes, dim), X.dtype)
            mass = z.at[flat].add((w * m).reshape(-1))
            mom = zv.at[flat].add((w[:, :, None] * (m * v)[:, None, :]).reshape(-1, dim))
            force = zv.at[flat].add(-(dw * fi[:, None, None]).reshape(-1, dim))
            force = force.at[t_flat].add((t_w[:, :, None] * (t_vec * T)[:, None, :]).reshape(-1, dim))
            active = (mass > 0)[:, None]
            safe = jnp.where(active, mass[:, None], 1)
            vn = jnp.where(active, mom / safe, 0)
            acc = jnp.where(active, force / safe, 0)
            vnew = vn + dt * acc
            vg, ag, tg = vnew[idx], acc[idx], vnew[t_idx]
            # sums over the stencil in unrolled adds: as a reduce, XLA's CPU backend fuses each with
            # the gather and the nodal arithmetic before it and redoes those per read (3.9x slower
            # in 2D at 102,400 particles, measured)
            v = v + dt * sum(w[:, c, None] * ag[:, c] for c in range(K))
            x = x + dt * sum(w[:, c, None] * vg[:, c] for c in range(K))
            grad_v = sum(vg[:, c, :, None] * dw[:, c, None, :] for c in range(K))
            F = F + dt * jnp.matmul(grad_v, F)
            x_tr = x_tr + dt * sum(t_w[:, c, None] * tg[:, c] for c in range(K))
            return (x, v, F, x_tr), None

        F0 = jnp.broadcast_to(jnp.eye(dim, dtype=X.dtype), (X.shape[0], dim, dim))
        init = (X, P["beta"] * X, F0, x_tr)
        return jax.lax.scan(step, init, jnp.arange(steps, dtype=X.dtype))[0]

    f = np.float64 if jnp.result_type(float) == jnp.float64 else np.float32
    X = jnp.asarray(initial_particles(L, f))
    x_tr, t_vec = (jnp.asarray(a) for a in traction_layout(L, f))
    t0 = time.perf_counter()
    compiled = jax.jit(run).lower(X, x_tr, t_vec).compile()
    t1 = time.perf_counter()
    out = jax.block_until_ready(compiled(X, x_tr, t_vec))
    t2 = time.perf_counter()
    x, v, F, x_tr = (np.asarray(a) for a in out)
    return t1 - t0, t2 - t1, float(np.mean(F)), health(x, v, F, x_tr, *grid_span(L), _det(F))


_TAICHI_ND = {}


def _taichi_kernels_nd(dtype: str, dim: int):
    """Taichi's kernels for ``dim``; Taichi is initialised once per process with ``dtype`` as its
    default float (by ``_baselines._taichi_kernels``, which the 1D kernels share)."""
    from . import _baselines

    if (dtype, dim) in _TAICHI_ND:
        return _TAICHI_ND[(dtype, dim)]
    ti = _baselines._taichi_kernels(dtype)[0]  # raises if this process runs the other float type
    D, K = dim, 2**dim
    bits = [tuple(int(b) for b in c) for c in _corners(dim)]

    @ti.kernel
    def p2g(
        x: ti.types.ndarray(),
        v: ti.types.ndarray(),
        F: ti.types.ndarray(),
        gm: ti.types.ndarray(),
        gp: ti.types.ndarray(),
        gf: ti.types.ndarray(),
        x_tr: ti.types.ndarray(),
        t_vec: ti.types.ndarray(),
        x_min: float,
        h: float,
        N: int,
        lo: int,
        hi: int,
        m: float,
        V0: float,
        P0: float,
        gamma: float,
        p_atm: float,
        T: float,
    ):
        for p in range(x.shape[0]):
            s = (x[p] - x_min) / h
            base = ti.floor(s, int)
            fr = s - base
            Fp = F[p]
            J = Fp.determinant()
            fi = -(P0 * J ** (-gamma) - p_atm) * V0 * J
            for c in ti.static(range(K)):
                node = 0
                wv = ti.Vector.zero(float, D)
                for a in ti.static(range(D)):
                    node = node * N + base[a] + bits[c][a]
                    wv[a] = fr[a] if ti.static(bits[c][a]) else 1.0 - fr[a]
                w = 1.0
                g = ti.Vector.zero(float, D)
                for a in ti.static(range(D)):
                    w *= wv[a]
                    ga = (1.0 if ti.static(bits[c][a]) else -1.0) / h
                    for b in ti.static(range(D)):
                        if ti.static(b != a):
                            ga *= wv[b]
                    g[a] = ga
                gm[node] += w * m
                gp[node] += w * m * v[p]
                gf[node] -= fi * g
        for q in range(x_tr.shape[0]):  # the traction points, onto the body's nodes lo .. hi
            s = (x_tr[q] - x_min) / h
            base = ti.floor(s, int)
            fr = s - base
            for c in ti.static(range(K)):
                node = 0
                w = 1.0
                for a in ti.static(range(D)):
                    node = node * N + ti.min(ti.max(base[a] + bits[c][a], lo), hi)
                    w *= fr[a] if ti.static(bits[c][a]) else 1.0 - fr[a]
                gf[node] += w * T * t_vec[q]

    @ti.kernel
    def grid(
        gm: ti.types.ndarray(),
        gp: ti.types.ndarray(),
        gf: ti.types.ndarray(),
        ga: ti.types.ndarray(),
        gv: ti.types.ndarray(),
        dt: float,
    ):
        for k in range(gm.shape[0]):
            a = ti.Vector.zero(float, D)
            vn = ti.Vector.zero(float, D)
            if gm[k] > 0:
                a = gf[k] / gm[k]
                vn = gp[k] / gm[k]
            ga[k] = a
            gv[k] = vn + dt * a
            gm[k] = 0.0
            gp[k] = ti.Vector.zero(float, D)
            gf[k] = ti.Vector.zero(float, D)

    @ti.kernel
    def g2p(
        x: ti.types.ndarray(),
        v: ti.types.ndarray(),
        F: ti.types.ndarray(),
        ga: ti.types.ndarray(),
        gv: ti.types.ndarray(),
        x_tr: ti.types.ndarray(),
        x_min: float,
        h: float,
        N: int,
        dt: float,
    ):
        for p in range(x.shape[0]):
            s = (x[p] - x_min) / h
            base = ti.floor(s, int)
            fr = s - base
            dv = ti.Vector.zero(float, D)
            dx = ti.Vector.zero(float, D)
            Lp = ti.Matrix.zero(float, D, D)
            for c in ti.static(range(K)):
                node = 0
                wv = ti.Vector.zero(float, D)
                for a in ti.static(range(D)):
                    node = node * N + base[a] + bits[c][a]
                    wv[a] = fr[a] if ti.static(bits[c][a]) else 1.0 - fr[a]
                w = 1.0
                g = ti.Vector.zero(float, D)
                for a in ti.static(range(D)):
                    w *= wv[a]
                    gaa = (1.0 if ti.static(bits[c][a]) else -1.0) / h
                    for b in ti.static(range(D)):
                        if ti.static(b != a):
                            gaa *= wv[b]
                    g[a] = gaa
                vi = gv[node]
                dv += w * ga[node]
                dx += w * vi
                Lp += vi.outer_product(g)
            v[p] += dt * dv
            x[p] += dt * dx
            F[p] = F[p] + dt * (Lp @ F[p])
        for q in range(x_tr.shape[0]):
            s = (x_tr[q] - x_min) / h
            base = ti.floor(s, int)
            fr = s - base
            dx = ti.Vector.zero(float, D)
            for c in ti.static(range(K)):
                node = 0
                w = 1.0
                for a in ti.static(range(D)):
                    node = node * N + base[a] + bits[c][a]
                    w *= fr[a] if ti.static(bits[c][a]) else 1.0 - fr[a]
                dx += w * gv[node]
            x_tr[q] += dt * dx

    _TAICHI_ND[(dtype, dim)] = (ti, p2g, grid, g2p)
    return _TAICHI_ND[(dtype, dim)]


def taichi_spq_nd(n: int, steps: int, dtype: str, dim: int = 2):
    """Taichi CPU kernels (parallel loops with atomics), three launches a step (particles and
    traction points share the particle-to-grid and grid-to-particle kernels).

    Args:
        n: particles, ``(2 k)^dim``.
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``. Taichi runs one float type per process.
        dim: 2 or 3.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: the first step's time (it compiles the kernels), the run
        time (the compiled steps, scaled to ``steps``), the mean of the final F and the final state's
        ``health`` (checked after the timed run).
    """
    ti, p2g, grid, g2p = _taichi_kernels_nd(dtype, dim)
    f = np.float32 if dtype == "f32" else np.float64
    tf = ti.f32 if dtype == "f32" else ti.f64
    L = layout_nd(n, dim)
    P = PROBLEM_ND
    X = initial_particles(L, f)
    X_tr, T_vec = traction_layout(L, f)

    def vectors(a):
        out = ti.Vector.ndarray(dim, tf, a.shape[0])
        out.from_numpy(a)
        return out

    x, v, x_tr, t_vec = vectors(X), vectors((P["beta"] * X).astype(f)), vectors(X_tr), vectors(T_vec)
    F = ti.Matrix.ndarray(dim, dim, tf, n)
    F.from_numpy(np.broadcast_to(np.eye(dim, dtype=f), (n, dim, dim)).copy())
    gm = ti.ndarray(tf, L["nodes"])
    gm.fill(0.0)
    gp, gf, ga, gv = (vectors(np.zeros((L["nodes"], dim), f)) for _ in range(4))
    N, x_min, h, dt = L["axis_nodes"], L["x_min"], L["h"], L["dt"]
    lo, hi = L["pad"], L["pad"] + L["cells"]
    gas = (P["P0"], P["gamma"], P["p_atm"])
    k = [0]

    def one():
        T = face_stress(k[0] * dt, dim)
        k[0] += 1
        p2g(x, v, F, gm, gp, gf, x_tr, t_vec, x_min, h, N, lo, hi, L["m"], L["V0"], *gas, T)
        grid(gm, gp, gf, ga, gv, dt)
        g2p(x, v, F, ga, gv, x_tr, x_min, h, N, dt)

    t0 = time.perf_counter()
    one()  # the first launch compiles (Taichi caches kernels on disk between processes)
    ti.sync()
    t1 = time.perf_counter()
    for _ in range(steps - 1):
        one()
    ti.sync()
    t2 = time.perf_counter()
    run_s = (t2 - t1) * steps / max(steps - 1, 1)
    x, v, F, x_tr = (a.to_numpy() for a in (x, v, F, x_tr))
    return t1 - t0, run_s, float(np.mean(F)), health(x, v, F, x_tr, *grid_span(L), _det(F))


_WARP_ND = {}


def _warp_kernels_nd(dtype: str, dim: int):
    """Warp's kernels for ``dtype`` and ``dim`` (closures over the dimension and float type), each
    built as its own module, so that building the 3D kernels leaves the 2D ones as they are."""
    import warp as wp

    if (dtype, dim) in _WARP_ND:
        return _WARP_ND[(dtype, dim)]
    wp.config.quiet = True
    wp.init()
    T = wp.float32 if dtype == "f32" else wp.float64
    D, K = dim, 2**dim
    Vec = wp.types.vector(length=dim, dtype=T)
    Mat = wp.types.matrix(shape=(dim, dim), dtype=T)
    IVec = wp.types.vector(length=dim, dtype=wp.int32)

    @wp.func
    def corner_node(base: IVec, c: int, N: int):
        node = wp.int32(0)
        for a in range(D):
            node = node * N + base[a] + ((c >> (D - 1 - a)) & 1)
        return node

    @wp.func
    def box_node(base: IVec, c: int, N: int, lo: int, hi: int):
        node = wp.int32(0)
        for a in range(D):
            node = node * N + wp.clamp(base[a] + ((c >> (D - 1 - a)) & 1), lo, hi)
        return node

    @wp.func
    def corner_weights(fr: Vec, c: int):
        wv = Vec()
        for a in range(D):
            wv[a] = wp.where(((c >> (D - 1 - a)) & 1) == 1, fr[a], T(1.0) - fr[a])
        return wv

    @wp.func
    def corner_gradient(wv: Vec, c: int, h: T):
        g = Vec()
        for a in range(D):
            ga = wp.where(((c >> (D - 1 - a)) & 1) == 1, T(1.0), T(-1.0)) / h
            for b in range(D):
                if b != a:
                    ga = ga * wv[b]
            g[a] = ga
        return g

    @wp.func
    def product(wv: Vec):
        w = T(1.0)
        for a in range(D):
            w = w * wv[a]
        return w

    @wp.func
    def locate(y: Vec, x_min: T, h: T):
        base = IVec()
        fr = Vec()
        for a in range(D):
            s = (y[a] - x_min) / h
            fl = wp.floor(s)
            base[a] = int(fl)
            fr[a] = s - fl
        return base, fr

    @wp.kernel(module="unique")
    def p2g(
        x: wp.array(dtype=Vec),
        v: wp.array(dtype=Vec),
        F: wp.array(dtype=Mat),
        gm: wp.array(dtype=T),
        gp: wp.array(dtype=Vec),
        gf: wp.array(dtype=Vec),
        x_min: T,
        h: T,
        N: int,
        m: T,
        V0: T,
        P0: T,
        gamma: T,
        p_atm: T,
    ):
        p = wp.tid()
        base, fr = locate(x[p], x_min, h)
        J = wp.determinant(F[p])
        fi = -(P0 * wp.pow(J, -gamma) - p_atm) * V0 * J
        for c in range(K):
            node = corner_node(base, c, N)
            wv = corner_weights(fr, c)
            w = product(wv)
            wp.atomic_add(gm, node, w * m)
            wp.atomic_add(gp, node, (w * m) * v[p])
            wp.atomic_add(gf, node, -fi * corner_gradient(wv, c, h))

    @wp.kernel(module="unique")
    def traction(
        x_tr: wp.array(dtype=Vec),
        t_vec: wp.array(dtype=Vec),
        gf: wp.array(dtype=Vec),
        x_min: T,
        h: T,
        N: int,
        lo: int,
        hi: int,
        tr: T,
    ):
        q = wp.tid()
        base, fr = locate(x_tr[q], x_min, h)
        for c in range(K):  # onto the body's nodes lo .. hi along each axis
            w = product(corner_weights(fr, c))
            wp.atomic_add(gf, box_node(base, c, N, lo, hi), (w * tr) * t_vec[q])

    @wp.kernel(module="unique")
    def grid(
        gm: wp.array(dtype=T),
        gp: wp.array(dtype=Vec),
        gf: wp.array(dtype=Vec),
        ga: wp.array(dtype=Vec),
        gv: wp.array(dtype=Vec),
        dt: T,
    ):
        k = wp.tid()
        a = Vec()
        vn = Vec()
        if gm[k] > T(0.0):
            a = gf[k] / gm[k]
            vn = gp[k] / gm[k]
        ga[k] = a
        gv[k] = vn + dt * a
        gm[k] = T(0.0)
        gp[k] = Vec()
        gf[k] = Vec()

    @wp.kernel(module="unique")
    def g2p(
        x: wp.array(dtype=Vec),
        v: wp.array(dtype=Vec),
        F: wp.array(dtype=Mat),
        ga: wp.array(dtype=Vec),
        gv: wp.array(dtype=Vec),
        x_min: T,
        h: T,
        N: int,
        dt: T,
    ):
        p = wp.tid()
        base, fr = locate(x[p], x_min, h)
        dv = Vec()
        dx = Vec()
        Lp = Mat()
        for c in range(K):
            node = corner_node(base, c, N)
            wv = corner_weights(fr, c)
            w = product(wv)
            vi = gv[node]
            dv = dv + w * ga[node]
            dx = dx + w * vi
            Lp = Lp + wp.outer(vi, corner_gradient(wv, c, h))
        v[p] = v[p] + dt * dv
        x[p] = x[p] + dt * dx
        F[p] = F[p] + dt * (Lp @ F[p])

    @wp.kernel(module="unique")
    def move_traction(x_tr: wp.array(dtype=Vec), gv: wp.array(dtype=Vec), x_min: T, h: T, N: int, dt: T):
        q = wp.tid()
        base, fr = locate(x_tr[q], x_min, h)
        dx = Vec()
        for c in range(K):
            dx = dx + product(corner_weights(fr, c)) * gv[corner_node(base, c, N)]
        x_tr[q] = x_tr[q] + dt * dx

    _WARP_ND[(dtype, dim)] = (wp, T, Vec, Mat, p2g, traction, grid, g2p, move_traction)
    return _WARP_ND[(dtype, dim)]


def warp_spq_nd(n: int, steps: int, dtype: str, dim: int = 2):
    """Warp CPU kernels, five launches a step (particles to grid, traction points to grid, grid,
    grid to particles, grid to traction points).

    Args:
        n: particles, ``(2 k)^dim``.
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``.
        dim: 2 or 3.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: the first step's time (it builds the kernels), the run time
        (the compiled steps, scaled to ``steps``), the mean of the final F and the final state's
        ``health`` (checked after the timed run).
    """
    wp, T, Vec, Mat, p2g, traction, grid, g2p, move_traction = _warp_kernels_nd(dtype, dim)
    f = np.float32 if dtype == "f32" else np.float64
    L = layout_nd(n, dim)
    P = PROBLEM_ND
    X = initial_particles(L, f)
    X_tr, T_vec = traction_layout(L, f)
    x, v = wp.array(X, dtype=Vec, device="cpu"), wp.array((P["beta"] * X).astype(f), dtype=Vec, device="cpu")
    F = wp.array(np.broadcast_to(np.eye(dim, dtype=f), (n, dim, dim)).copy(), dtype=Mat, device="cpu")
    x_tr, t_vec = (wp.array(a, dtype=Vec, device="cpu") for a in (X_tr, T_vec))
    nodes = L["nodes"]
    gm = wp.zeros(nodes, dtype=T, device="cpu")
    gp, gf, ga, gv = (wp.zeros(nodes, dtype=Vec, device="cpu") for _ in range(4))
    N, lo, hi = L["axis_nodes"], L["pad"], L["pad"] + L["cells"]
    c = {key: T(L[key]) for key in ("x_min", "h", "m", "V0", "dt")}
    P0, gamma, p_atm = T(P["P0"]), T(P["gamma"]), T(P["p_atm"])
    n_tr = X_tr.shape[0]
    k = [0]

    def one():
        tr = T(face_stress(k[0] * L["dt"], dim))
        k[0] += 1
        xm, h, dt = c["x_min"], c["h"], c["dt"]
        wp.launch(p2g, n, [x, v, F, gm, gp, gf, xm, h, N, c["m"], c["V0"], P0, gamma, p_atm], device="cpu")
        wp.launch(traction, n_tr, [x_tr, t_vec, gf, xm, h, N, lo, hi, tr], device="cpu")
        wp.launch(grid, nodes, [gm, gp, gf, ga, gv, dt], device="cpu")
        wp.launch(g2p, n, [x, v, F, ga, gv, xm, h, N, dt], device="cpu")
        wp.launch(move_traction, n_tr, [x_tr, gv, xm, h, N, dt], device="cpu")

    t0 = time.perf_counter()
    one()  # the first launches build the kernels (Warp caches them on disk between processes)
    wp.synchronize()
    t1 = time.perf_counter()
    for _ in range(steps - 1):
        one()
    wp.synchronize()
    t2 = time.perf_counter()
    run_s = (t2 - t1) * steps / max(steps - 1, 1)
    x, v, F, x_tr = (a.numpy() for a in (x, v, F, x_tr))
    return t1 - t0, run_s, float(np.mean(F)), health(x, v, F, x_tr, *grid_span(L), _det(F))


BASELINES_ND = {
    "NumPy": numpy_spq_nd,
    "plain JAX": plain_jax_spq_nd,
    "Taichi": taichi_spq_nd,
    "Warp": warp_spq_nd,
}
"""The 2D/3D reference codes by name, each ``(n, steps, dtype, dim) -> (compile_s, run_s, F_mean,
status)``."""
