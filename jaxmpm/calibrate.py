"""Gradient-based calibration of the gas's constants from a free-surface trajectory.

The cylinder test calibrates an explosive product's equation of state by fitting a measured wall
trajectory; here the gas slab's free surface ``x_R(t)`` plays that part. Given observations
``(t_i, x_i)``, ``calibrate`` fits named continuous parameters of a scene (``gamma``, ``P0``,
optionally ``rho0``) by minimising

    loss = mean_i ((x_R(t_i; params) - x_i) / L)^2,

with ``x_R`` from a jaxmpm run (its saved history, interpolated linearly in time), by gradient
descent through the whole run:

- parameters are kept in their physical ranges by a change of variables ``theta``: ``gamma = 1 +
  (gamma_0 - 1) e^theta``, ``P0 = p_atm + (P0_0 - p_atm) e^theta``, ``rho0 = rho0_0 e^theta`` (any
  other positive parameter: ``p_0 e^theta``), so ``theta = 0`` is the start and every ``theta`` is
  admissible;
- ``method="adam"`` (``optax.adam``) or ``"lbfgs"`` (``optax.lbfgs`` with its zoom line search);
- several starts at once: ``starts`` is a list of start dicts, run as one ``vmap``-ed update per
  iteration; the best final loss wins;
- a progress bar (tqdm) on long fits; the loss history and the fitted values are returned.

A run that breaks down during the fit (a trial too stiff for the time step, a slab that leaves the
grid) makes that start's loss non-finite: that start stops where it was, ``Fit.failed_starts`` says
at which iteration, with which values, and why (the step, particle and quantity of the broken run),
and the other starts go on. When every start has broken down, ``calibrate`` raises
``CalibrationError`` with those messages: a fit never continues from NaN.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ._checks import check_int, check_positive
from ._simulate import SaveAt, simulate
from .interpolators import AbstractInterpolator
from .scenes import AbstractScene
from .scenes.gas_slab import free_surface
from .sensitivity import check_names, continuous_parameters

NOT_FITTED = {"h": "the grid spacing", "dt": "the model's time step"}
"""Continuous inputs of a run that are not material constants, so ``calibrate`` does not fit them."""


def fittable(scene: AbstractScene) -> tuple[str, ...]:
    """The names ``calibrate`` can fit: the scene's continuous parameters but ``h`` and ``dt``.

    Args:
        scene: the scene (or its class).

    Returns:
        The names, in the scene's order (for the gas slab ``P0, gamma, p_atm, rho0``).
    """
    return tuple(n for n in continuous_parameters(scene) if n not in NOT_FITTED)


class CalibrationError(RuntimeError):
    """A fit could not go on: a trial run broke down or the loss became non-finite."""


@dataclasses.dataclass
class Fit:
    """The result of ``calibrate``.

    Attributes:
        fitted: the best start's fitted values, name to float.
        loss: its final loss.
        iterations: iterations taken.
        history: loss per iteration and start, shape ``(iterations + 1, starts)``.
        starts_fitted: every start's fitted values, name to array ``(starts,)``.
        wall_s: wall time of the fit (compilation included).
        failed_starts: start index to why it stopped (a trial run broke down); the others went on.
    """

    fitted: dict
    loss: float
    iterations: int
    history: np.ndarray
    starts_fitted: dict
    wall_s: float
    failed_starts: dict = dataclasses.field(default_factory=dict)


def trajectory(scene: AbstractScene, interpolator: AbstractInterpolator, ts, *, dt, **kwargs) -> jax.Array:
    """The free-surface position at times ``ts`` (linear between steps), from one run of ``dt`` steps.

    Args:
        scene: the scene (a ``GasSlab``).
        interpolator: the MPM method.
        ts: the times (``>= 0``).
        dt: the time step.
        **kwargs: passed to ``simulate``.

    Returns:
        ``x_R(ts)`` (``scenes.gas_slab.free_surface``), NaN everywhere when the run broke down.
    """
    ts = jnp.asarray(ts)
    steps = int(np.ceil(float(np.max(np.asarray(ts))) / float(dt) - 1e-9))
    fields = ("x", "F", "corners") if interpolator.tracks_corners else ("x", "F")
    sol = simulate(
        scene, interpolator, dt=dt, steps=steps, saveat=SaveAt(every=1, fields=fields), throw=False, **kwargs
    )
    h = sol.history
    xr = free_surface(h["x"], h["F"], h.get("corners"), sol.body)
    bad = sol.state.status != 0
    return jnp.where(bad, jnp.nan, jnp.interp(ts, sol.ts, xr))


def _transforms(scene, names):
    """``(to_physical(theta) -> dict, starts)`` keeping each parameter in its range."""
    p_atm = getattr(scene, "p_atm", None)

    def to_physical(theta, start):
        out = {}
        for i, n in enumerate(names):
            e = jnp.exp(theta[i])
            if n == "gamma":
                out[n] = 1.0 + (start[n] - 1.0) * e
            elif n == "P0" and p_atm is not None:
                out[n] = p_atm + (start[n] - p_atm) * e
            else:
                out[n] = start[n] * e
        return out

    return to_physical


def calibrate(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    t_data,
    x_data,
    fit: Sequence[str] = ("gamma", "P0"),
    starts: Sequence[dict] | dict | None = None,
    *,
    dt,
    method: str = "lbfgs",
    iterations: int = 50,
    learning_rate: float = 0.05,
    tol: float = 1e-14,
    progress: bool | None = None,
    **simulate_kwargs,
) -> Fit:
    """Fit ``fit`` (names of the scene's continuous parameters) to a free-surface trajectory.

    Args:
        scene: the scene; parameters not fitted keep its values.
        interpolator: the MPM method of the model.
        t_data: observation times (``t >= 0``).
        x_data: the free-surface positions observed at them.
        fit: the names to fit (e.g. ``("gamma", "P0")``, optionally with ``"rho0"``).
        starts: one dict or a list of dicts of start values (missing names start at the scene's
            values); several starts run at once under ``vmap``.
        dt: the model's time step (fixed through the fit; ``cfl_limit`` still guards it).
        method: ``"lbfgs"`` (default) or ``"adam"``.
        iterations: the most iterations; the fit stops earlier when every start's loss is below
            ``tol`` or stops improving.
        learning_rate: Adam's step in ``theta`` (log) space.
        progress: a tqdm bar (``None``: only on a terminal or in a notebook).
        **simulate_kwargs: passed to ``simulate`` (``transfer``, ``artificial_cells``, ...).

    Returns:
        A ``Fit``.

    Raises:
        ValueError: bad input (names that are not continuous parameters, ``h`` or ``dt``, a name
            given twice, an unknown method, data of mismatched shapes or not finite, times not
            increasing from ``>= 0``).
        CalibrationError: every start broke down.
    """
    names = tuple(fit)
    check_names(scene, names)
    for n in names:
        if n in NOT_FITTED:
            raise ValueError(
                f"{n} is {NOT_FITTED[n]}, not a material constant; it cannot be fitted; "
                f"fittable: {', '.join(fittable(scene))}"
            )
    if len(set(names)) != len(names):
        raise ValueError(f"fit names a parameter twice: {names}")
    if method not in ("lbfgs", "adam"):
        raise ValueError(f"method must be 'lbfgs' or 'adam', got {method!r}")
    check_int("iterations", iterations, 1)
    check_positive("learning_rate", learning_rate)
    t_data = jnp.asarray(t_data, dtype=scene.h.dtype)
    x_data = jnp.asarray(x_data, dtype=scene.h.dtype)
    if t_data.ndim != 1 or t_data.shape != x_data.shape or t_data.size < 2:
        raise ValueError("t_data and x_data must be 1D arrays of the same length (>= 2)")
    for what, a in (("t_data", t_data), ("x_data", x_data)):
        bad = np.flatnonzero(~np.isfinite(np.asarray(a)))
        if bad.size:
            raise ValueError(f"{what} must be finite; entry {int(bad[0])} is {float(a[bad[0]])}")
    t_host = np.asarray(t_data)
    if t_host[0] < 0 or np.any(np.diff(t_host) <= 0):
        raise ValueError("t_data must start at >= 0 and increase")
    if isinstance(starts, dict) or starts is None:
        starts = [starts or {}]
    base = {n: float(getattr(scene, n)) for n in names}
    start_vals = {n: jnp.asarray([float(s.get(n, base[n])) for s in starts]) for n in names}
    unknown = [k for s in starts for k in s if k not in names]
    if unknown:
        raise ValueError(
            f"starts name parameters that are not fitted: {sorted(set(unknown))}; fitted: {names}"
        )
    to_physical = _transforms(scene, names)
    L = scene.length

    def loss_fn(theta, start):
        params = to_physical(theta, start)
        sc = type(scene)(**{**scene.parameter_values(), **params})
        x = trajectory(sc, interpolator, t_data, dt=dt, **simulate_kwargs)
        return jnp.mean(jnp.square((x - x_data) / L))

    n_starts = len(starts)
    theta0 = jnp.zeros((n_starts, len(names)), dtype=scene.h.dtype)
    if method == "adam":
        opt = optax.adam(learning_rate)
    else:
        opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss_fn) if method == "lbfgs" else None

    def update(theta, state, start):
        # optax's L-BFGS mixes int32 and int64 counters: allow it standard promotion even where a
        # user (or the test suite) runs JAX with strict promotion.
        with jax.numpy_dtype_promotion("standard"):
            if method == "lbfgs":
                value, grad = value_and_grad(theta, start, state=state)
                updates, state = opt.update(
                    grad, state, theta, value=value, grad=grad, value_fn=lambda th: loss_fn(th, start)
                )
            else:
                value, grad = jax.value_and_grad(loss_fn)(theta, start)
                updates, state = opt.update(grad, state, theta)
            return optax.apply_updates(theta, updates), state, value

    update_all = jax.jit(jax.vmap(update))
    with jax.numpy_dtype_promotion("standard"):
        state = jax.vmap(opt.init)(theta0)
    theta = theta0
    history = []
    t0 = time.perf_counter()
    bar = _bar(progress, iterations)
    alive = np.ones(n_starts, dtype=bool)
    failed: dict[int, str] = {}
    frozen: dict[int, np.ndarray] = {}

    def physical(th, starts_):
        return {n: np.asarray(v) for n, v in to_physical_batch(to_physical, th, starts_).items()}

    run_starts = dict(start_vals)  # a broken start's slot takes a live start's values (see below)

    it = 0
    try:
        for it in range(1, iterations + 1):
            new_theta, new_state, value = update_all(theta, state, run_starts)
            value = np.asarray(value)
            broke = alive & ~(np.isfinite(value) & np.all(np.isfinite(np.asarray(new_theta)), axis=1))
            for b in np.flatnonzero(broke):  # say why, from a plain run at that start's trial values
                trial = {n: float(v[b]) for n, v in physical(theta, run_starts).items()}
                why = _why(scene, interpolator, trial, t_data, dt, simulate_kwargs)
                failed[int(b)] = f"iteration {it}: {why}"
                frozen[int(b)] = np.asarray(theta[b])
            alive &= ~broke
            if not alive.any():
                raise CalibrationError(
                    "calibrate: every start broke down: "
                    + "; ".join(f"start {b}, {msg}" for b, msg in failed.items())
                    + ". Reduce dt, choose starts nearer the data, or use method='adam' with a smaller "
                    "learning_rate."
                )
            # A broken start is frozen (its values kept for the report) and its slot follows a live
            # start, so that no NaN enters the batch (a NaN member would keep L-BFGS's line search,
            # which runs to the slowest member under vmap, going to its bound every iteration).
            src = jnp.asarray(np.where(alive, np.arange(n_starts), int(np.flatnonzero(alive)[0])))
            theta = new_theta[src]
            state = jax.tree_util.tree_map(lambda a: a[src], new_state)
            run_starts = {n: v[src] for n, v in run_starts.items()}
            value = np.where(alive, value, np.nan)
            history.append(value)
            if bar is not None:
                bar.update(1)
                bar.set_postfix(loss=f"{np.nanmin(value):.3e}")
            live = value[alive]
            if np.all(live < tol) or (  # converged, or no start improved by 1e-9 in 3 iterations
                len(history) > 3 and np.all(np.abs(history[-4][alive] - live) <= 1e-9 * live)
            ):
                break
    finally:
        if bar is not None:
            bar.close()
    final = np.where(alive, np.asarray(jax.jit(jax.vmap(loss_fn))(theta, run_starts)), np.nan)
    history.append(final)
    wall = time.perf_counter() - t0
    theta = np.array(theta)
    for b, th in frozen.items():
        theta[b] = th
    fitted_all = physical(jnp.asarray(theta), start_vals)  # live slots kept their own starts
    best = int(np.nanargmin(final))
    return Fit(
        fitted={n: float(v[best]) for n, v in fitted_all.items()},
        loss=float(final[best]),
        iterations=it,
        history=np.stack(history),
        starts_fitted=fitted_all,
        failed_starts=failed,
        wall_s=wall,
    )


def _why(scene, interpolator, trial, t_data, dt, simulate_kwargs) -> str:
    """What broke in a plain run at ``trial`` (the step, particle and quantity), for a message."""
    sc = type(scene)(**{**scene.parameter_values(), **trial})
    steps = int(np.ceil(float(np.max(np.asarray(t_data))) / float(dt) - 1e-9))
    sol = simulate(sc, interpolator, dt=dt, steps=steps, throw=False, **simulate_kwargs)
    f = sol.failure()
    where = ", ".join(f"{k}={v:.6g}" for k, v in trial.items())
    if f is None:
        return f"the loss at {where} is not finite"
    return f"the run at {where} broke down at step {f['step']}, particle {f['particle']}: " + "; ".join(
        f["quantities"]
    )


def to_physical_batch(to_physical: Callable, theta: jax.Array, start_vals: dict) -> dict:
    """Every start's physical values from its ``theta``.

    Args:
        to_physical: the change of variables ``(theta, start) -> {name: value}``.
        theta: one row of ``theta`` per start.
        start_vals: name to the start values, one per start.

    Returns:
        Name to the physical values, one per start.
    """
    return jax.vmap(to_physical)(theta, start_vals)


def _bar(progress, total):
    from .long_run import show_progress

    if not show_progress(progress):
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="calibrate", unit="it", dynamic_ncols=True)
