"""The benchmark's reference codes: one 1D MPM algorithm written directly in NumPy, plain JAX,
Taichi and Warp.

All four run the same problem as ``jm.GasExpansion`` with ``jm.SPQ()``, FLIP and USL: linear hats,
the adiabatic gas, the exact traction ``-/+ sigma(t)`` at two boundary points that move with the grid
velocity, no artificial cells, no checks (jaxmpm's step also folds force that lands on a node without
mass onto its neighbour; these codes drop it). Taichi and Warp are optional (``pip install
jaxmpm[bench]``); each function here imports its package when called. Every function returns
``(compile_s, run_s, F_mean, status)``, ``F_mean`` the mean final ``F``, which the benchmark compares
across codes so that a wrong kernel cannot pass as a fast one.

(No ``from __future__ import annotations`` here: Taichi and Warp read the kernels' annotations.)
"""

import math
import time

import numpy as np

from jaxmpm.status import LEFT_GRID, NONFINITE, NONPOSITIVE_F

PROBLEM = dict(beta=200.0, P0=2.0e5, gamma=1.4, p_atm=1.0e5, rho0=1.0)


def layout(n: int) -> dict:
    """Grid and step of the ``n``-particle problem: two particles per cell on ``[0, 1]``.

    Args:
        n: particles (even).

    Returns:
        ``cells``, ``h``, ``pad``, ``nodes``, ``x_min`` (the grid's first node), ``dt``
        (``0.2 h / (c0 + beta)``), ``m`` and ``V0`` (each particle's mass and volume).
    """
    cells = n // 2
    h = 1.0 / cells
    pad = cells // 8 + 4
    c0 = math.sqrt(PROBLEM["gamma"] * PROBLEM["P0"] / PROBLEM["rho0"])
    return dict(
        cells=cells,
        h=h,
        pad=pad,
        nodes=cells + 2 * pad + 1,
        x_min=-pad * h,
        dt=0.2 * h / (c0 + PROBLEM["beta"]),
        m=h / 2 * PROBLEM["rho0"],
        V0=h / 2,
    )


def _initial(n: int, dtype):
    L = layout(n)
    X = ((np.arange(n) + 0.5) / 2 * L["h"]).astype(dtype)
    return L, X.copy(), (PROBLEM["beta"] * X).astype(dtype), np.ones(n, dtype)


def health(x, v, F, x_tr, x_lo: float, x_hi: float, J=None) -> int:
    """The status bits of a reference code's state, as jaxmpm's step sets them (``jaxmpm.status``).

    Args:
        x, v, F: the particles' positions, velocities and deformation gradients (any shapes).
        x_tr: the traction points' positions (query points of the grid, as the particles are).
        x_lo, x_hi: the grid's first and last node along each axis: a point's stencil stays on the
            grid while ``x_lo <= x < x_hi`` (jaxmpm's grid bounds).
        J: ``det F`` per particle in 2D and 3D; ``None``: ``F`` itself (1D).

    Returns:
        ``NONFINITE`` where ``x``, ``v``, ``F`` or ``x_tr`` is not finite, ``NONPOSITIVE_F`` where
        ``F`` (``det F``) is not positive, ``LEFT_GRID`` where a particle or traction point is off the
        grid's nodes, ORed; 0 for a healthy state.
    """
    x, v, F, x_tr = (np.asarray(a) for a in (x, v, F, x_tr))
    J = F if J is None else np.asarray(J)
    status = 0
    if not all(np.isfinite(a).all() for a in (x, v, F, x_tr)):
        status |= NONFINITE
    if (J <= 0).any():
        status |= NONPOSITIVE_F
    if any(((a < x_lo) | (a >= x_hi)).any() for a in (x, x_tr)):
        status |= LEFT_GRID
    return status


def grid_span(L: dict) -> tuple[float, float]:
    """The first and last node of the grid of ``layout`` (1D) or ``layout_nd`` (along each axis)."""
    nodes = L.get("axis_nodes", L["nodes"])
    return L["x_min"], L["x_min"] + (nodes - 1) * L["h"]


def boundary_stress(t: float) -> float:
    """The exact solution's stress at time ``t``.

    The traction is ``-sigma`` at the left end, ``+sigma`` at the right (as ``GasExpansion.traction``).

    Args:
        t: time (s).

    Returns:
        ``sigma(t) = -(P0 (1 + beta t)^-gamma - p_atm)``.
    """
    P = PROBLEM
    return -(P["P0"] * (1.0 + P["beta"] * t) ** -P["gamma"] - P["p_atm"])


def scatter_sum(idx: np.ndarray, values: np.ndarray, nodes: int, dtype) -> np.ndarray:
    """``values`` summed per node ``idx`` (``np.bincount``, which sums in float64 whatever the values),
    rounded to ``dtype``, the run's type."""
    return np.bincount(idx, values, nodes).astype(dtype, copy=False)


def numpy_spq(n: int, steps: int, dtype: str, fold: bool = False):
    """A Python loop of NumPy steps, ``np.bincount`` scatters (which sum in float64: in float32 each
    nodal sum is rounded to float32, and the step goes on in float32).

    With ``fold``, also what jaxmpm's step does at a free end: node masses under ``256 eps m`` count
    as empty, and force on an empty node moves to its neighbour with mass (``_step.fold_massless``).
    The benchmark times the standard algorithm (``fold=False``); ``fold=True`` is the check that
    ``jaxmpm spq`` computes exactly this method.

    Args:
        n: particles (two per cell).
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``.
        fold: also fold the force off empty nodes, as jaxmpm does.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time (0 where nothing compiles), run time, the
        mean final ``F`` and the final state's ``health``. A step that cannot run (NumPy's
        ``bincount`` meets a particle off the grid, or the index of a non-finite position) ends the
        run: the time is that of the steps before it, the status that of their state. With ``fold``,
        the state is checked after every step, as jaxmpm does, and the run stops at the first
        unhealthy one, ``F_mean`` NaN.
    """
    f = np.float32 if dtype == "f32" else np.float64
    L, x, v, F = _initial(n, f)
    h, nodes, x_min, dt = f(L["h"]), L["nodes"], f(L["x_min"]), f(L["dt"])
    m, V0 = f(L["m"]), f(L["V0"])
    P0, gamma, p_atm = f(PROBLEM["P0"]), f(PROBLEM["gamma"]), f(PROBLEM["p_atm"])
    x_tr = np.array([0.0, L["cells"] * L["h"]], f)
    lo, hi = grid_span(L)
    error = None

    def scatter(idx, values):
        return scatter_sum(idx, values, nodes, f)

    t0 = time.perf_counter()
    try:
        for k in range(steps):
            sig_t = f(boundary_stress(k * L["dt"]))
            s_tr = (x_tr - x_min) / h
            j = np.floor(s_tr).astype(np.int64)
            u1 = (s_tr - j).astype(f)
            u0 = 1 - u1
            trac = np.array([-sig_t, sig_t], f)
            s = (x - x_min) / h
            i = np.floor(s).astype(np.int64)
            w1 = (s - i).astype(f)
            w0 = 1 - w1
            sig = -(P0 * F**-gamma - p_atm)
            mass = scatter(i, w0 * m) + scatter(i + 1, w1 * m)
            mom = scatter(i, w0 * m * v) + scatter(i + 1, w1 * m * v)
            fi = sig * V0 * F / h
            force = scatter(i, fi) - scatter(i + 1, fi)
            force += scatter(j, u0 * trac) + scatter(j + 1, u1 * trac)
            active = mass > (256 * np.finfo(f).eps * m if fold else 0)
            if fold:  # the stray force, to the left neighbour with mass first, else to the right one
                stray = np.where(active, 0, force)
                left_ok = np.r_[False, active[:-1]]
                right_ok = np.r_[active[1:], False]
                to_left = np.where(left_ok, stray, 0)
                to_right = np.where(~left_ok & right_ok, stray, 0)
                force = np.where(active, force, 0) + np.r_[to_left[1:], 0] + np.r_[0, to_right[:-1]]
            safe = np.where(active, mass, 1)
            vn = np.where(active, mom / safe, 0)
            a = np.where(active, force / safe, 0)
            vnew = (vn + dt * a).astype(f)
            a = a.astype(f)
            v = v + dt * (w0 * a[i] + w1 * a[i + 1])
            x = x + dt * (w0 * vnew[i] + w1 * vnew[i + 1])
            F = F * (1 + dt * (vnew[i + 1] - vnew[i]) / h)
            x_tr = x_tr + dt * (u0 * vnew[j] + u1 * vnew[j + 1])
            if fold and health(x, v, F, x_tr, lo, hi):  # checked every step, as jaxmpm does
                break
    except (ValueError, IndexError) as e:  # a bincount met an index off the grid
        error = e  # x, v, F, x_tr: the state before the step
    run_s = time.perf_counter() - t0
    status = health(x, v, F, x_tr, lo, hi)
    if error is not None and status == 0:
        raise error
    return 0.0, run_s, float("nan") if fold and status else float(np.mean(F)), status


def plain_jax_spq(n: int, steps: int, dtype: str):
    """The same algorithm as one ``lax.scan`` with ``.at[].add`` scatters.

    Args:
        n: particles (two per cell).
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``; not read: the float type is the process's (float64 exactly
            when x64 is on).

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time (0 where nothing compiles), run time, the
        mean final ``F`` and the final state's ``health`` (checked after the timed run).
    """
    import jax
    import jax.numpy as jnp

    del dtype  # float64 exactly when the process enabled x64
    L = layout(n)
    h, nodes, x_min, dt, m, V0 = (L[k] for k in ("h", "nodes", "x_min", "dt", "m", "V0"))
    P = PROBLEM

    def run(X):
        def step(c, k):
            x, v, F, x_tr = c
            t = k * dt
            sig_t = -(P["P0"] * (1.0 + P["beta"] * t) ** -P["gamma"] - P["p_atm"])
            s_tr = (x_tr - x_min) / h
            j = jnp.floor(s_tr).astype(jnp.int32)
            u1 = s_tr - jnp.floor(s_tr)
            u0 = 1 - u1
            trac = jnp.stack([-sig_t, sig_t])
            s = (x - x_min) / h
            i = jnp.floor(s).astype(jnp.int32)
            w1 = s - jnp.floor(s)
            w0 = 1 - w1
            sig = -(P["P0"] * F ** -P["gamma"] - P["p_atm"])
            z = jnp.zeros(nodes, X.dtype)
            mass = z.at[i].add(w0 * m).at[i + 1].add(w1 * m)
            mom = z.at[i].add(w0 * m * v).at[i + 1].add(w1 * m * v)
            fi = sig * V0 * F / h
            force = z.at[i].add(fi).at[i + 1].add(-fi).at[j].add(u0 * trac).at[j + 1].add(u1 * trac)
            active = mass > 0
            safe = jnp.where(active, mass, 1)
            vn = jnp.where(active, mom / safe, 0)
            a = jnp.where(active, force / safe, 0)
            vnew = vn + dt * a
            v = v + dt * (w0 * a[i] + w1 * a[i + 1])
            x = x + dt * (w0 * vnew[i] + w1 * vnew[i + 1])
            F = F * (1 + dt * (vnew[i + 1] - vnew[i]) / h)
            x_tr = x_tr + dt * (u0 * vnew[j] + u1 * vnew[j + 1])
            return (x, v, F, x_tr), None

        x_tr = jnp.asarray([0.0, L["cells"] * h], X.dtype)
        init = (X, P["beta"] * X, jnp.ones_like(X), x_tr)
        return jax.lax.scan(step, init, jnp.arange(steps, dtype=X.dtype))[0]

    X = (jnp.arange(n, dtype=jnp.result_type(float)) + 0.5) / 2 * h
    t0 = time.perf_counter()
    compiled = jax.jit(run).lower(X).compile()
    t1 = time.perf_counter()
    out = jax.block_until_ready(compiled(X))
    t2 = time.perf_counter()
    x, v, F, x_tr = (np.asarray(a) for a in out)
    return t1 - t0, t2 - t1, float(np.mean(F)), health(x, v, F, x_tr, *grid_span(L))


_TAICHI = {}


def _taichi_kernels(dtype: str):
    """Taichi is initialised once per process, with the benchmark's dtype as its default float."""
    import taichi as ti

    if dtype in _TAICHI:
        return _TAICHI[dtype]
    if _TAICHI:
        raise RuntimeError("Taichi runs one float type per process")
    ti.init(arch=ti.cpu, default_fp=ti.f32 if dtype == "f32" else ti.f64, log_level=ti.ERROR)

    @ti.kernel
    def p2g(
        x: ti.types.ndarray(),
        v: ti.types.ndarray(),
        F: ti.types.ndarray(),
        gm: ti.types.ndarray(),
        gp: ti.types.ndarray(),
        gf: ti.types.ndarray(),
        x_tr: ti.types.ndarray(),
        x_min: float,
        h: float,
        m: float,
        V0: float,
        P0: float,
        gamma: float,
        p_atm: float,
        sig_t: float,
    ):
        for p in x:
            s = (x[p] - x_min) / h
            i = int(ti.floor(s))
            w1 = s - i
            w0 = 1.0 - w1
            sig = -(P0 * F[p] ** (-gamma) - p_atm)
            fi = sig * V0 * F[p] / h
            ti.atomic_add(gm[i], w0 * m)
            ti.atomic_add(gm[i + 1], w1 * m)
            ti.atomic_add(gp[i], w0 * m * v[p])
            ti.atomic_add(gp[i + 1], w1 * m * v[p])
            ti.atomic_add(gf[i], fi)
            ti.atomic_add(gf[i + 1], -fi)
            if p == 0 or p == x.shape[0] - 1:  # the end particles also carry the boundary tractions
                e = 0 if p == 0 else 1
                tr = -sig_t if p == 0 else sig_t
                st = (x_tr[e] - x_min) / h
                j = int(ti.floor(st))
                ti.atomic_add(gf[j], (1.0 - (st - j)) * tr)
                ti.atomic_add(gf[j + 1], (st - j) * tr)

    @ti.kernel
    def grid(
        gm: ti.types.ndarray(),
        gp: ti.types.ndarray(),
        gf: ti.types.ndarray(),
        ga: ti.types.ndarray(),
        gv: ti.types.ndarray(),
        dt: float,
    ):
        for k in gm:
            a = 0.0
            vn = 0.0
            if gm[k] > 0:
                a = gf[k] / gm[k]
                vn = gp[k] / gm[k]
            ga[k] = a
            gv[k] = vn + dt * a
            gm[k] = 0.0
            gp[k] = 0.0
            gf[k] = 0.0

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
        dt: float,
    ):
        for p in x:
            s = (x[p] - x_min) / h
            i = int(ti.floor(s))
            w1 = s - i
            w0 = 1.0 - w1
            v[p] += dt * (w0 * ga[i] + w1 * ga[i + 1])
            x[p] += dt * (w0 * gv[i] + w1 * gv[i + 1])
            F[p] *= 1.0 + dt * (gv[i + 1] - gv[i]) / h
            if p == 0 or p == x.shape[0] - 1:
                e = 0 if p == 0 else 1
                st = (x_tr[e] - x_min) / h
                j = int(ti.floor(st))
                x_tr[e] += dt * ((1.0 - (st - j)) * gv[j] + (st - j) * gv[j + 1])

    _TAICHI[dtype] = (ti, p2g, grid, g2p)
    return _TAICHI[dtype]


def taichi_spq(n: int, steps: int, dtype: str):
    """Taichi CPU kernels (parallel loops with atomics), three launches a step.

    Args:
        n: particles (two per cell).
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``. Taichi runs one float type per process.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time (0 where nothing compiles), run time, the
        mean final ``F`` and the final state's ``health`` (checked after the timed run).
    """
    ti, p2g, grid, g2p = _taichi_kernels(dtype)
    f = np.float32 if dtype == "f32" else np.float64
    tf = ti.f32 if dtype == "f32" else ti.f64
    L, x0, v0, F0 = _initial(n, f)
    arrays = {}
    for name, a in (("x", x0), ("v", v0), ("F", F0)):
        arrays[name] = ti.ndarray(tf, n)
        arrays[name].from_numpy(a)
    for name in ("gm", "gp", "gf", "ga", "gv"):
        arrays[name] = ti.ndarray(tf, L["nodes"])
        arrays[name].fill(0.0)
    x, v, F = arrays["x"], arrays["v"], arrays["F"]
    gm, gp, gf, ga, gv = (arrays[k] for k in ("gm", "gp", "gf", "ga", "gv"))
    x_tr = ti.ndarray(tf, 2)
    x_tr.from_numpy(np.array([0.0, L["cells"] * L["h"]], f))
    P = PROBLEM
    k = [0]

    def one():
        sig_t = boundary_stress(k[0] * L["dt"])
        k[0] += 1
        p2g(
            x,
            v,
            F,
            gm,
            gp,
            gf,
            x_tr,
            L["x_min"],
            L["h"],
            L["m"],
            L["V0"],
            P["P0"],
            P["gamma"],
            P["p_atm"],
            sig_t,
        )
        grid(gm, gp, gf, ga, gv, L["dt"])
        g2p(x, v, F, ga, gv, x_tr, L["x_min"], L["h"], L["dt"])

    t0 = time.perf_counter()
    one()  # the first launch compiles (Taichi caches kernels on disk between processes)
    ti.sync()
    t1 = time.perf_counter()
    for _ in range(steps - 1):
        one()
    ti.sync()
    t2 = time.perf_counter()
    run_s = (t2 - t1) * steps / max(steps - 1, 1)  # the compiled steps, scaled to ``steps``
    state = [a.to_numpy() for a in (x, v, F, x_tr)]
    return t1 - t0, run_s, float(np.mean(state[2])), health(*state, *grid_span(L))


_WARP = {}


def _warp_kernels(dtype: str):
    import warp as wp

    if dtype in _WARP:
        return _WARP[dtype]
    wp.config.quiet = True
    wp.init()
    T = wp.float32 if dtype == "f32" else wp.float64

    @wp.kernel
    def p2g(
        x: wp.array(dtype=T),
        v: wp.array(dtype=T),
        F: wp.array(dtype=T),
        gm: wp.array(dtype=T),
        gp: wp.array(dtype=T),
        gf: wp.array(dtype=T),
        x_tr: wp.array(dtype=T),
        x_min: T,
        h: T,
        m: T,
        V0: T,
        P0: T,
        gamma: T,
        p_atm: T,
        sig_t: T,
    ):
        p = wp.tid()
        s = (x[p] - x_min) / h
        fl = wp.floor(s)
        i = int(fl)
        w1 = s - fl
        w0 = T(1.0) - w1
        sig = -(P0 * wp.pow(F[p], -gamma) - p_atm)
        fi = sig * V0 * F[p] / h
        wp.atomic_add(gm, i, w0 * m)
        wp.atomic_add(gm, i + 1, w1 * m)
        wp.atomic_add(gp, i, w0 * m * v[p])
        wp.atomic_add(gp, i + 1, w1 * m * v[p])
        wp.atomic_add(gf, i, fi)
        wp.atomic_add(gf, i + 1, -fi)
        if p == 0 or p == x.shape[0] - 1:  # the end particles also carry the boundary tractions
            e = 0
            tr = -sig_t
            if p != 0:
                e = 1
                tr = sig_t
            st = (x_tr[e] - x_min) / h
            fj = wp.floor(st)
            j = int(fj)
            wp.atomic_add(gf, j, (T(1.0) - (st - fj)) * tr)
            wp.atomic_add(gf, j + 1, (st - fj) * tr)

    @wp.kernel
    def grid(
        gm: wp.array(dtype=T),
        gp: wp.array(dtype=T),
        gf: wp.array(dtype=T),
        ga: wp.array(dtype=T),
        gv: wp.array(dtype=T),
        dt: T,
    ):
        k = wp.tid()
        a = T(0.0)
        vn = T(0.0)
        if gm[k] > T(0.0):
            a = gf[k] / gm[k]
            vn = gp[k] / gm[k]
        ga[k] = a
        gv[k] = vn + dt * a
        gm[k] = T(0.0)
        gp[k] = T(0.0)
        gf[k] = T(0.0)

    @wp.kernel
    def g2p(
        x: wp.array(dtype=T),
        v: wp.array(dtype=T),
        F: wp.array(dtype=T),
        ga: wp.array(dtype=T),
        gv: wp.array(dtype=T),
        x_tr: wp.array(dtype=T),
        x_min: T,
        h: T,
        dt: T,
    ):
        p = wp.tid()
        s = (x[p] - x_min) / h
        fl = wp.floor(s)
        i = int(fl)
        w1 = s - fl
        w0 = T(1.0) - w1
        v[p] = v[p] + dt * (w0 * ga[i] + w1 * ga[i + 1])
        x[p] = x[p] + dt * (w0 * gv[i] + w1 * gv[i + 1])
        F[p] = F[p] * (T(1.0) + dt * (gv[i + 1] - gv[i]) / h)
        if p == 0 or p == x.shape[0] - 1:
            e = 0
            if p != 0:
                e = 1
            st = (x_tr[e] - x_min) / h
            fj = wp.floor(st)
            j = int(fj)
            x_tr[e] = x_tr[e] + dt * ((T(1.0) - (st - fj)) * gv[j] + (st - fj) * gv[j + 1])

    _WARP[dtype] = (wp, T, p2g, grid, g2p)
    return _WARP[dtype]


def warp_spq(n: int, steps: int, dtype: str):
    """Warp CPU kernels, three launches a step.

    Args:
        n: particles (two per cell).
        steps: steps to run.
        dtype: ``"f32"`` or ``"f64"``.

    Returns:
        ``(compile_s, run_s, F_mean, status)``: compile time (0 where nothing compiles), run time, the
        mean final ``F`` and the final state's ``health`` (checked after the timed run).
    """
    wp, T, p2g, grid, g2p = _warp_kernels(dtype)
    f = np.float32 if dtype == "f32" else np.float64
    L, x0, v0, F0 = _initial(n, f)
    x, v, F = (wp.array(a, dtype=T, device="cpu") for a in (x0, v0, F0))
    gm, gp, gf, ga, gv = (wp.zeros(L["nodes"], dtype=T, device="cpu") for _ in range(5))
    x_tr = wp.array(np.array([0.0, L["cells"] * L["h"]], f), dtype=T, device="cpu")
    P = PROBLEM
    c = {k: T(L[k]) for k in ("x_min", "h", "m", "V0", "dt")}
    P0, gamma, p_atm = T(P["P0"]), T(P["gamma"]), T(P["p_atm"])
    k = [0]

    def one():
        sig_t = T(boundary_stress(k[0] * L["dt"]))
        k[0] += 1
        args = [x, v, F, gm, gp, gf, x_tr, c["x_min"], c["h"], c["m"], c["V0"], P0, gamma, p_atm, sig_t]
        wp.launch(p2g, n, args, device="cpu")
        wp.launch(grid, L["nodes"], [gm, gp, gf, ga, gv, c["dt"]], device="cpu")
        wp.launch(g2p, n, [x, v, F, ga, gv, x_tr, c["x_min"], c["h"], c["dt"]], device="cpu")

    t0 = time.perf_counter()
    one()  # the first launch builds the module (Warp caches it on disk between processes)
    wp.synchronize()
    t1 = time.perf_counter()
    for _ in range(steps - 1):
        one()
    wp.synchronize()
    t2 = time.perf_counter()
    run_s = (t2 - t1) * steps / max(steps - 1, 1)
    state = [a.numpy() for a in (x, v, F, x_tr)]
    return t1 - t0, run_s, float(np.mean(state[2])), health(*state, *grid_span(L))


BASELINES = {"NumPy": numpy_spq, "plain JAX": plain_jax_spq, "Taichi": taichi_spq, "Warp": warp_spq}
"""The 1D reference codes by name, each ``(n, steps, dtype) -> (compile_s, run_s, F_mean, status)``."""
