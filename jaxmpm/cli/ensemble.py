"""``jaxmpm ensemble``: a batch of parameter sets in one compiled, sharded call."""

import itertools
import json
import math
import sys
import time

import numpy as np

import jaxmpm as jm
from jaxmpm import _memory
from jaxmpm._checks import check_int, check_positive
from jaxmpm._simulate import prepare
from jaxmpm.ensemble import variable_parameters
from jaxmpm.scenes.gas_slab import pad_for
from jaxmpm.sensitivity import static_parameters

from . import _assign
from ._common import UsageError, add_viscosity_option, as_option, flags, measured_where, print_json

_MOST_STEPS = 2**31 - 1  # the bound of a step counter


def add_parser(subparsers) -> None:
    """Add the ``ensemble`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser(
        "ensemble",
        help="run a batch of parameter sets in one compiled, sharded call",
        description=(
            "Run --members parameter sets drawn uniformly in the --vary ranges in one compiled, sharded "
            "call. Exit status: 0 when at least one member finished (members that broke down are listed); "
            "3 when every member broke down (one line on stderr; the table or JSON is still printed); "
            "2 for bad input."
        ),
    )
    p.add_argument("scene", help="scene name (see `jaxmpm scenes`)")
    p.add_argument("params", nargs="*", metavar="name=value", help="fixed scene parameters")
    p.add_argument(
        "--vary",
        action="append",
        metavar="NAME=LOW:HIGH",
        help="a continuous scene parameter, not a static one (x0, split); repeatable (or --from-fit)",
    )
    p.add_argument(
        "--from-fit",
        metavar="FIT.json",
        help="draw the fitted constants from the Gaussian of a `jaxmpm calibrate --json` output",
    )
    p.add_argument("--members", type=int, required=True, help="members (uniform random in the ranges)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the sample, an integer >= 0 (0)")
    p.add_argument(
        "--interpolator", choices=list(jm.INTERPOLATORS), help="(default cpdi; with --from-fit the fit's)"
    )
    p.add_argument("--transfer", default="flip", choices=list(jm.TRANSFERS))
    p.add_argument("--artificial-cells", type=int, default=0, metavar="N")
    add_viscosity_option(p, " (with --from-fit: the fit's)")
    p.add_argument("--dt", type=float, help="time step, with --steps (default: run to --t-end)")
    p.add_argument("--steps", type=int, help="number of steps, with --dt")
    p.add_argument("--t-end", type=float, metavar="T", help="end time (default: two wave transits, 2 L/c0)")
    p.add_argument("--cfl", type=float, default=0.5, help="with --t-end: dt = CFL h / max(c + |v|)")
    p.add_argument("--max-steps", type=int, metavar="N", help="with --t-end (default: 3x an estimate)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(handler=command)


def command(args) -> int:
    """Sample ``--members`` parameter sets uniformly in the ``--vary`` ranges, run them as one ensemble,
    and print each member's status, failure and result.

    A member that broke down is reported with its status, failure, time and steps; its measures
    (``x_free``, ``F_max_rel``) are withheld: null in the JSON, ``withheld`` in the table.

    Args:
        args: the parsed command line.

    Returns:
        The exit status: 0 when at least one member ran to the end (members that broke down are
        reported, not raised); 3 when every member broke down (the report is printed all the same,
        and one line on stderr says so).

    Raises:
        UsageError: bad input.
    """
    items = list(args.params)
    fit_file = _fit_json(args.from_fit) if args.from_fit else None
    if fit_file is not None:
        items += fit_scene(fit_file, args.scene, items, _assign.names(args.vary or []))
    scene = _assign.scene(args.scene, items, options=flags(args))
    varying = list(variable_parameters(scene))
    for k in _assign.names(args.vary or []):
        if k in static_parameters(scene):
            raise UsageError(
                f"--vary: {k} is static in {scene.name} (it places the particles when the run is "
                f"compiled), so one compiled ensemble cannot vary it: give it as a scene parameter "
                f"({k}=...) and run an ensemble per value; parameters that can vary: {', '.join(varying)}"
            )
    idle = jm.calibrate.unused(scene)
    for k in _assign.names(args.vary or []):
        if k in idle:
            raise UsageError(
                f"--vary: {k} cannot vary the run: {idle[k]}; every member would run the same; "
                f"parameters that can vary: {', '.join(varying)}"
            )
    ranges = _assign.ranges(args.vary or [], varying)
    fit = read_fit(args.from_fit, fit_file, scene, varying) if args.from_fit else None
    if not ranges and fit is None:
        raise UsageError(
            "give the varied parameters: --vary NAME=LOW:HIGH (repeatable), or --from-fit FIT.json"
        )
    fixed = _assign.names(args.params)
    for k in ranges:
        if k in fixed:
            raise UsageError(f"--vary: {k} is also given as a fixed scene parameter ({k}=...): give it once")
    bounds = dict(ranges)  # each varied parameter's extent: its range, or 6 standard deviations of a fit
    if fit is not None:
        for k in fit["names"]:
            if k in fixed or k in ranges:
                how = "a fixed scene parameter" if k in fixed else "varied by --vary"
                raise UsageError(f"--from-fit: {k} is fitted there and also {how}: give it once")
        bounds.update(fit["bounds"])
    for k, (lo, hi) in ranges.items():  # both ends are values a member may take (uniform on [lo, hi))
        for end in (lo, hi):
            try:
                type(scene)(**{**scene.parameter_values(), k: end})
            except ValueError as e:
                raise UsageError(
                    f"--vary: {e} (at {k}={end:g}, an end of the range {k}={lo:g}:{hi:g})"
                ) from None
    if args.members < 1:
        raise UsageError(f"--members must be an integer >= 1, got {args.members}")
    if args.seed < 0:
        raise UsageError(f"--seed must be an integer >= 0, got {args.seed}")
    interpolator, viscosity = _model(args, fit_file, scene)
    settings = dict(
        transfer=jm.TRANSFERS[args.transfer](), artificial_cells=args.artificial_cells, viscosity=viscosity
    )
    if args.dt is not None or args.steps is not None:
        if args.dt is None or args.steps is None or args.t_end is not None:
            raise UsageError("give --dt and --steps together, or --t-end (or neither: two wave transits)")
        for dest, option in (("max_steps", "--max-steps"), ("cfl", "--cfl")):
            if dest in args.given:
                raise UsageError(f"{option} goes with a run to an end time, not --dt and --steps")
        timing = dict(dt=args.dt, steps=args.steps)
    else:  # the fastest member sets the bound of the defaults: sound speeds at the ranges' corners
        try:
            check_positive("--cfl", args.cfl)
            if args.cfl > 1.0:  # the stability check's limit (simulate's cfl_limit)
                raise ValueError(
                    f"--cfl must be <= 1 (every full step above it fails its check), got {args.cfl:g}"
                )
            if args.t_end is not None:
                check_positive("--t-end", args.t_end)
            if args.max_steps is not None:
                check_int("--max-steps", args.max_steps, 1)
                if args.max_steps > _MOST_STEPS:
                    raise ValueError(
                        f"--max-steps must be <= {_MOST_STEPS} (the bound of a step counter), got "
                        f"{args.max_steps}"
                    )
        except ValueError as e:
            raise as_option(e) from None
        if args.t_end is not None and args.max_steps is not None:
            t_end, max_steps = args.t_end, args.max_steps
        else:
            speeds = []
            for corner in itertools.product(*[[(k, lo), (k, hi)] for k, (lo, hi) in bounds.items()]):
                try:
                    values = {**scene.parameter_values(), **dict(corner)}
                    speeds.append(float(type(scene)(**values).wave_speed))
                except ValueError as e:
                    source = " and ".join(o for o, on in (("--vary", ranges), ("--from-fit", fit)) if on)
                    raise UsageError(f"{source}: {e}") from None
            c_min, c_max = min(speeds), max(speeds)
            if not (math.isfinite(c_max) and c_min > 0):
                raise UsageError(
                    f"the default --t-end and --max-steps come from the sound speed, which in the ranges "
                    f"of --vary must be finite and > 0, got {c_min:.6g} to {c_max:.6g}: give --t-end T "
                    "and --max-steps N"
                )
            t_end = args.t_end if args.t_end is not None else 2.0 * float(scene.length) / c_min
            max_steps = args.max_steps or int(3 * t_end * c_max / (args.cfl * float(scene.h))) + 100
        if max_steps > _MOST_STEPS:
            raise UsageError(
                f"--t-end {t_end:.6g} at --cfl {args.cfl:g} needs about {max_steps:.3g} steps, more than "
                f"{_MOST_STEPS}; give a shorter --t-end or --max-steps"
            )
        timing = dict(t_end=t_end, cfl=args.cfl, max_steps=max_steps)
    if scene.name == "gas-slab":
        scene = _size_grid(scene, bounds, timing, fixed)
    interp = jm.INTERPOLATORS[interpolator]()
    try:
        model, _, steps, saveat = prepare(scene, interp, **timing, **settings)
    except ValueError as e:
        raise as_option(e) from None
    try:  # before the sample is drawn: nothing of the size of --members is allocated first
        _memory.check_run(model, steps, saveat, members=args.members)
    except ValueError as e:
        raise UsageError(f"--members {args.members}: {e}") from None
    rng = np.random.default_rng(args.seed)
    vary = {k: rng.uniform(lo, hi, args.members) for k, (lo, hi) in ranges.items()}
    if fit is not None:
        C = fit["covariance_theta"]
        vary.update(jm.calibrate.draw(fit["fitted"], fit["offsets"], fit["names"], C, args.members, rng))
    t0 = time.perf_counter()
    try:
        ens = jm.ensemble(scene, interp, vary, **timing, **settings)
    except ValueError as e:
        raise as_option(e) from None
    wall = time.perf_counter() - t0
    st = ens.solution.state
    results = []
    for i in range(args.members):
        member = ens.member(i)
        r = dict(
            params={k: float(v[i]) for k, v in vary.items()}, status=int(ens.status[i]), t=float(st.t[i])
        )
        r["steps"] = int(st.step[i])
        failure = member.failure()
        if failure is not None:
            r["failure"] = dict(
                step=failure["step"], particle=failure["particle"], quantities=failure["quantities"]
            )
        # A member that broke down stopped at its last good state, not at the end: its measures are
        # withheld (null), never reported as if it had finished.
        broke = failure is not None or r["status"] != 0
        if scene.name == "gas-slab":
            ms = member.state
            r["x_free"] = (
                None if broke else float(jm.scenes.gas_slab.free_surface(ms.x, ms.F, ms.corners, member.body))
            )
        if scene.exact is not None:
            r["F_max_rel"] = None
            if not broke:  # null too past the time the exact solution holds (t_valid)
                member_scene = type(scene)(**{**scene.parameter_values(), **r["params"]})
                # measured where jaxmpm run measures: a scene with fronts (the detonation) away from
                # them, null before any particle is far enough behind the front
                where = measured_where(member_scene, member)
                if where is None or bool(np.any(np.asarray(where))):
                    err = jm.errors(member_scene, member.state, member.body, where=where)
                    r["F_max_rel"] = None if err["F_max_rel"] is None else float(err["F_max_rel"])
        results.append(r)
    out = dict(
        scene=args.scene,
        interpolator=interpolator,
        viscosity=None if viscosity is None else list(viscosity.coefficients()),
        members=args.members,
        devices=ens.devices,
        ok=int(np.sum(ens.ok)),
        failed=int(np.sum(~ens.ok)),
        wall_s=wall,
        timing={k: float(v) if k != "max_steps" and k != "steps" else int(v) for k, v in timing.items()},
        pad=scene.pad,
        from_fit=None if fit is None else fit["names"],
        results=results,
    )
    status = 0 if out["ok"] else _all_failed(results)
    if args.json:
        print_json(out)
        return status
    print(
        f"{args.members} members on {ens.devices} device(s): {out['ok']} ok, {out['failed']} failed, "
        f"wall_s={wall:.3f}"
    )
    for i, r in enumerate(results):
        broke = r["status"] != 0 or "failure" in r
        extra = ""
        if "x_free" in r:
            extra += "  x_free=" + ("withheld" if broke else f"{r['x_free']:.6g}")
        if "F_max_rel" in r:
            if broke:
                extra += "  F_max_rel=withheld"
            elif r["F_max_rel"] is None:
                extra += "  F_max_rel=none (past t_valid, where the exact solution stops holding)"
            else:
                extra += f"  F_max_rel={r['F_max_rel']:.3g}"
        fail = ""
        if "failure" in r:
            p = r["failure"]["particle"]
            fail = (
                f"  FAILED at step {r['failure']['step']}, {'the run' if p < 0 else f'particle {p}'}: "
                f"{' and '.join(r['failure']['quantities'])}"
            )
        print(f"{i:>5} " + " ".join(f"{k}={v:.6g}" for k, v in r["params"].items()) + extra + fail)
    return status


def _all_failed(results: list[dict]) -> int:
    """Say on stderr, in one line, that every member broke down (the first member's step and quantity);
    the exit status 3."""
    first = results[0]
    where = ", ".join(f"{k}={v:.6g}" for k, v in first["params"].items())
    what = (
        f"at step {first['failure']['step']}: {' and '.join(first['failure']['quantities'])}"
        if "failure" in first
        else f"with status {first['status']}"
    )
    print(
        f"jaxmpm: every member of the ensemble broke down ({len(results)} of {len(results)}); "
        f"member 0 ({where}) {what}. Each member's failure is in the report.",
        file=sys.stderr,
    )
    return 3


def _size_grid(scene, bounds: dict, timing: dict, fixed) -> "jm.GasSlab":
    """The gas slab with a grid that holds every member's free surface to the end of the run.

    The bound is ``GasSlab.max_reach(t_end)`` (energy and escape speed), largest at a corner of the
    varied parameters' extents (it grows with ``P0`` and ``h`` and falls with ``gamma`` and ``p_atm``).
    Without ``pad=`` the grid is enlarged to hold it; a given ``pad=`` is kept (members that leave its
    grid are reported as failures).
    """
    t_end = timing["t_end"] if "t_end" in timing else timing["dt"] * timing["steps"]
    reach, widest = 0.0, scene
    for corner in itertools.product(*[[(k, lo), (k, hi)] for k, (lo, hi) in bounds.items()]):
        try:
            sc = type(scene)(**{**scene.parameter_values(), **dict(corner)})
        except ValueError as e:
            raise UsageError(f"--vary: {e}") from None
        if sc.max_reach(t_end) > reach:
            reach, widest = sc.max_reach(t_end), sc
    need = pad_for(widest, 1.05 * reach)
    if need <= scene.pad or "pad" in fixed:
        return scene
    return type(scene)(**{**scene.parameter_values(), "pad": need})


def _fit_json(path: str):
    """The JSON object in ``path``, for ``--from-fit``.

    Raises:
        UsageError: the file cannot be read, or is not JSON.
    """
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except OSError as e:
        raise UsageError(f"--from-fit: cannot read {path}: {e.strerror or e}") from None
    except (ValueError, UnicodeDecodeError):
        raise UsageError(
            f"--from-fit: {path} is not JSON (the output of `jaxmpm calibrate --json`)"
        ) from None


def _model(args, fit, scene) -> tuple[str, jm.ArtificialViscosity | None]:
    """The members' interpolator and artificial viscosity: the command line's, or with ``--from-fit``
    those the fit ran with (``jaxmpm calibrate`` fits with FLIP and no artificial cells), the model
    whose constants the draws are; another given with it is refused.

    Args:
        args: the parsed command line.
        fit: the fit's JSON object (``_fit_json``), or ``None``.
        scene: the ensemble's scene.

    Returns:
        ``(interpolator name, viscosity or None)``.

    Raises:
        UsageError: a bad ``--viscosity``, or one of ``--interpolator``, ``--viscosity``,
            ``--transfer``, ``--artificial-cells`` that differs from the fit's.
    """
    viscosity = _assign.viscosity(args.viscosity, scene)
    if fit is None:
        return args.interpolator or "cpdi", viscosity
    theirs = "and its constants are that model's"
    ran = fit.get("interpolator")
    ran = ran if ran in jm.INTERPOLATORS else "cpdi"
    if args.interpolator is not None and args.interpolator != ran:
        raise UsageError(
            f"--interpolator {args.interpolator}: the fit ran with {ran}, {theirs}; leave --interpolator "
            f"out (or give {ran})"
        )
    coefficients = fit.get("viscosity")
    fitted = None
    if isinstance(coefficients, list) and coefficients:
        fitted = _assign.viscosity(",".join(str(float(c)) for c in coefficients), scene)
    if viscosity is not None:
        if fitted is None:
            raise UsageError(
                f"--viscosity {args.viscosity}: the fit ran without artificial viscosity, {theirs}; "
                "leave it out"
            )
        if viscosity.coefficients() != fitted.coefficients():
            shown = ",".join(str(c) for c in fitted.coefficients())
            raise UsageError(
                f"--viscosity {args.viscosity}: the fit ran with the artificial viscosity {shown}, "
                f"{theirs}; leave --viscosity out (or give the fit's)"
            )
    if args.transfer != "flip":
        raise UsageError(f"--transfer {args.transfer}: the fit ran with flip, {theirs}")
    if args.artificial_cells:
        raise UsageError(
            f"--artificial-cells {args.artificial_cells}: the fit ran without artificial cells, {theirs}"
        )
    return ran, fitted


def fit_scene(obj, name: str, items, varied) -> list[str]:
    """The scene parameters a fit ran with (its ``fixed``, from ``jaxmpm calibrate --json``) that the
    command line leaves out, as ``name=value`` items, so that the members run the fit's scene; ``pad``
    is left to the ensemble, which sizes its grid for the draws. A parameter the command line gives
    must have the fit's value. A fit without ``fixed`` gives none (``read_fit`` says what else is
    wrong with it).

    Args:
        obj: the fit's JSON object (``_fit_json``).
        name: the ensemble's scene.
        items: the command line's scene parameters (``name=value``).
        varied: the names of ``--vary``.

    Returns:
        The items to add.

    Raises:
        UsageError: the command line gives a parameter another value than the fit ran with.
    """
    fixed = obj.get("fixed") if isinstance(obj, dict) and obj.get("scene", name) == name else None
    if not isinstance(fixed, dict):
        return []
    given = {}
    for item in items:
        try:
            given.update(_assign.scene_arguments(name, [item]))
        except UsageError:  # said when the scene is made, with the command's options
            continue
    added = []
    for k, v in fixed.items():
        if k == "pad" or k in varied or not isinstance(v, (bool, int, float, str)):
            continue
        if k in given:
            same = given[k] == v if isinstance(v, (bool, str)) else float(given[k]) == float(v)
            if not same:
                raise UsageError(
                    f"--from-fit: the fit ran {name} with {k}={v!r}, and the command line gives "
                    f"{k}={given[k]!r}: leave {k} out to run the fit's scene, or fit again with it"
                )
            continue
        added.append(
            f"{k}={str(v).lower() if isinstance(v, bool) else repr(v) if isinstance(v, float) else v}"
        )
    return added


def read_fit(path: str, obj, scene, allowed) -> dict:
    """What ``--from-fit`` draws from: the output of ``jaxmpm calibrate --json``.

    Args:
        path: the JSON file (for the messages).
        obj: its JSON object (``_fit_json``).
        scene: the ensemble's scene (the fit's ``scene`` must name it).
        allowed: the parameters that may vary.

    Returns:
        A dict: ``names``, ``fitted``, ``offsets``, ``covariance_theta`` (an array) and ``bounds`` (name
        to the physical values at 6 standard deviations either side, for the time step and the grid).

    Raises:
        UsageError: the file is not such JSON, is a fit without an answer, names
            another scene or parameters that cannot vary, or has no finite, positive semi-definite
            covariance.
    """
    if isinstance(obj, dict) and obj.get("fitted", "") is None and isinstance(obj.get("error"), str):
        raise UsageError(f"--from-fit: {path} is a fit that has no answer: {obj['error']}")
    keys = ("fitted", "covariance_theta", "offsets")
    if not isinstance(obj, dict) or not all(isinstance(obj.get(k), dict) for k in keys):
        raise UsageError(
            f"--from-fit: {path} is not the output of `jaxmpm calibrate --json` (it needs {', '.join(keys)})"
        )
    if obj.get("scene", scene.name) != scene.name:
        raise UsageError(f"--from-fit: {path} is a fit of {obj['scene']!r}, not of {scene.name!r}")
    names = list(obj["fitted"])
    if not names:
        raise UsageError(f"--from-fit: {path} fits no parameter (its fitted is empty)")
    idle = jm.calibrate.unused(scene)
    for k in names:
        if k in idle:
            raise UsageError(f"--from-fit: {path} fits {k}, which cannot vary this run: {idle[k]}")
        if k not in allowed:
            raise UsageError(f"--from-fit: {k!r} is not a continuous parameter of {scene.name}")
    try:
        fitted = {k: float(obj["fitted"][k]) for k in names}
        offs = {k: float(obj["offsets"][k]) for k in names}
        C = np.array([[float(obj["covariance_theta"][a][b]) for b in names] for a in names])
    except (KeyError, TypeError, ValueError):
        raise UsageError(
            f"--from-fit: {path} has no finite covariance for {', '.join(names)} (null where the data do "
            "not determine the constants; see its warning)"
        ) from None
    finite = all(math.isfinite(v) for v in [*fitted.values(), *offs.values()]) and np.all(np.isfinite(C))
    if not finite or any(fitted[k] <= offs[k] for k in names):
        raise UsageError(
            f"--from-fit: {path}: fitted values, offsets and covariance must be finite, fitted > offset"
        )
    w = np.linalg.eigvalsh(0.5 * (C + C.T))
    if not np.allclose(C, C.T, rtol=1e-9, atol=0) or w[0] < -1e-12 * max(abs(w[-1]), 1e-300):
        raise UsageError(f"--from-fit: {path}: covariance_theta is not symmetric positive semi-definite")
    sd = np.sqrt(np.maximum(np.diag(C), 0.0))
    loose = [k for i, k in enumerate(names) if 6.0 * sd[i] > 700.0]  # exp(6 sd) beyond a float64
    if loose:
        k = loose[0]
        raise UsageError(
            f"--from-fit: {path}: the data hardly determine {k} (standard deviation of log({k} - offset) "
            f"{sd[names.index(k)]:.3g}): members drawn from this fit would span no physical range"
        )
    bounds = {
        k: tuple(offs[k] + (fitted[k] - offs[k]) * math.exp(z * sd[i]) for z in (-6.0, 6.0))
        for i, k in enumerate(names)
    }
    for k, (lo, _) in bounds.items():
        if not lo > offs[k]:  # (fitted - offset) exp(-6 sd) is lost beside the offset in float64
            raise UsageError(
                f"--from-fit: {path}: the data hardly determine {k} (standard deviation of log({k} - "
                f"offset) {sd[names.index(k)]:.3g}): members drawn from this fit would reach {k} = "
                f"{offs[k]:g}, its bound, in float64"
            )
    return dict(names=names, fitted=fitted, offsets=offs, covariance_theta=C, bounds=bounds)
