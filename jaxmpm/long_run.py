"""Long runs: chunks compiled once, a progress bar, crash-safe checkpoints, resume, saved outputs.

``run`` takes the same arguments as ``simulate`` and drives the same scan (``advance``) in chunks of
``chunk`` steps. Every chunk has the same length, and steps past the end are masked, so the chunk
compiles once. Between chunks the host updates a progress bar and, every ``checkpoint_every``
chunks, writes the whole run to ``out`` atomically. That covers the state (MPQ corners, APIC
matrices and traction points included), status, step count, parameters, and the history so far. A
run that breaks down stops at its last good step (the failing step is never taken), saves that,
and says where. ``resume(path)`` continues a saved run with the same chunk boundaries and the same
compiled chunk, so a resumed run equals an uninterrupted one bit for bit.

The file format (NumPy ``.npz``; open it with ``numpy.load`` alone, no pickles):

- ``meta``: a JSON string, ``json.loads(str(f["meta"]))``, with ``format`` ("jaxmpm-run"),
  ``format_version``, ``jaxmpm_version``, ``scene`` and ``params`` (every scene parameter),
  ``interpolator`` (name and options), ``transfer``, ``artificial_cells``, ``ordering``,
  ``cfl_limit``, ``dt``, ``steps`` (the target), ``chunk``, ``saveat``, ``checkpoint_every``,
  ``step`` (steps done), ``complete``, ``status`` and ``failure`` (or null), ``saved_at`` (UTC).
- ``state.<name>``: the state at ``step``: ``t``, ``step``, ``x`` (n, dim), ``v`` (n, dim),
  ``F`` (n, dim, dim), ``sigma`` (n, dim, dim), and where the run has them ``C``, ``corners``,
  ``x_traction``; ``status``, ``fail_step``, ``fail_particle``.
- ``body.X`` (reference positions, n x dim) and ``body.boundary`` (boundary-cell particles).
- ``history.ts`` and ``history.<name>`` (leading time axis) when the run saved a history.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import os
import pathlib
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import status as st_bits
from ._checks import check_int
from ._simulate import SaveAt, SimulationError, Solution, advance, failure_message, prepare, save_fields
from ._step import initial_state, setup
from .interpolators import INTERPOLATORS, AbstractInterpolator
from .particles import State
from .scenes import SCENES, AbstractScene
from .transfers import TRANSFERS

FORMAT = "jaxmpm-run"
"""The ``format`` a saved run's metadata carries."""
FORMAT_VERSION = 1
"""The version of the file format this jaxmpm writes (and the newest it reads)."""
STATE_NAMES = tuple(f.name for f in dataclasses.fields(State))
"""Every ``State`` field, each saved as ``state.<name>`` where the run has it."""


@eqx.filter_jit
def _start(model):
    prepared = setup(model)
    return initial_state(model, prepared), prepared.body


@eqx.filter_jit
def _chunk(model, dt, state, limit, n: int, saveat: SaveAt):
    return advance(model, setup(model), state, dt, n, saveat, None, limit)


def show_progress(progress: bool | None) -> bool:
    """Whether to show a progress bar.

    Args:
        progress: ``True`` or ``False`` to decide, or ``None``: the environment variable
            ``JAXMPM_PROGRESS`` (``0``, ``false``, ``no`` or empty for no) if set, else a bar in a
            notebook or on a terminal and none in pipes or CI.

    Returns:
        Whether to show it.
    """
    if progress is not None:
        return progress
    env = os.environ.get("JAXMPM_PROGRESS")
    if env is not None:
        return env not in ("0", "", "false", "no")
    return "ipykernel" in sys.modules or sys.stderr.isatty()


def _progress_bar(total: int, initial: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="step",
        disable=not enabled,
        dynamic_ncols=True,
        desc="jaxmpm",
        leave=True,
    )


def _interpolator_meta(interp: AbstractInterpolator) -> dict:
    """The interpolator's registry name and its options (its static fields), for a saved run."""
    return dict(name=interp.name, **{f.name: getattr(interp, f.name) for f in dataclasses.fields(interp)})


def _interpolator_from(meta: dict) -> AbstractInterpolator:
    """The interpolator of ``_interpolator_meta``, rebuilt from the registry ``INTERPOLATORS``."""
    options = {k: v for k, v in meta.items() if k != "name"}
    return INTERPOLATORS[meta["name"]](**options)


def _scene_params(scene) -> dict:
    named = scene.parameters()
    for f in dataclasses.fields(scene):
        if f.name not in named and getattr(scene, f.name) is not f.default:
            raise ValueError(
                f"a saved run records the scene by its parameters, and {f.name} of {scene.name} is not one "
                f"(a Python function cannot be saved); run it with simulate instead"
            )
    return scene.parameter_values()


def _write_npz(path: pathlib.Path, arrays: dict) -> None:
    """Write ``arrays`` to ``path`` atomically: a temporary file, fsync, then an atomic rename.

    A crash at any point leaves either the previous file or the new one, never a broken one.
    """
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    try:  # make the rename itself durable
        fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:  # pragma: no cover - some filesystems do not allow fsync on a directory
        pass


class _Recorder:
    """Host-side record of a run: its settings, its history so far, and how to save it."""

    def __init__(self, meta: dict, body, history: dict | None, ts: list | None):
        self.meta = meta
        self.body = body
        self.history = history
        self.ts = ts

    def add(self, saved: dict | None, first_step: int, done: int, every: int | None, dt: float) -> None:
        if saved is None:
            return
        for i in range(next(iter(saved.values())).shape[0]):
            nominal = first_step + (i + 1) * every
            if nominal > done:  # masked tail or frozen after a failure: not a state the run reached
                break
            for name, arr in saved.items():
                self.history[name].append(np.asarray(arr[i]))
            self.ts.append(nominal * dt)

    def solution(self, state: State) -> Solution:
        if self.history is None:
            return Solution(state, self.body, None, None)
        hist = {k: jnp.asarray(np.stack(v)) for k, v in self.history.items()}
        return Solution(state, self.body, jnp.asarray(np.asarray(self.ts)), hist)

    def save(self, path: pathlib.Path, state: State) -> None:
        step = int(state.step)
        status = int(state.status)
        meta = dict(
            self.meta,
            step=step,
            complete=step >= self.meta["steps"] and status == 0,
            status=status,
            failure=None,
            saved_at=datetime.datetime.now(datetime.timezone.utc).isoformat(),
        )
        if status:
            meta["failure"] = dict(
                step=int(state.fail_step),
                particle=int(state.fail_particle),
                quantities=st_bits.describe(status),
            )
        arrays = {"meta": np.asarray(json.dumps(meta))}
        for name in STATE_NAMES:
            value = getattr(state, name)
            if value is not None:
                arrays[f"state.{name}"] = np.asarray(value)
        arrays["body.X"] = np.asarray(self.body.X)
        arrays["body.boundary"] = np.asarray(self.body.boundary)
        if self.history is not None:
            arrays["history.ts"] = np.asarray(self.ts, dtype=np.float64)
            for name, items in self.history.items():
                arrays[f"history.{name}"] = np.stack(items)
        _write_npz(path, arrays)


def _drive(
    model, dt_arr, saveat, state, rec: _Recorder, *, steps, chunk, out, checkpoint_every, progress, throw
) -> tuple[Solution, float, float]:
    every = saveat.every
    dt = float(dt_arr)
    n_particles = rec.body.n
    limit = jnp.asarray(steps, dtype=jnp.int32)
    done = int(state.step)
    t_compile = time.perf_counter()
    compiled = _chunk.lower(model, dt_arr, state, limit, chunk, saveat).compile()  # once, for every chunk
    t_start = time.perf_counter()
    compile_s = t_start - t_compile
    bar = _progress_bar(steps, done, show_progress(progress))
    chunks_done = 0
    try:
        while done < steps and int(state.status) == 0:
            t0 = time.perf_counter()
            state, saved = compiled(model, dt_arr, state, limit, chunk, saveat)
            state = jax.block_until_ready(state)
            before, done = done, int(state.step)
            rec.add(None if saved is None else jax.device_get(saved), before, done, every, dt)
            chunks_done += 1
            elapsed = time.perf_counter() - t0
            bar.update(done - before)
            bar.set_postfix_str(
                f"t={float(state.t):.4g}  {n_particles * (done - before) / elapsed / 1e6:.1f} "
                "M particle-steps/s",
                refresh=False,
            )
            if out is not None and checkpoint_every and chunks_done % checkpoint_every == 0:
                rec.save(out, state)
    finally:
        bar.close()
    if out is not None:
        rec.save(out, state)
    wall_s = time.perf_counter() - t_start
    sol = rec.solution(state)
    if int(state.status) and throw:
        where = f" Everything up to it is saved in {out}." if out is not None else ""
        raise SimulationError(failure_message(sol, dt) + where, sol)
    return sol, compile_s, wall_s


def run(scene: AbstractScene, interpolator: AbstractInterpolator, **kwargs) -> Solution:
    """``simulate`` in chunks, with progress, checkpoints and a saved result.

    Args:
        scene: as for ``run_timed``.
        interpolator: as for ``run_timed``.
        **kwargs: as for ``run_timed``.

    Returns:
        The ``Solution``.

    Raises:
        ValueError: bad input, before anything is traced.
        SimulationError: the run broke down (after saving it, with ``out``).
    """
    return run_timed(scene, interpolator, **kwargs)[0]


def run_timed(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    *,
    dt,
    steps: int,
    chunk: int = 1000,
    transfer=None,
    artificial_cells: int = 0,
    saveat: SaveAt | None = None,
    cfl_limit: float | None = 1.0,
    ordering: str = "usl",
    out: str | os.PathLike | None = None,
    checkpoint_every: int | None = None,
    progress: bool | None = None,
    throw: bool = True,
) -> tuple[Solution, float, float]:
    """``simulate`` in chunks of ``chunk`` steps, with progress, checkpoints and a saved result.

    Args:
        scene: as for ``simulate``.
        interpolator: as for ``simulate``.
        dt: as for ``simulate``.
        steps: as for ``simulate``.
        transfer: as for ``simulate``.
        artificial_cells: as for ``simulate``.
        saveat: as for ``simulate``. With ``saveat.every``, ``chunk`` must be a multiple of it.
        cfl_limit: as for ``simulate``.
        ordering: as for ``simulate``.
        chunk: steps per compiled chunk (the chunk compiles once; the last is masked past the end).
        out: a ``.npz`` file to write the run to (at the end, at checkpoints, and on breakdown).
        checkpoint_every: write ``out`` every this many chunks (``None``: only at the end).
        progress: show a progress bar (steps, simulated time, particle-steps per second). ``None``
            shows it in a terminal or notebook and not in pipes or CI; the environment variable
            ``JAXMPM_PROGRESS=0`` or ``1`` overrides that.
        throw: raise ``SimulationError`` on breakdown (after saving); else return with the status.

    Returns:
        ``(solution, compile_s, wall_s)``: the ``Solution`` (the same state as ``simulate`` gives),
        the time of the chunk's one compilation, and the time of everything after it.

    Raises:
        ValueError: bad input, before anything is traced.
        SimulationError: the run broke down (after saving it, with ``out``).
    """
    check_int("chunk", chunk, 1)
    if checkpoint_every is not None:
        check_int("checkpoint_every", checkpoint_every, 1)
        if out is None:
            raise ValueError("checkpoint_every needs out=FILE to write the checkpoints to")
    model, dt_arr, _, saveat = prepare(
        scene,
        interpolator,
        dt=dt,
        steps=steps,
        transfer=transfer,
        artificial_cells=artificial_cells,
        saveat=saveat,
        cfl_limit=cfl_limit,
        ordering=ordering,
    )
    if saveat.every is not None and chunk % saveat.every:
        raise ValueError(f"chunk must be a multiple of saveat.every, got chunk={chunk}, every={saveat.every}")
    out = None if out is None else pathlib.Path(out)
    state, body = _start(model)
    meta = dict(
        format=FORMAT,
        format_version=FORMAT_VERSION,
        jaxmpm_version=_version(),
        scene=scene.name,
        params=_scene_params(scene),
        interpolator=_interpolator_meta(interpolator),
        transfer=model.transfer.name,
        artificial_cells=artificial_cells,
        ordering=ordering,
        cfl_limit=cfl_limit,
        dt=float(dt_arr),
        steps=steps,
        chunk=chunk,
        saveat=dict(every=saveat.every, fields=list(saveat.fields)),
        checkpoint_every=checkpoint_every,
    )
    history = ts = None
    if saveat.every is not None:
        first = jax.device_get(save_fields(state, saveat.fields))
        history = {k: [np.asarray(v)] for k, v in first.items()}
        ts = [0.0]
    rec = _Recorder(meta, body, history, ts)
    return _drive(
        model,
        dt_arr,
        saveat,
        state,
        rec,
        steps=steps,
        chunk=chunk,
        out=out,
        checkpoint_every=checkpoint_every,
        progress=progress,
        throw=throw,
    )


def load(path: str | os.PathLike) -> tuple[Solution, dict]:
    """Read a run saved by ``run`` (or ``resume``).

    Args:
        path: the saved run.

    Returns:
        ``(solution, meta)``: its ``Solution`` and its ``meta`` dict (see the module's docstring).

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: the file is not a jaxmpm run, or was written by a newer jaxmpm.
    """
    sol, meta, _ = _load(pathlib.Path(path))
    return sol, meta


def _load(path: pathlib.Path):
    if not path.exists():
        raise FileNotFoundError(f"no saved run at {path}")
    with np.load(path, allow_pickle=False) as f:
        meta = json.loads(str(f["meta"]))
        if meta.get("format") != FORMAT:
            raise ValueError(f"{path} is not a jaxmpm run file (format {meta.get('format')!r})")
        if meta.get("format_version", 0) > FORMAT_VERSION:
            raise ValueError(
                f"{path} was written by a newer jaxmpm (format version {meta['format_version']})"
            )
        arrays = {k: f[k] for k in f.files if k != "meta"}
    scene = SCENES[meta["scene"]](**meta["params"])
    interp = _interpolator_from(meta["interpolator"])
    model, dt_arr, _, saveat = prepare(
        scene,
        interp,
        dt=meta["dt"],
        steps=meta["steps"],
        transfer=TRANSFERS[meta["transfer"]](),
        artificial_cells=meta["artificial_cells"],
        saveat=SaveAt(every=meta["saveat"]["every"], fields=tuple(meta["saveat"]["fields"])),
        cfl_limit=meta["cfl_limit"],
        ordering=meta["ordering"],
    )
    fresh, body = _start(model)
    fields = {}
    for name in STATE_NAMES:
        key = f"state.{name}"
        template = getattr(fresh, name)
        if (key in arrays) != (template is not None):
            raise ValueError(f"{path}: state.{name} does not match the run's settings")
        fields[name] = None if template is None else jnp.asarray(arrays[key], dtype=template.dtype)
    state = State(**fields)
    history = ts = None
    if saveat.every is not None:
        history = {
            k[len("history.") :]: list(arrays[k])
            for k in arrays
            if k.startswith("history.") and k != "history.ts"
        }
        ts = list(arrays["history.ts"])
    rec = _Recorder(
        {k: v for k, v in meta.items() if k not in ("step", "complete", "status", "failure", "saved_at")},
        body,
        history,
        ts,
    )
    return rec.solution(state), meta, (model, dt_arr, saveat, state, rec)


def resume(
    path: str | os.PathLike,
    *,
    out: str | os.PathLike | None = None,
    progress: bool | None = None,
    throw: bool = True,
) -> Solution:
    """Continue a run saved by ``run`` to its target step count, checkpointing as it was set up to.

    A resumed run equals the uninterrupted one bit for bit: the same chunk boundaries, the same
    compiled chunk, the state read back exactly. A run that had broken down is not continued: its
    failure is raised again (or returned with ``throw=False``).

    Args:
        path: the saved run.
        out: where to keep writing (default: ``path`` itself).
        progress: as for ``run``.
        throw: as for ``run``.

    Returns:
        The ``Solution`` of the whole run.

    Raises:
        SimulationError: the run broke down (now or before it was saved).
    """
    return resume_timed(path, out=out, progress=progress, throw=throw)[0]


def resume_timed(
    path: str | os.PathLike,
    *,
    out: str | os.PathLike | None = None,
    progress: bool | None = None,
    throw: bool = True,
) -> tuple[Solution, float, float, dict]:
    """``resume``, timed.

    Args:
        path: as for ``resume``.
        out: as for ``resume``.
        progress: as for ``resume``.
        throw: as for ``resume``.

    Returns:
        ``(solution, compile_s, wall_s, meta)``: as ``run_timed``, and the saved run's ``meta``.

    Raises:
        SimulationError: the run broke down (now or before it was saved).
    """
    path = pathlib.Path(path)
    sol, meta, (model, dt_arr, saveat, state, rec) = _load(path)
    out = path if out is None else pathlib.Path(out)
    return *_drive(
        model,
        dt_arr,
        saveat,
        state,
        rec,
        steps=meta["steps"],
        chunk=meta["chunk"],
        out=out,
        checkpoint_every=meta["checkpoint_every"],
        progress=progress,
        throw=throw,
    ), meta


def _version() -> str:
    from . import __version__

    return __version__
