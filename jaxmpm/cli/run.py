"""``jaxmpm run``: run a scene and report its errors (a table, or one JSON object)."""

import contextlib
import dataclasses
import pathlib
import re
import time

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxmpm as jm
from jaxmpm import _memory
from jaxmpm._checks import check_int, check_positive
from jaxmpm._simulate import advance, failure_message, finish_to_end, prepare
from jaxmpm._step import shard_particles
from jaxmpm.long_run import _check_out, wait

from . import _assign
from ._common import (
    Breakdown,
    CannotWrite,
    UsageError,
    add_process_options,
    add_viscosity_option,
    as_option,
    devices_option,
    flags,
    floats,
    local_solution,
    measured_where,
    print_json,
    scalar,
    start_processes,
    writable_folder,
)

CHUNK_S = 0.25
"""About how long one compiled chunk of a plain ``jaxmpm run`` (no ``--out``) takes: between chunks
the run stops at a breakdown and answers Ctrl-C, so a broken run stops computing and Ctrl-C is
answered within about this time. Chunked runs equal one scan bit for bit."""

STEP_NS = 70.0
"""Nanoseconds per particle-stencil node and per grid node of one step, measured on one CPU core
(2D and 3D, every interpolator: 67-81 ns); it sizes the chunks."""


def add_parser(subparsers) -> None:
    """Add the ``run`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser("run", help="run a scene and report its errors")
    p.add_argument("scene", help="scene name (see `jaxmpm scenes`)")
    p.add_argument("params", nargs="*", default=[], metavar="name=value", help="scene parameters")
    p.add_argument(
        "--interpolator",
        required=True,
        choices=list(jm.INTERPOLATORS),
        help="gimp is uGIMP (l = r0); cpgimp is contiguous-particle GIMP (l = F r0)",
    )
    p.add_argument("--artificial-cells", type=int, default=0, metavar="N", help="layers at each free end")
    p.add_argument("--transfer", default="flip", choices=list(jm.TRANSFERS))
    p.add_argument(
        "--ordering",
        default="usl",
        choices=["usl", "musl"],
        help="usl: the talk's (default); musl: re-project nodal velocities before kinematics",
    )
    p.add_argument("--dt", type=float, help="time step (> 0), with --steps")
    p.add_argument("--steps", type=int, help="number of steps (>= 0), with --dt")
    p.add_argument("--t-end", type=float, metavar="T", help="instead of --dt/--steps: run to time T")
    p.add_argument("--cfl", type=float, default=0.5, help="with --t-end: dt = CFL h / max(c + |v|) (0.5)")
    p.add_argument("--max-steps", type=int, metavar="N", help="with --t-end: the bound on the step count")
    add_viscosity_option(p)
    p.add_argument(
        "--cfl-limit",
        default="1.0",
        metavar="X",
        help="fail a step with dt > X h / max(c + |v|); 'none' disables (default 1.0)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--vtk", metavar="DIR", help="write ParaView files (particles, grid, .pvd series) to DIR")
    p.add_argument(
        "--vtk-every",
        type=int,
        metavar="K",
        help="with --vtk: a frame every K steps (steps/10; max-steps/10 with --t-end)",
    )
    p.add_argument("--out", metavar="FILE", help="run in chunks and save the run to FILE (.npz)")
    p.add_argument(
        "--overwrite", action="store_true", help="with --out or --vtk: replace what is there (else refused)"
    )
    p.add_argument("--checkpoint-every", type=int, metavar="N", help="with --out: save every N chunks")
    p.add_argument("--chunk", type=int, default=1000, metavar="STEPS", help="with --out: steps per chunk")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (long runs, --out)")
    p.add_argument(
        "--grad",
        metavar="NAME[,NAME...]",
        help="add d(F_rms_rel)/d(NAME) for continuous parameters (scene parameters, h, dt)",
    )
    add_process_options(p)
    p.set_defaults(handler=command)


def command(args) -> int:
    """Run the scene (in one compiled scan, or in chunks saved to ``--out``) and report it.

    Args:
        args: the parsed command line.

    Returns:
        The exit status, 0.

    Raises:
        UsageError: bad input.
        Breakdown: the run broke down (after writing the frames of ``--vtk`` up to it).
    """
    # What can be checked without a device is checked before joining other processes (--distributed),
    # which waits until they all start: a misspelt parameter or option is said at once.
    _assign.scene_arguments(args.scene, args.params, options=flags(args))
    _check_timing_options(args)
    first = start_processes(args)
    scene = _assign.scene(args.scene, args.params, options=flags(args))
    if args.cfl_limit.lower() == "none":
        cfl = None
    else:
        try:
            cfl = float(args.cfl_limit)
        except ValueError:
            raise UsageError(f"--cfl-limit must be a number or 'none', got {args.cfl_limit!r}") from None
    names = None
    if args.grad is not None:
        names = _assign.comma_list(args.grad, "--grad")
        _check_grad(scene, names)
    interp = jm.INTERPOLATORS[args.interpolator]()
    transfer = jm.TRANSFERS[args.transfer]()
    viscosity = _assign.viscosity(args.viscosity, scene)
    settings = dict(
        transfer=transfer,
        artificial_cells=args.artificial_cells,
        cfl_limit=cfl,
        ordering=args.ordering,
        viscosity=viscosity,
        devices=devices_option(args),
    )
    if args.t_end is not None:
        if args.dt is not None or args.steps is not None:
            raise UsageError(
                "give either --dt and --steps, or --t-end (with --cfl and --max-steps), not both"
            )
        if args.max_steps is None:
            raise UsageError("--t-end needs --max-steps N (the bound on the number of steps)")
        if args.out is not None or args.grad is not None:
            raise UsageError("--out and --grad take fixed steps (--dt and --steps), not --t-end")
        if cfl is not None and args.cfl > cfl:
            raise UsageError(
                f"--cfl {args.cfl:g} is above --cfl-limit {cfl:g}: every full step would fail its "
                "stability check; give --cfl <= --cfl-limit (or --cfl-limit none)"
            )
        timing = dict(t_end=args.t_end, cfl=args.cfl, max_steps=args.max_steps)
    else:
        if args.dt is None or args.steps is None:
            raise UsageError("give --dt and --steps, or --t-end and --max-steps")
        for dest, option in (("max_steps", "--max-steps"), ("cfl", "--cfl")):
            if dest in args.given:
                raise UsageError(f"{option} goes with --t-end (a run to an end time), not --dt and --steps")
        timing = dict(dt=args.dt, steps=args.steps)
    if names is not None and args.dt is not None and args.steps is not None:
        t_run = args.dt * args.steps
        if not jm.metrics.exact_holds(scene, t_run):
            raise UsageError(
                f"--grad: the run ends at t = {t_run:.6g}, past t_valid = {float(scene.t_valid):.6g}, where "
                "the scene's exact solution stops holding, so F_rms_rel is not measured there: give "
                "fewer --steps or a smaller --dt"
            )
    if args.overwrite and args.out is None and args.vtk is None:
        raise UsageError("--overwrite goes with --out FILE or --vtk DIR (what it would replace)")
    if "chunk" in args.given and args.out is None:
        raise UsageError("--chunk needs --out FILE (a run saved in chunks of that many steps)")
    if args.checkpoint_every is not None and args.out is None:
        raise UsageError("--checkpoint-every needs --out FILE to write the checkpoints to")
    if args.vtk_every is not None and args.vtk is None:
        raise UsageError("--vtk-every needs --vtk DIR to write the frames to")
    if args.vtk is not None:
        if args.out is not None:
            raise UsageError("--vtk writes a run's saved frames; it does not combine with --out")
        steps = args.steps if args.steps is not None else args.max_steps  # the bound, with --t-end
        every = args.vtk_every if args.vtk_every is not None else max(1, steps // 10)
        if every < 1:
            raise UsageError(f"--vtk-every must be an integer >= 1, got {every}")
        fields = ("x", "v", "F", "sigma") + (("corners",) if interp.tracks_corners else ())
        fields += ("e", "internal") if scene.regions is not None else ()  # kept where the run has them
        settings["saveat"] = jm.SaveAt(every=every, fields=fields + (("C",) if transfer.affine else ()))
    if args.out is not None:
        try:
            _check_out(args.out, overwrite=args.overwrite, option="--out")
        except ValueError as e:
            raise as_option(e) from None
    made = [] if args.vtk is None else _missing(pathlib.Path(args.vtk))  # what --vtk will make
    vtk_made = bool(made)
    if args.vtk is not None:
        _check_vtk_folder(args.vtk, args.overwrite)
    with _removed_on_failure(made):  # a refused or broken run leaves none
        progress = False if args.no_progress or not first else None
        try:
            if args.out is not None:
                try:
                    sol, compile_s, wall_s = jm.long_run.run_timed(
                        scene,
                        interp,
                        dt=args.dt,
                        steps=args.steps,
                        chunk=args.chunk,
                        out=args.out,
                        checkpoint_every=args.checkpoint_every,
                        progress=progress,
                        overwrite=args.overwrite,
                        **settings,
                    )
                except jm.SimulationError as e:
                    failed = local_solution(e.solution)
                    _breakdown_json(args, scene, failed, viscosity, devices=settings["devices"])
                    raise Breakdown(failed, dt=args.dt, saved_in=pathlib.Path(args.out)) from None
                except OSError as e:  # e.g. the disk filled up while saving: a checkpoint before it is intact
                    raise CannotWrite(f"--out {args.out}", e) from None
            else:
                try:
                    sol, compile_s, wall_s = _plain(scene, interp, timing, settings, progress)
                except jm.SimulationError as e:
                    # the good frames are written before the breakdown is reported
                    failed = local_solution(e.solution)
                    vtk = None
                    if args.vtk is not None and first:
                        vtk = _write_vtk(args, scene, interp, settings, failed, vtk_made)
                    _breakdown_json(args, scene, failed, viscosity, vtk, settings["devices"])
                    raise Breakdown(failed, dt=args.dt) from None
        except ValueError as e:
            raise as_option(e) from None
        sol = local_solution(sol)
        grad = grad_s = None
        if names is not None and not _measured(scene, sol):  # no error, so no derivative of it
            grad = dict.fromkeys(names)
        elif names is not None:
            t0 = time.perf_counter()
            try:
                g = jm.gradient(
                    scene, interp, names, dt=args.dt, steps=args.steps, checkpoint=True, **settings
                )
            except ValueError as e:  # _check_grad has refused what it can before the run
                raise UsageError(f"--grad: {e}") from None
            grad = {n: float(g[n]) for n in names}
            grad_s = time.perf_counter() - t0
        run = _settings(args, sol, viscosity, settings["devices"])
        if args.vtk is not None and first:
            run["vtk"] = _write_vtk(args, scene, interp, settings, sol, vtk_made)
        return report(run, scene, sol, compile_s, wall_s, grad=grad, grad_s=grad_s, as_json=args.json)


@contextlib.contextmanager
def _removed_on_failure(folders):
    """Remove ``folders`` (the ones this command makes, deepest first) when the command fails while
    they are still empty, so that a run refused after the folder check (``--devices`` beyond the
    devices there, say) leaves nothing behind; a folder with files in it stays."""
    try:
        yield
    except BaseException:
        for folder in folders:
            try:
                folder.rmdir()  # only if empty
            except OSError:
                break
        raise


def _missing(folder: pathlib.Path) -> list[pathlib.Path]:
    """The folders that making ``folder`` makes: it and each missing parent, deepest first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


def _plain(scene, interp, timing, settings, progress):
    """A run without ``--out``: one compiled scan when it is short, else compiled chunks of about
    ``CHUNK_S`` seconds (``jaxmpm.long_run``, nothing saved), so that a breakdown stops it and Ctrl-C
    is answered between chunks."""
    keys = ("transfer", "artificial_cells", "cfl_limit", "ordering", "viscosity")
    model = jm.Model(scene, interp, **{k: settings[k] for k in keys})
    particles, nodes = _memory.sizes(model)
    step_s = 1e-9 * STEP_NS * (particles * interp.stencil_width**scene.dim + nodes) + 2e-6
    chunk = max(1, int(CHUNK_S / step_s))
    saveat = settings.get("saveat")
    if "t_end" in timing:
        if saveat is not None or timing["max_steps"] <= chunk:
            return jm.simulate_timed(scene, interp, **timing, **settings)
        return _to_end_in_chunks(scene, interp, timing, settings, chunk)
    if saveat is not None:
        chunk = max(saveat.every, chunk // saveat.every * saveat.every)
    if timing["steps"] <= chunk:
        return jm.simulate_timed(scene, interp, **timing, **settings)
    return jm.long_run.run_timed(scene, interp, **timing, chunk=chunk, progress=progress, **settings)


def _to_end_in_chunks(scene, interp, timing, settings, chunk):
    """A run to ``--t-end`` in compiled chunks of ``chunk`` steps (the scan of ``simulate``, cut
    into pieces: bit for bit the same), stopping at ``t_end``, a breakdown or ``--max-steps``."""
    model, dt, max_steps, _ = prepare(scene, interp, **timing, **settings)
    limit = jnp.asarray(max_steps, dtype=jnp.int32)
    t0 = time.perf_counter()
    state, body = _start(model)
    compiled = _advance.lower(model, state, dt, limit, chunk).compile()
    t1 = time.perf_counter()
    try:
        while int(state.status) == 0 and float(state.t) < float(dt.t_end) and int(state.step) < max_steps:
            state = wait(compiled(model, state, dt, limit, chunk))
    except KeyboardInterrupt:
        at = f"step {int(state.step)} (t = {float(state.t):.6g})"
        raise KeyboardInterrupt(f"interrupted at {at} of a run to t = {timing['t_end']:g}") from None
    sol = jm.Solution(finish_to_end(state, dt), body, None, None)
    wall = time.perf_counter() - t1
    if int(sol.state.status):
        raise jm.SimulationError(failure_message(sol, None, scene), sol)
    return sol, t1 - t0, wall


@eqx.filter_jit
def _start(model):
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    return shard_particles(model, state, state.x.shape[0]), s.body


@eqx.filter_jit
def _advance(model, state, dt, limit, chunk: int):
    return advance(model, jm.setup(model), state, dt, chunk, jm.SaveAt(), None, limit)[0]


def _breakdown_json(args, scene, sol, viscosity, vtk: dict | None = None, devices=None) -> None:
    """With ``--json``, the report of a run that broke down (its last good state, ``status`` and
    ``failure``, ``vtk``: the frames written up to it, and with ``--grad`` each derivative null) on
    stdout, before the one line on stderr."""
    if args.json:
        run = _settings(args, sol, viscosity, devices)
        if vtk is not None:
            run["vtk"] = vtk
        # no derivative of a run that broke down: each is null, as where F_rms_rel is not measured
        grad = None if args.grad is None else dict.fromkeys(_assign.comma_list(args.grad, "--grad"))
        report(run, scene, sol, None, None, grad=grad, as_json=True)


def _measured(scene, sol) -> bool:
    """Whether ``F_rms_rel`` is measured at the run's end: the exact solution holds there, and some
    particle is where the errors are measured."""
    where = measured_where(scene, sol)
    return jm.metrics.exact_holds(scene, sol.state.t) and (where is None or bool(np.any(np.asarray(where))))


def _check_timing_options(args) -> None:
    """The step's options as numbers, before anything touches a device: ``--dt`` and ``--t-end``
    finite and > 0, ``--steps`` >= 0, ``--max-steps`` >= 1 (in the library's words, naming the option;
    each is checked again where it is used)."""
    try:
        for value, option in ((args.dt, "--dt"), (args.t_end, "--t-end")):
            if value is not None:
                check_positive(option, value)
        for value, option, least in ((args.steps, "--steps", 0), (args.max_steps, "--max-steps", 1)):
            if value is not None:
                check_int(option, value, least)
    except ValueError as e:
        raise UsageError(str(e)) from None


def _check_grad(scene, names: list[str]) -> None:
    """``--grad NAMES`` before the run: the scene has an exact solution (``F_rms_rel`` is the error
    against it) and each name is one of its continuous parameters, ``h`` or ``dt``, that the run reads
    (``jaxmpm.calibrate.unused``)."""
    if scene.exact is None:
        having = [name for name, cls in jm.SCENES.items() if cls.exact is not None]
        raise UsageError(
            f"--grad gives d(F_rms_rel)/d(NAME), F_rms_rel being the error against the scene's exact "
            f"solution, and {scene.name} has none; scenes with one: {', '.join(having)}"
        )
    try:
        jm.sensitivity.check_names(scene, names)
    except ValueError as e:
        raise UsageError(f"--grad: {e}") from None
    idle = jm.calibrate.unused(scene)
    for name in names:
        if name in idle:  # its derivative is 0 because the run never reads it
            raise UsageError(f"--grad: {name} would do nothing: {idle[name]}")


def _settings(args, sol, viscosity, devices=None) -> dict:
    """The run's settings as ``report`` prints them first (and ``--json`` keeps them)."""
    run = dict(
        scene=args.scene,
        interpolator=args.interpolator,
        transfer=args.transfer,
        artificial_cells=args.artificial_cells,
        ordering=args.ordering,
        dt=args.dt,
        steps=args.steps,
    )
    if args.t_end is not None:
        run.update(t_end=args.t_end, cfl=args.cfl, max_steps=args.max_steps, steps_taken=int(sol.state.step))
    if viscosity is not None:
        run["viscosity"] = viscosity.coefficients()
    if args.out is not None:
        run["out"] = str(args.out)
    if devices is not None:
        run["devices"] = devices
    return run


def _check_vtk_folder(folder, overwrite: bool) -> None:
    """``--vtk DIR`` before the run: a folder that can be written, without the frames of another run
    (unless ``--overwrite``)."""
    path = writable_folder(folder, "--vtk")
    folders = sorted(p.name for p in path.iterdir() if _SERIES.fullmatch(p.name) and p.is_dir())
    if folders:  # a frame could not be written there: said before the run, not after it
        raise UsageError(
            f"--vtk {folder}: {folders[0]} is a folder, where the series writes a file of that name; "
            "move it, or choose another folder"
        )
    old = sorted(p.name for p in path.iterdir() if p.suffix in (".vtk", ".vtu", ".vts", ".vtr", ".pvd"))
    if old and not overwrite:
        raise UsageError(
            f"--vtk {folder} already holds ParaView files ({old[0]}{', ...' if len(old) > 1 else ''}); "
            "pass --overwrite to replace them, or choose another folder"
        )


def _write_vtk(args, scene, interp, settings, sol, made: bool) -> dict:
    """Write the run's ParaView series to ``--vtk DIR``, then remove the frames of an earlier series
    there (``--overwrite``) that the new one does not replace, so that the folder holds one run.

    A series that cannot be written whole leaves the folder as it was (``jm.vtk.write_series``), and a
    folder this command made for it is removed again, so that the command can be run again as is.

    Args:
        args: the parsed command line.
        scene, interp, settings: the run.
        sol: its solution (of a run that broke down: the good frames are written).
        made: the folder did not exist before this command.

    Returns:
        The ``vtk`` entry of the report: ``dir``, ``frames``, ``every``.

    Raises:
        UsageError: (without ``--overwrite``) a file to write is there already (put there during the
            run: ``_check_vtk_folder`` found none before it).
        CannotWrite: a file cannot be written (a full disk).
    """
    out_dir = pathlib.Path(args.vtk)
    keys = ("transfer", "artificial_cells", "cfl_limit", "ordering", "viscosity")
    model = jm.Model(scene, interp, **{k: settings[k] for k in keys})
    try:
        # a run that broke down writes its good frames (marked so in the .pvd files); the breakdown
        # itself is reported by the caller
        paths = jm.vtk.write_series(out_dir, model, sol, overwrite=args.overwrite, allow_broken=True)
    except FileExistsError:
        raise UsageError(
            f"--vtk {args.vtk}: a file of the series appeared there during the run (another run writing "
            "there?); pass --overwrite to replace it, or choose another folder"
        ) from None
    except ValueError as e:  # a folder under a frame's name, made there during the run
        raise UsageError(f"--vtk {args.vtk}: {e}") from None
    except OSError as e:
        if made:
            with contextlib.suppress(OSError):  # only if empty: what someone else put there stays
                out_dir.rmdir()
        raise CannotWrite(f"--vtk {args.vtk}", e) from None
    written = {p.name for p in paths}
    for old in out_dir.iterdir():
        if old.name not in written and _FRAME.fullmatch(old.name) and old.is_file():
            with contextlib.suppress(FileNotFoundError):
                old.unlink()
    return dict(dir=str(args.vtk), frames=(len(paths) - 2) // 2, every=settings["saveat"].every)


_FRAME = re.compile(r"(particles|grid)_\d{5,}\.vtk")
"""The name of a frame that ``jm.vtk.write_series`` writes."""

_SERIES = re.compile(r"(particles|grid)(_\d{5,}\.vtk|\.pvd)")
"""The name of a file that ``jm.vtk.write_series`` writes: a frame or a series' ``.pvd``."""


def report(
    run: dict,
    scene: jm.AbstractScene,
    sol: jm.Solution,
    compile_s: float | None,
    wall_s: float | None,
    *,
    grad: dict | None = None,
    grad_s: float | None = None,
    as_json: bool = False,
) -> int:
    """Print a run: its settings, parameters, particles, errors and diagnostics. For a run that broke
    down, its last good state, with ``status`` and ``failure`` (step, particle, quantities) saying why.

    In 1D the particle lists hold numbers; in 2D and 3D vectors and nested ``dim x dim`` lists, the
    particles by initial position, last axis fastest.

    Args:
        run: the run's settings (``scene``, ``interpolator``, ``dt``, ...), printed first.
        scene: the scene that ran.
        sol: its solution.
        compile_s: compile time (s), or ``None`` for a run that broke down.
        wall_s: run time (s), or ``None`` for a run that broke down.
        grad: ``d(F_rms_rel)/d(name)`` by name (each ``None`` where ``F_rms_rel`` is not measured at
            the run's end), or ``None``.
        grad_s: the time of the gradient (s), with ``grad`` (``None`` where none was computed).
        as_json: one JSON object instead of the table.

    Returns:
        The exit status, 0.
    """
    st = sol.state
    # A scene of regions with fronts (the detonation) is measured where its solution is smooth.
    where = measured_where(scene, sol)
    # Before the front has moved far enough in, no particle is away from it: nothing to measure yet.
    unmeasured = where is not None and not bool(np.any(np.asarray(where)))
    # After a breakdown this is the last good state's report, and it says so (status, failure).
    err = jm.errors(scene, st, sol.body, where=None if unmeasured else where, allow_broken=True)
    # Past the time the scene's exact solution holds (t_valid) its errors against it are null.
    holds = jm.metrics.exact_holds(scene, st.t)
    if unmeasured:
        err.update(dict.fromkeys(jm.metrics.EXACT_ERRORS))
    if where is not None:
        err["p_rms_rel"] = (
            jm.metrics.pressure_error(scene, st, sol.body, where, allow_broken=True)
            if holds and not unmeasured
            else None
        )
    diag = jm.diagnostics(scene, st, sol.body, allow_broken=True)
    params = scene.parameter_values()
    plate = ring = None
    if isinstance(scene, (jm.Detonation, jm.scenes.AbstractGurney)):
        params["cj"] = {k: float(v) for k, v in scene.cj().items()}
    if isinstance(scene, jm.GurneySlab):  # the plate's velocity, and Gurney's estimate of where it tends
        plate = dict(
            velocity=float(scene.plate_velocity(st, sol.body)), gurney=float(scene.gurney_velocity())
        )
    if isinstance(scene, jm.GurneyCylinder):  # the ring's radial velocity and mean radius, and Gurney's
        ring = dict(
            velocity=float(scene.ring_velocity(st, sol.body)),
            radius=float(scene.ring_radius(st, sol.body)),
            gurney=float(scene.gurney_velocity()),
        )
    if scene.dim == 1:
        particles = dict(
            X=floats(sol.body.X[:, 0]),
            x=floats(st.x[:, 0]),
            v=floats(st.v[:, 0]),
            F=floats(st.F[:, 0, 0]),
            sigma=floats(st.sigma[:, 0, 0]),
        )
    else:
        particles = dict(
            X=floats(sol.body.X), x=floats(st.x), v=floats(st.v), F=floats(st.F), sigma=floats(st.sigma)
        )
    if scene.regions is not None:  # a body of regions: each particle's region and thermodynamic state
        particles["rho"] = floats(jm.metrics.density(st, sol.body, allow_broken=True))
        particles["p"] = floats(jm.metrics.pressure(st, allow_broken=True))
        if st.e is not None:
            particles["e"] = floats(st.e)
        particles["region"] = [int(r) for r in np.asarray(sol.body.region)]
        if st.internal is not None:
            particles.update({f"internal.{k}": floats(val) for k, val in st.internal.items()})
            if "lambda" in st.internal:  # a programmed burn's burn fraction
                particles["lambda"] = floats(st.internal["lambda"])
    euler = jm.metrics.euler_errors(scene, st, sol.body, allow_broken=True) if float(st.t) > 0 else None
    if euler is None and hasattr(scene, "solution") and st.e is not None and scene.dim == 1:
        # an exact Euler solution that is not measured now (at t = 0, or past t_valid): the keys stay
        euler = {f"{k}_L1": None for k in jm.metrics.EULER_FIELDS}
    if euler is not None:
        err = {**err, **euler}
    if as_json:
        out = dict(
            **run,
            t=float(st.t),
            params=params,
            **({"regions": _regions(scene)} if scene.regions is not None else {}),
            **({"plate": plate} if plate is not None else {}),
            **({"ring": ring} if ring is not None else {}),
            particles=particles,
            errors={k: scalar(v) for k, v in err.items()},
            diagnostics={k: (float(v) if np.ndim(v) == 0 else floats(v)) for k, v in diag.items()},
            status=int(st.status),
            failure=sol.failure(),
            wall_s=wall_s,
            compile_s=compile_s,
        )
        if grad is not None:
            out["grad"] = grad
            out["grad_s"] = grad_s
        print_json(out)
        return 0
    print("  ".join(f"{k}={v}" for k, v in run.items()) + f"  t={float(st.t):.6g}")
    print("params: " + "  ".join(f"{k}={v}" for k, v in params.items()))
    ex = jm.metrics.exact_fields(scene, sol.body, st.t)
    if scene.dim > 1:
        _print_particles_nd(sol, ex)
    else:
        _print_particles_1d(sol, particles, ex)
    if scene.exact is not None and not holds:
        print(
            f"(past t_valid = {float(scene.t_valid):.6g}, where the exact solution stops holding: no "
            "errors against it)"
        )
    elif unmeasured:
        print(
            "(no particle is yet away from the front, where the errors against the exact solution are "
            "measured (scene.smooth): they are not measurable yet)"
        )
    print("errors: " + "  ".join(f"{k}={scalar(v):.4g}" for k, v in err.items() if v is not None))
    print("diagnostics: " + "  ".join(f"{k}={_fmt(v)}" for k, v in diag.items()))
    if plate is not None:
        print(f"plate: velocity={plate['velocity']:.6g}  gurney={plate['gurney']:.6g}")
    if ring is not None:
        print(
            f"ring: velocity={ring['velocity']:.6g}  radius={ring['radius']:.6g}  gurney={ring['gurney']:.6g}"
        )
    if grad is not None and grad_s is None:
        print(f"d(F_rms_rel)/d {', '.join(grad)}: none (F_rms_rel is not measured at this time)")
    elif grad is not None:
        print(
            "d(F_rms_rel)/d: "
            + "  ".join(f"{k}={v:.10g}" for k, v in grad.items())
            + f"  (grad_s={grad_s:.3f})"
        )
    print(f"compile_s={compile_s:.3f}  wall_s={wall_s:.6f}")
    return 0


def _regions(scene) -> list[dict]:
    """Each region of a scene of regions: its material (name and parameters), density, velocity,
    energy and particle count, for ``--json``."""
    out = []
    for region, count in zip(scene.regions(), scene.layout().counts):
        out.append(
            dict(
                **_describe(region.material),
                rho0=float(region.rho0),
                velocity=floats(region.velocity) if scene.dim > 1 else float(region.velocity[0]),
                energy=float(region.energy),
                particles=count,
            )
        )
    return out


def _describe(mat) -> dict:
    """A material as JSON: ``material`` (its class) and its parameters, a wrapped material (a burn's
    reactant and products) nested the same way."""
    out: dict = dict(material=type(mat).__name__)
    for f in dataclasses.fields(mat):
        value = getattr(mat, f.name)
        if value is None or isinstance(value, (str, bool)):
            out[f.name] = value
        elif isinstance(value, eqx.Module):
            out[f.name] = _describe(value)
        else:
            out[f.name] = float(value) if np.ndim(value) == 0 else floats(value)
    return out


def _fmt(v) -> str:
    a = np.asarray(v, dtype=float)
    return f"{float(a):.6g}" if a.ndim == 0 else "(" + ", ".join(f"{x:.6g}" for x in a) + ")"


def _print_particles_1d(sol, particles, ex) -> None:
    head = f"{'p':>4} {'X':>12} {'x':>12} {'v':>12} {'F':>12} {'sigma':>13}"
    print(head + (f" {'F_exact':>12}" if ex is not None else ""))
    for p in range(sol.body.n):
        row = (
            f"{p:>4} {particles['X'][p]:>12.6g} {particles['x'][p]:>12.6g} {particles['v'][p]:>12.6g} "
            f"{particles['F'][p]:>12.8f} {particles['sigma'][p]:>13.6g}"
        )
        if ex is not None:
            row += f" {float(np.asarray(ex['F'])[p, 0, 0]):>12.8f}"
        print(row)


def _print_particles_nd(sol, ex) -> None:
    """One row per particle in 2D/3D: reference and current position, velocity, ``J = det F`` and the
    mean normal stress ``tr(sigma) / dim`` (``--json`` has every component)."""
    st = sol.state
    X, x, v = np.asarray(sol.body.X), np.asarray(st.x), np.asarray(st.v)  # to the host once, not per row
    J = np.linalg.det(np.asarray(st.F))
    p_mean = np.trace(np.asarray(st.sigma), axis1=1, axis2=2) / st.F.shape[1]
    head = f"{'p':>6} {'X':>28} {'x':>28} {'v':>28} {'J':>12} {'tr(sigma)/dim':>14}"
    if ex is not None:
        J_ex = np.linalg.det(np.asarray(ex["F"]))
        head += f" {'J_exact':>12}"
    print(head)
    for p in range(sol.body.n):
        row = f"{p:>6} {_fmt(X[p]):>28} {_fmt(x[p]):>28} {_fmt(v[p]):>28} {J[p]:>12.8f} {p_mean[p]:>14.6g}"
        if ex is not None:
            row += f" {J_ex[p]:>12.8f}"
        print(row)
