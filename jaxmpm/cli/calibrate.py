"""``jaxmpm calibrate``: fit material constants to a measured free-surface trajectory or plate velocity."""

import csv
import io
import math
import sys
import warnings

import numpy as np

import jaxmpm as jm
from jaxmpm._checks import check_positive
from jaxmpm._simulate import prepare
from jaxmpm.scenes.gas_slab import pad_for
from jaxmpm.sensitivity import static_parameters

from . import _assign
from ._common import UsageError, add_process_options, devices_option, flags, print_json, start_processes

SCENES = ("gas-slab", "gurney-slab")
"""The scenes ``calibrate`` fits: the gas slab's free surface ``t,x_free``, the Gurney slab's plate
velocity ``t,v_plate``."""


def add_parser(subparsers) -> None:
    """Add the ``calibrate`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser(
        "calibrate",
        help="fit constants to a free-surface trajectory (gas-slab) or a plate velocity (gurney-slab)",
    )
    p.add_argument("scene", help="scene name (gas-slab, gurney-slab)")
    p.add_argument("params", nargs="*", metavar="name=value", help="scene parameters (the model's)")
    p.add_argument(
        "--data",
        required=True,
        metavar="FILE.csv",
        help="header and columns t,x_free (gurney-slab: t,v_plate)",
    )
    p.add_argument(
        "--fit",
        default=None,
        metavar="NAME[,NAME...]",
        help="parameters to fit (gas-slab: gamma,P0 by default; gurney-slab: required)",
    )
    p.add_argument(
        "--start",
        action="append",
        metavar="NAME=V[,NAME=V...]",
        help="start values (default: the scene's); repeat for several starts, fitted at once (under vmap, "
        "or spread over --devices), the best one reported",
    )
    p.add_argument("--interpolator", default="cpdi", choices=list(jm.INTERPOLATORS))
    p.add_argument(
        "--method", default="lm", choices=list(jm.calibrate.METHODS), help="lm: Levenberg-Marquardt (default)"
    )
    p.add_argument("--iterations", type=int, default=50, help="the most iterations (50)")
    p.add_argument(
        "--viscosity",
        nargs="?",
        const="2.0,0.2",
        metavar="QUAD,LIN",
        help="artificial viscosity in compression in the model (default coefficients 2.0,0.2); "
        "gurney-slab's detonation front is a shock, which rings without it. No shear coefficient: both "
        "scenes are 1D, where a shear viscosity vanishes",
    )
    p.add_argument("--dt", type=float, help="model time step (default: CFL 0.2 at the start values)")
    p.add_argument(
        "--noise", type=float, metavar="SIGMA", help="noise of x_free (default: estimated from the residuals)"
    )
    p.add_argument(
        "--max-correlation",
        type=float,
        default=jm.calibrate.MAX_CORRELATION,
        metavar="C",
        help="warn when two constants correlate beyond C (0.99)",
    )
    p.add_argument(
        "--max-relative-std",
        type=float,
        default=jm.calibrate.MAX_RELATIVE_STD,
        metavar="R",
        help="warn when a standard error exceeds R times its value (0.1)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_process_options(p, spread="the starts (Levenberg-Marquardt)")
    p.set_defaults(handler=command)


_FARTHEST = 100.0  # data beyond this many times the starts' reach are refused unless pad is given


def read_trajectory(path: str, column: str = "x_free") -> tuple[np.ndarray, np.ndarray]:
    """The measured trajectory: a CSV file (UTF-8 text) with a header and the columns ``t`` and
    ``column`` (``x_free``, or ``v_plate`` for the Gurney slab); other columns are ignored, blank lines
    skipped.

    Args:
        path: the file.
        column: the observed quantity's column.

    Returns:
        ``(t, values)``, at least two rows, every value finite, ``t`` from ``>= 0`` increasing.

    Raises:
        UsageError: the file cannot be read or is not CSV text; it is empty or has no ``t,{column}``
            header; a cell is missing, not a number or not finite; or ``t`` is negative or does not
            increase. The message names the line (the header is line 1) and the column.
    """
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise UsageError(f"--data: cannot read {path}: {e.strerror or e}") from None

    def not_text(why) -> UsageError:
        return UsageError(
            f"--data {path} is not a CSV text file ({why}); it needs a header t,{column} and rows of numbers"
        )

    if b"\x00" in raw:
        raise not_text("it holds NUL bytes: a binary file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise not_text(f"line {line}, byte {e.start}, is not UTF-8 text") from None
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""), strict=True)  # strict: a quote left open
        header = reader.fieldnames
        rows = [(reader.line_num, row) for row in reader]
    except csv.Error as e:
        raise not_text(e) from None
    if header is None:
        raise UsageError(f"--data: {path} is empty; it needs a header with the columns t,{column} and 2 rows")
    if not {"t", column} <= {str(h).strip() for h in header}:
        shown = ",".join(str(h) for h in header)
        raise UsageError(
            f"--data: {path} needs a header with the columns t,{column}; its header is {shown[:80]!r}"
        )
    names = [str(h).strip() for h in header]
    for name in ("t", column):
        if names.count(name) > 1:
            raise UsageError(f"--data: {path} has {names.count(name)} columns named {name!r}; it needs one")
    columns = {str(h).strip(): h for h in header}
    t, x = [], []
    for line, row in rows:
        if None in row:  # DictReader keeps the fields past the header's under None
            raise UsageError(
                f"--data: {path}, line {line}: more fields than the header's {len(header)} "
                f"({','.join(names)})"
            )
        values = []
        for name in ("t", column):
            cell = row.get(columns[name])
            if cell is None or not cell.strip():
                raise UsageError(f"--data: {path}, line {line}: no value in column {name}")
            try:
                v = float(cell)
            except ValueError:
                raise UsageError(
                    f"--data: {path}, line {line}: {name} is not a number, got {cell.strip()[:40]!r}"
                ) from None
            if not math.isfinite(v):
                raise UsageError(
                    f"--data: {path}, line {line}: {name} is {cell.strip()[:40]}; "
                    "non-finite values are not allowed (remove the row)"
                )
            values.append(v)
        if t and not values[0] > t[-1]:
            raise UsageError(
                f"--data: {path}, line {line}: t must increase, got t={values[0]:.9g} after t={t[-1]:.9g}"
            )
        if not t and values[0] < 0:
            raise UsageError(f"--data: {path}, line {line}: t must start at >= 0, got t={values[0]:.9g}")
        t.append(values[0])
        x.append(values[1])
    if len(t) < 2:
        raise UsageError(f"--data: {path} has {len(t)} row(s) of t,{column}; need at least 2")
    return np.array(t), np.array(x)


def fit_names(scene: jm.AbstractScene, text: str) -> list[str]:
    """The names of ``--fit``, checked against the scene's kind: its constants, each once. Which of
    them this scene's run uses (the Gurney slab's ``explosive``) is ``check_used``'s.

    Args:
        scene: the scene.
        text: the comma-separated names, e.g. ``"gamma,P0"``.

    Returns:
        The names, in order.

    Raises:
        UsageError: no name, a name given twice, or a name that cannot be fitted (``h`` and ``dt``
            are not material constants; a static parameter such as the Gurney slab's ``split`` has
            no derivative; structural and unknown names are not parameters), with the names that
            can.
    """
    names = _assign.comma_list(text, "--fit")
    allowed = jm.calibrate.fittable(scene)
    if not names:
        raise UsageError(f"--fit: name at least one parameter; fittable: {', '.join(allowed)}")
    later = jm.calibrate.unused(scene)  # named by check_used
    for n in names:
        if n in allowed or n in later:
            continue
        if n in jm.calibrate.NOT_FITTED:
            why = f"{n} is {jm.calibrate.NOT_FITTED[n]}, not a material constant"
        elif n in static_parameters(scene):
            why = f"{n} is static (it places the particles when the run is compiled), so it has no derivative"
        elif n in type(scene).parameters():
            why = f"{n} is structural (an integer), not a material constant"
        else:
            why = f"unknown parameter {n!r}"
        raise UsageError(f"--fit: {why}; fittable: {', '.join(allowed)}")
    return names


def check_used(scene: jm.AbstractScene, names: list[str]) -> None:
    """Refuse a name of ``--fit`` that this scene's run does not use (``jm.calibrate.unused``: the
    Gurney slab's ``sqrt_2E``, and the constants its ``explosive`` does not take).

    Args:
        scene: the scene.
        names: the names of ``--fit`` (``fit_names``).

    Raises:
        UsageError: such a name, with why and the names that can be fitted.
    """
    idle = jm.calibrate.unused(scene)
    for n in names:
        if n in idle:
            raise UsageError(
                f"--fit: {n} cannot be fitted: {idle[n]}; fittable: {', '.join(jm.calibrate.fittable(scene))}"
            )


def viscosity_option(text: str | None) -> jm.ArtificialViscosity | None:
    """``--viscosity QUAD,LIN`` as the model's artificial viscosity (``None``: none).

    Args:
        text: the option's value (``"2.0,0.2"`` when given bare), or ``None``.

    Returns:
        The ``ArtificialViscosity`` (no shear viscosity), or ``None``.

    Raises:
        UsageError: not two numbers >= 0; a third (the shear coefficient of ``jaxmpm run``) is refused
            by name: the scenes ``calibrate`` fits are 1D, where a shear viscosity vanishes.
    """
    if text is None:
        return None
    items = text.split(",")
    if len(items) == 3:
        raise UsageError(
            f"--viscosity takes QUAD,LIN, got 3 numbers {text!r}: a third, SHEAR (as `jaxmpm run` takes "
            "it), would be a shear viscosity, which vanishes in 1D, and gas-slab and gurney-slab are 1D"
        )
    try:
        if len(items) != 2:
            raise ValueError(f"{len(items)} number" + ("" if len(items) == 1 else "s"))
        c_quad, c_lin = (float(c) for c in items)
        return jm.ArtificialViscosity(c_quad=c_quad, c_lin=c_lin)
    except ValueError as e:
        raise UsageError(f"--viscosity must be QUAD,LIN (two numbers >= 0), got {text!r}: {e}") from None


_MOST_STEPS = 2**31 - 1  # the bound of a step counter


def _check_model_run(scene, interp, path: str, t: np.ndarray, dt: float) -> None:
    """Refuse, naming ``--data``, a trajectory whose model run (every step saved) has too many steps
    or does not fit in memory, before the fit is traced."""
    steps = math.ceil(float(t[-1]) / dt - 1e-9)
    what = f"--data: {path}: t reaches {float(t[-1]):.6g}, {steps:.3g} model steps of dt = {dt:.3g}"
    if steps > _MOST_STEPS:
        raise UsageError(f"{what}, more than {_MOST_STEPS}; give times in seconds, or a larger --dt")
    if jm.calibrate.observable(scene) == "v_plate":
        fields = ("v",)
    else:
        fields = ("x", "F", "corners") if interp.tracks_corners else ("x", "F")
    try:  # prepare checks the run's memory, the saved history included
        prepare(scene, interp, dt=dt, steps=steps, saveat=jm.SaveAt(every=1, fields=fields))
    except ValueError as e:
        raise UsageError(f"{what}: {e}") from None


def command(args) -> int:
    """Fit ``--fit`` of the gas slab (or the Gurney slab) to the trajectory (plate velocity) in ``--data``
    and print the fitted values.

    Args:
        args: the parsed command line.

    Returns:
        The exit status: 0 (also when the data do not determine the constants: then one warning line
        on stderr), or 3 when the fit has no answer (every start broke down, or every step toward a
        lower loss is a run that breaks down).

    Raises:
        UsageError: bad input.
    """
    if args.scene not in SCENES:
        raise UsageError(
            "calibrate fits a free-surface trajectory (gas-slab) or a plate's velocity (gurney-slab): "
            f"the scene must be one of {', '.join(SCENES)}, got {args.scene}"
        )
    _assign.scene_arguments(args.scene, args.params, options=flags(args))  # before joining others
    first = start_processes(args)
    scene = _assign.scene(args.scene, args.params, options=flags(args))
    column = jm.calibrate.observable(scene)
    if args.fit is None and args.scene != "gas-slab":
        raise UsageError(
            f"--fit: name the constants to fit for {args.scene}; fittable with these parameters: "
            f"{', '.join(jm.calibrate.fittable(scene))} (explosive=gamma-law adds D, gamma, rho0; "
            "explosive=jwl the JWL constants)"
        )
    names = fit_names(scene, "gamma,P0" if args.fit is None else args.fit)
    starts = [_assign.numbers(text, "--start") for text in args.start] if args.start else [{}]
    given = _assign.names(args.params)
    for start in starts:
        for k in start:
            if k not in names:
                raise UsageError(f"--start: {k} is not fitted (fitted: {', '.join(names)})")
            if k in given:
                raise UsageError(
                    f"--start: {k} is also given as a scene parameter ({k}=...), which is its start: "
                    "give it once"
                )
    if args.iterations < 1:
        raise UsageError(f"--iterations must be an integer >= 1, got {args.iterations}")
    start_scenes = []
    for start in starts:
        try:
            start_scenes.append(type(scene)(**{**scene.parameter_values(), **start}))
        except ValueError as e:
            raise UsageError(f"--start: {e}") from None
    devices = devices_option(args)
    if devices is not None and args.method != "lm":
        raise UsageError(f"--devices spreads the starts of --method lm only, got --method {args.method}")
    positive = (("--dt", args.dt), ("--noise", args.noise), ("--max-relative-std", args.max_relative_std))
    for flag, value in positive:
        if value is not None:
            try:
                check_positive(flag, value)
            except ValueError as e:
                raise UsageError(str(e)) from None
    if not 0.0 < args.max_correlation <= 1.0:  # NaN fails too
        raise UsageError(f"--max-correlation must be a number in (0, 1], got {args.max_correlation}")
    viscosity = viscosity_option(args.viscosity)
    t, x = read_trajectory(args.data, column)
    check_used(scene, names)
    if column == "v_plate" and viscosity is None:
        print(
            f"jaxmpm: note: calibrate {args.scene} runs without artificial viscosity; its detonation front "
            "is a shock, which rings without it: --viscosity (coefficients 2.0,0.2) adds it",
            file=sys.stderr,
        )
    # a grid for the gas slab's data and the start's expansion, with room for trial runs
    if "pad" not in given and column == "x_free":
        start_reach = max(s.max_reach() for s in start_scenes)
        if float(np.max(x)) > _FARTHEST * start_reach:
            raise UsageError(
                f"--data: x_free reaches {float(np.max(x)):.6g}, more than {_FARTHEST:g} times as far as any "
                f"start's slab can go ({start_reach:.6g}), which asks for a grid of "
                f"{pad_for(scene, 1.25 * float(np.max(x))):,} cells beyond the slab: check the units of "
                "x_free, or give pad=N (those cells) to size the grid yourself"
            )
        reach = max(float(np.max(x)), start_reach)
        pad = max(scene.pad, pad_for(scene, 1.25 * reach))
        if pad != scene.pad:
            scene = type(scene)(**{**scene.parameter_values(), "pad": pad})
    # CFL 0.2 at the fastest start
    dt = (
        args.dt
        if args.dt is not None
        else 0.2 * float(scene.h) / max(float(s.wave_speed) for s in start_scenes)
    )
    interp = jm.INTERPOLATORS[args.interpolator]()
    _check_model_run(scene, interp, args.data, t, dt)
    try:
        with warnings.catch_warnings():  # the library's warning is printed once, below
            warnings.simplefilter("ignore", jm.calibrate.CalibrationWarning)
            fit = jm.calibrate.calibrate(
                scene,
                interp,
                t,
                x,
                fit=names,
                starts=starts,
                devices=devices,
                dt=dt,
                method=args.method,
                iterations=args.iterations,
                noise=args.noise,
                max_correlation=args.max_correlation,
                max_relative_std=args.max_relative_std,
                progress=False if args.no_progress else None,
                **({} if viscosity is None else {"viscosity": viscosity}),
            )
    except ValueError as e:  # the data's column by its name in the file, not the library's argument
        raise UsageError(str(e).replace("x_data reach", f"--data: {column} reaches", 1)) from None
    except jm.calibrate.CalibrationError as e:
        if args.json and first:  # a reader of the JSON gets an object that says why there is no fit
            print_json(
                dict(
                    fitted=None,
                    error=str(e),
                    **_settings(args, dt, scene, viscosity, names),
                    starts=_start_values(scene, names, starts),
                )
            )
        print(f"jaxmpm: {e}", file=sys.stderr)
        return 3

    if not first:  # the first process reports for all: they hold the same fit
        return 0
    start_values = _start_values(scene, names, starts)

    def matrix(m):
        return {a: {b: _number(m[i, j]) for j, b in enumerate(fit.names)} for i, a in enumerate(fit.names)}

    out = dict(
        fitted=fit.fitted,
        loss=fit.loss,
        iterations=fit.iterations,
        wall_s=fit.wall_s,
        **_settings(args, dt, scene, viscosity, names),
        start=start_values[fit.best_start],
        starts=start_values,
        best_start=fit.best_start,
        starts_fitted=[
            None if i in fit.failed_starts else {n: float(fit.starts_fitted[n][i]) for n in names}
            for i in range(len(starts))
        ],
        loss_history=[float(v) for v in fit.history[: fit.iterations + 1, fit.best_start]],
        converged=fit.converged,
        std={k: _number(v) for k, v in fit.std.items()},
        correlation=matrix(fit.correlation),
        condition=_number(fit.condition),
        covariance=matrix(fit.covariance),
        covariance_theta=matrix(fit.covariance_theta),
        offsets=fit.offsets,
        sigma=_number(fit.sigma),
        noise=args.noise,
        weakest=fit.weakest,
        warning=fit.warning,
        rejected_trials=len(fit.rejected),
        failed_starts={str(k): v for k, v in fit.failed_starts.items()},
    )
    if args.json:
        print_json(out)
    else:
        print("fitted: " + "  ".join(f"{k}={v:.10g}" for k, v in fit.fitted.items()))
        print("std:    " + "  ".join(f"{k}={v:.3g}" for k, v in fit.std.items()))
        print(
            f"loss={fit.loss:.6g}  iterations={fit.iterations}  wall_s={fit.wall_s:.3f}  dt={dt:.6g}  "
            f"pad={scene.pad}  condition={fit.condition:.3g}"
        )
    for i, why in fit.failed_starts.items():  # the fit is the other starts'; say which did not count
        print(f"jaxmpm: note: start {i} stopped and is not in the fit: {why}", file=sys.stderr)
    if fit.warning is not None:
        print(f"jaxmpm: warning: {fit.warning}", file=sys.stderr)
    return 0


def _settings(args, dt, scene, viscosity, names) -> dict:
    """The fit's settings, as ``--json`` reports them: scene, interpolator, method, dt, pad, viscosity,
    and ``fixed``, the scene's parameters other than the fitted ``names``, as the fit ran them."""
    return dict(
        scene=args.scene,
        interpolator=args.interpolator,
        method=args.method,
        dt=dt,
        pad=scene.pad,
        viscosity=None if viscosity is None else viscosity.coefficients(),
        fixed={k: _plain(v) for k, v in scene.parameter_values().items() if k not in names},
    )


def _plain(v):
    """A scene parameter's value for JSON: strings, booleans and integers as they are, numbers as floats."""
    return v if isinstance(v, str | bool | int) else float(v)


def _start_values(scene, names, starts) -> list[dict]:
    """Every start's values of the fitted names (a name a start does not give: the scene's)."""
    return [{n: float(s.get(n, float(getattr(scene, n)))) for n in names} for s in starts]


def _number(v):
    """A float for JSON: ``inf`` and NaN as ``null`` (JSON has neither)."""
    v = float(v)
    return v if math.isfinite(v) else None
