"""Long runs: chunks compiled once, a progress bar, crash-safe checkpoints, resume, saved outputs.

``run`` takes the arguments of ``simulate`` for fixed steps (``dt`` and ``steps``; not ``t_end``,
``cfl``, ``max_steps``, ``checkpoint`` or ``volume_average``, see ``SIMULATE_ONLY``) and drives the
same scan (``advance``) in chunks of ``chunk`` steps. Every chunk has the same length, and steps
past the end are masked, so the chunk compiles once. Between chunks the host updates a progress bar
and, every ``checkpoint_every`` chunks, writes the whole run to ``out`` atomically. That covers the
state (MPQ corners, APIC matrices and traction points included), status, step count, parameters, and
the history so far. A run that breaks down stops at its last good step (the failing step is never
taken), saves that, and says where. ``resume(path)`` continues a saved run with the same chunk
boundaries and the same compiled chunk, so a resumed run equals an uninterrupted one bit for bit (a
run spread over several devices, ``devices=``, continues on as many). With several processes the
first writes the whole run and every process reads it.

The file format (NumPy ``.npz``; open it with ``numpy.load`` alone, no pickles):

- ``meta``: a JSON string, ``json.loads(str(f["meta"]))``, with ``format`` ("jaxmpm-run"),
  ``format_version``, ``jaxmpm_version``, ``scene`` and ``params`` (every scene parameter),
  ``interpolator`` (name and options), ``transfer``, ``artificial_cells``, ``ordering``,
  ``cfl_limit``, ``dt``, ``steps`` (the target), ``chunk``, ``saveat``, ``checkpoint_every``,
  ``viscosity`` (``[c_quad, c_lin]``, with ``c_shear`` third when there is a shear viscosity, or
  null; a file without it has none), ``devices`` (the count
  of devices the run was spread over, or null; a file without it ran on one), ``step`` (steps done),
  ``complete``, ``status`` and ``failure`` (or null), ``saved_at`` (UTC).
- ``state.<name>``: the state at ``step``: ``t``, ``step``, ``x`` (n, dim), ``v`` (n, dim),
  ``F`` (n, dim, dim), ``sigma`` (n, dim, dim), and where the run has them ``C``, ``corners``,
  ``x_traction``; ``status``, ``fail_step``, ``fail_particle``; ``e`` (n) where a material has an
  energy equation, and ``state.internal.<variable>`` (n) for each internal variable.
- ``body.X`` (reference positions, n x dim) and ``body.boundary`` (boundary-cell particles).
- ``history.ts`` and ``history.<name>`` (leading time axis) when the run saved a history.

Safety:

- ``run`` never replaces a file: if ``out`` exists it raises ``ValueError`` (naming the file and, for
  a checkpoint, its scene and step) unless ``overwrite=True``. An ``out`` in a folder that does not
  exist or cannot be written, or that is a folder, is a ``ValueError`` too; all of this before
  anything is compiled. ``resume`` keeps writing to its own file.
- ``load`` and ``resume`` check a file before using it: an empty, truncated or foreign file, a
  metadata that is not JSON or lacks keys, an unknown scene, interpolator or transfer, parameters
  the scene rejects, state arrays missing or of the wrong shape or dtype, and arrays that do not
  match what the metadata names, as far as the arrays tell without running the run again (``load``
  lists the checks and the settings they cannot see) each raise ``ValueError`` with one line naming
  the file and what is wrong. A missing file is a ``FileNotFoundError``.
- Ctrl-C (``KeyboardInterrupt``) stops a run within a moment (the host polls the running chunk
  instead of blocking on it), discards the chunk in flight, saves the last finished chunk to
  ``out`` (atomically, as every save; before the first chunk of this call there is none, and
  ``out`` keeps what it held) and raises ``Interrupted``, a ``KeyboardInterrupt`` with
  ``step``, ``saved_in`` and ``solution``; ``resume(out)`` then continues bit for bit. A run over
  several processes' devices finishes the chunk in flight instead (its collectives need every
  process), and all processes stop after the same chunk when any of them had a Ctrl-C.
"""

from __future__ import annotations

import dataclasses
import datetime
import errno
import json
import os
import pathlib
import signal
import sys
import tempfile
import threading
import time
import typing

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import multihost_utils

from . import status as st_bits
from ._checks import any_traced, check_bool, check_int, check_keywords
from ._files import write_whole
from ._simulate import SaveAt, SimulationError, Solution, advance, failure_message, prepare, save_fields
from ._step import initial_state, material_stress, place_particles, setup, shard_particles
from ._util import host
from .interpolators import INTERPOLATORS, AbstractInterpolator
from .particles import State
from .scenes import SCENES, AbstractScene
from .transfers import TRANSFERS
from .viscosity import ArtificialViscosity

FORMAT = "jaxmpm-run"
"""The ``format`` a saved run's metadata carries."""
FORMAT_VERSION = 1
"""The version of the file format this jaxmpm writes (and the newest it reads)."""
STATE_NAMES = tuple(f.name for f in dataclasses.fields(State))
"""Every ``State`` field, each saved as ``state.<name>`` where the run has it."""
META_KEYS = (
    "format",
    "format_version",
    "scene",
    "params",
    "interpolator",
    "transfer",
    "artificial_cells",
    "ordering",
    "cfl_limit",
    "dt",
    "steps",
    "chunk",
    "saveat",
    "checkpoint_every",
    "step",
)
"""The ``meta`` keys that ``load`` and ``resume`` need (a saved run has more, see above)."""
SIMULATE_ONLY = {
    "t_end": "a long run takes fixed steps (dt and steps); run to an end time with "
    "jaxmpm.simulate(t_end=..., max_steps=...)",
    "cfl": "a long run takes fixed steps (dt and steps); a CFL-limited run to an end time is "
    "jaxmpm.simulate(t_end=..., cfl=..., max_steps=...)",
    "max_steps": "a long run takes fixed steps (dt and steps); a run to an end time is "
    "jaxmpm.simulate(t_end=..., max_steps=...)",
    "checkpoint": "simulate's checkpoint is checkpointed reverse mode (for jax.grad), which a long run "
    "does not take; a long run saves its state to a file with out=FILE and checkpoint_every=N",
    "volume_average": "a saved run does not record it; run volume-averaged kinematics with "
    "jaxmpm.simulate(volume_average=...)",
}
"""The arguments of ``simulate`` that a long run does not take, and why (the message of the
``ValueError`` that ``run`` raises for each)."""
_POLL_S = 0.02  # the longest sleep between two looks at a running chunk
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")  # a zip archive (an .npz), with members or empty


class Interrupted(KeyboardInterrupt):
    """A long run stopped by Ctrl-C (``KeyboardInterrupt``), after saving its last finished chunk.

    A ``KeyboardInterrupt`` itself, so that code which lets Ctrl-C through still does. The chunk
    that was running is discarded; the state of the one before it is in ``solution`` and, with
    ``out``, in the file, from which ``resume`` continues bit for bit.

    Args:
        message: one line, "interrupted at step N of M; saved in FILE (continue with
            `jaxmpm resume FILE`)", or without the file when the run has none, or saying that
            nothing was saved when no chunk had finished.
        step: the last finished step.
        saved_in: the file the run was saved to, or ``None`` (a run without ``out``, or stopped
            before its first chunk finished: the file is then as it was).
        solution: the ``Solution`` up to ``step`` (its history included).

    Attributes:
        step: as above.
        saved_in: as above (a ``pathlib.Path``).
        solution: as above.
    """

    def __init__(self, message: str, *, step: int, saved_in: pathlib.Path | None, solution: Solution):
        super().__init__(message)
        self.step = step
        self.saved_in = saved_in
        self.solution = solution


@eqx.filter_jit
def _start(model):
    prepared = setup(model)
    state = initial_state(model, prepared)
    return shard_particles(model, state, state.x.shape[0]), prepared.body


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
    return _in_notebook() or sys.stderr.isatty()


def _in_notebook() -> bool:
    """Whether this code runs in a Jupyter kernel (an IPython shell over ZMQ), not merely in a process
    that imported ``ipykernel`` (a test runner that executed notebooks does)."""
    ipython = sys.modules.get("IPython")
    get = getattr(ipython, "get_ipython", None)
    shell = get() if get is not None else None
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


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


def _unsaved_field(scene) -> str | None:
    """The first field of ``scene`` that is not one of its parameters and not its default (a Python
    object a file cannot record: the parts of ``jm.Bodies``), or ``None``."""
    named = scene.parameters()
    for f in dataclasses.fields(scene):
        if f.name not in named and getattr(scene, f.name) is not f.default:
            return f.name
    return None


def _write_npz(path: pathlib.Path, arrays: dict) -> None:
    """Write ``arrays`` to ``path`` atomically: a temporary file, fsync, then an atomic rename.

    A crash at any point leaves either the previous file or the new one, never a broken one; a write
    that fails (a full disk) removes its temporary file and raises the ``OSError``.
    """
    write_whole(path, lambda f: np.savez(f, **arrays), durable=True)
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
        new = {name: [] for name in saved}
        ts = []
        for i in range(next(iter(saved.values())).shape[0]):
            nominal = first_step + (i + 1) * every
            if nominal > done:  # masked tail or frozen after a failure: not a state the run reached
                break
            for name, arr in saved.items():
                new[name].append(np.asarray(arr[i]))
            ts.append(nominal * dt)
        for name, items in new.items():  # all fields at once: the history stays consistent
            self.history[name].extend(items)
        self.ts.extend(ts)

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
            if isinstance(value, dict):  # internal variables: one array per variable
                for k, v in value.items():
                    arrays[f"state.{name}.{k}"] = host(v)
            elif value is not None:
                arrays[f"state.{name}"] = host(value)
        arrays["body.X"] = host(self.body.X)
        arrays["body.boundary"] = host(self.body.boundary)
        if self.history is not None:
            arrays["history.ts"] = np.asarray(self.ts, dtype=np.float64)
            for name, items in self.history.items():
                arrays[f"history.{name}"] = np.stack(items)
        # With several processes (a run over their devices), the first writes the whole run and the
        # others wait for it, so that every process then reads the same file.
        if jax.process_index() == 0:
            _write_npz(path, arrays)
        if jax.process_count() > 1:
            multihost_utils.sync_global_devices(f"jaxmpm: saved {path} at step {step}")


class InterruptLatch:
    """A SIGINT handler that raises ``KeyboardInterrupt`` and remembers that it did.

    Python ignores an exception raised where it cannot propagate (a garbage-collector callback, a
    ``__del__``): with its own handler a Ctrl-C that lands there is lost, and the run goes on. With
    this one installed, ``wait`` raises the lost interrupt again at its next poll. The command line
    installs it (``install``); a library caller keeps whatever handler it has.

    Attributes:
        pending: Ctrl-C was pressed.
    """

    def __init__(self):
        self.pending = False

    def __call__(self, signum, frame):
        self.note(signum)
        raise KeyboardInterrupt

    def note(self, signum) -> None:
        """Note the signal (``pending``) without raising: the interrupt is raised by who held it back.

        Args:
            signum: the signal's number.
        """
        self.pending = True

    @classmethod
    def install(cls) -> InterruptLatch:
        """Make a new latch the process's SIGINT handler (an entry point's choice: global state).

        Python reports an exception it ignores through ``sys.unraisablehook``, whose default prints
        ``Exception ignored in ...`` and a traceback. The interrupts a latch sees are raised again at
        the next poll, so they are not reported: the hook is wrapped once (``_QuietLostInterrupt``),
        and every other ignored exception still goes to the hook there was.

        Returns:
            The latch.
        """
        latch = cls()
        signal.signal(signal.SIGINT, latch)
        if not isinstance(sys.unraisablehook, _QuietLostInterrupt):
            sys.unraisablehook = _QuietLostInterrupt(sys.unraisablehook)
        return latch


class _QuietLostInterrupt:
    """``sys.unraisablehook`` under an ``InterruptLatch``: a ``KeyboardInterrupt`` that Python ignored
    while a latch that saw it is the SIGINT handler is dropped (the latch raises it again); anything
    else goes to ``previous``."""

    def __init__(self, previous):
        self.previous = previous

    def __call__(self, unraisable):
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _lost_interrupt():
            return
        self.previous(unraisable)


def _lost_interrupt() -> bool:
    """Whether an installed ``InterruptLatch`` saw a Ctrl-C (raised where Python may have ignored it)."""
    handler = signal.getsignal(signal.SIGINT)
    return isinstance(handler, InterruptLatch) and handler.pending


class _DeferInterrupt:
    """Hold Ctrl-C back while the host commits a finished chunk or writes the file.

    In the main thread, with Python's own SIGINT handler or an ``InterruptLatch`` installed, a SIGINT
    that arrives inside the block is noted (``pending``) rather than raised, so that a chunk is either
    wholly recorded (and saved) or not at all; so is a SIGTERM whose handler is an ``InterruptLatch``
    (the command line's). Elsewhere (another thread, a handler of the user's) it changes nothing.
    """

    def __init__(self):
        self.pending = False
        self._previous = {}

    def _note(self, signum, frame):
        self.pending = True
        self._signals.append(signum)

    def __enter__(self):
        self._signals = []
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                handler = signal.getsignal(sig)
                if isinstance(handler, InterruptLatch) or (
                    sig == signal.SIGINT and handler is signal.default_int_handler
                ):
                    self._previous[sig] = signal.signal(sig, self._note)
        return self

    def __exit__(self, *exc):
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        if self.pending and self._signals[0] != signal.SIGINT:  # a SIGTERM held back: its handler
            handler = self._previous.get(self._signals[0])  # notes what it was before the raise
            if isinstance(handler, InterruptLatch):
                handler.note(self._signals[0])
        return False


def wait(tree):
    """Wait until every array in ``tree`` is computed, answering Ctrl-C at once.

    Polls ``jax.Array.is_ready`` with short sleeps instead of blocking in ``jax.block_until_ready``,
    so that Python sees Ctrl-C at once. A sleep is at most ``_POLL_S`` and at most a twentieth of
    the time waited so far, so that short chunks lose little to it.

    Args:
        tree: a pytree of arrays being computed (a compiled call's result).

    Returns:
        ``tree``, computed.

    Raises:
        KeyboardInterrupt: Ctrl-C while waiting, or earlier where Python ignored it (an
            ``InterruptLatch`` remembers it; the computation is abandoned, not stopped).
    """
    t0 = time.perf_counter()
    for leaf in jax.tree_util.tree_leaves(tree):
        if isinstance(leaf, jax.Array):
            while not leaf.is_ready():
                if _lost_interrupt():
                    raise KeyboardInterrupt
                time.sleep(min(_POLL_S, max(1e-4, 0.05 * (time.perf_counter() - t0))))
    if _lost_interrupt():
        raise KeyboardInterrupt
    return tree


def computed(fn, *args):
    """``fn(*args)`` with every array it returns computed, answering Ctrl-C at once.

    Where the process's SIGINT handler is an ``InterruptLatch`` (the command line installs one) and
    this is the main thread, the call (tracing, compiling and running) goes to a worker thread while
    this one waits, so that a Ctrl-C during a long compiled call is answered at once: the call is
    abandoned, not stopped (the command line then exits without waiting for it). Elsewhere (a library
    caller, which may hold thread-local JAX settings) the call runs here and ``long_run.wait`` polls
    its result, which answers Ctrl-C at once where the device computes asynchronously (a GPU) and
    after the call on a CPU, which computes in the calling thread.

    Args:
        fn: a function of arrays, usually compiled.
        *args: its arguments.

    Returns:
        Its result, computed.

    Raises:
        KeyboardInterrupt: Ctrl-C while it computed.
    """
    latch = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or not isinstance(latch, InterruptLatch):
        return wait(fn(*args))
    box = {}

    def work():
        try:
            box["out"] = jax.block_until_ready(fn(*args))
        except BaseException as e:  # handed to the waiting thread, which raises it
            box["error"] = e

    worker = threading.Thread(target=work, name="jaxmpm-compute", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(0.05)
        if latch.pending:  # a Ctrl-C that Python ignored where it landed
            raise KeyboardInterrupt
    if "error" in box:
        raise box["error"]
    return box["out"]


def _any_process(flag: bool) -> bool:
    """Whether ``flag`` is set on any process (a collective: every process calls it at the same point).

    Args:
        flag: this process's flag.

    Returns:
        The flags of every process, or-ed.
    """
    return bool(np.any(multihost_utils.process_allgather(np.asarray(flag, dtype=np.int32))))


def _drive(
    model,
    dt_arr,
    saveat,
    state,
    rec: _Recorder,
    *,
    steps,
    chunk,
    out,
    checkpoint_every,
    progress,
    throw,
    new_out: bool = False,
) -> tuple[Solution, float, float]:
    """Run ``rec``'s run from ``state`` in chunks to ``steps``, saving to ``out`` (with ``new_out``,
    a file that did not exist before the run: one another process made there meanwhile is not
    replaced, ``FileExistsError``, checked just before the first save)."""
    every = saveat.every
    dt = float(dt_arr)
    n_particles = rec.body.n
    limit = jnp.asarray(steps, dtype=jnp.int32)
    done = start = int(state.step)
    bar = None
    held = None  # the step that ``out`` holds, written by this drive
    # A run over several processes' devices: each chunk's collectives need every process, so a Ctrl-C
    # in any of them stops all of them after the same chunk (they agree on it after each chunk).
    together = model.devices is not None and len({d.process_index for d in model.devices}) > 1
    carried = False  # a Ctrl-C noted during the last vote
    writing = False  # inside rec.save: an exception there leaves the previous file (the write is atomic)

    def save():
        nonlocal held, writing
        writing = True
        # out was checked before the run and not there. (Over several processes only the first
        # writes, and the others may see its file: not checked there.)
        if new_out and held is None and jax.process_count() == 1 and os.path.lexists(out):
            raise FileExistsError(
                errno.EEXIST,
                "appeared while the run computed (another run writing it?), and is not replaced; this "
                "run is not saved",
                str(out),
            )
        rec.save(out, state)
        writing = False
        held = int(state.step)

    try:
        t_compile = time.perf_counter()
        compiled = _chunk.lower(model, dt_arr, state, limit, chunk, saveat).compile()  # once, for every chunk
        t_start = time.perf_counter()
        compile_s = t_start - t_compile
        bar = _progress_bar(steps, done, show_progress(progress))
        chunks_done = 0
        while done < steps and int(state.status) == 0:
            t0 = time.perf_counter()
            if together:  # every process finishes the chunk: a Ctrl-C is noted, and agreed on below
                with _DeferInterrupt() as held_chunk:
                    result = compiled(model, dt_arr, state, limit, chunk, saveat)
                    new_state, saved = jax.block_until_ready(result)
            else:
                new_state, saved = wait(compiled(model, dt_arr, state, limit, chunk, saveat))
            saved = None if saved is None else jax.tree.map(host, saved)
            with _DeferInterrupt() as held_back:  # record the chunk (and save it) whole, or not at all
                state = new_state
                before, done = done, int(state.step)
                rec.add(saved, before, done, every, dt)
                chunks_done += 1
                elapsed = time.perf_counter() - t0
                bar.update(done - before)
                bar.set_postfix_str(
                    f"t={float(state.t):.4g}  {n_particles * (done - before) / elapsed / 1e6:.1f} "
                    "M particle-steps/s",
                    refresh=False,
                )
                if out is not None and checkpoint_every and chunks_done % checkpoint_every == 0:
                    save()
            if together:  # the vote is a collective: a Ctrl-C during it counts in the next one
                mine = held_chunk.pending or held_back.pending or carried or _lost_interrupt()
                with _DeferInterrupt() as held_vote:
                    stop = _any_process(mine)
                carried = held_vote.pending
                if stop:
                    raise KeyboardInterrupt
            elif held_back.pending:
                raise KeyboardInterrupt
        with _DeferInterrupt() as held_back:
            if out is not None and held != done:
                save()
        if held_back.pending:
            raise KeyboardInterrupt
        wall_s = time.perf_counter() - t_start
        sol = rec.solution(state)
    except KeyboardInterrupt:
        if writing:  # raised inside the write itself, not a Ctrl-C (held back there): out is as it was
            raise
        step = int(state.step)
        # Before its first chunk this drive has nothing to save, and out keeps what it holds (with
        # overwrite, an earlier run's file; resumed, the checkpoint it started from).
        saving = out is not None and (held is not None or step != start)
        if saving:
            with _DeferInterrupt():  # a second Ctrl-C does not break this save
                if held != step:
                    save()
        if saving:
            where = f"; saved in {out} (continue with `jaxmpm resume {out}`)"
        elif out is not None:
            kept = f"{out} is as it was" if os.path.lexists(out) else f"no {out} was written"
            where = f", before its first chunk finished: nothing saved ({kept})"
        else:
            where = ""
        raise Interrupted(
            f"interrupted at step {step} of {steps}{where}",
            step=step,
            saved_in=out if saving else None,
            solution=rec.solution(state),
        ) from None
    finally:
        if bar is not None:
            bar.close()
    if int(state.status) and throw:
        where = f" Everything up to it is saved in {out}." if out is not None else ""
        raise SimulationError(failure_message(sol, dt, model.scene) + where, sol)
    return sol, compile_s, wall_s


def _check_switches(progress, throw) -> None:
    """Refuse a ``progress`` that is not ``None``, ``True`` or ``False``, and a ``throw`` that is not
    a bool."""
    if progress is not None and not isinstance(progress, (bool, np.bool_)):
        raise ValueError(f"progress must be None, True or False, got {progress!r}")
    check_bool("throw", throw)


@typing.no_type_check  # validates every argument itself, raising ValueError (see run_timed)
def run(scene: AbstractScene, interpolator: AbstractInterpolator, **kwargs) -> Solution:
    """``simulate`` in chunks, with progress, checkpoints and a saved result.

    Args:
        scene: as for ``run_timed``.
        interpolator: as for ``run_timed``.
        **kwargs: as for ``run_timed``.

    Returns:
        The ``Solution``.

    Raises:
        ValueError: bad input, before anything is traced (as for ``run_timed``), and an argument of
            ``simulate`` that a long run does not take (``t_end``, ``cfl``, ``max_steps``,
            ``checkpoint``, ``volume_average``: ``SIMULATE_ONLY`` says why and what to use).
        TypeError: a keyword that no run takes (the message lists those ``run`` takes).
        SimulationError: the run broke down (after saving it, with ``out``).
        Interrupted: Ctrl-C (after saving the last finished chunk, with ``out``).
    """
    check_keywords("long_run.run", kwargs, run_timed, SIMULATE_ONLY)
    return run_timed(scene, interpolator, **kwargs)[0]


@typing.no_type_check  # validates every argument itself, raising ValueError
def _check_concrete(scene, dt) -> None:
    """Refuse a scene or ``dt`` traced by a JAX transformation: a long run is driven from Python (its
    chunks, progress and files), so it runs outside ``jax.jit``, ``jax.grad`` and ``jax.vmap``.

    Raises:
        ValueError: a traced value, naming what to use instead.
    """
    if any_traced((scene, dt)):
        raise ValueError(
            "a long run is driven from Python (chunks, progress, files) and runs outside jax.jit, "
            "jax.grad and jax.vmap; inside them use jm.simulate (its checkpoint= bounds reverse mode's "
            "memory), or jm.ensemble for many values"
        )


def run_timed(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    *,
    dt=None,
    steps: int | None = None,
    chunk: int = 1000,
    transfer=None,
    artificial_cells: int = 0,
    saveat: SaveAt | None = None,
    cfl_limit: float | None = 1.0,
    ordering: str = "usl",
    viscosity: ArtificialViscosity | None = None,
    devices=None,
    out: str | os.PathLike | None = None,
    checkpoint_every: int | None = None,
    progress: bool | None = None,
    throw: bool = True,
    overwrite: bool = False,
    **others,
) -> tuple[Solution, float, float]:
    """``simulate`` in chunks of ``chunk`` steps, with progress, checkpoints and a saved result.

    Args:
        scene: as for ``simulate``.
        interpolator: as for ``simulate``.
        dt: as for ``simulate`` (required).
        steps: as for ``simulate`` (required).
        transfer: as for ``simulate``.
        artificial_cells: as for ``simulate``.
        saveat: as for ``simulate``. With ``saveat.every``, ``chunk`` must be a multiple of it.
        cfl_limit: as for ``simulate``.
        ordering: as for ``simulate``.
        viscosity: as for ``simulate`` (saved with the run).
        devices: as for ``simulate``; the file records their count, and ``resume`` continues on as
            many devices (bit for bit on the same layout). With several processes, the first
            process writes ``out`` (the whole run) and the others wait for it.
        chunk: steps per compiled chunk (the chunk compiles once; the last is masked past the end). A
            chunk longer than the run is cut to the run's steps (rounded up to a multiple of
            ``saveat.every``), and saved so.
        out: a ``.npz`` file to write the run to (at the end, at checkpoints, on breakdown and on
            Ctrl-C). Its folder must exist and be writable.
        checkpoint_every: write ``out`` every this many chunks (``None``: only at the end).
        progress: show a progress bar (steps, simulated time, particle-steps per second). ``None``
            shows it in a terminal or notebook and not in pipes or CI; the environment variable
            ``JAXMPM_PROGRESS=0`` or ``1`` overrides that.
        throw: raise ``SimulationError`` on breakdown (after saving); else return with the status.
        overwrite: replace ``out`` if it exists (only with ``out``). Without it an existing ``out`` is
            an error, so that no saved run is lost (continue a saved run with ``resume`` instead).
        **others: refused: an argument of ``simulate`` that a long run does not take
            (``SIMULATE_ONLY``), or a keyword no run takes.

    Returns:
        ``(solution, compile_s, wall_s)``: the ``Solution`` (the same state as ``simulate`` gives),
        the time of the chunk's one compilation, and the time of everything after it.

    Raises:
        ValueError: bad input, before anything is traced (``dt`` or ``steps`` missing, ``progress``
            not ``None``, ``True`` or ``False``, ``throw`` not a bool, an argument of ``simulate``
            that a long run does not take, ...); also an ``out`` that exists (without
            ``overwrite``), is a folder, or lies in a folder that does not exist or is not writable.
        TypeError: a keyword that no run takes (the message lists those it takes).
        SimulationError: the run broke down (after saving it, with ``out``).
        Interrupted: Ctrl-C (after saving the last finished chunk, with ``out``).
    """
    check_keywords("long_run.run_timed", others, run_timed, SIMULATE_ONLY)
    if dt is None or steps is None:
        raise ValueError(
            "a long run takes fixed steps: give dt (> 0) and steps (an integer >= 0); run to an end "
            "time with jaxmpm.simulate(t_end=..., max_steps=...)"
        )
    _check_switches(progress, throw)
    _check_concrete(scene, dt)
    check_int("chunk", chunk, 1)
    chunk = int(chunk)  # a NumPy integer too: the chunk is static, and saved with the run
    if checkpoint_every is not None:
        check_int("checkpoint_every", checkpoint_every, 1)
        checkpoint_every = int(checkpoint_every)
        if out is None:
            raise ValueError("checkpoint_every needs out=FILE to write the checkpoints to")
    if not isinstance(overwrite, bool):
        raise ValueError(f"overwrite must be True or False, got {overwrite!r}")
    if overwrite and out is None:
        raise ValueError("overwrite=True needs out=FILE, the file it lets the run replace")
    model, dt_arr, steps, saveat = prepare(
        scene,
        interpolator,
        dt=dt,
        steps=steps,
        transfer=transfer,
        artificial_cells=artificial_cells,
        saveat=saveat,
        cfl_limit=cfl_limit,
        ordering=ordering,
        viscosity=viscosity,
        devices=devices,
    )
    if saveat.every is not None and chunk % saveat.every:
        raise ValueError(f"chunk must be a multiple of saveat.every, got chunk={chunk}, every={saveat.every}")
    every = saveat.every or 1
    chunk = min(chunk, max(-(-steps // every) * every, every))  # no more than the run
    unsaved = _unsaved_field(scene)
    if unsaved is not None and out is not None:
        raise ValueError(
            f"a saved run records the scene by its parameters, and {unsaved} of {scene.name} is not one "
            f"(a Python function cannot be saved); run it without out, or with simulate"
        )
    params = None if unsaved is not None else scene.parameter_values()  # (nothing is saved then)
    out = None if out is None else _check_out(out, overwrite=overwrite)
    new_out = out is not None and not os.path.lexists(out)  # made by this run: never over another's
    meta = dict(
        format=FORMAT,
        format_version=FORMAT_VERSION,
        jaxmpm_version=_version(),
        scene=scene.name,
        params=params,
        interpolator=_interpolator_meta(interpolator),
        transfer=model.transfer.name,
        artificial_cells=model.artificial_cells,
        ordering=ordering,
        cfl_limit=cfl_limit,
        dt=float(dt_arr),
        steps=steps,
        chunk=chunk,
        saveat=dict(every=saveat.every, fields=list(saveat.fields)),
        checkpoint_every=checkpoint_every,
        viscosity=None if viscosity is None else viscosity.coefficients(),
        devices=None if model.devices is None else len(model.devices),
    )
    state, body = _start(model)
    history = ts = None
    if saveat.every is not None:
        first = jax.tree.map(host, save_fields(state, saveat.fields))
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
        new_out=new_out,
    )


def _check_out(
    out, *, overwrite: bool, own: pathlib.Path | None = None, option: str | None = None
) -> pathlib.Path:
    """``out`` as a path, once it is known that the run can be written there without losing a file.

    Args:
        out: the file to write.
        overwrite: whether an existing ``out`` may be replaced.
        own: the saved run being resumed: ``out`` may be it.
        option: the command-line option that gave ``out`` (``"--out"``), for messages in its terms
            (``--overwrite``); ``None`` for the keywords of ``run``.

    Returns:
        ``out`` as a ``pathlib.Path``.

    Raises:
        ValueError: ``out`` is not a path, is a folder or another file that is not a regular one (a
            device, even with ``overwrite``), exists (unless ``overwrite`` or ``own``), or lies in a
            folder that does not exist or cannot be written.
    """
    if not isinstance(out, (str, os.PathLike)):
        raise ValueError(f"out must be a file path (a str or os.PathLike), got {out!r}")
    path = pathlib.Path(out)
    named = f"out={path}" if option is None else f"{option} {path}"
    if isinstance(out, str) and out.endswith(("/", os.sep)):  # (a Path drops the slash)
        named = f"out={out}" if option is None else f"{option} {out}"
        raise ValueError(
            f"{named} ends with a slash, which names a folder, not a file; give a file to write the "
            f"run to, e.g. {path / 'run.npz'}"
        )
    if path.is_dir():
        raise ValueError(
            f"{named} is a folder, not a file; give a file to write the run to, e.g. {path / 'run.npz'}"
        )
    if path.exists() and not path.is_file():  # a device, a pipe, a socket: never replaced by a file
        raise ValueError(
            f"{named} is not a regular file (a device, pipe or socket), which a saved run would replace; "
            "give a file path"
        )
    folder = path.parent
    if not folder.exists():
        raise ValueError(f"{named}: the folder {folder} does not exist (create it first)")
    if not folder.is_dir():
        raise ValueError(f"{named}: {folder} is not a folder")
    if (
        (path.exists() or path.is_symlink())
        and not overwrite
        and not (own is not None and _same_file(path, own))
    ):
        what = _describe(path)
        hint = f", or continue it with `jaxmpm resume {path}`" if what.startswith("a jaxmpm") else ""
        how = "overwrite=True (`--overwrite` on the command line)" if option is None else "--overwrite"
        raise ValueError(
            f"{path if option is None else named} already exists ({what}) and would be overwritten: "
            f"pass {how} to replace it{hint}, or choose another file"
        )
    try:  # the save writes FILE.tmp next to FILE and renames it: the folder itself must be writable
        fd, probe = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise ValueError(f"{named}: cannot write in the folder {folder} ({e.strerror or e})") from None
    return path


def _same_file(a: pathlib.Path, b: pathlib.Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def _describe(path: pathlib.Path) -> str:
    """What an existing file is, in words, read cheaply: a jaxmpm checkpoint's scene and step, or
    "an existing file"."""
    try:
        with open(path, "rb") as fh:
            if fh.read(4) not in _ZIP_MAGIC:
                return "an existing file, not a jaxmpm checkpoint"
        with np.load(path, allow_pickle=False) as f:
            meta = json.loads(str(f["meta"]))
        if meta.get("format") != FORMAT:
            return "an existing file, not a jaxmpm checkpoint"
        what = f"a jaxmpm checkpoint of {meta['scene']} at step {int(meta['step'])} of {int(meta['steps'])}"
        if meta.get("failure"):
            what += f", broken down at step {int(meta['failure']['step'])}"
        elif meta.get("complete"):
            what += ", complete"
        return what
    except Exception:  # whatever it holds, it is a file the user may want
        return "an existing file"


def load(path: str | os.PathLike) -> tuple[Solution, dict]:
    """Read a run saved by ``run`` (or ``resume``), after checking it.

    The checks: the file is a NumPy ``.npz`` archive that can be read whole; its ``meta`` is JSON
    with the keys ``META_KEYS``, of this ``FORMAT`` and at most ``FORMAT_VERSION``; the scene,
    interpolator and transfer it names exist and accept its parameters; every state (and history)
    array the run needs is there with the shape and dtype the run gives it (which checks the
    particle count, the dimension, and the parts of the state a setting carries: APIC's ``C``,
    MPQ's ``corners``, an energy and internal variables); and the arrays are those of the run the
    metadata describes, up to round-off: ``body.X`` and ``body.boundary`` equal those of the named
    scene; ``state.step`` is the saved ``step``, at most the run's ``steps``, and ``state.t`` is
    ``step * dt``; a state of status 0 is finite with ``det F > 0``; ``state.sigma`` is the stress
    the named materials give at the saved ``F`` (and ``e`` and internal variables), which checks the
    parameters that set the stress (a gas's ``P0``, ``gamma`` and ``p_atm``, a solid's moduli, an
    equation of state's constants and density ``rho0``); and a history's times are one save every
    ``saveat.every`` steps of ``dt``, its first frame the initial state of the named scene (its
    velocity, stress, energy, ...). Settings that leave no trace in the saved arrays are not checked:
    the transfer between FLIP and PIC, ``artificial_cells``, ``ordering``, ``cfl_limit``, ``chunk``,
    ``checkpoint_every``, the interpolator (SPQ, GIMP, CPDI between themselves: their state has the
    same parts) and its options, the grid's ``pad``, and scene parameters that act only through the
    motion (``rho0`` of a material of ``F`` alone, walls, loads); nor is the stress of a run with an
    artificial ``viscosity`` (it holds the viscous stress of the last step's rate, which is not saved).

    Args:
        path: the saved run.

    Returns:
        ``(solution, meta)``: its ``Solution`` and its ``meta`` dict (see the module's docstring). The
        solution is the run as far as it was saved: ``meta["step"]`` of ``meta["steps"]`` steps, and
        ``meta["complete"]`` true only when every step was taken without a breakdown.

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: one line naming the file and what is wrong: it is a folder, empty, truncated or
            damaged, not a ``.npz`` archive, not a jaxmpm run, written by a newer jaxmpm, or its
            metadata and arrays do not describe a run this jaxmpm can continue.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file path (a str or os.PathLike), got {path!r}")
    sol, meta, _ = _load(pathlib.Path(path), on_devices=False)
    return sol, meta


def _check_file(path: pathlib.Path) -> None:
    """Raise if ``path`` is not a file that could hold a saved run (cheap: its first bytes)."""
    if path.is_dir():
        raise ValueError(f"{path} is a folder, not a saved run (a .npz file written by `jaxmpm run --out`)")
    if not path.exists():
        raise FileNotFoundError(f"no saved run at {path}")
    try:
        with open(path, "rb") as fh:
            head = fh.read(6)
    except OSError as e:
        raise ValueError(f"{path} cannot be read ({e.strerror or e})") from None
    if not head:
        raise ValueError(f"{path} is empty (0 bytes): not a jaxmpm checkpoint")
    if head.startswith(b"\x93NUMPY"):
        raise ValueError(f"{path} is a single NumPy array (.npy), not a jaxmpm checkpoint (an .npz archive)")
    if head[:4] not in _ZIP_MAGIC:
        raise ValueError(f"{path} is not a jaxmpm checkpoint (not a NumPy .npz archive)")


def _read(path: pathlib.Path) -> tuple[dict, dict]:
    """The checked ``meta`` and the raw arrays of a saved run."""
    _check_file(path)
    damaged = f"{path} is damaged or truncated (a .npz archive that cannot be read whole"
    try:
        f = np.load(path, allow_pickle=False)
    except Exception as e:  # zipfile, numpy and OS errors alike: the archive cannot be opened
        raise ValueError(f"{damaged}: {_reason(e)})") from None
    with f:
        if "meta" not in f.files:
            raise ValueError(f"{path} is not a jaxmpm checkpoint (a .npz archive without 'meta')")
        arrays = {}
        for key in f.files:
            try:
                arrays[key] = f[key]
            except Exception as e:
                raise ValueError(f"{damaged}: array {key!r}: {_reason(e)})") from None
    raw = arrays.pop("meta")
    if raw.ndim != 0 or raw.dtype.kind not in "US":
        raise ValueError(
            f"{path}: its 'meta' is not a JSON string (found a {raw.dtype} array of shape {raw.shape})"
        )
    try:
        meta = json.loads(str(raw))
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: its 'meta' is not valid JSON ({e.msg} at character {e.pos})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: its 'meta' is not a JSON object (found {type(meta).__name__})")
    if meta.get("format") != FORMAT:
        raise ValueError(
            f"{path} is not a jaxmpm run file (format {meta.get('format')!r}, expected {FORMAT!r})"
        )
    version = meta.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise ValueError(f"{path}: its meta's format_version must be an integer, got {version!r}")
    if version > FORMAT_VERSION:
        raise ValueError(
            f"{path} was written by a newer jaxmpm (format version {version}; this jaxmpm "
            f"{_version()} reads up to {FORMAT_VERSION}): update jaxmpm to continue it"
        )
    missing = [k for k in META_KEYS if k not in meta]
    if missing:
        raise ValueError(
            f"{path}: its meta lacks {', '.join(missing)} "
            f"(a jaxmpm checkpoint's meta has {', '.join(META_KEYS)})"
        )
    return meta, arrays


def _reason(e: Exception) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__


def _names(registry) -> str:
    return ", ".join(sorted(registry))


def _kind(default) -> str:
    """What a scene parameter with this default must be, in words (as ``_is`` reads them)."""
    if isinstance(default, bool):
        return "true or false"
    if isinstance(default, int):
        return "an integer"
    if isinstance(default, str):
        return "a string"
    return "a number"


def _is(value, kind: str) -> bool:
    """Whether a JSON value is of ``kind`` (one of ``_kind``'s words, or "a number or null")."""
    if kind == "true or false":
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False
    if kind == "an integer":
        return isinstance(value, int)
    if kind == "a string":
        return isinstance(value, str)
    if kind == "a number or null" and value is None:
        return True
    return isinstance(value, (int, float))


def _settings(path: pathlib.Path, meta: dict, on_devices: bool = True):
    """The run the metadata describes: ``(scene, model, dt_arr, saveat)``, every name and value
    checked (before anything is traced); with ``on_devices``, on as many devices as it ran on (else
    on one: to read it anywhere)."""
    name = meta["scene"]
    if not isinstance(name, str) or name not in SCENES:
        raise ValueError(f"{path}: unknown scene {name!r}; allowed: {_names(SCENES)}")
    params = meta["params"]
    if not isinstance(params, dict):
        raise ValueError(f"{path}: its meta's params must be a JSON object, got {params!r}")
    allowed = SCENES[name].parameters()
    unknown = [k for k in params if k not in allowed]
    if unknown:
        raise ValueError(
            f"{path}: unknown parameter {unknown[0]!r} of scene {name}; allowed: {', '.join(allowed)}"
        )
    for key, value in params.items():
        kind = _kind(allowed[key])
        if not _is(value, kind):
            raise ValueError(
                f"{path}: the saved parameter {key} of scene {name} must be {kind}, got {value!r}"
            )
    try:
        scene = SCENES[name](**params)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{path}: scene {name} rejects the saved parameters: {e}") from None
    interp_meta = meta["interpolator"]
    if not isinstance(interp_meta, dict) or not isinstance(interp_meta.get("name"), str):
        raise ValueError(
            f"{path}: its meta's interpolator must be a JSON object with a name, got {interp_meta!r}"
        )
    if interp_meta["name"] not in INTERPOLATORS:
        raise ValueError(
            f"{path}: unknown interpolator {interp_meta['name']!r}; allowed: {_names(INTERPOLATORS)}"
        )
    try:
        interp = _interpolator_from(interp_meta)
    except (TypeError, ValueError) as e:
        raise ValueError(
            f"{path}: interpolator {interp_meta['name']} rejects the saved options: {e}"
        ) from None
    transfer = meta["transfer"]
    if not isinstance(transfer, str) or transfer not in TRANSFERS:
        raise ValueError(f"{path}: unknown transfer {transfer!r}; allowed: {_names(TRANSFERS)}")
    for key, kind in (("dt", "a number"), ("cfl_limit", "a number or null")):
        if not _is(meta[key], kind):
            raise ValueError(f"{path}: its meta's {key} must be {kind}, got {meta[key]!r}")
    saved = meta.get("devices")
    if on_devices and isinstance(saved, int) and not isinstance(saved, bool) and saved > len(jax.devices()):
        raise ValueError(
            f"{path}: the run was saved from {saved} devices and resumes on as many; this process has "
            f"{len(jax.devices())} (jax.devices())"
        )
    try:
        check_int("chunk", meta["chunk"], 1)
        check_int("step", meta["step"], 0)
        if meta["checkpoint_every"] is not None:
            check_int("checkpoint_every", meta["checkpoint_every"], 1)
        sv = meta["saveat"]
        if not isinstance(sv, dict) or "every" not in sv or not isinstance(sv.get("fields"), list):
            raise ValueError(f"saveat must be a JSON object with every and fields, got {sv!r}")
        saveat = SaveAt(every=sv["every"], fields=tuple(sv["fields"]))
        if saveat.every is not None and meta["chunk"] % saveat.every:
            raise ValueError(
                f"chunk must be a multiple of saveat.every, got chunk={meta['chunk']}, every={saveat.every}"
            )
        model, dt_arr, _, saveat = prepare(
            scene,
            interp,
            dt=meta["dt"],
            steps=meta["steps"],
            transfer=TRANSFERS[transfer](),
            artificial_cells=meta["artificial_cells"],
            saveat=saveat,
            cfl_limit=meta["cfl_limit"],
            ordering=meta["ordering"],
            viscosity=_viscosity_from(meta.get("viscosity")),
            devices=meta.get("devices") if on_devices else None,
        )
    except (TypeError, ValueError) as e:
        raise ValueError(f"{path}: its meta does not describe a run: {e}") from None
    return scene, model, dt_arr, saveat


def _viscosity_from(saved) -> ArtificialViscosity | None:
    """The run's artificial viscosity from its meta's ``viscosity`` (``[c_quad, c_lin]``,
    ``[c_quad, c_lin, c_shear]`` or null)."""
    if saved is None:
        return None
    if not isinstance(saved, list) or len(saved) not in (2, 3):
        raise ValueError(
            f"viscosity must be [c_quad, c_lin], [c_quad, c_lin, c_shear] or null, got {saved!r}"
        )
    shear = float(saved[2]) if len(saved) == 3 else None
    return ArtificialViscosity(c_quad=float(saved[0]), c_lin=float(saved[1]), c_shear=shear)


def _check_array(path: pathlib.Path, key: str, arrays: dict, shape: tuple, dtype) -> np.ndarray:
    """``arrays[key]``, once it is there with ``shape`` and ``dtype``."""
    if key not in arrays:
        raise ValueError(
            f"{path}: the array {key} is missing (the saved run's settings need it, shape {shape})"
        )
    a = arrays[key]
    if a.shape != shape:
        raise ValueError(
            f"{path}: {key} has shape {a.shape}, expected {shape} for the run its meta describes"
        )
    if a.dtype != dtype:
        hint = ""
        if a.dtype == np.float64 and np.dtype(dtype) == np.float32:
            hint = " (the run was saved in float64: call jax.config.update('jax_enable_x64', True) first)"
        elif key == "body.X" and a.dtype == np.float32 and np.dtype(dtype) == np.float64:
            hint = (
                " (the run was saved in float32: load or resume it in Python with float64 off; "
                "jaxmpm resume runs in float64)"
            )
        raise ValueError(f"{path}: {key} has dtype {a.dtype}, expected {np.dtype(dtype)}{hint}")
    return a


def _load(path: pathlib.Path, on_devices: bool = True):
    meta, arrays = _read(path)
    scene, model, dt_arr, saveat = _settings(path, meta, on_devices)
    fresh, body = _start(model)
    described = f"scene {meta['scene']} with the saved params"
    X = _check_array(path, "body.X", arrays, tuple(body.X.shape), body.X.dtype)
    fresh_X = host(body.X)
    tol = 64 * np.finfo(fresh_X.dtype).eps * max(1.0, float(np.max(np.abs(fresh_X), initial=0.0)))
    if not np.all(np.abs(X - fresh_X) <= tol):
        worst = int(np.argmax(np.max(np.abs(X - fresh_X), axis=1)))
        raise ValueError(
            f"{path}: body.X does not match the reference positions of {described} (particle {worst}: "
            f"saved {X[worst].tolist()}, the scene gives {fresh_X[worst].tolist()}); the meta names "
            f"another scene or other parameters than the arrays hold"
        )
    boundary = _check_array(path, "body.boundary", arrays, tuple(body.boundary.shape), body.boundary.dtype)
    if not np.array_equal(boundary, host(body.boundary)):
        raise ValueError(
            f"{path}: body.boundary does not match the boundary particles of {described}; the meta "
            f"names another scene or other parameters than the arrays hold"
        )
    fields = {}
    for name in STATE_NAMES:
        key = f"state.{name}"
        template = getattr(fresh, name)
        if template is None:
            if key in arrays:
                raise ValueError(
                    f"{path}: it holds {key}, which a run with its meta's settings does not have "
                    f"(interpolator {meta['interpolator']['name']}, transfer {meta['transfer']})"
                )
            fields[name] = None
        elif isinstance(template, dict):
            fields[name] = {
                k: np.asarray(
                    _check_array(path, f"{key}.{k}", arrays, tuple(t.shape), t.dtype), dtype=t.dtype
                )
                for k, t in template.items()
            }
        else:
            a = _check_array(path, key, arrays, tuple(template.shape), template.dtype)
            fields[name] = np.asarray(a, dtype=template.dtype)
    if model.devices is None:
        state = State(**jax.tree.map(jnp.asarray, fields))
    else:  # laid out over the devices as the chunks' states are, so that the chunk compiles once
        state = State(**place_particles(model, fields, X.shape[0]))
    if int(state.step) != meta["step"]:
        raise ValueError(f"{path}: state.step is {int(state.step)} but its meta says step {meta['step']}")
    t = fields["t"]
    t_step = np.asarray(meta["step"], dtype=t.dtype) * np.asarray(host(dt_arr), dtype=t.dtype)
    if t != t_step:  # every fixed step sets t = step * dt exactly
        raise ValueError(
            f"{path}: state.t is {float(t)!r} but step {meta['step']} of dt = {meta['dt']!r} is at "
            f"t = {float(t_step)!r}; the file was edited or belongs to another run"
        )
    if "status" in meta and meta["status"] != int(state.status):
        raise ValueError(
            f"{path}: state.status is {int(state.status)} but its meta says status {meta['status']!r}"
        )
    if meta["step"] > meta["steps"]:
        raise ValueError(f"{path}: its meta says step {meta['step']} of a run of {meta['steps']} steps")
    # the step that broke down follows the kept (last good) state; 0 where the initial state failed
    fail = int(state.fail_step)
    if int(state.status) != 0 and fail != meta["step"] + 1 and not (fail == 0 == meta["step"]):
        raise ValueError(
            f"{path}: state.status is {int(state.status)} (a breakdown) but state.fail_step is {fail}, "
            f"not the step after the kept state's ({meta['step'] + 1}); the file was edited or is damaged"
        )
    if int(state.status) != 0:
        unknown = int(state.status) & ~sum(st_bits.QUANTITY)
        if unknown:
            raise ValueError(
                f"{path}: state.status is {int(state.status)}, which holds bits that no check sets "
                f"({unknown}); the file was edited or is damaged"
            )
        n, p = X.shape[0], int(state.fail_particle)
        if not -1 <= p < n:
            raise ValueError(
                f"{path}: state.fail_particle is {p}, not one of the run's {n} particles (0 to {n - 1}) or "
                "-1 (the run itself); the file was edited or is damaged"
            )
    if int(state.status) == 0:  # a healthy state is finite: every step checks it
        for name in ("x", "v", "F", "sigma", "e"):
            a = fields.get(name)
            if a is not None and not np.all(np.isfinite(a)):
                raise ValueError(f"{path}: state.{name} is not finite, yet its status is 0 (healthy)")
        J = np.linalg.det(np.asarray(fields["F"], dtype=np.float64))  # every step checks det F > 0 too
        if not np.all(J > 0):
            p = int(np.argmax(~(J > 0)))
            raise ValueError(
                f"{path}: particle {p} has det F = {J[p]:.6g} <= 0, yet its status is 0 (healthy); the file "
                "was edited or is damaged"
            )
    if model.viscosity is None:  # (a viscous stress depends on the last step's rate, which is not saved)
        _check_stress(path, model, fields, described)
    history = ts = None
    held = sorted(k for k in arrays if k.startswith("history."))
    if saveat.every is None:
        if held:
            raise ValueError(
                f"{path}: it holds {held[0]}, but its meta saves no history (saveat.every is null)"
            )
    else:
        n_saved = meta["step"] // saveat.every + 1  # steps 0, every, 2 every, ... up to step
        ts = list(_check_array(path, "history.ts", arrays, (n_saved,), np.dtype(np.float64)))
        templates = save_fields(fresh, saveat.fields)
        names = list(templates)
        extra = [k for k in held if k != "history.ts" and k[len("history.") :] not in names]
        if extra:
            raise ValueError(f"{path}: it holds {extra[0]}, which is not among the saved fields {names}")
        history = {}
        for f in names:
            template = templates[f]
            a = _check_array(path, f"history.{f}", arrays, (n_saved, *template.shape), template.dtype)
            history[f] = list(a)
        _check_history(path, meta, saveat, float(dt_arr), np.asarray(ts), history, templates, described)
    rec = _Recorder(
        {k: v for k, v in meta.items() if k not in ("step", "complete", "status", "failure", "saved_at")},
        body,
        history,
        ts,
    )
    return rec.solution(state), meta, (model, dt_arr, saveat, state, rec)


_MISMATCH = "the checkpoint's arrays do not match its metadata"
"""How the refusal of arrays made by another run than the one the metadata describes begins."""
_ROUND_OFF = 4096
"""The round-off allowed between a saved value and the same value computed again, in ulps of the
size of the terms it sums (a compiled run and a check compute it in different programs)."""


def _check_stress(path: pathlib.Path, model, fields: dict, described: str) -> None:
    """Refuse a saved stress that is not the stress the metadata's materials give at the saved ``F``
    (and ``e`` and internal variables), beyond round-off: arrays of a run with other material
    parameters, another scene or another viscosity.

    The round-off allowed is ``_ROUND_OFF`` ulps of the size of the stress's terms
    (``_step.material_stress``), times ``det F``'s condition (the product of the norms of ``F``'s rows
    over ``|det F|``, at least 1), by which the rounding of ``det F`` grows.
    """
    sigma = fields["sigma"]
    expected, size = material_stress(model, jnp.asarray(fields["F"]), fields["e"], fields["internal"])
    expected, size = np.asarray(expected, dtype=np.float64), np.asarray(size, dtype=np.float64)
    saved = np.asarray(sigma, dtype=np.float64)
    F = np.asarray(fields["F"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        condition = np.prod(np.linalg.norm(F, axis=2), axis=1) / np.abs(np.linalg.det(F))
        allowed = _ROUND_OFF * np.finfo(sigma.dtype).eps * np.maximum(condition, 1.0)
        allowed = allowed * (np.max(np.abs(expected), axis=(1, 2)) + size)
        off = np.abs(saved - expected)
        close = np.max(off, axis=(1, 2)) <= allowed  # (false where either is NaN)
    unbounded = ~np.isfinite(condition)  # det F = 0 or F not finite (a broken state): no bound
    neither = ~np.isfinite(saved).all(axis=(1, 2)) & ~np.isfinite(expected).all(axis=(1, 2))
    bad = ~(close | unbounded | neither)
    if not bad.any():
        return
    p = int(np.argmax(bad))
    worst = np.where(np.isnan(off[p]), np.inf, off[p])
    i, j = np.unravel_index(int(np.argmax(worst)), worst.shape)
    held = (
        ["F"]
        + (["e"] if fields["e"] is not None else [])
        + (["internal variables"] if fields["internal"] else [])
    )
    of = held[0] if len(held) == 1 else f"{', '.join(held[:-1])} and {held[-1]}"
    raise ValueError(
        f"{path}: {_MISMATCH}: state.sigma[{p}, {i}, {j}] is {float(saved[p, i, j])!r}, but the material "
        f"of {described} gives {float(expected[p, i, j])!r} at the saved {of}; the meta names another "
        "scene, other parameters or another viscosity than the arrays hold"
    )


def _check_history(
    path: pathlib.Path, meta: dict, saveat, dt: float, ts: np.ndarray, history: dict, initial, described
) -> None:
    """Refuse a history whose times are not the saves' (one every ``saveat.every`` steps of ``dt``),
    or whose first frame is not the initial state of the run the metadata describes (``initial``:
    its saved fields), beyond round-off."""
    every = saveat.every
    due = np.arange(ts.shape[0], dtype=np.float64) * every * dt
    wrong = ~(np.abs(ts - due) <= 16 * np.finfo(np.float64).eps * np.abs(due))
    if wrong.any():
        k = int(np.argmax(wrong))
        raise ValueError(
            f"{path}: {_MISMATCH}: history.ts[{k}] is {float(ts[k])!r}, but save {k} of one every {every} "
            f"steps of dt = {meta['dt']!r} is at t = {float(due[k])!r}"
        )
    for name, fresh in initial.items():
        first, fresh = np.asarray(history[name][0]), host(fresh)
        if first.dtype.kind != "f":
            differs = first != fresh
        else:
            finite = np.abs(fresh[np.isfinite(fresh)])
            tol = _ROUND_OFF * np.finfo(first.dtype).eps
            atol = tol * (float(np.max(finite)) if finite.size else 0.0)
            differs = ~np.isclose(first, fresh, rtol=tol, atol=atol, equal_nan=True)
        if differs.any():
            at = np.unravel_index(int(np.argmax(differs)), differs.shape)
            where = ", ".join(str(int(k)) for k in (0, *at))
            raise ValueError(
                f"{path}: {_MISMATCH}: history.{name}[{where}] (t = 0) is {float(first[at])!r}, but the "
                f"initial state of {described} has {float(fresh[at])!r} (the first frame of a history is "
                "the run's initial state); the meta names another scene or other parameters than the "
                "arrays hold"
            )


@typing.no_type_check  # validates every argument itself, raising ValueError (see resume_timed)
def resume(
    path: str | os.PathLike,
    *,
    out: str | os.PathLike | None = None,
    progress: bool | None = None,
    throw: bool = True,
    overwrite: bool = False,
) -> Solution:
    """Continue a run saved by ``run`` to its target step count, checkpointing as it was set up to.

    A resumed run equals the uninterrupted one bit for bit: the same chunk boundaries, the same
    compiled chunk, the state read back exactly. A run spread over several devices (``devices``)
    continues on as many of this process's devices, bit for bit too. A run that had broken down is
    not continued: its failure is raised again (or returned with ``throw=False``). The file is
    checked first, as by ``load``.

    Args:
        path: the saved run.
        out: where to keep writing (default: ``path`` itself; for a link, the file it names).
        progress: as for ``run``.
        throw: as for ``run``.
        overwrite: replace ``out`` if it is another file that exists (``path`` itself is always
            rewritten).

    Returns:
        The ``Solution`` of the whole run.

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: ``path`` is not a saved run this jaxmpm can continue (as for ``load``), ``out``
            cannot be written (as for ``run``'s ``out``), or ``progress`` or ``throw`` is not what
            ``run`` allows.
        SimulationError: the run broke down (now or before it was saved).
        Interrupted: Ctrl-C (after saving the last finished chunk to ``out``).
    """
    return resume_timed(path, out=out, progress=progress, throw=throw, overwrite=overwrite)[0]


@typing.no_type_check  # validates every argument itself, raising ValueError
def resume_timed(
    path: str | os.PathLike,
    *,
    out: str | os.PathLike | None = None,
    progress: bool | None = None,
    throw: bool = True,
    overwrite: bool = False,
) -> tuple[Solution, float, float, dict]:
    """``resume``, timed.

    Args:
        path: as for ``resume``.
        out: as for ``resume``.
        progress: as for ``resume``.
        throw: as for ``resume``.
        overwrite: as for ``resume``.

    Returns:
        ``(solution, compile_s, wall_s, meta)``: as ``run_timed``, and the saved run's ``meta``.

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: as for ``resume``.
        SimulationError: the run broke down (now or before it was saved).
        Interrupted: Ctrl-C (after saving the last finished chunk to ``out``).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file path (a str or os.PathLike), got {path!r}")
    _check_switches(progress, throw)
    if not isinstance(overwrite, bool):
        raise ValueError(f"overwrite must be True or False, got {overwrite!r}")
    path = pathlib.Path(path)
    _check_file(path)
    if out is None:  # the run goes on in its file: through a link, the file it names (the link kept)
        out = pathlib.Path(os.path.realpath(path)) if path.is_symlink() else path
    out = _check_out(out, overwrite=overwrite, own=path)
    new_out = not os.path.lexists(out)  # another file than path, made by this run
    sol, meta, (model, dt_arr, saveat, state, rec) = _load(path)
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
        new_out=new_out,
    ), meta


def _version() -> str:
    from . import __version__

    return __version__
