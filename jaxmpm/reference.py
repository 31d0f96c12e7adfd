"""An independent reference for the gas slab: a Lagrangian method of lines, by diffrax.

The gas on ``[0, L]`` is cut into ``cells`` equal Lagrangian cells of width ``dX``. Each cell carries
its ``F``; each node its velocity (staggered, second order in space):

    dF_i / dt = (v_{i+1} - v_i) / dX,                       v_0 = 0 (the wall),
    rho0 dX dv_j / dt = sigma_j - sigma_{j-1},              interior nodes,
    rho0 (dX / 2) dv_N / dt = 0 - sigma_{N-1},              the free surface (zero gauge traction),
    dx_R / dt = v_N,

with ``sigma = -(P0 F^-gamma - p_atm)``. The ODE system is integrated by diffrax (Tsit5, adaptive
steps under a PID controller with ``rtol`` and ``atol``), so the time error is controlled and what
remains is the spatial error of ``cells``, which ``reference_convergence`` measures. Nothing here
shares code with the MPM solver: it is the yardstick for MPM's error on this problem.

It is differentiable in ``P0``, ``gamma``, ``p_atm`` and ``rho0`` (diffrax's adjoint through the
solver steps).
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._checks import check_int, check_positive


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

    def F_at(self, X: Float[Array, "*points"]) -> Float[Array, " nt *points"]:
        """``F(X, t)`` at any reference positions, linear between cell centres (constant at the ends).

        Args:
            X: reference positions.

        Returns:
            ``F`` at ``X`` at every time of ``ts``.
        """
        return jax.vmap(lambda F: jnp.interp(X, self.X, F))(self.F)


def gas_slab(
    scene,
    ts,
    cells: int = 400,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 200_000,
) -> SlabSolution:
    """Solve the gas slab of ``scene`` (a ``GasSlab``; its ``P0, gamma, p_atm, rho0`` and length).

    Args:
        scene: the ``GasSlab`` whose parameters to use (its ``cells`` and ``h`` give only ``L``).
        ts: increasing times to report at (``ts[0] >= 0``).
        cells: Lagrangian cells of the reference (independent of the MPM resolution).
        rtol: diffrax's relative tolerance.
        atol: diffrax's absolute tolerance, relative to the scales of F, v and x.
        max_steps: diffrax's step bound.

    Returns:
        The ``SlabSolution``.

    Raises:
        ValueError: bad ``cells``, ``rtol`` or ``atol``.
    """
    check_int("cells", cells, 2)
    check_positive("rtol", rtol)
    check_positive("atol", atol)
    ts = jnp.asarray(ts, dtype=scene.h.dtype)
    L = scene.length
    dX = L / cells
    P0, gamma, p_atm, rho0 = scene.P0, scene.gamma, scene.p_atm, scene.rho0
    c0 = jnp.sqrt(gamma * P0 / rho0)

    # Scaled unknowns, each O(1): F, v / c0, (x_R - L) / L, time in units of L / c0.
    def rhs(tau, y, args):
        del tau, args
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

    y0 = (jnp.ones(cells, ts.dtype), jnp.zeros(cells, ts.dtype), jnp.zeros((), ts.dtype))
    tau = ts * c0 / L
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(rhs),
        diffrax.Tsit5(),
        t0=jnp.zeros((), ts.dtype),
        t1=tau[-1],
        dt0=None,
        y0=y0,
        saveat=diffrax.SaveAt(ts=tau),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps,
    )
    F, _, xr = sol.ys
    X = (jnp.arange(cells, dtype=ts.dtype) + 0.5) * dX
    return SlabSolution(ts=ts, x_free=L + L * xr, F=F, X=X, stats=dict(sol.stats))


def reference_convergence(scene, ts, cells=(100, 200, 400, 800), **kwargs) -> list[dict]:
    """The reference's own convergence: the free-surface trajectory at each resolution against the
    finest, with the observed order between successive resolutions (Richardson).

    Args:
        scene: the ``GasSlab``.
        ts: the times.
        cells: the resolutions, coarse to fine (each twice the last for an order).
        **kwargs: passed to ``gas_slab``.

    Returns:
        One row per resolution: ``cells``, ``x_free_max_diff`` and (between the first and the last)
        ``order``.
    """
    sols = [gas_slab(scene, ts, n, **kwargs) for n in cells]
    finest = sols[-1].x_free
    rows = []
    for n, s in zip(cells, sols):
        rows.append(dict(cells=n, x_free_max_diff=float(jnp.max(jnp.abs(s.x_free - finest)))))
    for i in range(len(sols) - 2):
        d1 = jnp.max(jnp.abs(sols[i].x_free - sols[i + 1].x_free))
        d2 = jnp.max(jnp.abs(sols[i + 1].x_free - sols[i + 2].x_free))
        rows[i + 1]["order"] = float(jnp.log2(d1 / d2))
    return rows
