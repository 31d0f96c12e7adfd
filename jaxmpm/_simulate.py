"""The one time-loop driver: ``lax.scan`` over pure steps, saving only what was asked."""

import dataclasses
import functools
import math
import time
import typing
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from . import _memory
from . import status as st_bits
from ._checks import brief, check_int, check_keywords, check_positive, check_scalar, is_concrete, python_int
from ._step import (
    Model,
    Setup,
    check_cfl_limit,
    check_devices,
    check_dt,
    check_parts,
    check_structure,
    pad_particles,
    setup,
    shard_particles,
    stable_dt,
    start_state,
    take_step,
    unpad_particles,
)
from ._util import as_float, det, host
from .interpolators import AbstractInterpolator
from .materials import AbstractEOS
from .particles import Body, State
from .scenes import AbstractScene
from .transfers import FLIP, AbstractTransfer
from .viscosity import ArtificialViscosity

STATE_FIELDS = ("x", "v", "F", "sigma", "C", "corners", "x_traction", "e", "internal")
"""The ``State`` fields a ``SaveAt`` may name: the per-particle (and per-corner) arrays (``internal``
is saved as one entry ``internal.<variable>`` per internal variable)."""


DEFAULT_CFL = 0.5
"""The Courant number of a run to ``t_end`` given no ``cfl``."""

MAX_STEP_COUNT = 2**31 - 1
"""The most steps one run may take: ``State.step`` is a 32-bit integer."""


# How a parameter given as an array is to be run instead (appended to its one-number message).
_SEVERAL = ": to run several values, jax.vmap over simulate or use jaxmpm.ensemble"


class SaveAt(eqx.Module):
    """What ``simulate`` keeps besides the final state.

    By default nothing (like diffrax's ``SaveAt(t1=True)``). With ``every=k`` it keeps the named
    ``fields`` at steps ``0, k, 2k, ...`` (nested scans: only the saved slices are stored). A named
    field that the run does not have (``C`` without APIC, ``corners`` without MPQ or CPDI2, ``e``
    without an energy equation, ``internal`` without history variables, ``x_traction`` without
    tractions) is left out of the history; one that names none of the run's is refused.

    Attributes:
        every: save every ``every`` steps, or ``None`` to keep no history (static).
        fields: names of ``State`` fields to save, at least one (static).

    Raises:
        ValueError: ``every`` is not ``None`` or an integer >= 1, or ``fields`` is not a non-empty
            tuple (or list) of names among ``STATE_FIELDS``, or ``fields`` other than the default
            are given without ``every`` (nothing would be kept).
    """

    every: int | None = eqx.field(static=True, default=None, converter=python_int)
    fields: tuple[str, ...] = eqx.field(static=True, default=("x", "v", "F", "sigma"))

    def __check_init__(self):
        if self.every is not None:
            check_int("SaveAt.every", self.every, 1)
        elif self.fields != SaveAt.fields:
            raise ValueError(
                f"SaveAt.fields={self.fields!r} without every keeps no history: give every=k to keep "
                "them every k steps"
            )
        if isinstance(self.fields, str) or not isinstance(self.fields, tuple | list):
            raise ValueError(
                f"SaveAt.fields must be a tuple of names among {STATE_FIELDS}, got {self.fields!r}"
            )
        unknown = [f for f in self.fields if f not in STATE_FIELDS]
        if unknown:
            raise ValueError(f"SaveAt.fields must be among {STATE_FIELDS}, got {unknown}")
        if not self.fields:
            raise ValueError(
                f"SaveAt.fields must name at least one field among {STATE_FIELDS}, got an empty "
                "tuple (to keep no history, leave every=None)"
            )


class Solution(eqx.Module):
    """The result of ``simulate``.

    Attributes:
        state: the final state; after a failure, the last good state (the failing step is not taken).
        body: the reference configuration (``X``, masses, which particles are in boundary cells).
        ts: times of the saved history, or ``None``. A run to ``t_end`` takes up to ``max_steps``
            steps, and the saves after the step that reaches ``t_end`` repeat its final state, with
            its time; after a failure the saves that follow it repeat the last good state, with its
            time.
        history: saved fields, each with a leading time axis, or ``None``.
    """

    state: State
    body: Body
    ts: Float[Array, " n_save"] | None
    history: dict[str, Array] | None

    @property
    def status(self) -> Int[Array, ""]:
        """The final state's failure bitmask (``jaxmpm.status``); 0 for a healthy run."""
        return self.state.status

    def failure(self) -> dict | None:
        """The first failure of the run.

        Returns:
            ``None`` for a healthy run, else a dict with the ``status`` bitmask, the ``step`` and
            ``particle`` of the first failure and the failed ``quantities`` in words.

        Raises:
            ValueError: the solution holds a batch of runs (``jax.vmap``): read one member
                (``jax.tree.map(lambda a: a[i], solution).failure()``) or use ``jaxmpm.ensemble``,
                whose ``Ensemble.failures()`` lists the members that broke down.
        """
        if np.ndim(self.state.status) != 0:
            raise ValueError(
                f"failure() reads one run, and this solution holds a batch of shape "
                f"{np.shape(self.state.status)} (jax.vmap): read member i with "
                f"jax.tree.map(lambda a: a[i], solution).failure(), or run jaxmpm.ensemble, whose "
                f"Ensemble.failures() lists the members that broke down"
            )
        status = int(self.state.status)
        if status == 0:
            return None
        return dict(
            status=status,
            step=int(self.state.fail_step),
            particle=int(self.state.fail_particle),
            quantities=st_bits.describe(status),
        )


class ToEnd(eqx.Module):
    """A run to an end time with the CFL-limited step ``cfl h / max_p(c_p + |v_p|)``, recomputed
    every step; the last step is cut to land exactly on ``t_end``, and steps past it are masked, so a
    bounded scan (``max_steps`` long) carries it and ``jax.grad`` goes through (``t_end`` and ``cfl``
    are traced).

    Attributes:
        t_end: the end time.
        cfl: the Courant number of every step.
    """

    t_end: Float[Array, ""] = eqx.field(converter=as_float)
    cfl: Float[Array, ""] = eqx.field(converter=as_float)


class SimulationError(RuntimeError):
    """A run broke down. ``error.solution`` holds everything computed up to the last good step.

    Args:
        message: what failed, where and when (``failure_message``).
        solution: the run's ``Solution``, its state the last good one.
    """

    def __init__(self, message: str, solution: Solution):
        super().__init__(message)
        self.solution = solution


def _validate(scene, interpolator, transfer, dt, steps, artificial_cells, cfl_limit, checkpoint, viscosity):
    check_parts(scene, interpolator, transfer, viscosity)
    for f in dataclasses.fields(scene):
        if f.metadata.get("converter") is as_float:
            check_scalar(f"{type(scene).__name__}.{f.name}", getattr(scene, f.name), _SEVERAL)
    if isinstance(dt, ToEnd):
        check_positive("t_end", dt.t_end)
        check_positive("cfl", dt.cfl)
        check_int("max_steps", steps, 1)
    else:
        check_dt(dt, _SEVERAL)
        check_int("steps", steps, 0)
    if steps > MAX_STEP_COUNT:
        name = "max_steps" if isinstance(dt, ToEnd) else "steps"
        raise ValueError(
            f"{name} must be <= {MAX_STEP_COUNT} (the step counter is a 32-bit integer), got {steps}"
        )
    check_int("artificial_cells", artificial_cells, 0)
    check_structure(scene, int(artificial_cells))
    if not isinstance(checkpoint, bool) and (not isinstance(checkpoint, int | np.integer) or checkpoint < 1):
        raise ValueError(
            "checkpoint must be True (blocks of ceil(sqrt(steps / 8)) steps), False (no "
            f"checkpointing) or an integer >= 1 (the block length), got {brief(checkpoint)}"
        )
    check_cfl_limit(cfl_limit)


def _check_resolved(name: str, value, dtype) -> None:
    """Refuse a concrete positive time (or Courant number) that the run's float type rounds to 0.

    Raises:
        ValueError: ``value`` is a number > 0 that becomes 0 in ``dtype`` (``dt = 1e-50`` in float32).
    """
    if isinstance(value, bool | np.bool_) or not is_concrete(value) or np.ndim(value) != 0:
        return
    try:
        given = float(value)
    except (TypeError, ValueError):
        return  # not a number: the checks that follow name it
    if given > 0.0 and float(np.asarray(given, dtype=dtype)) == 0.0:
        raise ValueError(
            f"{name}={given!r} rounds to 0 in {np.dtype(dtype).name}, the run's float type (its smallest "
            f"number > 0 is {float(np.finfo(dtype).smallest_subnormal):.3g}); give a larger {name}, or "
            "switch float64 on"
        )


def _refuse_to_end_options(cfl, max_steps) -> None:
    """Refuse ``cfl`` and ``max_steps`` given to a run of fixed steps, which they do not apply to."""
    if max_steps is not None:
        raise ValueError(
            f"max_steps (got {brief(max_steps)}) is the bound of a run to an end time (t_end=..., with "
            "cfl); a run of fixed steps (dt and steps) takes exactly steps steps: leave max_steps out"
        )
    if cfl is not None:
        raise ValueError(
            f"cfl (got {brief(cfl)}) sets the step of a run to an end time (t_end=..., with max_steps); "
            "a run of fixed steps (dt and steps) steps by dt: leave cfl out (cfl_limit sets each "
            "step's stability check)"
        )


def as_devices(devices) -> tuple[jax.Device, ...] | None:
    """The ``devices`` argument of a run as a tuple of devices (``None`` stays ``None``).

    Args:
        devices: ``None``, a count ``k`` (the first ``k`` of ``jax.devices()``: with several
            processes, of all of them), or a sequence of devices.

    Returns:
        ``None`` or a tuple of distinct devices.

    Raises:
        ValueError: anything else, or more devices than there are.
    """
    if devices is None:
        return None
    if isinstance(devices, int | np.integer) and not isinstance(devices, bool):
        every = jax.devices()
        if not 1 <= devices <= len(every):
            raise ValueError(
                f"devices must be a count from 1 to {len(every)} (jax.devices()), or a sequence of "
                f"devices, got {devices}"
            )
        return tuple(every[: int(devices)])
    return check_devices(devices)


def save_fields(state: State, fields: Sequence[str]) -> dict[str, Array]:
    """The named fields of ``state`` that the run has (``C``, ``corners``, ``x_traction``, ``e`` and
    ``internal`` may be ``None`` and are then left out; ``internal`` gives one entry
    ``internal.<variable>`` per variable).

    Args:
        state: the state.
        fields: names of ``State`` fields (``STATE_FIELDS``).

    Returns:
        Field name to array.
    """
    out = {}
    for name in fields:
        value = getattr(state, name)
        if isinstance(value, dict):
            out.update({f"{name}.{k}": v for k, v in value.items()})
        elif value is not None:
            out[name] = value
    return out


# Reverse mode stores the carried state at every block end and one block's per-step residuals, so
# memory is (n / b) s + b r, least at b = sqrt(n s / r). Measured on the 1D step (1,000 particles,
# experiments/grad_memory.py), residuals are r ~ 8 s (331 KB against ~40 KB per step).
RESIDUAL_TO_STATE = 8


def checkpoint_block(checkpoint: bool | int | np.integer | None, steps: int) -> int | None:
    """Steps per checkpointed block of reverse mode.

    Args:
        checkpoint: ``True`` for ``ceil(sqrt(steps / 8))`` (memory ~ sqrt(steps)), an int for that
            block length, ``False`` or ``None`` for no checkpointing.
        steps: steps of the run.

    Returns:
        The block length, or ``None``.
    """
    if checkpoint is None or checkpoint is False:
        return None
    if checkpoint is True:
        return max(1, math.ceil(math.sqrt(steps / RESIDUAL_TO_STATE)))
    return int(checkpoint)  # a NumPy integer too: the block length is static


def advance(
    model: Model,
    setup: Setup,
    state: State,
    dt: Float[Array, ""] | ToEnd,
    steps: int,
    saveat: SaveAt,
    checkpoint: int | None = None,
    limit: Int[Array, ""] | None = None,
) -> tuple[State, dict[str, Array] | None]:
    """Take ``steps`` steps from ``state`` in one scan (the loop every driver has in common).

    The particles are padded with inert copies to a multiple of 8 a device (``pad_particles``), and
    over several devices laid out over them (``shard_particles``); the state returned and the fields
    saved hold the real particles only.

    Args:
        model: the run.
        setup: what it derives once (``jaxmpm.setup(model)``).
        state: the state to start from.
        dt: the time step, or a ``ToEnd`` for CFL-limited steps to an end time.
        steps: how many steps (static).
        saveat: with ``every=k``, the named fields after every k-th step are returned.
        checkpoint: block length of checkpointed reverse mode, or ``None``.
        limit: steps with ``state.step >= limit`` are masked (not taken), so that every chunk of a
            chunked run has the same length and compiles once; ``None`` for no limit.

    Returns:
        ``(state, saved)``, ``saved`` a dict of fields with a leading axis ``steps // k``, or ``None``.
    """

    n_real = state.x.shape[0]
    setup, state = pad_particles(model, setup, state)
    n_particles = state.x.shape[0]
    setup = eqx.tree_at(lambda z: z.body, setup, shard_particles(model, setup.body, n_particles))
    state = shard_particles(model, state, n_particles)

    def one(state, _):
        return shard_particles(model, taken(state), n_particles), None

    def taken(state):
        if not isinstance(dt, ToEnd):
            return take_step(model, setup, state, dt, limit)
        remaining = dt.t_end - state.t
        active = remaining > 0

        def take(st):
            h_dt = stable_dt(model, setup, st, dt.cfl)
            last = h_dt >= remaining
            dt_n = jnp.where(active & last, remaining, h_dt)  # past the end: a harmless step, discarded
            t_new = jnp.where(last, dt.t_end, st.t + dt_n)  # lands on t_end exactly
            return take_step(model, setup, st, dt_n, limit, active=active, t_new=t_new)

        # Past t_end (or after a breakdown) nothing changes: lax.cond skips the step's work, its
        # stable step included, so a generous max_steps costs little. (Under vmap the branches become
        # a select and both run.)
        go = active & (state.status == 0)
        return jax.lax.cond(go, take, lambda st: st, state)

    def scan(state, n):
        return jax.lax.scan(one, state, None, length=n)[0] if n > 0 else state

    def run(state, n):
        # Reverse mode through a scan stores every step's residuals. With a block of b steps under
        # jax.checkpoint, only the states at block ends are stored; the backward pass recomputes one
        # block at a time, so memory goes as (n / b) states + b steps of residuals, for the price of
        # one extra forward pass (Griewank & Walther, "Evaluating derivatives", ch. 12).
        if checkpoint is None or n <= checkpoint:
            return scan(state, n)
        blocks, rem = divmod(n, checkpoint)
        block = jax.checkpoint(lambda st, _: (scan(st, checkpoint), None), prevent_cse=False)
        state = jax.lax.scan(block, state, None, length=blocks)[0]
        return scan(state, rem)

    def real(state):  # the real particles, laid out as the caller's state
        return shard_particles(model, unpad_particles(state, n_real), n_real)

    if saveat.every is None:
        return real(run(state, steps)), None
    k = saveat.every
    n_out, rem = divmod(steps, k)

    def block(state, _):
        state = run(state, k)
        out = save_fields(unpad_particles(state, n_real), saveat.fields)
        if isinstance(dt, ToEnd):
            out["t"] = state.t
        return state, out

    def blocks(state, m):  # m save intervals of k steps, and what each saves
        return jax.lax.scan(block, state, None, length=m)

    if checkpoint is None or k > checkpoint or n_out * k <= checkpoint:
        state, saved = blocks(state, n_out)
    else:
        # Save intervals no longer than a checkpoint block (each scanned plainly by run) are
        # checkpointed in groups of a block's length, so that reverse mode stores the state at group
        # ends only, as without a history.
        g = checkpoint // k
        groups, left = divmod(n_out, g)
        group = jax.checkpoint(lambda st, _: blocks(st, g), prevent_cse=False)
        state, saved = jax.lax.scan(group, state, None, length=groups)
        saved = jax.tree.map(lambda a: a.reshape((groups * g, *a.shape[2:])), saved)
        if left:
            state, more = blocks(state, left)
            saved = jax.tree.map(lambda a, b: jnp.concatenate([a, b]), saved, more)
    return real(run(state, rem)), saved


def finish_to_end(state: State, dt: ToEnd) -> State:
    """The final state of a run to ``dt.t_end``: if its ``max_steps`` ran out before ``t_end``, that
    is a failure of the run (``MAX_STEPS``, at the step after the last), not of a particle.

    Args:
        state: the state after the run's last step.
        dt: the run's ``ToEnd``.

    Returns:
        ``state``, its status and failure step set when it fell short of ``t_end``.
    """
    short = (state.status == 0) & (state.t < dt.t_end)
    return eqx.tree_at(
        lambda z: (z.status, z.fail_step),
        state,
        (
            jnp.where(short, st_bits.MAX_STEPS, state.status),
            jnp.where(short, state.step + 1, state.fail_step),
        ),
    )


def run_scan(
    model: Model, dt: Float[Array, ""] | ToEnd, steps: int, saveat: SaveAt, checkpoint: int | None
) -> Solution:
    """One whole run of ``model`` from its initial state, traceable (``simulate`` compiles it).

    Args:
        model: the run.
        dt: the time step, or a ``ToEnd``.
        steps: steps (with a ``ToEnd``: ``max_steps``), static.
        saveat: what to keep besides the final state.
        checkpoint: block length of checkpointed reverse mode (``checkpoint_block``), or ``None``.

    Returns:
        The ``Solution``, its status recording any failure (nothing is raised).
    """
    s = setup(model)
    state0 = start_state(model, s)  # (advance lays the particles out over model.devices)
    state, saved = advance(model, s, state0, dt, steps, saveat, checkpoint)
    if isinstance(dt, ToEnd):
        state = finish_to_end(state, dt)
    if saved is None:
        return Solution(state, s.body, None, None)
    first = save_fields(state0, saveat.fields)
    if not first:  # at trace time: before anything runs
        raise ValueError(
            f"SaveAt(fields={saveat.fields!r}) names no field this run has (C is APIC's, corners "
            "an interpolator's that tracks them (MPQ, CPDI2), e a material's with an energy equation, "
            "internal one with history variables, x_traction a scene's with tractions): the history "
            "would be empty"
        )
    history = {name: jnp.concatenate([first[name][None], saved[name]]) for name in first}
    if isinstance(dt, ToEnd):
        ts = jnp.concatenate([state0.t[None], saved["t"]])
    else:
        frame_steps = jnp.arange(steps // saveat.every + 1, dtype=state.step.dtype) * saveat.every
        ts = frame_steps.astype(dt.dtype) * dt  # as each step sets its t: step * dt
        # After a breakdown the state stays at its last good step, and every later save repeats
        # it: those frames carry its time, not one the run never reached.
        ts = jnp.where(frame_steps <= state.step, ts, state.t.astype(ts.dtype))
    return Solution(state, s.body, ts, history)


_run_scan_jit = eqx.filter_jit(run_scan)


def _energy(sol: Solution, p: int, scene: AbstractScene | None) -> str:
    """``, region k, e = ...`` for a particle of a body of regions ("" otherwise); ``e`` only where
    the particle's material carries an energy (a region of a model of ``F`` alone carries none)."""
    region = None if sol.body.region is None else int(host(sol.body.region)[p])
    out = "" if region is None else f", region {region}"
    if sol.state.e is None:
        return out
    if region is not None and scene is not None and scene.regions is not None:
        if not isinstance(scene.regions()[region].material, AbstractEOS):
            return out
    return out + f", e = {float(host(sol.state.e)[p]):.6g}"


def failure_message(
    sol: Solution, dt: float | Float[Array, ""] | None, scene: AbstractScene | None = None
) -> str:
    """The message of a breakdown: the step, the time, the first failing particle and the quantities.

    Args:
        sol: a solution whose status is not 0.
        dt: the fixed time step (a number, or a tracer under ``jax.grad`` in ``dt``: the time is then
            given in steps of it), or ``None`` for a run to an end time (variable steps).
        scene: the run's scene, if known: a particle's ``e`` is then given only where its region's
            material carries an energy.

    Returns:
        The message of ``SimulationError``.
    """
    f = sol.failure()
    p = f["particle"]
    start = f["step"] == 0  # the initial state failed its checks: no step was taken
    last = max(f["step"] - 1, 0)
    st = sol.state
    # The particle is the first of the lowest bit's; a step that failed several checks may have
    # failed the others at other particles.
    first, *others = f["quantities"]
    lines = (
        first
        if not others
        else f"{first}; in the same step, at this particle or others: {' and '.join(others)}"
    )
    # Under a transformation that traces the state but not the status (jax.grad, jax.jvp outside
    # jit), the step, the particle and the quantities are known, the state's values are not.
    traced = not all(is_concrete(a) for a in jax.tree.leaves((st, sol.body)))
    if dt is not None and is_concrete(dt):
        when = f"t = {f['step'] * float(dt):.6g}"
    elif dt is not None:
        when = f"t = {f['step']} dt"
    else:
        when = "a variable step" if traced else f"after t = {float(st.t):.6g}"
    if traced:
        who = "the run" if p < 0 else f"particle {p} (at step {last})"
        if start:
            return f"jaxmpm: the initial state is not valid: {who}: {lines}. No step was taken."
        return (
            f"jaxmpm: the run broke down at step {f['step']} ({when}): {who}: {lines}. The state is "
            f"traced by a transformation (jax.grad or jax.jvp); run without it to read the state of "
            f"the last good step ({last})."
        )
    if p < 0:
        who = "the run"
    else:
        # host(...): the whole array on this process, also from several processes' devices
        X, x, F = host(sol.body.X)[p], host(st.x)[p], host(st.F)[p]
        if st.x.shape[1] == 1:
            who = (
                f"particle {p} (X = {float(X[0]):.6g}, x = {float(x[0]):.6g}, F = {float(F[0, 0]):.6g}"
                f"{_energy(sol, p, scene)} at step {last})"
            )
        else:  # 2D, 3D: vectors, and J = det F

            def vec(a):
                return "(" + ", ".join(f"{float(c):.6g}" for c in a) + ")"

            J = float(det(jnp.asarray(F)))
            who = (
                f"particle {p} (X = {vec(X)}, x = {vec(x)}, J = det F = {J:.6g}"
                f"{_energy(sol, p, scene)} at step {last})"
            )
    if start:
        return (
            f"jaxmpm: the initial state is not valid: {who}: {lines}. No step was taken; the initial "
            f"state is in error.solution."
        )
    return (
        f"jaxmpm: the run broke down at step {f['step']} ({when}): {who}: "
        f"{lines}. The state of the last good step ({last}) is in error.solution."
    )


def _finish(sol: Solution, dt, throw: bool, model: Model) -> Solution:
    if not throw:  # (simulate checks that throw is a bool before the run)
        return sol
    if is_concrete(sol.state.status):  # also under jax.grad or jax.jvp outside a jit
        if int(sol.state.status) != 0:
            raise SimulationError(
                failure_message(sol, float(dt) if is_concrete(dt) and dt is not None else dt, model.scene),
                sol,
            )
        return sol
    if model.devices is not None and len(model.devices) > 1:
        # eqx.error_if raises on one device while the others wait for it in the step's all-reduce:
        # the process would abort (a rendezvous timeout), with nothing to catch
        raise ValueError(
            "a run over several devices cannot raise its breakdown from inside jax.jit or jax.vmap (the "
            "device that finds it would stop while the others wait for it, and the process would abort): "
            "pass throw=False and read Solution.state.status or Solution.failure(), or call simulate "
            "outside the transformation"
        )
    message = (
        "jaxmpm: the run broke down: a step failed one of its checks (F <= 0, a non-finite state, a "
        "particle leaving the grid, dt beyond the stable limit, negative internal energy, ...; see "
        "jaxmpm.status). Inside a jit the step, particle and quantity cannot be named: run with "
        "throw=False and read Solution.failure(), or call simulate outside the jit."
    )
    # eqx.error_if ties the check to the solution's values, and a derivative under jax.jit uses none
    # of them (jax.jit(jax.grad(...)) of a sum of positions needs no position): the check would be
    # dropped with them, and the derivative returned as if the run had finished. A debug callback
    # is an effect, which JAX keeps.
    jax.debug.callback(functools.partial(_raise_if_broken, message), sol.state.status)
    return eqx.error_if(sol, sol.state.status != 0, message)


def _raise_if_broken(message: str, status) -> None:
    """Raise ``RuntimeError(message)`` if a status (or any of a batch's) is not 0 (a host callback)."""
    if np.any(np.asarray(status) != 0):
        raise RuntimeError(message)


@typing.no_type_check  # validates every argument itself, raising ValueError (see _validate)
def prepare(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    *,
    dt=None,
    steps: int | None = None,
    t_end=None,
    cfl=None,
    max_steps: int | None = None,
    transfer: AbstractTransfer | None = None,
    artificial_cells: int = 0,
    saveat: SaveAt | None = None,
    cfl_limit: float | None = 1.0,
    ordering: str = "usl",
    checkpoint: bool | int = False,
    viscosity: ArtificialViscosity | None = None,
    volume_average: str | None = None,
    devices=None,
) -> tuple[Model, Float[Array, ""] | ToEnd, int, SaveAt]:
    """Validate a run's arguments (before anything is traced) and build its ``Model``.

    Args:
        scene, interpolator, dt, steps, t_end, cfl, max_steps, transfer, artificial_cells, saveat,
            cfl_limit, ordering, checkpoint, viscosity, volume_average, devices: as for ``simulate``.

    Returns:
        ``(model, dt, steps, saveat)``: ``dt`` an array, or a ``ToEnd`` for a run to ``t_end`` (then
        ``steps`` is ``max_steps``); ``saveat`` the default ``SaveAt()`` when none was given.

    Raises:
        ValueError: bad input (``cfl`` or ``max_steps`` with a run of fixed steps among it), or a
            run too large for the memory of the device (estimated from its sizes, before anything
            is allocated).
    """
    transfer = FLIP() if transfer is None else transfer
    saveat = SaveAt() if saveat is None else saveat
    if not isinstance(saveat, SaveAt):
        raise ValueError(
            f"saveat must be None or a jaxmpm.SaveAt (SaveAt(every=k, fields=...)), got {saveat!r}"
        )
    if t_end is not None:
        if dt is not None or steps is not None:
            raise ValueError("give either dt and steps (fixed steps) or t_end, cfl and max_steps, not both")
        if max_steps is None:
            raise ValueError("max_steps (an integer >= 1, the bound of the scan) is required with t_end")
        cfl = DEFAULT_CFL if cfl is None else cfl
        for name, value in (("t_end", t_end), ("cfl", cfl)):
            check_positive(name, value)
            check_scalar(name, value, _SEVERAL)
        dt, steps = ToEnd(t_end=t_end, cfl=cfl), max_steps
    elif dt is None or steps is None:
        raise ValueError("give dt and steps (fixed steps), or t_end, cfl and max_steps (to an end time)")
    else:
        _refuse_to_end_options(cfl=cfl, max_steps=max_steps)
    if isinstance(scene, AbstractScene):
        for name, value in (("t_end", t_end), ("cfl", cfl)) if t_end is not None else (("dt", dt),):
            _check_resolved(name, value, scene.h.dtype)
    _validate(scene, interpolator, transfer, dt, steps, artificial_cells, cfl_limit, checkpoint, viscosity)
    if isinstance(dt, ToEnd) and cfl_limit is not None and is_concrete(cfl) and float(cfl) > cfl_limit:
        raise ValueError(
            f"cfl = {float(cfl):g} is above cfl_limit = {cfl_limit:g}: every full step would fail its "
            "stability check; give cfl <= cfl_limit (or cfl_limit=None to run without the check)"
        )
    steps, artificial_cells = int(steps), int(artificial_cells)  # NumPy integers too: both are static
    model = Model(
        scene,
        interpolator,
        transfer,
        artificial_cells,
        cfl_limit,
        ordering,
        viscosity,
        volume_average,
        as_devices(devices),
    )
    _memory.check_run(model, steps, saveat)
    return model, dt if isinstance(dt, ToEnd) else as_float(dt), steps, saveat


@typing.no_type_check  # validates every argument itself, raising ValueError (see _validate)
def simulate(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    *,
    dt=None,
    steps: int | None = None,
    t_end=None,
    cfl=None,
    max_steps: int | None = None,
    transfer: AbstractTransfer | None = None,
    artificial_cells: int = 0,
    saveat: SaveAt | None = None,
    cfl_limit: float | None = 1.0,
    ordering: str = "usl",
    checkpoint: bool | int = False,
    viscosity: ArtificialViscosity | None = None,
    volume_average: str | None = None,
    devices=None,
    throw: bool = True,
) -> Solution:
    """Run explicit steps in one compiled ``lax.scan``: ``steps`` steps of ``dt``, or to ``t_end``.

    Compiled once per structure (scene class, static sizes, method choices, ``steps`` or
    ``max_steps``, ``saveat``): new parameter values (``beta``, ``h``, ``dt``, ``t_end``, ``cfl``,
    ...) reuse the compiled run. Works under ``jax.grad``, ``jax.vmap`` and ``jax.jit``.

    Args:
        scene: the scene and its parameters.
        interpolator: ``SPQ()``, ``GIMP()``, ``GIMP(contiguous=True)``, ``CPDI()``, ``MPQ()``, ... (one of
            ``INTERPOLATORS``).
        dt: time step (> 0), with ``steps``. A concrete ``dt`` is checked before anything is traced;
            a traced one (under ``jax.jit`` or ``jax.vmap`` over ``dt``) is not, and a ``dt <= 0``
            there runs backwards or stands still with status 0 (a NaN one breaks down, non-finite).
        steps: the number of steps of ``dt`` (>= 0), static: a new count compiles a new run.
        t_end: instead of ``dt`` and ``steps``, run to this time with the CFL-limited step
            ``cfl h / max_p(c_p + |v_p|)`` recomputed every step (``cfl``: default, or ``None``,
            0.5) in a scan of ``max_steps`` steps (required), the steps after ``t_end`` masked. A run
            that needs more steps stops at ``max_steps`` with the status ``MAX_STEPS``.
            Differentiable in ``t_end``, ``cfl`` and the scene's parameters (the step count is
            piecewise constant in them). ``cfl`` and ``max_steps`` belong to such a run alone: a run
            of fixed steps (``dt``, ``steps``) refuses them.
        cfl: with ``t_end``, the CFL number of each step (> 0; ``None``: 0.5).
        max_steps: with ``t_end``, the length of the scan (>= 1), static.
        transfer: ``FLIP()`` (default), ``PIC()`` or ``APIC()``.
        artificial_cells: layers of artificial cells at each free end (``jaxmpm.boundaries``; 0 on a
            scene without a free face, where they would add nothing).
        saveat: what to keep besides the final state (default: nothing). With ``t_end``, the saved
            times ``Solution.ts`` are those of the saved steps.
        cfl_limit: fail a step whose ``dt`` exceeds ``cfl_limit h / max(c + |v|)``; ``None`` to
            allow any step.
        ordering: ``"usl"`` (default) or ``"musl"`` (see ``jaxmpm.Model``).
        checkpoint: bounded-memory reverse mode: ``True`` runs the loop in checkpointed blocks of
            ``ceil(sqrt(steps / 8))`` steps (memory ~ sqrt(steps)), an int sets the block length,
            ``False`` (default) stores every step's residuals (fastest for short runs). Results
            agree to round-off.
        viscosity: ``ArtificialViscosity()`` to damp the ringing behind shocks; ``None`` (default).
        volume_average: ``None`` (default), ``"cell"`` or ``"node"``: the stress at the volume-averaged
            ``F`` (J-bar, ``jaxmpm.Model``); refused for regions of different materials.
        devices: ``None`` (default: one device), a count ``k`` (the first ``k`` of ``jax.devices()``)
            or a sequence of devices: the particles are sharded over them (padded with inert copies
            of the last particle to an equal share a device, which the solution leaves out), the
            grid replicated and its sums added across them each step. Equal to the run on one
            device to round-off.
        throw: raise on breakdown (default); with ``False`` return the solution with its status.
            A run over several devices inside ``jax.jit`` or ``jax.vmap`` needs ``False``.

    Returns:
        The ``Solution``.

    Raises:
        ValueError: bad input, before anything is traced: among others a scene class for a scene
            object, ``cfl`` or ``max_steps`` with ``dt`` and ``steps``, or a ``checkpoint`` that is
            not ``True``, ``False`` or an integer >= 1; and while the run is traced, before anything
            is compiled or run, a ``saveat`` that names no field the run has (``C`` of a FLIP run),
            or several devices with ``throw=True`` inside ``jax.jit`` or ``jax.vmap`` (only the
            trace tells).
        SimulationError: the run broke down; ``error.solution`` holds the last good state (also
            under ``jax.grad`` or ``jax.jvp`` outside a jit, where the state is traced).
    """
    model, dt_arr, n, saveat = prepare(
        scene,
        interpolator,
        dt=dt,
        steps=steps,
        t_end=t_end,
        cfl=cfl,
        max_steps=max_steps,
        transfer=transfer,
        artificial_cells=artificial_cells,
        saveat=saveat,
        cfl_limit=cfl_limit,
        ordering=ordering,
        checkpoint=checkpoint,
        viscosity=viscosity,
        volume_average=volume_average,
        devices=devices,
    )
    _check_throw(throw)
    sol = _run_scan_jit(model, dt_arr, n, saveat, checkpoint_block(checkpoint, n))
    return _finish(sol, dt, throw, model)


def _check_throw(throw) -> None:
    if not isinstance(throw, bool | np.bool_):
        raise ValueError(f"throw must be True or False, got {throw!r}")


@typing.no_type_check  # validates every argument itself, raising ValueError (see _validate)
def simulate_timed(
    scene: AbstractScene, interpolator: AbstractInterpolator, *, throw: bool = True, **kwargs
) -> tuple[Solution, float, float]:
    """``simulate`` with compile time and run time measured apart (ahead-of-time compilation).

    Args:
        scene: as for ``simulate``.
        interpolator: as for ``simulate``.
        throw: as for ``simulate``.
        **kwargs: as for ``simulate``.

    Returns:
        ``(solution, compile_s, wall_s)``: ``compile_s`` covers tracing, lowering and XLA
        compilation; ``wall_s`` the compiled run alone, to results ready on the host.

    Raises:
        ValueError: bad input, before anything is traced (as for ``simulate``).
        TypeError: a keyword ``simulate`` does not take (the message lists those it takes).
        SimulationError: the run broke down; ``error.solution`` holds the last good state.
    """
    check_keywords("simulate_timed", kwargs, simulate)
    model, dt_arr, n, saveat = prepare(scene, interpolator, **kwargs)
    _check_throw(throw)
    t0 = time.perf_counter()
    block = checkpoint_block(kwargs.get("checkpoint", False), n)
    compiled = _run_scan_jit.lower(model, dt_arr, n, saveat, block).compile()
    t1 = time.perf_counter()
    sol = jax.block_until_ready(compiled(model, dt_arr, n, saveat, block))
    t2 = time.perf_counter()
    return _finish(sol, kwargs.get("dt"), throw, model), t1 - t0, t2 - t1
