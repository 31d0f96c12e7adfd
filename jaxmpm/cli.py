"""The ``jaxmpm`` command: ``scenes``, ``run`` and ``study``.

A contract that outside scripts rely on: command names, ``name=value`` scene parameters and the
JSON keys of ``run --json`` are kept stable (extended, never renamed).
"""

import argparse
import json
import math
import re
import sys
import time

BENCH_CODES = ("numpy", "jax", "taichi", "warp", "jaxmpm")  # jaxmpm.bench.CODES, without importing it

STUDIES = {
    "talk": "talk",
    "convergence": "convergence",
    "work-precision": "work_precision",
    "stability": "stability",
    "multid": "multid",
}


class UsageError(Exception):
    """Bad input from the command line: one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # argparse takes '-1e-5' for an option (its matcher has no exponent); the check that follows
        # must say "dt must be > 0", not "expected one argument".
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message):  # one clear line, no usage dump, no traceback
        raise UsageError(message)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="jaxmpm", description="Differentiable MPM in JAX: SPQ, GIMP, CPDI and MPQ side by side.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    sc = sub.add_parser("scenes", help="list scenes with their parameters and defaults")
    sc.add_argument("--json", action="store_true", help="print one JSON object")

    run = sub.add_parser("run", help="run a scene and report its errors")
    run.add_argument("scene", help="scene name (see `jaxmpm scenes`)")
    run.add_argument("params", nargs="*", metavar="name=value", help="scene parameters")
    run.add_argument(
        "--interpolator",
        required=True,
        choices=["spq", "gimp", "cpgimp", "cpdi", "mpq"],
        help="gimp is uGIMP (l = r0); cpgimp is contiguous-particle GIMP (l = F r0)",
    )
    run.add_argument("--artificial-cells", type=int, default=0, metavar="N", help="layers at each free end")
    run.add_argument("--transfer", default="flip", choices=["flip", "pic", "apic"])
    run.add_argument(
        "--ordering",
        default="usl",
        choices=["usl", "musl"],
        help="usl: the talk's (default); musl: re-project nodal velocities before kinematics",
    )
    run.add_argument("--dt", type=float, help="time step (> 0), with --steps")
    run.add_argument("--steps", type=int, help="number of steps (>= 0), with --dt")
    run.add_argument("--t-end", type=float, metavar="T", help="instead of --dt/--steps: run to time T")
    run.add_argument("--cfl", type=float, default=0.5, help="with --t-end: dt = CFL h / max(c + |v|) (0.5)")
    run.add_argument("--max-steps", type=int, metavar="N", help="with --t-end: the bound on the step count")
    run.add_argument(
        "--viscosity",
        nargs="?",
        const="2.0,0.2",
        metavar="QUAD,LIN",
        help="artificial viscosity in compression (default coefficients 2.0,0.2)",
    )
    run.add_argument(
        "--cfl-limit",
        default="1.0",
        metavar="X",
        help="fail a step with dt > X h / max(c + |v|); 'none' disables (default 1.0)",
    )
    run.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    run.add_argument(
        "--vtk", metavar="DIR", help="write ParaView files (particles, grid, .pvd series) to DIR"
    )
    run.add_argument(
        "--vtk-every", type=int, metavar="K", help="with --vtk: a frame every K steps (steps/10)"
    )
    run.add_argument("--out", metavar="FILE", help="run in chunks and save the run to FILE (.npz)")
    run.add_argument("--checkpoint-every", type=int, metavar="N", help="with --out: save every N chunks")
    run.add_argument("--chunk", type=int, default=1000, metavar="STEPS", help="with --out: steps per chunk")
    run.add_argument("--no-progress", action="store_true", help="no progress bar (with --out)")
    run.add_argument(
        "--grad",
        metavar="NAME[,NAME...]",
        help="add d(F_rms_rel)/d(NAME) for continuous parameters (scene parameters, h, dt)",
    )

    cal = sub.add_parser("calibrate", help="fit constants (gamma, P0, rho0) to a free-surface trajectory")
    cal.add_argument("scene", help="scene name (gas-slab)")
    cal.add_argument("params", nargs="*", metavar="name=value", help="scene parameters (the model's)")
    cal.add_argument("--data", required=True, metavar="FILE.csv", help="header and columns t,x_free")
    cal.add_argument("--fit", default="gamma,P0", metavar="NAME[,NAME...]", help="parameters to fit")
    cal.add_argument("--start", metavar="NAME=V[,NAME=V...]", help="start values (default: the scene's)")
    cal.add_argument("--interpolator", default="cpdi", choices=["spq", "gimp", "cpgimp", "cpdi", "mpq"])
    cal.add_argument("--method", default="lbfgs", choices=["lbfgs", "adam"])
    cal.add_argument("--iterations", type=int, default=50, help="the most iterations (50)")
    cal.add_argument("--dt", type=float, help="model time step (default: CFL 0.2 at the start values)")
    cal.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    cal.add_argument("--no-progress", action="store_true", help="no progress bar")

    ens = sub.add_parser("ensemble", help="run a batch of parameter sets in one compiled, sharded call")
    ens.add_argument("scene", help="scene name (see `jaxmpm scenes`)")
    ens.add_argument("params", nargs="*", metavar="name=value", help="fixed scene parameters")
    ens.add_argument("--vary", action="append", required=True, metavar="NAME=LOW:HIGH", help="repeatable")
    ens.add_argument("--members", type=int, required=True, help="members (uniform random in the ranges)")
    ens.add_argument("--seed", type=int, default=0, help="random seed of the sample (0)")
    ens.add_argument("--interpolator", default="cpdi", choices=["spq", "gimp", "cpgimp", "cpdi", "mpq"])
    ens.add_argument("--transfer", default="flip", choices=["flip", "pic", "apic"])
    ens.add_argument("--artificial-cells", type=int, default=0, metavar="N")
    ens.add_argument("--dt", type=float, help="time step, with --steps (default: run to --t-end)")
    ens.add_argument("--steps", type=int, help="number of steps, with --dt")
    ens.add_argument("--t-end", type=float, metavar="T", help="end time (default: two wave transits, 2 L/c0)")
    ens.add_argument("--cfl", type=float, default=0.5, help="with --t-end: dt = CFL h / max(c + |v|)")
    ens.add_argument("--max-steps", type=int, metavar="N", help="with --t-end (default: 3x an estimate)")
    ens.add_argument("--json", action="store_true", help="print one JSON object on stdout")

    rs = sub.add_parser("resume", help="continue a run saved with `run --out FILE`")
    rs.add_argument("file", help="the saved run (.npz)")
    rs.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    rs.add_argument("--no-progress", action="store_true", help="no progress bar")

    bn = sub.add_parser("bench", help="particle-steps per second against NumPy, plain JAX, Taichi and Warp")
    bn.add_argument(
        "--sizes", default="1000,8000,64000,256000,1000000", help="particle counts, comma-separated"
    )
    bn.add_argument("--steps", type=int, default=100, help="steps per run (a quarter from 500k particles up)")
    bn.add_argument(
        "--sizes-2d",
        default="16384,102400",
        help="particle counts of jaxmpm's 2D runs (4 k^2: k^2 cells of 2 x 2), comma-separated; '' for none",
    )
    bn.add_argument("--dtypes", default="f32,f64", help="f32, f64 or both (each in its own process)")
    bn.add_argument(
        "--codes",
        default=",".join(BENCH_CODES),
        help="among numpy, jax (plain JAX), taichi, warp (when installed: pip install jaxmpm[bench]), jaxmpm",
    )
    bn.add_argument("--interpolators", default="spq,gimp,cpgimp,cpdi,mpq", help="jaxmpm's, comma-separated")
    bn.add_argument(
        "--no-extras", action="store_true", help="skip the reverse-mode and ensemble measurements"
    )
    bn.add_argument("--out", help="directory for bench.csv, bench.json and bench.md")
    bn.add_argument("--json", action="store_true", help="print one JSON object on stdout")

    st = sub.add_parser("study", help="run a study and write its figures and tables")
    st.add_argument(
        "name",
        choices=list(STUDIES),
        help="talk: the 2013 MPM workshop comparison; convergence: observed orders on the verification "
        "ladder; work-precision: error against run time; stability: the stiff and extreme map; multid: 2D "
        "and 3D (first step, axis-aligned orders, blast domain gaps, a 100k-particle 2D run)",
    )
    st.add_argument("--out", required=True, help="output directory")
    st.add_argument("--small", action="store_true", help="a quick reduced version (for tests)")
    return p


def _scene_from(name: str, assignments: list[str]):
    from .scenes import SCENES

    if name not in SCENES:
        raise UsageError(f"unknown scene {name!r}; allowed: {', '.join(sorted(SCENES))}")
    cls = SCENES[name]
    defaults = cls.parameters()
    kwargs = {}
    for item in assignments:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise UsageError(f"scene parameters are name=value, got {item!r}")
        if key not in defaults:
            raise UsageError(f"unknown parameter {key!r} for scene {name}; allowed: {', '.join(defaults)}")
        if isinstance(defaults[key], str):
            kwargs[key] = raw
        elif isinstance(defaults[key], bool):
            if raw.lower() not in ("true", "false", "1", "0"):
                raise UsageError(f"{key} must be true or false, got {raw!r}")
            kwargs[key] = raw.lower() in ("true", "1")
        elif isinstance(defaults[key], int):
            try:
                kwargs[key] = int(raw)
            except ValueError:
                raise UsageError(f"{key} must be an integer, got {raw!r}") from None
        else:
            try:
                value = float(raw)
            except ValueError:
                raise UsageError(f"{key} must be a number, got {raw!r}") from None
            if not math.isfinite(value):
                raise UsageError(f"{key} must be finite, got {raw}")
            kwargs[key] = value
    try:
        return cls(**kwargs)
    except ValueError as e:
        raise UsageError(str(e)) from None


def _floats(a) -> list:
    import numpy as np

    arr = np.asarray(a, dtype=float)
    return arr.tolist()


def _scalar(x):
    return None if x is None else float(x)


def _cmd_scenes(args) -> int:
    from .scenes import SCENES

    if args.json:
        out = {
            name: dict(description=cls.description, parameters=cls.parameters())
            for name, cls in SCENES.items()
        }
        print(json.dumps(out))
        return 0
    for name, cls in SCENES.items():
        print(f"{name}: {cls.description}")
        for key, value in cls.parameters().items():
            kind = type(value).__name__
            print(f"    {key:<8} = {value!r:<10} ({kind})")
    return 0


def _cmd_run(args) -> int:

    import jaxmpm as jm

    scene = _scene_from(args.scene, args.params)
    if args.cfl_limit.lower() == "none":
        cfl = None
    else:
        try:
            cfl = float(args.cfl_limit)
        except ValueError:
            raise UsageError(f"--cfl-limit must be a number or 'none', got {args.cfl_limit!r}") from None
    names = None
    if args.grad is not None:
        names = [n for n in args.grad.split(",") if n]
        try:
            jm.sensitivity.check_names(scene, names)
        except ValueError as e:
            raise UsageError(f"--grad: {e}") from None
    interp = jm.INTERPOLATORS[args.interpolator]()
    transfer = jm.TRANSFERS[args.transfer]()
    viscosity = None
    if args.viscosity is not None:
        try:
            quad, lin = (float(c) for c in args.viscosity.split(","))
            viscosity = jm.ArtificialViscosity(c_quad=quad, c_lin=lin)
        except ValueError as e:
            raise UsageError(
                f"--viscosity must be QUAD,LIN (two numbers >= 0), got {args.viscosity!r}: {e}"
            ) from None
    settings = dict(
        transfer=transfer,
        artificial_cells=args.artificial_cells,
        cfl_limit=cfl,
        ordering=args.ordering,
        viscosity=viscosity,
    )
    if viscosity is not None and args.out is not None:
        raise UsageError("--viscosity is not saved by --out runs yet; run without --out")
    if args.t_end is not None:
        if args.dt is not None or args.steps is not None:
            raise UsageError(
                "give either --dt and --steps, or --t-end (with --cfl and --max-steps), not both"
            )
        if args.max_steps is None:
            raise UsageError("--t-end needs --max-steps N (the bound on the number of steps)")
        if args.out is not None or args.grad is not None:
            raise UsageError("--out and --grad take fixed steps (--dt and --steps), not --t-end")
        timing = dict(t_end=args.t_end, cfl=args.cfl, max_steps=args.max_steps)
    else:
        if args.dt is None or args.steps is None:
            raise UsageError("give --dt and --steps, or --t-end and --max-steps")
        timing = dict(dt=args.dt, steps=args.steps)
    if args.checkpoint_every is not None and args.out is None:
        raise UsageError("--checkpoint-every needs --out FILE to write the checkpoints to")
    if args.vtk_every is not None and args.vtk is None:
        raise UsageError("--vtk-every needs --vtk DIR to write the frames to")
    if args.vtk is not None:
        if args.out is not None:
            raise UsageError("--vtk writes a run's saved frames; it does not combine with --out")
        every = args.vtk_every if args.vtk_every is not None else max(1, (args.steps or args.max_steps) // 10)
        if every < 1:
            raise UsageError(f"--vtk-every must be an integer >= 1, got {every}")
        fields = ("x", "v", "F", "sigma") + (("corners",) if interp.tracks_corners else ())
        settings["saveat"] = jm.SaveAt(every=every, fields=fields + (("C",) if transfer.affine else ()))
    try:
        if args.out is None:
            try:
                sol, compile_s, wall_s = jm.simulate_timed(scene, interp, **timing, **settings)
            except jm.SimulationError as e:  # the good frames are written before the error is reported
                if args.vtk is not None:
                    _write_vtk(args.vtk, scene, interp, settings, e.solution)
                raise
        else:
            sol, compile_s, wall_s = jm.long_run.run_timed(
                scene,
                interp,
                dt=args.dt,
                steps=args.steps,
                chunk=args.chunk,
                out=args.out,
                checkpoint_every=args.checkpoint_every,
                progress=False if args.no_progress else None,
                **{k: v for k, v in settings.items() if k != "viscosity"},
            )
    except ValueError as e:
        raise UsageError(str(e)) from None
    grad = grad_s = None
    if names is not None:
        t0 = time.perf_counter()
        try:
            g = jm.gradient(scene, interp, names, dt=args.dt, steps=args.steps, checkpoint=True, **settings)
        except ValueError as e:
            raise UsageError(f"--grad: {e}") from None
        grad = {n: float(g[n]) for n in names}
        grad_s = time.perf_counter() - t0
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
        run["viscosity"] = [float(viscosity.c_quad), float(viscosity.c_lin)]
    if args.out is not None:
        run["out"] = str(args.out)
    if args.vtk is not None:
        paths = _write_vtk(args.vtk, scene, interp, settings, sol)
        run["vtk"] = dict(dir=str(args.vtk), frames=(len(paths) - 2) // 2, every=settings["saveat"].every)
    return _report(run, scene, sol, compile_s, wall_s, grad, grad_s, args.json)


def _write_vtk(out_dir, scene, interp, settings, sol):
    import jaxmpm as jm

    keys = ("transfer", "artificial_cells", "cfl_limit", "ordering", "viscosity")
    model = jm.Model(scene, interp, **{k: settings[k] for k in keys})
    return jm.vtk.write_series(out_dir, model, sol)


def _cmd_resume(args) -> int:
    import jaxmpm as jm

    try:
        sol, compile_s, wall_s, meta = jm.long_run.resume_timed(
            args.file, progress=False if args.no_progress else None
        )
    except (FileNotFoundError, ValueError) as e:
        raise UsageError(str(e)) from None
    scene = jm.SCENES[meta["scene"]](**meta["params"])
    run = dict(
        scene=meta["scene"],
        interpolator=meta["interpolator"]["name"],
        transfer=meta["transfer"],
        artificial_cells=meta["artificial_cells"],
        ordering=meta["ordering"],
        dt=meta["dt"],
        steps=meta["steps"],
        out=str(args.file),
    )
    return _report(run, scene, sol, compile_s, wall_s, None, None, args.json)


def _report(run: dict, scene, sol, compile_s, wall_s, grad, grad_s, as_json: bool) -> int:
    import numpy as np

    import jaxmpm as jm

    err = jm.errors(scene, sol.state, sol.body)
    diag = jm.diagnostics(scene, sol.state, sol.body)
    params = scene.parameter_values()
    st = sol.state
    if scene.dim == 1:  # numbers, as in every 1D release
        particles = dict(
            X=_floats(sol.body.X[:, 0]),
            x=_floats(st.x[:, 0]),
            v=_floats(st.v[:, 0]),
            F=_floats(st.F[:, 0, 0]),
            sigma=_floats(st.sigma[:, 0, 0]),
        )
    else:  # lists of dim numbers, dim x dim nested lists; particles by initial position, last axis fastest
        particles = dict(
            X=_floats(sol.body.X), x=_floats(st.x), v=_floats(st.v), F=_floats(st.F), sigma=_floats(st.sigma)
        )
    if as_json:
        out = dict(
            **run,
            t=float(st.t),
            params=params,
            particles=particles,
            errors={k: _scalar(v) for k, v in err.items()},
            diagnostics={k: (float(v) if np.ndim(v) == 0 else _floats(v)) for k, v in diag.items()},
            status=int(st.status),
            wall_s=wall_s,
            compile_s=compile_s,
        )
        if grad is not None:
            out["grad"] = grad
            out["grad_s"] = grad_s
        print(json.dumps(out))
        return 0
    print("  ".join(f"{k}={v}" for k, v in run.items()) + f"  t={float(st.t):.6g}")
    print("params: " + "  ".join(f"{k}={v}" for k, v in params.items()))
    ex = jm.metrics.exact_fields(scene, sol.body, st.t)
    if scene.dim > 1:
        _print_particles_nd(sol, ex)
    else:
        _print_particles_1d(sol, particles, ex)
    print("errors: " + "  ".join(f"{k}={_scalar(v):.4g}" for k, v in err.items() if v is not None))
    print("diagnostics: " + "  ".join(f"{k}={_fmt(v)}" for k, v in diag.items()))
    if grad is not None:
        print(
            "d(F_rms_rel)/d: "
            + "  ".join(f"{k}={v:.10g}" for k, v in grad.items())
            + f"  (grad_s={grad_s:.3f})"
        )
    print(f"compile_s={compile_s:.3f}  wall_s={wall_s:.6f}")
    return 0


def _fmt(v) -> str:
    import numpy as np

    a = np.asarray(v, dtype=float)
    return f"{float(a):.6g}" if a.ndim == 0 else "(" + ", ".join(f"{x:.6g}" for x in a) + ")"


def _print_particles_1d(sol, particles, ex) -> None:
    import numpy as np

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
    import numpy as np

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


def _named_values(text: str, what: str) -> dict:
    out = {}
    for item in [i for i in text.split(",") if i]:
        key, sep, raw = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[key] = float(raw)
        except ValueError:
            raise UsageError(f"{what} takes NAME=VALUE[,NAME=VALUE...], got {item!r}") from None
    return out


def _read_trajectory(path: str):
    import csv

    import numpy as np

    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise UsageError(f"--data: cannot read {path}: {e.strerror}") from None
    if not rows or not {"t", "x_free"} <= set(rows[0]):
        raise UsageError(f"--data: {path} needs a header with the columns t,x_free")
    try:
        t = np.array([float(r["t"]) for r in rows])
        x = np.array([float(r["x_free"]) for r in rows])
    except (TypeError, ValueError):
        raise UsageError(f"--data: {path} has a value in t or x_free that is not a number") from None
    if len(t) < 2 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(x)):
        raise UsageError("--data: need at least 2 rows of finite t,x_free")
    if t[0] < 0 or np.any(np.diff(t) <= 0):
        raise UsageError("--data: t must start at >= 0 and increase")
    return t, x


def _cmd_calibrate(args) -> int:
    import jaxmpm as jm

    scene = _scene_from(args.scene, args.params)
    if scene.name != "gas-slab":
        raise UsageError(
            f"calibrate fits a free-surface trajectory: the scene must be gas-slab, got {args.scene}"
        )
    t, x = _read_trajectory(args.data)
    names = [n for n in args.fit.split(",") if n]
    start = _named_values(args.start, "--start") if args.start else {}
    try:
        jm.sensitivity.check_names(scene, names)
        if args.dt is not None:
            jm._checks.check_positive("dt", args.dt)
        start_scene = type(scene)(**{**scene.parameter_values(), **start})
    except ValueError as e:
        raise UsageError(str(e)) from None
    dt = args.dt if args.dt is not None else 0.2 * float(scene.h) / float(start_scene.wave_speed)
    try:
        fit = jm.calibrate.calibrate(
            scene,
            jm.INTERPOLATORS[args.interpolator](),
            t,
            x,
            fit=names,
            starts=start,
            dt=dt,
            method=args.method,
            iterations=args.iterations,
            progress=False if args.no_progress else None,
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    except jm.calibrate.CalibrationError as e:
        print(f"jaxmpm: {e}", file=sys.stderr)
        return 3
    out = dict(
        fitted=fit.fitted,
        loss=fit.loss,
        iterations=fit.iterations,
        wall_s=fit.wall_s,
        scene=args.scene,
        interpolator=args.interpolator,
        method=args.method,
        dt=dt,
        start={n: float(start.get(n, float(getattr(scene, n)))) for n in names},
        loss_history=[float(v) for v in fit.history[:, 0]],
    )
    if args.json:
        print(json.dumps(out))
    else:
        print("fitted: " + "  ".join(f"{k}={v:.10g}" for k, v in fit.fitted.items()))
        print(f"loss={fit.loss:.6g}  iterations={fit.iterations}  wall_s={fit.wall_s:.3f}  dt={dt:.6g}")
    return 0


def _cmd_ensemble(args) -> int:
    import time

    import numpy as np

    import jaxmpm as jm

    scene = _scene_from(args.scene, args.params)
    check = jm.sensitivity.continuous_parameters(scene)
    ranges = {}
    for item in args.vary:
        key, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        if not sep or not sep2:
            raise UsageError(f"--vary takes NAME=LOW:HIGH, got {item!r}")
        if key not in check or key == "dt":
            raise UsageError(
                f"--vary: {key!r} is not a continuous scene parameter; allowed: {', '.join(check[:-1])}"
            )
        try:
            ranges[key] = (float(lo), float(hi))
        except ValueError:
            raise UsageError(f"--vary: LOW and HIGH must be numbers, got {item!r}") from None
        if not all(math.isfinite(v) for v in ranges[key]) or ranges[key][0] > ranges[key][1]:
            raise UsageError(f"--vary: need finite LOW <= HIGH, got {item!r}")
    if args.members < 1:
        raise UsageError(f"--members must be an integer >= 1, got {args.members}")
    rng = np.random.default_rng(args.seed)
    vary = {k: rng.uniform(lo, hi, args.members) for k, (lo, hi) in ranges.items()}
    settings = dict(transfer=jm.TRANSFERS[args.transfer](), artificial_cells=args.artificial_cells)
    if args.dt is not None or args.steps is not None:
        if args.dt is None or args.steps is None or args.t_end is not None:
            raise UsageError("give --dt and --steps together, or --t-end (or neither: two wave transits)")
        timing = dict(dt=args.dt, steps=args.steps)
    else:
        # the fastest member sets the bound: sound speeds at the ranges' corners
        import itertools

        speeds = []
        for corner in itertools.product(*[[(k, lo), (k, hi)] for k, (lo, hi) in ranges.items()]):
            try:
                speeds.append(float(type(scene)(**{**scene.parameter_values(), **dict(corner)}).wave_speed))
            except ValueError as e:
                raise UsageError(f"--vary: {e}") from None
        c_min, c_max = min(speeds), max(speeds)
        t_end = args.t_end if args.t_end is not None else 2.0 * float(scene.length) / c_min
        max_steps = args.max_steps or int(3 * t_end * c_max / (args.cfl * float(scene.h))) + 100
        timing = dict(t_end=t_end, cfl=args.cfl, max_steps=max_steps)
    t0 = time.perf_counter()
    try:
        ens = jm.ensemble(scene, jm.INTERPOLATORS[args.interpolator](), vary, **timing, **settings)
    except ValueError as e:
        raise UsageError(str(e)) from None
    wall = time.perf_counter() - t0
    st = ens.solution.state
    results = []
    for i in range(args.members):
        member = ens.member(i)
        r = dict(
            params={k: float(v[i]) for k, v in vary.items()}, status=int(ens.status[i]), t=float(st.t[i])
        )
        r["steps"] = int(st.step[i])
        if ens.status[i]:
            r["failure"] = dict(
                step=int(st.fail_step[i]),
                particle=int(st.fail_particle[i]),
                quantities=jm.status.describe(int(ens.status[i])),
            )
        if scene.name == "gas-slab":
            ms = member.state
            r["x_free"] = float(jm.scenes.gas_slab.free_surface(ms.x, ms.F, ms.corners, member.body))
        if scene.exact is not None and not ens.status[i]:  # a failed member's error says nothing
            err = jm.errors(
                type(scene)(**{**scene.parameter_values(), **r["params"]}), member.state, member.body
            )
            r["F_max_rel"] = float(err["F_max_rel"])
        results.append(r)
    out = dict(
        scene=args.scene,
        interpolator=args.interpolator,
        members=args.members,
        devices=ens.devices,
        ok=int(np.sum(ens.ok)),
        failed=int(np.sum(~ens.ok)),
        wall_s=wall,
        timing={k: float(v) if k != "max_steps" and k != "steps" else int(v) for k, v in timing.items()},
        results=results,
    )
    if args.json:
        print(json.dumps(out))
    else:
        print(
            f"{args.members} members on {ens.devices} device(s): {out['ok']} ok, {out['failed']} failed, "
            f"wall_s={wall:.3f}"
        )
        for i, r in enumerate(results):
            extra = f"  x_free={r['x_free']:.6g}" if "x_free" in r else ""
            extra += f"  F_max_rel={r['F_max_rel']:.3g}" if "F_max_rel" in r else ""
            fail = (
                f"  FAILED at step {r['failure']['step']}: {r['failure']['quantities'][0]}"
                if "failure" in r
                else ""
            )
            print(f"{i:>5} " + " ".join(f"{k}={v:.6g}" for k, v in r["params"].items()) + extra + fail)
    return 0


def _cmd_bench(args) -> int:
    from . import bench

    def names(text, what, allowed):
        items = [t.strip() for t in text.split(",") if t.strip()]
        bad = [t for t in items if t not in allowed]
        if not items or bad:
            raise UsageError(
                f"{what} must be a comma-separated list among {', '.join(allowed)}; got {text!r}"
            )
        return items

    try:
        sizes = [int(t) for t in args.sizes.split(",")]
    except ValueError:
        raise UsageError(f"--sizes must be comma-separated integers, got {args.sizes!r}") from None
    if any(n < 2 or n % 2 for n in sizes):
        raise UsageError(f"--sizes must be even particle counts >= 2 (two per cell), got {args.sizes!r}")
    if args.steps < 2:
        raise UsageError(f"--steps must be an integer >= 2, got {args.steps}")
    try:
        sizes_2d = [int(t) for t in args.sizes_2d.split(",") if t.strip()]
    except ValueError:
        raise UsageError(f"--sizes-2d must be comma-separated integers, got {args.sizes_2d!r}") from None
    if any(n < 4 or n % 4 or round(math.sqrt(n // 4)) ** 2 != n // 4 for n in sizes_2d):
        raise UsageError(
            f"--sizes-2d must be particle counts 4 k^2 (a square of k x k cells, 2 x 2 particles each), "
            f"got {args.sizes_2d!r}"
        )
    dtypes = names(args.dtypes, "--dtypes", ("f32", "f64"))
    codes = names(args.codes, "--codes", BENCH_CODES)
    interps = names(args.interpolators, "--interpolators", ("spq", "gimp", "cpgimp", "cpdi", "mpq"))
    missing = [c for c in codes if not bench.available(c)]
    if missing:
        print(
            f"jaxmpm bench: {', '.join(missing)} not installed, skipped (pip install jaxmpm[bench])",
            file=sys.stderr,
        )
    result = bench.run(
        sizes, args.steps, dtypes, codes, interps, extras=not args.no_extras, sizes_2d=sizes_2d
    )
    if args.out:
        paths = bench.write(result, args.out)
        if not args.json:
            print("wrote " + ", ".join(str(p) for p in paths))
    print(json.dumps(result) if args.json else bench.table(result))
    return 0


def _cmd_study(args) -> int:
    import importlib

    importlib.import_module(f".studies.{STUDIES[args.name]}", "jaxmpm").main(out=args.out, small=args.small)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxmpm`` console script. Enables float64 before anything is built."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from ._simulate import SimulationError
    from .status import MAX_STEPS

    try:
        args = _parser().parse_args(argv)
        commands = {
            "scenes": _cmd_scenes,
            "run": _cmd_run,
            "resume": _cmd_resume,
            "study": _cmd_study,
            "calibrate": _cmd_calibrate,
            "ensemble": _cmd_ensemble,
            "bench": _cmd_bench,
        }
        return commands[args.command](args)
    except UsageError as e:
        print(f"jaxmpm: error: {e}", file=sys.stderr)
        return 2
    except SimulationError as e:
        head, _, tail = str(e).partition(" The state of the last good step")
        saved = tail.partition("error.solution.")[2].strip()  # long runs add where they were saved
        last = int(e.solution.state.step)
        if getattr(args, "t_end", None) is None:
            hint = saved or f"Rerun with --steps {last} to see the last good state."
        elif e.solution.state.status & MAX_STEPS:
            hint = ""
        else:
            hint = f"Rerun with --t-end {float(e.solution.state.t):.9g} to see the last good state."
        print(f"{head} The last good state is step {last}. {hint}".rstrip(), file=sys.stderr)
        return 3


def console() -> None:
    """The console script: ``sys.exit(main())``."""
    sys.exit(main())


if __name__ == "__main__":
    console()
