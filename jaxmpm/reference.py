"""Independent references for gas against the atmosphere: Lagrangian methods of lines, by diffrax.

Both problems are ``AdiabaticGas`` at rest (gauge stress ``sigma = -(P0 J^-gamma - p_atm)``) whose free
surface carries no gauge traction, and both use the same staggered, second-order-in-space scheme:
cells carry the volume ratio, nodes the velocity, and each node's mass is half of each neighbouring
cell's.

``gas_slab``: the slab ``[0, L]`` with a wall at 0, in ``cells`` equal cells of width ``dX``:

    dF_i / dt = (v_{i+1} - v_i) / dX,                       v_0 = 0 (the wall),
    rho0 dX dv_j / dt = sigma_j - sigma_{j-1},              interior nodes,
    rho0 (dX / 2) dv_N / dt = 0 - sigma_{N-1},              the free surface (zero gauge traction),
    dx_R / dt = v_N.

``gas_radial``: a charge ``|X| <= radius`` in ``dim = 1, 2, 3`` (the slab again, a cylinder, a
sphere), moving radially. Nodes sit at ``R_j = j dR`` (node 0 the centre, at rest); per unit solid
angle cell ``i`` has reference volume ``V_i = (R_{i+1}^d - R_i^d) / d`` and node ``j`` the mass
``m_j = rho0 (V_{j-1} + V_j) / 2`` (``rho0 V_{N-1} / 2`` at the surface). With ``q_i = P0 J_i^-gamma -
p_atm`` (``q_N = 0`` beyond the surface) the compatible (energy-conserving) scheme is

    dJ_i / dt = (r_{i+1}^(d-1) v_{i+1} - r_i^(d-1) v_i) / V_i,
    m_j dv_j / dt = r_j^(d-1) (q_{j-1} - q_j),
    r_j^d = d sum_{i<j} V_i J_i,

the radii following from ``J`` (a sum of positive terms: no cancellation near the centre). It
conserves ``sum m v^2 / 2 + sum V_i (P0 J_i^(1-gamma) / (gamma-1) + p_atm J_i)``; in 1D it is
``gas_slab``'s system.

The unknowns are scaled to O(1) (``F`` or ``J``, velocities by ``c0 = sqrt(gamma P0 / rho0)``, time
by the length over ``c0``) and integrated by diffrax (Tsit5, adaptive steps under a PID controller
with ``rtol`` and ``atol``), so the time error is controlled and what remains is the spatial error
of ``cells``, which ``reference_convergence`` and ``radial_convergence`` measure: the free surface
converges at first order, since it starts as a pressure jump (``radial_profile_convergence``
measures the radial profiles). Nothing here shares code with the MPM
solver: these are the yardsticks for MPM's error on these problems. They are differentiable in
``P0``, ``gamma``, ``p_atm`` and ``rho0`` (diffrax's adjoint through the solver steps).

Without dissipation the radial scheme does not converge past a shock. In 2D and 3D the gas
over-expands below ``p_atm`` near the surface and the rarefaction focuses at the centre; that
steepens into a (barotropic) shock at which the solution rings at the grid scale (the surface cells'
``J``, the surface node's ``v``), and a sphere at a small pressure ratio (1.5) cavitates at its centre
(``J`` past 100 by 1.5 transits), after which the solver's steps shrink without bound. Only the
free-surface radius settles, and not to the shocked solution's: a barotropic shock must destroy
energy, which this scheme conserves (at 10:1 and 1600 cells, two transits, the cylinder's surface
sits at 1.5091 m against 1.5068 m with the viscosity, the sphere's at 1.1896 m against 1.1707 m).
``gas_radial(..., viscosity=True)`` adds to each compressing cell's
pressure the quadratic (von Neumann and Richtmyer 1950, J. Appl. Phys. 21, 232, eq. 4) and linear
(Landshoff 1955, LA-1930) artificial viscosity

    Q_i = rho_i (c_2 s_i^2 + c_1 a_i s_i),    s_i = max(0, -(r_{i+1} - r_i) (dJ_i/dt) / J_i),

with ``rho_i = rho0 / J_i``, ``a_i = c0 J_i^((1-gamma)/2)`` the cell's sound speed and ``c_2, c_1``
the ``q_quadratic, q_linear`` of ``gas_radial``; ``q_i + Q_i`` replaces ``q_i`` in the momentum
equation. ``s_i`` is the cell's compression speed, its width times its volumetric compression
rate: in 1D the velocity jump ``v_i - v_{i+1}`` of the classical form, and unlike the jump of the
radial velocity it vanishes whenever the cell does not compress (``v ~ r^(1-d)`` keeps ``J`` but
its ``v`` falls outward, which the jump would read as compression). It also makes the first cell,
a disk or ball about the centre, like any other (``s_0 = -d v_1`` when it compresses): no centre
treatment is needed. Since ``Q_i > 0`` only where ``dJ_i/dt < 0``, the energy balance becomes

    d/dt (sum m v^2 / 2 + sum V_i (P0 J_i^(1-gamma) / (gamma-1) + p_atm J_i)) = sum V_i Q_i dJ_i/dt <= 0,

dissipation exactly where cells compress and none in expansion, the energy a barotropic shock
destroys (its jump conditions are mass and momentum alone); ``RadialSolution.dissipated`` reports
it. Measured with the viscosity (``gamma = 1.4``, ``rho0 = 1.5``, ``p_atm = 1e5``, radius 0.5, at
one and two transits, by ``radial_profile_convergence``): ``v(R)`` and ``rho(R)`` converge at first
order in mass-weighted L1 (observed orders 0.80-1.04 between 100 and 3200 cells, for the cylinder
at 1.5, 10 and 100:1 and the sphere at 10:1), 800 cells within 0.24% of 1600 in both (0.12% at
1600 of 3200). Without it they do not fall (``v`` at two transits, 400 against 800 cells: 8% for
the cylinder at 1.5 and 10:1, 1.4% at 100:1, 88% for the sphere; orders from -0.45 to 1.4). The
sphere at 1.5:1 passes two transits (its centre's ``J`` reaches 14 at 1.5 transits, then
recompresses). The coefficients change the error's constant, not the order or the limit: over
``c_2`` in 0.5-2 and ``c_1`` in 0.25-1 it stays within a factor 2 of the defaults' (1 and 0.5),
while ``c_1 = 0`` leaves ringing behind the shock that raises it up to 5-fold (the sphere's
density). The viscosity is off by default: without it ``gas_radial`` is the conservative scheme,
in 1D ``gas_slab``'s system.
"""

from collections.abc import Iterable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._checks import (
    brief,
    check_finite,
    check_greater,
    check_int,
    check_nonnegative,
    check_positive,
    check_real,
    check_scalar,
    is_concrete,
)
from .scenes.gas_slab import GasSlab


class SlabSolution(eqx.Module):
    """The reference solution at the requested times.

    Attributes:
        ts: the times.
        x_free: free-surface position ``x_R(t)`` at ``ts``.
        F: cell values of ``F`` at ``ts``, shape ``(len(ts), cells)``.
        X: the cells' reference centres.
        stats: diffrax's step statistics (accepted and rejected steps).
    """

    ts: Float[Array, " nt"]
    x_free: Float[Array, " nt"]
    F: Float[Array, "nt cells"]
    X: Float[Array, " cells"]
    stats: dict

    def F_at(self, X: Float[ArrayLike, "*points"]) -> Float[Array, " nt *points"]:
        """``F(X, t)`` at any reference positions, linear between cell centres (constant at the ends,
        between the slab's end and the centre of its end cell).

        Args:
            X: reference positions in the slab, ``0 <= X <= L``.

        Returns:
            ``F`` at ``X`` at every time of ``ts``.

        Raises:
            ValueError: a concrete ``X`` that is not finite or lies outside the slab (its cells span
                ``[0, L]``: ``L`` is the last centre plus half a cell).
        """
        check_finite("X", X)
        if is_concrete(X):
            half = float(self.X[0])  # the centres are (i + 1/2) dX
            end = float(self.X[-1]) + half
            x = np.asarray(X, dtype=float)
            if x.size and not (x.min() >= 0.0 and x.max() <= end * (1 + 1e-12)):
                raise ValueError(
                    f"X must lie in the slab, 0 <= X <= {end:.6g}, got values from {x.min():.6g} to "
                    f"{x.max():.6g}"
                )
        return jax.vmap(lambda F: jnp.interp(X, self.X, F))(self.F)


def _slab_rhs(tau, y, args):
    """The slab's semi-discrete equations in scaled unknowns, each O(1): ``F``, ``v / c0`` and
    ``(x_R - L) / L``, in time units of ``L / c0``. A function of the module, the parameters in
    ``args``: every solve of the same sizes reuses one compiled program."""
    del tau
    c0, P0, gamma, p_atm, rho0, dX, L = args
    F, w, _ = y
    v = w * c0
    sigma = -(P0 * F ** (-gamma) - p_atm)
    v_full = jnp.concatenate([jnp.zeros((1,), v.dtype), v])
    dF = (v_full[1:] - v_full[:-1]) / dX
    dv_int = (sigma[1:] - sigma[:-1]) / (rho0 * dX)
    dv_end = -2.0 * sigma[-1:] / (rho0 * dX)
    dv = jnp.concatenate([dv_int, dv_end])
    scale = L / c0
    return dF * scale, dv * scale / c0, v[-1] / c0


def gas_slab(
    scene,
    ts,
    cells: int = 400,
    rtol: float | None = None,
    atol: float | None = None,
    max_steps: int = 200_000,
) -> SlabSolution:
    """Solve the gas slab of ``scene`` (a ``GasSlab``; its ``P0, gamma, p_atm, rho0`` and length).

    Args:
        scene: the ``GasSlab`` whose parameters to use (its ``cells`` and ``h`` give only ``L``).
        ts: non-decreasing times to report at, a non-empty 1-d sequence from ``ts[0] >= 0``.
        cells: Lagrangian cells of the reference (independent of the MPM resolution).
        rtol: diffrax's relative tolerance (``None``: 1e-8 in float64, 1e-6 in float32).
        atol: diffrax's absolute tolerance, relative to the scales of F, v and x (``None``: 1e-10 in
            float64, 1e-8 in float32).
        max_steps: diffrax's step bound (an integer >= 1).

    Returns:
        The ``SlabSolution``.

    Raises:
        ValueError: ``scene`` is not a ``GasSlab``; ``ts`` is not a non-empty 1-d sequence of finite,
            non-decreasing times from ``>= 0``; bad ``cells``, ``rtol``, ``atol`` or ``max_steps``
            (``rtol`` below 8 ulps or ``atol`` below 1/16 ulp of the scene's float type among them:
            the solver cannot meet them and shrinks its steps);
            or the solve to ``ts[-1]`` needs more than ``max_steps`` steps (under ``jax.jit``,
            ``jax.grad`` or ``jax.vmap`` that, and any other failure of the solver, is diffrax's
            runtime error).
    """
    if not isinstance(scene, GasSlab):
        raise ValueError(f"scene must be a GasSlab (jm.GasSlab(...)), got {type(scene).__name__}")
    _check_times(ts, strictly=False)
    check_int("cells", cells, 2)
    rtol, atol = _tolerances(scene.h.dtype, rtol, atol)
    check_int("max_steps", max_steps, 1)
    ts = jnp.asarray(ts, dtype=scene.h.dtype)
    L = scene.length
    dX = L / cells
    P0, gamma, p_atm, rho0 = scene.P0, scene.gamma, scene.p_atm, scene.rho0
    c0 = jnp.sqrt(gamma * P0 / rho0)

    y0 = (jnp.ones(cells, ts.dtype), jnp.zeros(cells, ts.dtype), jnp.zeros((), ts.dtype))
    tau = ts * c0 / L
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(_slab_rhs),
        diffrax.Tsit5(),
        t0=jnp.zeros((), ts.dtype),
        t1=tau[-1],
        dt0=None,
        y0=y0,
        args=(c0, P0, gamma, p_atm, rho0, dX, L),
        saveat=diffrax.SaveAt(ts=tau),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps,
        throw=False,
    )
    sol = _succeeded(sol, max_steps, ts)
    F, _, xr = sol.ys
    X = (jnp.arange(cells, dtype=ts.dtype) + 0.5) * dX
    return SlabSolution(ts=ts, x_free=L + L * xr, F=F, X=X, stats=dict(sol.stats))


def _tolerances(dtype, rtol, atol) -> tuple[float, float]:
    """``gas_slab``'s tolerances: the float type's defaults for ``None``, else the values given, once
    they are within what the type resolves.

    Raises:
        ValueError: a tolerance is not a positive finite number, or lies below what ``dtype`` resolves
            (``rtol`` under 8 ulps, ``atol`` under 1/16 ulp).
    """
    eps = float(jnp.finfo(dtype).eps)
    wide = jnp.dtype(dtype) == jnp.float64
    given = {"rtol": rtol, "atol": atol}
    out = {"rtol": 1e-8 if wide else 1e-6, "atol": 1e-10 if wide else 1e-8}
    least = {"rtol": 8.0 * eps, "atol": eps / 16.0}
    for name, value in given.items():
        if value is None:
            continue
        check_positive(name, value)
        if is_concrete(value) and float(value) < least[name]:
            raise ValueError(
                f"{name}={float(value)!r} is below what {jnp.dtype(dtype).name} resolves (at least "
                f"{least[name]:.3g}; the solver would shrink its steps to nothing): give {name} >= "
                f"{least[name]:.3g}"
                + ("" if wide else ', or switch float64 on (jax.config.update("jax_enable_x64", True))')
            )
        out[name] = value
    return out["rtol"], out["atol"]


def _succeeded(sol: diffrax.Solution, max_steps: int, ts: Array) -> diffrax.Solution:
    """``sol`` once its solve succeeded.

    Args:
        sol: the solution of a ``diffeqsolve`` with ``throw=False``.
        max_steps: the step bound it was given.
        ts: the report times (the solve ran to ``ts[-1]``).

    Returns:
        ``sol``, carrying diffrax's runtime check of its result where that result is a tracer.

    Raises:
        ValueError: a concrete result says the solve stopped at ``max_steps`` steps.
        EquinoxRuntimeError: a concrete result says the solve failed otherwise (diffrax's error).
    """
    result = sol.result
    if all(is_concrete(leaf) for leaf in jax.tree_util.tree_leaves(result)):
        if bool(result == diffrax.RESULTS.max_steps_reached):
            end = f"ts[-1]={float(ts[-1])!r}" if is_concrete(ts) else "ts[-1]"
            raise ValueError(
                f"max_steps={max_steps} was too few: the solve to {end} needs more steps; raise max_steps"
            )
    return result.error_if(sol, jnp.invert(diffrax.is_okay(result)))


def reference_convergence(scene, ts, cells=(100, 200, 400, 800), **kwargs) -> list[dict]:
    """The reference's own convergence: the free-surface trajectory at each resolution against the
    finest, with the observed order between successive resolutions (Richardson).

    Args:
        scene: the ``GasSlab``.
        ts: the times.
        cells: two or more resolutions (integers >= 2), increasing; three or more, each twice the
            last, for the orders.
        **kwargs: passed to ``gas_slab``.

    Returns:
        One row per resolution: ``cells``, ``x_free_max_diff`` and (between the first and the last)
        ``order``, ``None`` where two resolutions agree exactly (``ts`` all 0: nothing has moved).

    Raises:
        ValueError: ``cells`` is not such a sequence; or as ``gas_slab``.
    """
    cells = _check_resolutions(cells)
    return _surface_convergence(cells, [gas_slab(scene, ts, n, **kwargs).x_free for n in cells], "x_free")


def _check_resolutions(cells) -> list[int]:
    """Check the resolutions of a surface convergence study (``_surface_convergence``).

    Args:
        cells: the resolutions, as given.

    Returns:
        ``cells`` as a list of Python integers.

    Raises:
        ValueError: ``cells`` is not a sequence of two or more integers >= 2, increasing, or (three
            or more) not each twice the last, which the observed order ``log2(d_i / d_{i+1})``
            assumes.
    """
    cells = _resolutions(cells)
    if len(cells) < 2:
        raise ValueError(
            f"cells must hold at least two resolutions, to compare against the finest, got {cells}"
        )
    for coarse, fine in zip(cells[:-1], cells[1:]):
        if fine <= coarse:
            raise ValueError(f"cells must be strictly increasing (coarse to fine), got {cells}")
        if len(cells) > 2 and fine != 2 * coarse:
            raise ValueError(
                f"cells must each be twice the last for the observed order (log2 of successive differences), "
                f"got {cells}"
            )
    return cells


def _resolutions(cells) -> list[int]:
    """``cells`` as a list of Python integers, each >= 2.

    Args:
        cells: the resolutions, as given.

    Returns:
        The list.

    Raises:
        ValueError: ``cells`` is not a sequence, or holds something that is not an integer >= 2.
    """
    if isinstance(cells, (str, bytes)) or not isinstance(cells, Iterable):
        raise ValueError(f"cells must be a sequence of resolutions (integers >= 2), got {brief(cells)}")
    cells = list(cells)
    for n in cells:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise ValueError(f"cells must hold integers >= 2, got {brief(n)} in {brief(cells)}")
    return [int(n) for n in cells]


def _surface_convergence(cells, surfaces, name: str) -> list[dict]:
    """Rows of ``cells``, ``<name>_max_diff`` against the finest surface trajectory, and the observed
    order between each three successive resolutions (Richardson; ``None`` where one of the two
    differences is exactly zero)."""
    finest = surfaces[-1]
    rows = [
        {"cells": n, f"{name}_max_diff": float(jnp.max(jnp.abs(s - finest)))} for n, s in zip(cells, surfaces)
    ]
    for i in range(len(surfaces) - 2):
        d1 = jnp.max(jnp.abs(surfaces[i] - surfaces[i + 1]))
        d2 = jnp.max(jnp.abs(surfaces[i + 1] - surfaces[i + 2]))
        # Where a pair agrees exactly (all times at t = 0, or converged to the last bit) there is no
        # difference to take an order from: None, not log2(0 / 0).
        rows[i + 1]["order"] = float(jnp.log2(d1 / d2)) if float(d1) > 0 and float(d2) > 0 else None
    return rows


class RadialSolution(eqx.Module):
    """The radial reference solution at the requested times.

    Radii are per unit solid angle in the sense of ``gas_radial``: ``r`` and ``R`` are distances
    from the centre (from the wall, in 1D).

    Attributes:
        ts: the times.
        r_free: free-surface radius ``r(radius, t)`` at ``ts``.
        R: the cells' reference centres (mid-radius).
        R_nodes: the nodes' reference radii, ``0`` to ``radius``.
        r: node radii at ``ts``.
        v: node radial velocities at ``ts``.
        rho: cell densities ``rho0 / J`` at ``ts``.
        J: cell volume ratios at ``ts``.
        dissipated: the energy the artificial viscosity has dissipated by ``ts``, per unit solid
            angle (``int sum V_i Q_i (-dJ_i/dt) dt``; zero without the viscosity), in the units of
            the kinetic energy ``sum m v^2 / 2``.
        stats: diffrax's step statistics (accepted and rejected steps).
    """

    ts: Float[Array, " nt"]
    r_free: Float[Array, " nt"]
    R: Float[Array, " cells"]
    R_nodes: Float[Array, " nodes"]
    r: Float[Array, "nt nodes"]
    v: Float[Array, "nt nodes"]
    rho: Float[Array, "nt cells"]
    J: Float[Array, "nt cells"]
    dissipated: Float[Array, " nt"]
    stats: dict

    def at(self, R: Float[ArrayLike, "*points"]) -> dict[str, Float[Array, " nt *points"]]:
        """The fields at any reference radii: ``r`` and ``v`` linear between nodes, ``rho`` and ``J``
        linear between cell centres (constant beyond the first and last centres).

        Args:
            R: reference radii, in ``[0, radius]`` (``radius`` is the last node, ``R_nodes[-1]``; a
                radius beyond it by round-off, a relative ``1e-12``, is taken as the surface).

        Returns:
            ``{"r", "v", "rho", "J"}``, each at ``R`` at every time of ``ts``.

        Raises:
            ValueError: a concrete ``R`` (any entry) is not a finite real number or lies outside
                ``[0, radius]`` (the fields are not extrapolated); a traced ``R`` is not checked
                (outside the charge it takes the nearest end's values).
        """
        check_finite("R", R)
        if is_concrete(R) and is_concrete(self.R_nodes):
            end = float(self.R_nodes[-1])
            radii = np.asarray(R, dtype=float)
            if radii.size and not (radii.min() >= 0.0 and radii.max() <= end * (1 + 1e-12)):
                raise ValueError(
                    f"R must lie in the charge, 0 <= R <= {end!r}, got values from {float(radii.min())!r} "
                    f"to {float(radii.max())!r}"
                )
        R = jnp.asarray(R, dtype=self.R.dtype)

        def interp(xp, fp):
            # (1 - t) f_i + t f_{i+1}: exactly the nodal value at a node, the last one included
            i = jnp.clip(jnp.searchsorted(xp, R, side="right") - 1, 0, xp.shape[0] - 2)
            t = jnp.clip((R - xp[i]) / (xp[i + 1] - xp[i]), 0.0, 1.0)
            return (1.0 - t)[None] * fp[:, i] + t[None] * fp[:, i + 1]

        return dict(
            r=interp(self.R_nodes, self.r),
            v=interp(self.R_nodes, self.v),
            rho=interp(self.R, self.rho),
            J=interp(self.R, self.J),
        )


def gas_radial(
    P0,
    gamma,
    p_atm,
    rho0,
    radius,
    dim: int,
    ts,
    cells: int = 400,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 200_000,
    viscosity: bool = False,
    q_quadratic=None,
    q_linear=None,
) -> RadialSolution:
    """Solve the radial expansion of a gas charge at rest against the atmosphere.

    The charge fills ``|X| <= radius``: the slab ``[0, radius]`` with a wall at 0 (``dim=1``, the
    ``gas_slab`` problem), a cylinder (``dim=2``) or a sphere (``dim=3``). The gas is ``AdiabaticGas``
    (gauge pressure ``P0 J^-gamma - p_atm``); its free surface carries no gauge traction. The scheme
    and what it resolves are in the module's docstring: the free-surface radius converges at first
    order; past the formation of a shock (in 2D and 3D, after about a transit) the fields ring at the
    grid scale unless ``viscosity`` is on, with which the profiles ``v(R)`` and ``rho(R)`` converge
    at first order too.

    Args:
        P0: initial absolute pressure, > ``p_atm``.
        gamma: adiabatic exponent, > 1.
        p_atm: ambient pressure, > 0.
        rho0: initial density, > 0.
        radius: the charge's radius (the slab's length in 1D), > 0.
        dim: 1, 2 or 3 (planar, cylindrical, spherical).
        ts: increasing times to report at (``ts[0] >= 0``).
        cells: Lagrangian cells along the radius.
        rtol: diffrax's relative tolerance.
        atol: diffrax's absolute tolerance, relative to the scales of ``J``, ``v`` (``c0``).
        max_steps: diffrax's step bound (an integer >= 1).
        viscosity: add the artificial viscosity ``Q`` of the module's docstring (static: the solve
            without it is the inviscid scheme, unchanged). Off by default; on for a reference of
            the profiles past the shock.
        q_quadratic: its quadratic coefficient ``c_2`` (>= 0; 1 if not given), only with
            ``viscosity``.
        q_linear: its linear coefficient ``c_1`` (>= 0; 0.5 if not given), which damps the ringing
            behind a shock, only with ``viscosity``.

    Returns:
        The ``RadialSolution`` (its ``dissipated`` zero without the viscosity).

    Raises:
        ValueError: bad ``P0``, ``gamma``, ``p_atm``, ``rho0``, ``radius``, ``dim``, ``ts``,
            ``cells``, ``rtol``, ``atol``, ``max_steps``, ``viscosity``, ``q_quadratic`` or
            ``q_linear`` (given without ``viscosity=True``, which would ignore it), named in the
            message (each number parameter is one number: ``jax.vmap``
            over ``gas_radial`` solves several charges); or the solve to ``ts[-1]`` needs more than
            ``max_steps`` steps (under ``jax.jit``, ``jax.grad`` or ``jax.vmap`` that, and any other
            failure of the solver, is diffrax's runtime error).
    """
    batch = "; for several charges, jax.vmap over gas_radial"
    for name, value in (("P0", P0), ("gamma", gamma), ("p_atm", p_atm), ("rho0", rho0), ("radius", radius)):
        check_real(name, value)
        check_scalar(name, value, batch)
    check_positive("P0", P0)
    check_greater("gamma", gamma, 1.0)
    check_positive("p_atm", p_atm)
    check_positive("rho0", rho0)
    check_positive("radius", radius)
    if is_concrete(P0) and is_concrete(p_atm) and not float(P0) > float(p_atm):
        raise ValueError(f"P0 must be > p_atm (the gas expands), got P0={float(P0)}, p_atm={float(p_atm)}")
    if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim not in (1, 2, 3):
        raise ValueError(f"dim must be 1, 2 or 3, got {dim!r}")
    dim = int(dim)
    check_int("cells", cells, 2)
    for name, value in (("rtol", rtol), ("atol", atol)):
        check_real(name, value)
        check_scalar(name, value)
        check_positive(name, value)
    check_int("max_steps", max_steps, 1)
    if not isinstance(viscosity, bool):
        raise ValueError(f"viscosity must be True or False, got {viscosity!r}")
    for name, value in (("q_quadratic", q_quadratic), ("q_linear", q_linear)):
        if value is None:
            continue
        check_real(name, value)
        check_scalar(name, value, batch)
        check_nonnegative(name, value)
        if not viscosity:
            raise ValueError(
                f"{name} is a coefficient of the artificial viscosity: give viscosity=True with it"
            )
    q_quadratic = 1.0 if q_quadratic is None else q_quadratic
    q_linear = 0.5 if q_linear is None else q_linear
    _check_times(ts)

    dtype = jnp.result_type(float)
    ts = jnp.asarray(ts, dtype=dtype)
    P0, gamma, p_atm, rho0, radius = (jnp.asarray(p, dtype=dtype) for p in (P0, gamma, p_atm, rho0, radius))
    c0 = jnp.sqrt(gamma * P0 / rho0)

    # Everything in units of radius, c0, rho0 (time radius / c0, pressure rho0 c0^2): the unknowns J
    # and w = v / c0 are O(1). Per unit solid angle, cell i has reference volume V_i; node j lumps
    # half of each neighbour's mass.
    R_nodes = jnp.arange(cells + 1, dtype=dtype) / cells
    V = (R_nodes[1:] ** dim - R_nodes[:-1] ** dim) / dim
    m = 0.5 * jnp.concatenate([V[:-1] + V[1:], V[-1:]])
    p0, pa = P0 / (rho0 * c0**2), p_atm / (rho0 * c0**2)

    y0 = (jnp.ones(cells, dtype), jnp.zeros(cells, dtype))
    args = (V, m, p0, pa, gamma)
    if viscosity:  # the energy dissipated so far joins the unknowns
        y0 = y0 + (jnp.zeros((), dtype),)
        args = args + tuple(jnp.asarray(c, dtype=dtype) for c in (q_quadratic, q_linear))
    tau = ts * c0 / radius
    field = _RadialField(dim, viscosity)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(field),
        diffrax.Tsit5(),
        t0=jnp.zeros((), dtype),
        t1=tau[-1],
        dt0=None,
        y0=y0,
        args=args,
        saveat=diffrax.SaveAt(ts=tau),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps,
        throw=False,
    )
    sol = _succeeded(sol, max_steps, ts)
    J, w = sol.ys[:2]
    energy_unit = rho0 * c0**2 * radius**dim  # per unit solid angle
    dissipated = energy_unit * sol.ys[2] if viscosity else jnp.zeros_like(ts)
    zero = jnp.zeros((ts.shape[0], 1), dtype)
    r = radius * jnp.concatenate([zero, jax.vmap(lambda J: field.radii(J, V))(J)], axis=1)
    v = c0 * jnp.concatenate([zero, w], axis=1)
    return RadialSolution(
        ts=ts,
        r_free=r[:, -1],
        R=radius * 0.5 * (R_nodes[1:] + R_nodes[:-1]),
        R_nodes=radius * R_nodes,
        r=r,
        v=v,
        rho=rho0 / J,
        J=J,
        dissipated=dissipated,
        stats=dict(sol.stats),
    )


class _RadialField(eqx.Module):
    """The semi-discrete radial system in units of ``radius``, ``c0`` and ``rho0``: a module with a
    static ``dim`` and no closure, so that a second solve of the same shapes reuses the compiled one.

    Attributes:
        dim: 1, 2 or 3.
        viscosity: whether to add the artificial viscosity; with it the unknowns end with the
            dissipated energy and the arguments with ``c_2, c_1``.
    """

    dim: int = eqx.field(static=True)
    viscosity: bool = eqx.field(static=True, default=False)

    def radii(self, J: Float[Array, " cells"], V: Float[Array, " cells"]) -> Float[Array, " cells"]:
        """Node radii ``r_1 .. r_N`` from the cells' ``J``: ``r_j^d = d sum_{i<j} V_i J_i``, a sum of
        positive terms, with no cancellation near the centre.

        Args:
            J: the cells' volume ratios.
            V: the cells' reference volumes per unit solid angle.

        Returns:
            The radii of nodes 1 to N (node 0 is the centre).
        """
        return (self.dim * jnp.cumsum(V * J)) ** (1.0 / self.dim)

    def __call__(self, tau, y, args):
        if self.viscosity:
            J, w, _ = y
            V, m, p0, pa, gamma, c_quadratic, c_linear = args
        else:
            J, w = y
            V, m, p0, pa, gamma = args
        r = self.radii(J, V)  # nodes 1..N
        area = r ** (self.dim - 1)
        flux = area * w  # r^(d-1) v at nodes 1..N; 0 at the centre
        dJ = (flux - jnp.concatenate([jnp.zeros((1,), flux.dtype), flux[:-1]])) / V
        q = p0 * J ** (-gamma) - pa  # gauge pressure of each cell; 0 beyond the free surface
        if self.viscosity:
            # The compression speed across each cell: its current width times its compression rate,
            # -(r_{i+1} - r_i) (dJ_i/dt) / J_i, which in 1D is the velocity jump v_i - v_{i+1}. In
            # units of c0 and rho0, the cell's density is 1 / J and its sound speed J^((1-gamma)/2).
            width = r - jnp.concatenate([jnp.zeros((1,), r.dtype), r[:-1]])
            s = jnp.maximum(-width * dJ / J, 0.0)
            q_visc = (c_quadratic * s + c_linear * J ** (0.5 * (1.0 - gamma))) * s / J
            q = q + q_visc
        dw = area * (q - jnp.concatenate([q[1:], jnp.zeros((1,), q.dtype)])) / m
        if self.viscosity:
            return dJ, dw, -jnp.sum(V * q_visc * dJ)  # the rate of dissipation, >= 0
        return dJ, dw


def radial_convergence(ts, cells=(100, 200, 400, 800), **kwargs) -> list[dict]:
    """The radial reference's own convergence: the free-surface radius at each resolution against the
    finest, with the observed order between successive resolutions (Richardson).

    Args:
        ts: the times.
        cells: two or more resolutions (integers >= 2), increasing; three or more, each twice the
            last, for the orders.
        **kwargs: passed to ``gas_radial`` (``P0``, ``gamma``, ``p_atm``, ``rho0``, ``radius``,
            ``dim`` and any of its options).

    Returns:
        One row per resolution: ``cells``, ``r_free_max_diff`` and (between the first and the last)
        ``order``.

    Raises:
        ValueError: ``cells`` is not such a sequence; or as ``gas_radial``.
    """
    cells = _check_resolutions(cells)
    return _surface_convergence(cells, [gas_radial(ts=ts, cells=n, **kwargs).r_free for n in cells], "r_free")


def radial_profile_convergence(
    P0, gamma, p_atm, rho0, radius, dim: int, ts, cells=(100, 200, 400, 800), **kwargs
) -> list[dict]:
    """The radial reference's own convergence in its profiles: ``v(R)`` and ``rho(R)`` at each
    resolution against the next finer, with the observed orders.

    Each finer grid refines the last by an integer factor ``k`` (2 for the default), so the
    comparison needs no interpolation: the coarse nodes are every ``k``-th fine node (``v`` is
    compared there), and each coarse cell is ``k`` fine cells, whose volume ratio is their
    volume-weighted mean (``rho = rho0 / J`` then compared cell by cell). The L1 norms are over the
    reference volume (``R^(d-1) dR``, the mass: the average over equal-volume particles): the nodes
    weighted by their masses, the cells by their volumes.

    Args:
        P0: as for ``gas_radial``.
        gamma: as for ``gas_radial``.
        p_atm: as for ``gas_radial``.
        rho0: as for ``gas_radial``.
        radius: as for ``gas_radial``.
        dim: as for ``gas_radial``.
        ts: the times (a time at which every resolution agrees exactly, such as 0, has no order).
        cells: three or more resolutions, coarse to fine, each an integer multiple of the last.
        **kwargs: passed to ``gas_radial`` (``viscosity``, its coefficients, tolerances).

    Returns:
        One row per resolution but the finest, each with arrays over ``ts``: ``cells``; ``v_l1``
        (m/s) and ``rho_l1`` (kg/m^3), the mass-weighted mean absolute differences from the next
        finer resolution; ``v_l1_rel`` and ``rho_l1_rel``, the same over the finer one's mean
        ``|v|`` and ``rho``; ``r_free_diff``, the free surfaces' difference (m); and, on every row
        but the last, ``v_order``, ``rho_order`` and ``r_free_order``, the observed orders
        ``log(d_i / d_{i+1}) / log(k)`` from this row's differences and the next row's.
        Undefined values are NaN, without a warning: ``v_l1_rel`` at a time where the finer
        resolution's velocity is zero everywhere (at ``t = 0``, the gas at rest: ``v_l1`` is 0
        there), and an order where both differences are zero (every resolution agrees exactly, as
        at ``t = 0``); an order where only one difference is zero is ``+inf`` or ``-inf``.

    Raises:
        ValueError: ``cells`` is not a sequence of integers >= 2, holds fewer than three
            resolutions, or one that is not a multiple of the last; or as ``gas_radial``.
    """
    cells = _resolutions(cells)
    if len(cells) < 3:
        raise ValueError(f"cells must hold at least three resolutions for an order, got {cells}")
    for coarse, fine in zip(cells[:-1], cells[1:]):
        if fine <= coarse or fine % coarse:
            raise ValueError(f"cells must each be an integer multiple of the last, got {cells}")
    problem = dict(P0=P0, gamma=gamma, p_atm=p_atm, rho0=rho0, radius=radius, dim=dim)
    sols = [gas_radial(**problem, ts=ts, cells=n, **kwargs) for n in cells]
    rows = []
    for n, n_fine, coarse, fine in zip(cells[:-1], cells[1:], sols[:-1], sols[1:]):
        k = n_fine // n
        R = np.asarray(coarse.R_nodes) / float(radius)
        V = (R[1:] ** dim - R[:-1] ** dim) / dim
        m = 0.5 * (np.concatenate([[0.0], V]) + np.concatenate([V, [0.0]]))
        R_f = np.asarray(fine.R_nodes) / float(radius)
        V_f = ((R_f[1:] ** dim - R_f[:-1] ** dim) / dim).reshape(n, k)
        J_f = np.sum(np.asarray(fine.J).reshape(-1, n, k) * V_f, axis=2) / np.sum(V_f, axis=1)
        v_c, v_f = np.asarray(coarse.v), np.asarray(fine.v)[:, ::k]
        rho_c, rho_f = np.asarray(coarse.rho), float(rho0) / J_f
        v_l1 = np.sum(m * np.abs(v_c - v_f), axis=1) / np.sum(m)
        rho_l1 = np.sum(V * np.abs(rho_c - rho_f), axis=1) / np.sum(V)
        v_norm = np.sum(m * np.abs(v_f), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            # The gas at rest (t = 0) has no velocity to measure a relative difference against: NaN.
            v_l1_rel = np.where(v_norm > 0, v_l1 * np.sum(m) / v_norm, np.nan)
        rows.append(
            dict(
                cells=n,
                v_l1=v_l1,
                v_l1_rel=v_l1_rel,
                rho_l1=rho_l1,
                rho_l1_rel=rho_l1 * np.sum(V) / np.sum(V * rho_f, axis=1),
                r_free_diff=np.abs(np.asarray(coarse.r_free) - np.asarray(fine.r_free)),
            )
        )
    for row, finer, n, n_fine in zip(rows[:-1], rows[1:], cells[:-1], cells[1:]):
        log_k = np.log(n_fine / n)
        with np.errstate(divide="ignore", invalid="ignore"):
            for key in ("v", "rho", "r_free"):
                d = "r_free_diff" if key == "r_free" else f"{key}_l1"
                row[f"{key}_order"] = np.log(row[d] / finer[d]) / log_k
    return rows


def _check_times(ts, strictly: bool = True) -> None:
    """Check the report times: a finite, increasing 1-d sequence from ``ts[0] >= 0``; a tracer passes.

    Args:
        ts: the times, as given.
        strictly: whether each time must exceed the last (``gas_radial``), or may equal it
            (``gas_slab``: diffrax reports a repeated time twice).

    Raises:
        ValueError: ``ts`` is not such a sequence.
    """
    check_real("ts", ts)
    if not is_concrete(ts):
        return
    arr = np.asarray(ts)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"ts must be a non-empty 1-d sequence of times, got shape {arr.shape}")
    check_finite("ts", arr)
    if arr[0] < 0:
        raise ValueError(f"ts must start at >= 0, got ts[0]={float(arr[0])}")
    step = np.diff(arr)
    if strictly and not np.all(step > 0):
        i = int(np.flatnonzero(~(step > 0))[0])
        raise ValueError(
            f"ts must be strictly increasing, got ts[{i}]={float(arr[i])}, ts[{i + 1}]={float(arr[i + 1])}"
        )
    if not np.all(step >= 0):
        i = int(np.flatnonzero(~(step >= 0))[0])
        raise ValueError(
            f"ts must be non-decreasing, got ts[{i}]={float(arr[i])}, ts[{i + 1}]={float(arr[i + 1])}"
        )
