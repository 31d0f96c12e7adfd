"""Calibration of constants from a measured trajectory, with their uncertainty.

The cylinder test calibrates an explosive product's equation of state by fitting a measured wall
trajectory. Here two scenes play that part (``observable``):

- the gas slab (``GasSlab``): its free surface ``x_R(t)``. Given observations ``(t_i, x_i)``,
  ``calibrate`` fits named continuous parameters of the scene (``gamma``, ``P0``, optionally
  ``rho0`` or ``p_atm``) by least squares,

      loss = mean_i (r_i / L)^2,        r_i = x_R(t_i; params) - x_i;

- the Gurney slab (``GurneySlab``, an explosive driving a plate): the plate's velocity
  ``v_plate(t)`` (a PDV record), fitting the products' constants (``D``, ``gamma``, or JWL's ``A``,
  ``B``, ...), with the residuals divided by the largest observed speed instead of ``L``.

The observable comes from a jaxmpm run (its saved history, interpolated linearly in time).

**The fit's variables.** Parameters stay in their physical ranges by a change of variables
``theta = ln(p - p_off)``: ``p_off = 1`` for ``gamma``, ``p_atm`` for ``P0``, 0 for any other (positive)
parameter. In exact arithmetic every ``theta`` is admissible; in floating point ``exp`` underflows far
out (``gamma = 1 + exp(-40)`` is 1.0) and overflows, so a trial point whose value reaches its bound or
is not finite, or that the scene refuses otherwise (``P0 > p_atm`` with both fitted), counts as a run
that breaks down. When the data pull a constant against its bound (the loss falls all the way to the
edge: no minimum inside the range), the fit ends at the edge and ``Fit.warning`` says so, naming it.

**Methods.** ``method="lm"`` (the default): Levenberg-Marquardt on the residuals (damping isotropic in
``theta``, updated by Nielsen's rule), with the Jacobian
``J = dr / dtheta`` by forward-mode autodiff through the whole run. Each iteration evaluates one trial
point; a trial whose run breaks down (or whose loss is higher) is rejected, the damping raised and the
step shortened: a broken run's loss is never used (``Fit.rejected`` lists every rejected trial).
``"lbfgs"`` (``optax.lbfgs`` with its zoom line search, gradients in reverse mode) and ``"adam"``
are the other methods. A broken trial gives L-BFGS a NaN loss, which its line search refuses; Adam,
which has no line search, refuses a step whose point breaks down and takes the step from the point
before again, half as long (20 halvings in a row stop the start); a step that does not break down lets
the next grow back, doubled up to its full length. Several starts run at once
under ``vmap``; the lowest final loss wins.

**Uncertainty at the optimum.** From ``J`` at the best point: the Gauss-Newton covariance
``C = sigma^2 (J^T J)^-1`` with ``sigma^2 = sum r^2 / (n - p)`` (or the measurement noise, ``noise``),
in the fit's variables and in the physical ones (``C_phys = D C D``, ``D = diag(p - p_off)``); each
parameter's standard error ``sqrt(C_ii)``, the correlation matrix, and the condition number of
``J^T J`` in relative variables (``d r / d ln p``: units drop out). Where ``J^T J`` is singular, a
constant whose unit vector is orthogonal to its null space is still determined: its standard error
comes from the pseudo-inverse, on ``n - rank`` degrees of freedom; the others' are infinite.

**Identifiability.** When the data do not separate the parameters (a correlation beyond
``max_correlation``, 0.99, or a relative standard error above ``max_relative_std``, 10%), the fit still
returns its best point, with ``Fit.warning`` saying so, naming the direction the data cannot see (the
weakest eigenvector of ``J^T J`` in relative variables) and, for the gas slab observed only before its
first turnaround, when that turnaround comes; ``calibrate`` also issues a ``CalibrationWarning``.

**Faults.** A start whose own run breaks down stops there (``Fit.failed_starts`` says why: the step,
particle and quantity), the others go on; when every start broke down, ``CalibrationError``. When the
best start cannot go on because every step toward a lower loss is a run that breaks down, the fit has
no answer: ``CalibrationError`` names the breakdown and what to change. A fit stopped by its iteration
count before converging says so in ``Fit.warning``. Data beyond the grid are refused before any run,
and so are names that cannot be fitted (``fittable``: not ``h`` or ``dt``, not a static parameter,
not one the run does not use). Ctrl-C raises ``KeyboardInterrupt`` naming the iteration it stopped in.

**Experiment design.** ``information`` gives the Fisher information ``J^T J / sigma^2`` of an
observation plan at given constants, and the standard errors a fit would have, before any data exist.
``profile`` evaluates the loss along the weakest direction. ``Fit.sample`` draws constants from the
fitted Gaussian (for ``jm.ensemble``).
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._checks import (
    any_traced,
    brief,
    check_bool,
    check_finite,
    check_int,
    check_keywords,
    check_nonnegative,
    check_positive,
    check_real,
    check_scalar,
    is_concrete,
)
from ._simulate import SaveAt, SimulationError, as_devices, failure_message, simulate
from ._step import check_interpolator
from ._util import host
from .interpolators import AbstractInterpolator
from .long_run import computed
from .scenes import AbstractScene
from .scenes.detonation import Detonation
from .scenes.gas_slab import GasSlab, free_surface, pad_for
from .scenes.gurney import AbstractGurney, GurneySlab
from .scenes.manufactured import Manufactured
from .sensitivity import check_names, continuous_parameters, static_parameters
from .status import LEFT_GRID

NOT_FITTED = {"h": "the grid spacing", "dt": "the model's time step"}
"""Continuous inputs of a run that are not material constants, so ``calibrate`` does not fit them."""

MAX_CORRELATION = 0.99
"""Default bound on the magnitude of a correlation between fitted parameters before ``Fit.warning``."""

MAX_RELATIVE_STD = 0.10
"""Default bound on a parameter's relative standard error before ``Fit.warning``."""

METHODS = ("lm", "lbfgs", "adam")
"""The optimisers ``calibrate`` offers."""

_NO_RUN = "has no run"
"""What ``_Model.why`` says of values the scene refuses (``"... where GasSlab has no run: ..."``)."""

_EDGE_SHRINK = 1e6
"""How many times closer to its bound ``p_off`` than its scale (the start's distance, or ``|p_off|``) a
fitted value must be (with the Gauss-Newton step pointing past the bound) for ``_at_edge`` to say the
fit ran into the bound."""


def fittable(scene: AbstractScene | type[AbstractScene]) -> tuple[str, ...]:
    """The names ``calibrate`` can fit: the scene's continuous parameters but ``h`` and ``dt`` (not
    material constants), the static ones (``jaxmpm.sensitivity.static_parameters``, such as the Gurney
    scenes' ``split``: fixed when the run is compiled, they have no derivative) and those its run does
    not use (``unused``; of a scene class, those no run of it uses).

    Args:
        scene: the scene (or its class).

    Returns:
        The names, in the scene's order (for the gas slab ``P0, gamma, p_atm, rho0``; for the Gurney
        slab of ``explosive="gamma-law"`` ``D, gamma, rho0, burn_width, L``).

    Raises:
        ValueError: ``scene`` is neither a jaxmpm scene nor a scene class.
    """
    if not (
        isinstance(scene, AbstractScene) or (isinstance(scene, type) and issubclass(scene, AbstractScene))
    ):
        raise ValueError(
            f"scene must be a jaxmpm scene or scene class such as jm.GasSlab, got {brief(scene)}"
        )
    skip = set(NOT_FITTED) | set(static_parameters(scene)) | set(unused(scene))
    return tuple(n for n in continuous_parameters(scene) if n not in skip)


_JWL_CONSTANTS = ("A", "B", "R1", "R2", "w")
"""The Gurney scenes' JWL constants, which only ``explosive="jwl"`` uses."""


def unused(scene: AbstractScene | type[AbstractScene]) -> dict[str, str]:
    """The continuous parameters of ``scene`` that its run does not use, each with why: a fit of one
    would fit nothing (the loss does not depend on it).

    The Gurney scenes' ``sqrt_2E`` is the constant of Gurney's formula (``gurney_velocity``), never
    of the run. With ``explosive="gamma-law"`` the run does not use the JWL constants ``A, B, R1, R2,
    w``; with ``"jwl"`` not ``gamma``; with a row of ``jaxmpm.explosives.EXPLOSIVES`` (``"compb"``,
    ...) none of ``D, gamma, rho0, A, B, R1, R2, w``: the row has its own. A ``Detonation`` of such a
    row does not use ``D, gamma, rho0``. With ``burn="volume"`` (the beta burn) the detonation and
    Gurney scenes do not use ``burn_width``. A ``Manufactured`` bar does not use the other model's
    constants (``model="neo-hookean"``: ``P0, gamma, p_atm``; ``"gas"``: ``lam, mu``), nor, with a
    ``displacement_fn`` of the user's, the amplitude ``A``, unless the field reads them. Other scenes
    use every continuous parameter.

    Args:
        scene: the scene, or its class (then only what no run of it uses: ``sqrt_2E``).

    Returns:
        Name to a clause saying why (empty where the run uses every continuous parameter).
    """
    cls = scene if isinstance(scene, type) else type(scene)
    if issubclass(cls, Manufactured):
        return {} if isinstance(scene, type) else _manufactured_unused(scene)
    if issubclass(cls, Detonation):
        if isinstance(scene, type):
            return {}
        out = _burn_unused(scene)
        if scene.explosive == "gamma-law":
            return out
        why = (
            f"the run of explosive={scene.explosive} does not use it: the products are that row of "
            "jm.explosives.EXPLOSIVES, with its own detonation speed, density and constants "
            "(explosive=gamma-law takes D, gamma and rho0 from the scene)"
        )
        return {**dict.fromkeys(("D", "gamma", "rho0"), why), **out}
    if not issubclass(cls, AbstractGurney):
        return {}
    out = {"sqrt_2E": "it is the constant of Gurney's formula (gurney_velocity), not of the run"}
    if isinstance(scene, type):
        return out
    out.update(_burn_unused(scene))
    explosive = scene.explosive
    if explosive == "gamma-law":
        names = _JWL_CONSTANTS
        why = "the run of explosive=gamma-law does not use it (a JWL constant: explosive=jwl uses it)"
    elif explosive == "jwl":
        names = ("gamma",)
        why = "the run of explosive=jwl does not use it (the gamma law's: explosive=gamma-law uses it)"
    else:
        names = ("D", "gamma", "rho0", *_JWL_CONSTANTS)
        why = (
            f"the run of explosive={explosive} does not use it: the products are that row of "
            "jm.explosives.EXPLOSIVES, with its own constants (explosive=gamma-law or jwl takes them "
            "from the scene)"
        )
    out.update(dict.fromkeys(names, why))
    return out


def _burn_unused(scene: Detonation | AbstractGurney) -> dict[str, str]:
    """``unused`` of a programmed burn: a volume burn lights by compression alone, without the time
    burn's length ``burn_width``."""
    if scene.burn != "volume":
        return {}
    why = "the run of burn=volume does not use it (the time burn's length: burn=time or max uses it)"
    return {"burn_width": why}


_MANUFACTURED_MODELS = {"neo-hookean": ("lam", "mu"), "gas": ("P0", "gamma", "p_atm")}


def _manufactured_unused(scene: Manufactured) -> dict[str, str]:
    """``unused`` of a ``Manufactured`` bar: the other model's constants, and with a field of the
    user's the default field's amplitude ``A``, each unless the field reads it."""
    out = {}
    for model, names in _MANUFACTURED_MODELS.items():
        if model != scene.model:
            why = (
                f"the run of model={scene.model} does not use it (a constant of model={model}, which uses it)"
            )
            out.update(dict.fromkeys(names, why))
    if scene.displacement_fn is not None:
        out["A"] = "displacement_fn does not read it (it is the default field's amplitude)"
        read = _read_by(scene.displacement_fn, scene, tuple(out))
        out = {name: why for name, why in out.items() if name not in read}
    return out


def _read_by(fn, scene: AbstractScene, names: tuple[str, ...]) -> set[str]:
    """Which of the scene's parameters ``names`` the field ``fn(scene, X, t)`` reads: those its traced
    program takes as an operand (a value read and then multiplied by zero counts as read)."""
    point = jax.ShapeDtypeStruct((scene.dim,), scene.h.dtype)
    time_ = jax.ShapeDtypeStruct((), scene.h.dtype)

    def field(values, X, t):
        return fn(eqx.tree_at(lambda z: tuple(getattr(z, n) for n in names), scene, values), X, t)

    closed = jax.make_jaxpr(field)(tuple(getattr(scene, n) for n in names), point, time_)
    jaxpr = closed.jaxpr
    operands = {id(v) for eqn in jaxpr.eqns for v in eqn.invars} | {id(v) for v in jaxpr.outvars}
    return {n for n, v in zip(names, jaxpr.invars[: len(names)]) if id(v) in operands}


class CalibrationError(RuntimeError):
    """A fit has no answer: every start broke down, or the way to a lower loss is runs that break down."""


class CalibrationWarning(UserWarning):
    """A fit returned its best point, but the data do not determine it well (or it did not converge)."""


def offsets(scene: AbstractScene, names: Sequence[str]) -> dict:
    """The lower bound ``p_off`` of each parameter: ``theta = ln(p - p_off)`` is the fit's variable.

    Args:
        scene: the scene (``p_atm`` bounds ``P0`` from below).
        names: the fitted names.

    Returns:
        Name to ``p_off``: 1 for ``gamma``, ``p_atm`` for ``P0`` (when the scene has it), else 0.
    """
    out = {}
    for n in names:
        if n == "gamma":
            out[n] = 1.0
        elif n == "P0" and hasattr(scene, "p_atm") and "p_atm" not in names:
            out[n] = float(scene.p_atm)
        else:
            out[n] = 0.0
    return out


@dataclasses.dataclass
class Fit:
    """The result of ``calibrate``.

    Attributes:
        fitted: the best start's fitted values, name to float.
        loss: its final loss, ``mean((r / L)^2)``.
        iterations: iterations the best start took.
        history: loss per iteration and start, from the starts' own loss, shape ``(1 + k, starts)``
            with ``k`` the iterations of the start that took the most (NaN for a start that broke
            down; after a start's own iterations, its final loss). The best start's history is
            ``history[: iterations + 1, best_start]``.
        starts_fitted: every start's fitted values, name to array ``(starts,)``; for a start in
            ``failed_starts``, the values where it stopped, which are not a fit.
        wall_s: wall time of the fit (compilation included).
        failed_starts: start index to why it stopped (its run broke down, or every step toward a lower
            loss from where it stood did); the others went on.
        method: the optimiser.
        converged: whether the best start met the convergence test (else ``warning`` says so).
        names: the fitted names, the order of the matrices below.
        std: each parameter's standard error (physical units).
        covariance: the Gauss-Newton covariance in physical units, ``(p, p)``.
        covariance_theta: the same in the fit's variables ``theta = ln(p - p_off)``.
        correlation: the correlation matrix, ``(p, p)`` (NaN where undefined: a constant whose
            standard error is infinite, which ``warning`` names).
        condition: the condition number of ``J^T J`` in relative variables (``d r / d ln p``).
        sigma: the noise level used: ``noise`` when given, else ``sqrt(sum r^2 / (n - rank))``
            (``rank = p`` unless ``J^T J`` is singular).
        noise_given: whether ``sigma`` is the given noise.
        weakest: the direction the data see least, a unit vector in ``d ln p`` (name to component).
        warning: ``None``, or why the answer should not be trusted as it stands (identifiability, no
            convergence, a constant the data pull against the bound of its range).
        offsets: name to ``p_off`` of the fit's variables.
        rejected: every rejected trial point (``"lm"`` and ``"adam"``): start, iteration, values, and
            whether its run broke down (``broke``, with the reason in ``why`` for the first ones) or
            raised the loss (``"lm"`` only).
        residuals: the best start's residuals ``x_model - x_data`` at the data times.
        best_start: the index of the best start (the one ``fitted`` comes from) in ``starts``.
    """

    fitted: dict
    loss: float
    iterations: int
    history: np.ndarray
    starts_fitted: dict
    wall_s: float
    failed_starts: dict = dataclasses.field(default_factory=dict)
    method: str = "lm"
    converged: bool = True
    names: tuple = ()
    std: dict = dataclasses.field(default_factory=dict)
    covariance: np.ndarray | None = None
    covariance_theta: np.ndarray | None = None
    correlation: np.ndarray | None = None
    condition: float = float("nan")
    sigma: float = float("nan")
    noise_given: bool = False
    weakest: dict = dataclasses.field(default_factory=dict)
    warning: str | None = None
    offsets: dict = dataclasses.field(default_factory=dict)
    rejected: list = dataclasses.field(default_factory=list)
    residuals: np.ndarray | None = None
    best_start: int = 0

    def sample(self, members: int, seed: int = 0) -> dict:
        """Constants drawn from the fitted Gaussian, for ``jm.ensemble(scene, interp, vary=...)``.

        The draw is Gaussian in the fit's variables ``theta = ln(p - p_off)`` (mean: the fitted
        values; covariance: ``covariance_theta``), so every member is admissible (``gamma > 1``,
        ``P0 > p_atm``): where ``P0`` and ``p_atm`` are both fitted, members with ``P0 <= p_atm`` are
        drawn again (the Gaussian restricted to the scene's range; ``draw``).

        Args:
            members: how many.
            seed: the seed of numpy's generator.

        Returns:
            Name to an array ``(members,)``.

        Raises:
            ValueError: the fit has no finite covariance (the data do not determine it).
        """
        check_int("members", members, 1)
        check_int("seed", seed, 0)
        C = self.covariance_theta
        if C is None or not np.all(np.isfinite(C)):
            raise ValueError("this fit has no finite covariance to draw from (see Fit.warning)")
        return draw(self.fitted, self.offsets, self.names, C, members, seed)


_ORDERED = (("P0", "p_atm"),)
"""Pairs ``(a, b)`` of constants a scene takes only with ``a > b`` (``GasSlab``: ``P0 > p_atm``)."""


def draw(fitted: dict, offs: dict, names: Sequence[str], covariance_theta, members: int, seed) -> dict:
    """Draw ``members`` parameter sets from ``N(theta_fit, covariance_theta)`` in ``theta = ln(p - p_off)``.

    Args:
        fitted: name to the fitted value.
        offs: name to ``p_off``.
        names: the order of the covariance's rows.
        covariance_theta: the covariance in the fit's variables, ``(p, p)``.
        members: how many.
        seed: the seed of numpy's generator, or a ``numpy.random.Generator``.

    Returns:
        Name to an array ``(members,)`` of physical values. Each value lies above its ``p_off``; where
        both of an ordered pair are drawn (``P0`` and ``p_atm``: a scene has ``P0 > p_atm``), members
        out of order are drawn again, so every member is one the scene takes.

    Raises:
        ValueError: fewer than one draw in a thousand is in order (the Gaussian lies almost wholly
            outside the scene's range).
    """
    names = tuple(names)
    C = np.asarray(covariance_theta, dtype=float)
    mean = np.array([np.log(fitted[n] - offs[n]) for n in names])
    rng = np.random.default_rng(seed)
    pairs = [(names.index(a), names.index(b)) for a, b in _ORDERED if a in names and b in names]

    def physical(theta):
        return np.array([offs[n] for n in names]) + np.exp(theta)

    values = physical(rng.multivariate_normal(mean, C, size=members, method="eigh"))
    for _ in range(1000):
        bad = np.zeros(members, dtype=bool)
        for i, j in pairs:
            bad |= ~(values[:, i] > values[:, j])
        if not bad.any():
            break
        values[bad] = physical(rng.multivariate_normal(mean, C, size=int(bad.sum()), method="eigh"))
    else:
        a, b = names[pairs[0][0]], names[pairs[0][1]]
        raise ValueError(
            f"the fitted Gaussian lies almost wholly outside the scene's range: fewer than one draw in a "
            f"thousand has {a} > {b}"
        )
    return {n: values[:, i] for i, n in enumerate(names)}


def observable(scene: AbstractScene) -> str:
    """What a scene's data observe: ``"v_plate"``, the plate's velocity of a ``GurneySlab``, or
    ``"x_free"``, the free-surface position of a ``GasSlab``.

    Args:
        scene: the scene.

    Returns:
        The observable's name (the data's column in ``jaxmpm calibrate --data``).
    """
    return "v_plate" if isinstance(scene, GurneySlab) else "x_free"


_TRAJECTORY_SETS = {
    "steps": "trajectory sets it from ts and dt (enough steps of dt to reach the last time)",
    "saveat": "trajectory saves every step, the fields its observable needs",
    "throw": "trajectory raises SimulationError on a breakdown of concrete values and gives NaN "
    "when traced (inside jit, vmap or a derivative)",
    "t_end": "trajectory runs fixed steps of dt to the last of ts",
    "cfl": "trajectory runs fixed steps of dt to the last of ts",
    "max_steps": "trajectory runs fixed steps of dt to the last of ts",
}
"""The keywords of ``simulate`` that ``trajectory`` refuses, each with why: it sets them itself."""


def trajectory(scene: AbstractScene, interpolator: AbstractInterpolator, ts, *, dt, **kwargs) -> jax.Array:
    """The scene's observable (``observable``) at times ``ts`` (linear between steps), from one run of
    ``dt`` steps: the gas slab's free-surface position ``x_R``, or the Gurney slab's plate velocity.

    Args:
        scene: the scene (a ``GasSlab`` or a ``GurneySlab``).
        interpolator: the MPM method.
        ts: the times (``>= 0``).
        dt: the time step.
        **kwargs: passed to ``simulate`` (``transfer``, ``artificial_cells``, ``viscosity``, ...),
            except those ``trajectory`` sets itself (``steps``, ``saveat``, ``throw``) and those of
            a run to an end time (``t_end``, ``cfl``, ``max_steps``).

    Returns:
        The observable at ``ts`` (``scenes.gas_slab.free_surface``, ``GurneySlab.plate_velocity``).
        Traced (inside ``jit``, ``vmap`` or a derivative, as the fit calls it), a run that broke down
        gives NaN everywhere, which the fit reads as a breakdown.

    Raises:
        ValueError: ``scene`` or ``interpolator`` is not jaxmpm's, ``ts`` is empty, not finite or
            negative, ``dt`` is not one number > 0, or a keyword that ``trajectory`` sets itself or
            that belongs to a run to an end time (named, with what ``trajectory`` does instead).
        TypeError: a keyword ``simulate`` does not take (the message lists those it takes).
        SimulationError: called on concrete values, the run broke down (the step, particle and
            quantity, as ``simulate`` says them).
    """
    check_keywords("trajectory", kwargs, simulate, refused=_TRAJECTORY_SETS)
    _check_parts(scene, interpolator)
    steps = _steps(ts, dt)
    ts = jnp.asarray(ts)
    if observable(scene) == "v_plate":
        fields = ("v",)
    else:
        fields = ("x", "F", "corners") if interpolator.tracks_corners else ("x", "F")
    sol = simulate(
        scene, interpolator, dt=dt, steps=steps, saveat=SaveAt(every=1, fields=fields), throw=False, **kwargs
    )
    h = sol.history
    if observable(scene) == "v_plate":
        w = jnp.where(sol.body.region == 1, sol.body.m, 0.0)
        values = h["v"][:, :, 0] @ w / jnp.sum(w)
    else:
        values = free_surface(h["x"], h["F"], h.get("corners"), sol.body)
    bad = sol.state.status != 0
    if is_concrete(bad) and bool(bad):
        raise SimulationError(failure_message(sol, float(dt), scene), sol)
    return jnp.where(bad, jnp.nan, jnp.interp(ts, sol.ts, values))


def _scale(scene, x_data) -> float:
    """The length (or speed) the loss divides the residuals by: the slab's length for a free surface,
    the largest observed speed for a plate."""
    if observable(scene) == "v_plate":
        return float(np.max(np.abs(np.asarray(x_data))))
    return float(scene.length)


def _steps(ts, dt, times: str = "ts") -> int:
    """The steps of ``dt`` that reach the last of the times ``ts`` (both checked first)."""
    check_positive("dt", dt)
    check_scalar("dt", dt)
    check_real(times, ts)
    if np.size(ts) == 0:
        raise ValueError(f"{times} must hold at least one time (>= 0), got an empty array")
    check_nonnegative(times, ts)
    return int(np.ceil(float(np.max(np.asarray(ts))) / float(dt) - 1e-9))


def _refusal(scene: AbstractScene, names: Sequence[str], values, off) -> str | None:
    """Why ``scene`` with ``names`` set to ``values`` has no run (``None``: it has one).

    Args:
        scene: the scene.
        names: the fitted names.
        values: their physical values.
        off: each name's ``p_off`` (the value must exceed it).

    Returns:
        ``None``, or the reason in one line: a value not finite or not above its ``p_off``, or the
        scene's own ``ValueError`` (``"gamma must be > 1.0, got 1.0"``, ``"P0 must be > p_atm ..."``).
    """
    values = np.asarray(values, dtype=float)
    for n, v, o in zip(names, values, off):
        if not np.isfinite(v):
            return f"{n} must be finite, got {float(v)}"
        if not v > o:
            return f"{n} must be > {float(o):.6g}, got {float(v):.17g}"
    try:
        type(scene)(**{**scene.parameter_values(), **dict(zip(names, (float(v) for v in values)))})
    except ValueError as e:
        return str(e)
    return None


class _Model:
    """The residuals and their Jacobian in the fit's variables, batched over members (starts or data
    sets): one compiled ``vmap`` of a forward-mode Jacobian through the run."""

    def __init__(self, scene, interpolator, names, t_data, dt, simulate_kwargs, devices=None):
        self.scene, self.interpolator, self.names = scene, interpolator, tuple(names)
        self.t_data, self.dt, self.kwargs = t_data, dt, simulate_kwargs
        self.devices = devices
        offs = offsets(scene, names)
        self.off = np.array([offs[n] for n in names])
        self.offsets = offs
        self._refused: dict[bytes, str | None] = {}  # refused's answers, by the values' bytes
        dtype = scene.h.dtype
        off = jnp.asarray(self.off, dtype=dtype)

        def x_of(theta, start_theta):
            phys = off + jnp.exp(start_theta + theta)
            sc = type(scene)(**{**scene.parameter_values(), **dict(zip(names, phys))})
            x = trajectory(sc, interpolator, t_data, dt=dt, **simulate_kwargs)
            # exp underflows or overflows far out (gamma = 1 + 1e-20 is 1.0): a value past its bound
            # or not finite has no run, and reads as a run that broke down
            inside = jnp.all(jnp.isfinite(phys) & (phys > off))
            return jnp.where(inside, x, jnp.nan)

        self.x_of = x_of  # one member's trajectory, unbatched: ``(theta, start_theta) -> x_R(t_data)``

        def rj(theta, start_theta, data):
            def with_value(th):  # the run's value rides along as aux: one pass, not two
                x = x_of(th, start_theta)
                return x, x

            J, x = jax.jacfwd(with_value, has_aux=True)(theta)
            return x - data, J

        def r_only(theta, start_theta, data):
            return x_of(theta, start_theta) - data

        self._rj = jax.jit(jax.vmap(rj))
        self._r = jax.jit(jax.vmap(r_only))

    def physical(self, start_theta, theta) -> np.ndarray:
        with np.errstate(over="ignore"):  # a step far out: inf, which the scene then refuses by name
            return self.off + np.exp(np.asarray(start_theta) + np.asarray(theta))

    def _batched(self, fn, *args):
        """``fn`` of the members' rows, as NumPy arrays; with ``devices``, the rows are padded to a
        multiple of the device count (repeating the last), sharded over them, and gathered back
        (from every process)."""
        if self.devices is None:
            out = computed(fn, *(jnp.asarray(a) for a in args))
            return tuple(np.asarray(o) for o in out) if isinstance(out, tuple) else np.asarray(out)
        n, k = np.shape(args[0])[0], len(self.devices)
        padded = -(-n // k) * k
        sharding = NamedSharding(Mesh(np.asarray(self.devices), ("members",)), PartitionSpec("members"))
        dtype = self.scene.h.dtype
        put = []
        for a in args:
            a = np.asarray(a, dtype=dtype)
            put.append(jax.device_put(np.concatenate([a, np.repeat(a[-1:], padded - n, axis=0)]), sharding))
        out = computed(fn, *put)
        if isinstance(out, tuple):
            return tuple(host(o)[:n] for o in out)
        return host(out)[:n]

    def admitted(self, start_theta, theta, ok) -> np.ndarray:
        """``ok`` where the scene also takes the member's physical values (``refused`` is ``None``):
        a finite run at values the scene refuses (a cross-parameter bound the fit's variables do not
        keep, such as ``P0 > p_atm`` with both fitted) is no run."""
        phys = np.atleast_2d(self.physical(start_theta, theta))
        return np.array([bool(k) and self.refused(row) is None for k, row in zip(ok, phys)])

    def refused(self, values: np.ndarray) -> str | None:
        """Why the scene refuses these physical values, in its words (``None``: it takes them)."""
        key = np.asarray(values, dtype=float).tobytes()
        if key not in self._refused:
            if len(self._refused) > 4096:
                self._refused.clear()
            self._refused[key] = _refusal(self.scene, self.names, values, self.off)
        return self._refused[key]

    def residuals_and_jacobian(self, theta, start_theta, data):
        r, J = self._batched(self._rj, theta, start_theta, data)
        ok = np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(J), axis=(1, 2))
        return r, J, self.admitted(start_theta, theta, ok)

    def residuals(self, theta, start_theta, data):
        r = self._batched(self._r, theta, start_theta, data)
        return r, self.admitted(start_theta, theta, np.all(np.isfinite(r), axis=1))

    def why(self, values: np.ndarray, digits: int = 6) -> tuple[str, dict | None]:
        """A plain run at ``values`` (physical): what broke (the step, particle and quantity), or why
        the scene refuses them (the values written to ``digits`` significant digits)."""
        trial = dict(zip(self.names, (float(v) for v in values)))
        where = ", ".join(f"{k}={v:.{digits}g}" for k, v in trial.items())
        refused = self.refused(values)
        if refused is not None:  # a point the fit's variables reach, not one the user gave
            return f"the fit reached {where}, where {type(self.scene).__name__} {_NO_RUN}: {refused}", None
        sc = type(self.scene)(**{**self.scene.parameter_values(), **trial})
        steps = _steps(self.t_data, self.dt, "t_data")
        sol = computed(
            lambda: simulate(sc, self.interpolator, dt=self.dt, steps=steps, throw=False, **self.kwargs)
        )
        f = sol.failure()
        if f is None:
            return f"the loss at {where} is not finite", None
        return (
            f"the run at {where} broke down at step {f['step']}, particle {f['particle']}: "
            + "; ".join(f["quantities"]),
            f,
        )


def calibrate(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    t_data,
    x_data,
    fit: Sequence[str] = ("gamma", "P0"),
    starts: Sequence[dict] | dict | None = None,
    *,
    dt,
    method: str = "lm",
    iterations: int = 50,
    learning_rate: float | None = None,
    tol: float = 1e-14,
    noise: float | None = None,
    max_correlation: float = MAX_CORRELATION,
    max_relative_std: float = MAX_RELATIVE_STD,
    progress: bool | None = None,
    devices=None,
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
        method: ``"lm"`` (Levenberg-Marquardt, the default), ``"lbfgs"`` or ``"adam"``.
        iterations: the most iterations; the fit stops earlier when it converges (``lm``: the loss
            falls below ``tol``, a step would lower it by less than 1e-8 of itself, a step that
            would lower it by less than 1e-6 of itself does not, or an accepted step lowers it by
            less than 1e-8 of itself where the Gauss-Newton step from there would gain less than
            1e-6 of it; the others: no
            start improved by 1e-9 of its loss in 3 iterations, none of which, for Adam, went back
            from a point that broke down).
        learning_rate: Adam's step in ``theta`` (default 0.05); only with ``method="adam"``.
        tol: a loss below which a start has converged.
        noise: the measurement noise (a standard deviation, in the units of ``x_data``); ``None``:
            estimated from the residuals.
        max_correlation: the largest acceptable magnitude of a correlation (else ``Fit.warning``).
        max_relative_std: the largest acceptable relative standard error (else ``Fit.warning``).
        progress: a tqdm bar (``None``: only on a terminal or in a notebook).
        devices: spread the starts over these devices (``method="lm"``): a count (the first of
            ``jax.devices()``, which spans every process after ``jax.distributed.initialize``) or a
            sequence of devices; each device runs its share of the starts, and every process gets
            every start's result and makes the same choices. ``None`` (the default): one device.
        **simulate_kwargs: passed to ``simulate`` (``transfer``, ``artificial_cells``, ...).

    Returns:
        A ``Fit``, with its uncertainty. A ``CalibrationWarning`` is issued when ``Fit.warning`` is set.

    Raises:
        ValueError: bad input (a ``scene`` or ``interpolator`` that is not jaxmpm's, names that are
            not continuous parameters, ``h`` or ``dt``, a static name or one the run does not use
            (``fittable``), a name given twice, an unknown method, data of mismatched shapes, empty
            or not finite, times not increasing from ``>= 0``, data beyond the grid, ``starts``
            that are not a dict or a non-empty list of dicts of numbers, a start the scene refuses,
            a bad ``tol``, ``noise``, threshold or ``progress``, bad ``devices`` or ``devices``
            with a method other than ``"lm"``, a ``learning_rate`` with a method other than
            ``"adam"``).
        CalibrationError: every start broke down, or the best start cannot go on because every
            step toward a lower loss is a run that breaks down.
        KeyboardInterrupt: Ctrl-C during the fit, saying the iteration it stopped in (answered
            between iterations, and at once under the command line: ``jaxmpm.long_run.computed``);
            nothing is returned.
    """
    _check_parts(scene, interpolator)
    check_keywords("calibrate", simulate_kwargs, simulate, refused=_TRAJECTORY_SETS)
    _check_concrete(scene)
    names = tuple(_names(fit))
    _check_names(scene, names)
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(repr(m) for m in METHODS)}, got {method!r}")
    check_int("iterations", iterations, 1)
    if learning_rate is None:
        learning_rate = 0.05
    elif method != "adam":
        raise ValueError(
            f"learning_rate is Adam's step, and method={method!r} takes none (its steps come from its "
            "own model of the loss): leave learning_rate out, or use method='adam'"
        )
    check_positive("learning_rate", learning_rate)
    _check_tol(tol)
    _check_thresholds(noise, max_correlation, max_relative_std)
    if progress is not None:
        check_bool("progress", progress)
    devices = as_devices(devices)
    if devices is not None and method != "lm":
        raise ValueError(f"devices spreads the starts of method='lm' only, got method={method!r}")
    t_data, x_data = _check_data(scene, t_data, x_data)
    starts = _start_list(starts)
    unknown = [k for s in starts for k in s if k not in names]
    if unknown:
        raise ValueError(
            f"starts name parameters that are not fitted: {sorted(set(unknown))}; fitted: {names}"
        )
    base = {n: float(getattr(scene, n)) for n in names}
    start_phys = np.array([[float(s.get(n, base[n])) for n in names] for s in starts])
    model = _Model(scene, interpolator, names, t_data, dt, simulate_kwargs, devices)
    _check_starts(names, model.off, start_phys, scene)
    start_theta = np.log(start_phys - model.off)
    data = np.broadcast_to(np.asarray(x_data), (len(starts), x_data.shape[0]))
    L = _scale(scene, x_data)
    t0 = time.perf_counter()
    bar = _bar(progress, iterations)
    where = dict(iteration=0, loss=float("nan"))  # how far the fit got, for a Ctrl-C's message
    try:
        if method == "lm":
            run = _levenberg_marquardt(model, start_theta, data, iterations, tol, L, bar, where)
        else:
            run = _optax(model, start_theta, data, method, iterations, learning_rate, tol, L, bar, where)
        wall = time.perf_counter() - t0
        return _finish(
            model, run, start_theta, data, L, wall, method, noise, max_correlation, max_relative_std
        )
    except KeyboardInterrupt:
        raise KeyboardInterrupt(_interrupted(where, iterations)) from None
    finally:
        if bar is not None:
            bar.close()


def _interrupted(where: dict, iterations: int) -> str:
    """What a Ctrl-C during a fit says: the iteration it stopped in and the lowest loss so far."""
    it = where["iteration"]
    text = f"interrupted at iteration {it} of {iterations}"
    if it == 0:
        text += " (the starts' first runs)"
    elif np.isfinite(where["loss"]):
        text += f" (the lowest loss so far {where['loss']:.6g})"
    return text + ": the fit did not finish, and no fit is reported"


def calibrate_each(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    t_data,
    x_sets,
    fit: Sequence[str] = ("gamma", "P0"),
    start: dict | None = None,
    *,
    dt,
    iterations: int = 50,
    tol: float = 1e-14,
    noise: float | None = None,
    max_correlation: float = MAX_CORRELATION,
    max_relative_std: float = MAX_RELATIVE_STD,
    **simulate_kwargs,
) -> list[Fit]:
    """Fit each of several data sets at the same times, all in one ``vmap``-ed Levenberg-Marquardt.

    For studies of the fit itself: e.g. many noise draws of one experiment, to compare the reported
    standard errors with the spread of the fitted values. No warning is issued; each ``Fit`` carries
    its own ``warning``.

    Args:
        scene: the scene; parameters not fitted keep its values.
        interpolator: the MPM method of the model.
        t_data: observation times, shared.
        x_sets: the observed positions, ``(data sets, times)``.
        fit: the names to fit.
        start: start values (missing names start at the scene's values), the same for every set.
        dt: the model's time step.
        iterations: the most iterations.
        tol: a loss below which a fit has converged.
        noise: the measurement noise (``None``: estimated per data set).
        max_correlation: as for ``calibrate``.
        max_relative_std: as for ``calibrate``.
        **simulate_kwargs: passed to ``simulate``.

    Returns:
        One ``Fit`` per data set.

    Raises:
        ValueError: bad input, as for ``calibrate``; ``x_sets`` not 2D or holding no data set;
            ``start`` not a dict of numbers.
        CalibrationError: the start's run breaks down.
    """
    _check_parts(scene, interpolator)
    check_keywords("calibrate_each", simulate_kwargs, simulate, refused=_TRAJECTORY_SETS)
    _check_concrete(scene)
    names = tuple(_names(fit))
    _check_names(scene, names)
    check_int("iterations", iterations, 1)
    _check_tol(tol)
    _check_thresholds(noise, max_correlation, max_relative_std)
    check_real("x_sets", x_sets)
    x_sets = np.asarray(x_sets, dtype=float)
    if x_sets.ndim != 2 or x_sets.shape[0] == 0:
        raise ValueError(
            f"x_sets must be 2D (data sets, times) with at least one data set, got shape {x_sets.shape}"
        )
    t_data, _ = _check_data(scene, t_data, x_sets[0], what="x_sets[0]")
    for i, xs in enumerate(x_sets):
        _check_data(scene, t_data, xs, what=f"x_sets[{i}]")
    if start is not None and not isinstance(start, dict):
        raise ValueError(f"start must be a dict of start values (name to number) or None, got {brief(start)}")
    start = _start_list(start, what="start")[0]
    unknown = [k for k in start if k not in names]
    if unknown:
        raise ValueError(f"start names parameters that are not fitted: {sorted(unknown)}; fitted: {names}")
    model = _Model(scene, interpolator, names, t_data, dt, simulate_kwargs)
    one = np.array([[float(start.get(n, getattr(scene, n))) for n in names]])
    _check_starts(names, model.off, one, scene)
    start_theta = np.repeat(np.log(one - model.off), x_sets.shape[0], axis=0)
    L = _scale(scene, x_sets)
    t0 = time.perf_counter()
    run = _levenberg_marquardt(model, start_theta, x_sets, iterations, tol, L, None)
    wall = time.perf_counter() - t0
    if run["failed"]:
        why = next(iter(run["failed"].values()))
        raise CalibrationError(f"calibrate_each: the start's run broke down: {why}")
    fits = []
    for b in range(x_sets.shape[0]):
        one_run = {k: run[k][b : b + 1] for k in ("theta", "r", "J", "state", "taken")}
        one_run["iterations"] = int(run["taken"][b])
        one_run["history"] = run["history"][: one_run["iterations"] + 1, b : b + 1]
        one_run["rejected"] = [dict(r, start=0) for r in run["rejected"] if r["start"] == b]
        one_run["failed"] = {}
        fits.append(
            _finish(
                model,
                one_run,
                start_theta[b : b + 1],
                x_sets[b : b + 1],
                L,
                wall,
                "lm",
                noise,
                max_correlation,
                max_relative_std,
                warn=False,
            )
        )
    return fits


def _check_concrete(scene) -> None:
    """Refuse a scene traced by a JAX transformation: a fit is driven from Python (its iterations,
    starts and reports), so it runs outside ``jax.jit``, ``jax.grad`` and ``jax.vmap``."""
    if any_traced(scene):
        raise ValueError(
            "a fit is driven from Python (iterations, starts, reports) and runs outside jax.jit, "
            "jax.grad and jax.vmap; differentiate the model with jm.calibrate.trajectory or jm.simulate"
        )


def _check_parts(scene, interpolator) -> None:
    """Refuse a scene or an interpolator that is not jaxmpm's, naming what is allowed, before any run.

    Raises:
        ValueError: ``scene`` is not a jaxmpm scene, or one without an observable (not a ``GasSlab``
            or a ``GurneySlab``), or ``interpolator`` not a jaxmpm interpolator (``check_interpolator``:
            a registry name such as ``"mpq"`` is told to pass ``jm.MPQ()``).
    """
    if not isinstance(scene, AbstractScene):
        raise ValueError(f"scene must be a jaxmpm scene such as jm.GasSlab(), got {brief(scene)}")
    if not isinstance(scene, GasSlab | GurneySlab):
        raise ValueError(
            f"scene must be a jm.GasSlab (observed: its free surface) or a jm.GurneySlab (its plate's "
            f"velocity), the scenes with an observable to fit; got {type(scene).__name__}"
        )
    check_interpolator(interpolator)


def _names(fit, what: str = "fit") -> list:
    """``fit`` as a list, refused by the name ``what`` where it is not a sequence of names (a string
    would be read letter by letter: ``"gamma"`` for ``("gamma",)``)."""
    if not isinstance(fit, str):
        try:
            return list(fit)
        except TypeError:
            pass
    raise ValueError(
        f"{what} must be a sequence of parameter names such as ('gamma', 'P0'), got {brief(fit)}"
    )


def _start_list(starts, what: str = "starts") -> list[dict]:
    """``starts`` as a non-empty list of dicts of finite numbers (``None``: one start at the scene's
    values; one dict: one start).

    Raises:
        ValueError: ``starts`` is not ``None``, a dict, or a non-empty list or tuple of dicts; or a
            value is not one finite number.
    """
    if starts is None:
        starts = [{}]
    elif isinstance(starts, dict):
        starts = [starts]
    elif isinstance(starts, (list, tuple)):
        starts = list(starts)
        if not starts:
            raise ValueError(
                f"{what} must be a dict or a non-empty list of dicts of start values (or None: the "
                "scene's values), got an empty list"
            )
    else:
        raise ValueError(f"{what} must be a dict or a list of dicts of start values, got {brief(starts)}")
    for i, s in enumerate(starts):
        if not isinstance(s, dict):
            raise ValueError(f"{what}[{i}] must be a dict of start values (name to number), got {brief(s)}")
        for k, v in s.items():
            label = f"{what}[{i}][{k!r}]" if what == "starts" else f"{what}[{k!r}]"
            check_finite(label, v)
            check_scalar(label, v)
    return starts


def _check_tol(tol) -> None:
    check_nonnegative("tol", tol)
    check_scalar("tol", tol)


def _check_names(scene, names) -> None:
    if not names:
        raise ValueError(f"fit must name at least one constant; fittable: {', '.join(fittable(scene))}")
    for n in names:
        if isinstance(n, str) and n not in type(scene).parameters() and n != "dt":
            raise ValueError(f"unknown parameter {n!r} for a fit; fittable: {', '.join(fittable(scene))}")
    check_names(scene, names)
    static, idle = static_parameters(scene), unused(scene)
    for n in names:
        if n in NOT_FITTED:
            raise ValueError(
                f"{n} is {NOT_FITTED[n]}, not a material constant; it cannot be fitted; "
                f"fittable: {', '.join(fittable(scene))}"
            )
        if n in static:
            raise ValueError(
                f"{n} is static (it places the particles when the run is compiled), so it has no "
                f"derivative; it cannot be fitted; fittable: {', '.join(fittable(scene))}"
            )
        if n in idle:
            raise ValueError(f"{n} cannot be fitted: {idle[n]}; fittable: {', '.join(fittable(scene))}")
    if len(set(names)) != len(names):
        raise ValueError(f"fit names a parameter twice: {names}")


def _check_thresholds(noise, max_correlation, max_relative_std) -> None:
    if noise is not None:
        check_scalar("noise", noise, " (one standard deviation, in the units of the data)")
        check_positive("noise", noise)
    if not (isinstance(max_correlation, (int, float)) and 0.0 < max_correlation <= 1.0):
        raise ValueError(f"max_correlation must be a number in (0, 1], got {max_correlation!r}")
    check_positive("max_relative_std", max_relative_std)


_MOST_PAD = 10**9  # cells of padding: a 1D grid of that many nodes is already ~100 GB of state


def _check_data(scene, t_data, x_data, what="x_data"):
    dtype = scene.h.dtype
    check_real("t_data", t_data)
    check_real(what, x_data)
    t_data = jnp.asarray(t_data, dtype=dtype)
    x_data = jnp.asarray(x_data, dtype=dtype)
    if t_data.ndim != 1 or t_data.shape != x_data.shape or t_data.size < 2:
        raise ValueError(
            f"t_data and {what} must be 1D arrays of the same length (>= 2), got shapes "
            f"{tuple(t_data.shape)} and {tuple(x_data.shape)}"
        )
    for name, a in (("t_data", t_data), (what, x_data)):
        bad = np.flatnonzero(~np.isfinite(np.asarray(a)))
        if bad.size:
            raise ValueError(f"{name} must be finite; entry {int(bad[0])} is {float(a[bad[0]])}")
    t_host = np.asarray(t_data)
    if t_host[0] < 0 or np.any(np.diff(t_host) <= 0):
        raise ValueError("t_data must start at >= 0 and increase")
    if observable(scene) != "x_free":
        if not np.any(np.asarray(x_data)):  # the loss divides by the largest observed speed
            raise ValueError(
                f"{what} must hold a nonzero plate speed (the loss is scaled by the largest one), got "
                f"all zeros"
            )
        return t_data, x_data
    x_max = float(np.max(np.asarray(x_data)))
    grid_end = float(scene.length) + scene.pad * float(scene.h)
    # a particle's stencil reaches up to 2 cells past its domain (CPDI, GIMP): the grid must hold that
    if x_max > grid_end - 2.0 * float(scene.h):
        pad = pad_for(scene, 1.25 * x_max)
        use = (
            f"use pad >= {pad}"
            if pad <= _MOST_PAD
            else f"a grid holding them needs pad = {pad:.3g} cells, beyond any memory: check the data's units"
        )
        raise ValueError(
            f"{what} reach x = {x_max:.6g}, but the grid ends at x = {grid_end:.6g} (pad = {scene.pad} "
            f"cells of h = {float(scene.h):.6g}): the model cannot follow the data; {use}"
        )
    return t_data, x_data


def _check_starts(names, off, start_phys, scene=None) -> None:
    """Refuse start values at or below their ``p_off`` and, given ``scene``, any it refuses."""
    for i, n in enumerate(names):
        bad = np.flatnonzero(~(start_phys[:, i] > off[i]))
        if bad.size:
            raise ValueError(f"start {int(bad[0])}: {n} = {start_phys[bad[0], i]:.6g} must be > {off[i]:.6g}")
    if scene is not None:
        for b, row in enumerate(start_phys):
            why = _refusal(scene, names, row, off)
            if why is not None:
                values = ", ".join(f"{n}={v:.6g}" for n, v in zip(names, row))
                raise ValueError(f"start {b} ({values}): {type(scene).__name__} refuses it: {why}")


def _loss(r, L):
    return np.mean(np.square(r / L), axis=-1)


def _lowest(losses) -> float:
    """The lowest finite loss of an iteration's starts (NaN where every start broke down)."""
    losses = np.asarray(losses, dtype=float)
    finite = losses[np.isfinite(losses)]
    return float(finite.min()) if finite.size else float("nan")


def _levenberg_marquardt(model, start_theta, data, iterations, tol, L, bar, where=None) -> dict:
    """Levenberg-Marquardt, damping isotropic in ``theta`` (the fit's variables are logarithmic, so it
    damps relative changes alike), batched over members: a host loop around one compiled ``vmap`` of
    residuals and Jacobian per iteration. A trial that breaks down or raises the loss is rejected and
    the damping raised; a broken run's loss is never used. ``where`` (a dict), when given, holds the
    iteration under way and the lowest loss so far (for a Ctrl-C's message)."""
    where = {} if where is None else where
    B, p = start_theta.shape
    theta = np.zeros((B, p))
    r, J, ok = model.residuals_and_jacobian(theta, start_theta, data)
    failed: dict[int, str] = {}
    for b in np.flatnonzero(~ok):
        failed[int(b)] = "at its start: " + model.why(model.physical(start_theta[b], theta[b]))[0]
    cost = np.where(ok, 0.5 * np.sum(np.square(np.where(ok[:, None], r, 0.0)), axis=1), np.inf)
    lam, nu = np.full(B, 1e-3), np.full(B, 2.0)
    state = np.where(ok, "running", "failed").astype(object)
    rejected: list[dict] = []
    why_left = 8  # the first broken trials get their reason (a plain run each)
    history = [np.where(ok, _loss(np.where(ok[:, None], r, 0.0), L), np.nan)]
    taken = np.zeros(B, dtype=int)  # iterations each start took (a trial step each)
    it = 0
    for it in range(1, iterations + 1):
        where.update(iteration=it, loss=_lowest(history[-1]))
        active = state == "running"
        if not active.any():
            it -= 1
            break
        A = np.einsum("bni,bnj->bij", J, J)
        g = np.einsum("bni,bn->bi", J, r)
        # converged already: the full Gauss-Newton step would gain less than 1e-8 of the cost
        gn = np.zeros((B, p))
        for b in np.flatnonzero(active):
            gn[b] = -np.linalg.lstsq(A[b], g[b], rcond=None)[0]
        gain = -np.einsum("bi,bi->b", g, gn) * 0.5
        done = active & ((gain <= 1e-8 * cost) | (2.0 * cost / (data.shape[1] * L * L) <= tol))
        state[done] = "converged"
        active &= ~done
        if not active.any():
            it -= 1
            break
        taken[active] += 1
        delta = np.zeros((B, p))
        for b in np.flatnonzero(active):
            d = np.full(p, max(float(np.max(np.diag(A[b]))), 1e-300))  # Levenberg: isotropic in theta
            try:
                delta[b] = -np.linalg.solve(A[b] + lam[b] * np.diag(d), g[b])
            except np.linalg.LinAlgError:
                delta[b] = -np.linalg.lstsq(A[b] + lam[b] * np.diag(d), g[b], rcond=None)[0]
        trial = theta + delta
        r_t, J_t, ok_t = model.residuals_and_jacobian(trial, start_theta, data)
        cost_t = np.where(ok_t, 0.5 * np.sum(np.square(np.where(ok_t[:, None], r_t, 0.0)), axis=1), np.inf)
        pred = -(np.einsum("bi,bi->b", g, delta) + 0.5 * np.einsum("bi,bij,bj->b", delta, A, delta))
        accept = active & ok_t & (cost_t < cost)
        broke = active & ~ok_t
        for b in np.flatnonzero(active & ~accept):
            values = model.physical(start_theta[b], trial[b])
            entry = dict(
                start=int(b),
                iteration=it,
                values=dict(zip(model.names, (float(v) for v in values))),
                broke=bool(broke[b]),
                loss=float(2.0 * cost_t[b] / (data.shape[1] * L * L)) if ok_t[b] else float("nan"),
            )
            if broke[b] and why_left > 0:
                entry["why"], entry["failure"] = model.why(values)
                why_left -= 1
            rejected.append(entry)
        with np.errstate(divide="ignore", invalid="ignore"):  # inf - inf where a run broke: masked
            rho = np.where(accept & (pred > 0), (cost - cost_t) / pred, 0.0)
        # Nielsen's damping update: smooth in the gain ratio on success, doubling growth on failure
        lam = np.where(accept, lam * np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), lam * nu)
        nu = np.where(accept, 2.0, np.where(active, 2.0 * nu, nu))
        lam = np.maximum(lam, 1e-15)
        with np.errstate(invalid="ignore"):  # inf - inf where a run broke: not accepted
            gained = np.where(accept, cost - cost_t, np.inf)
        small = accept & (
            (gained <= 1e-8 * cost)
            | (np.max(np.abs(delta), axis=1) <= 1e-12)
            | (2.0 * cost_t / (data.shape[1] * L * L) <= tol)
        )
        # A tiny step is convergence only where Gauss-Newton sees little more to gain from its point
        # (as little as the loss's roughness hides, 1e-6 of the cost). A step made tiny by damping
        # that trials which broke down have raised is not: the fit goes on, and those trials decide.
        for b in np.flatnonzero(small & (2.0 * cost_t / (data.shape[1] * L * L) > tol)):
            A_t, g_t = J_t[b].T @ J_t[b], J_t[b].T @ r_t[b]
            step = -np.linalg.lstsq(A_t, g_t, rcond=None)[0]
            small[b] = -0.5 * float(g_t @ step) <= 1e-6 * cost_t[b]
        theta = np.where(accept[:, None], trial, theta)
        r = np.where(accept[:, None], r_t, r)
        J = np.where(accept[:, None, None], J_t, J)
        cost = np.where(accept, cost_t, cost)
        state[small] = "converged"
        # a step that would gain under 1e-6 of the cost is refused: the loss is as low as its
        # roughness (particles crossing cells make the trajectory only piecewise smooth) lets it go
        rough = active & ~accept & ~broke & (pred <= 1e-6 * cost)
        state[rough] = "converged"
        stuck = active & ~accept & ~rough & (lam > 1e12)
        for b in np.flatnonzero(stuck):
            state[b] = "blocked" if broke[b] else "stalled"
        history.append(np.where(state != "failed", 2.0 * cost / (data.shape[1] * L * L), np.nan))
        if bar is not None:
            bar.update(1)
            bar.set_postfix(loss=f"{np.nanmin(history[-1]):.3e}")
    # out of iterations while trial runs kept breaking down (in the last quarter of the iterations):
    # the breakdowns are what holds the fit back
    recent = {e["start"] for e in rejected if e["broke"] and e["iteration"] > 0.75 * it}
    for b in np.flatnonzero(state == "running"):
        state[b] = "blocked" if b in recent else "iterations"
    return dict(
        theta=theta,
        r=r,
        J=J,
        state=state,
        failed=failed,
        rejected=rejected,
        history=np.stack(history),
        iterations=it,
        taken=taken,
    )


_HALVINGS = 20
"""Adam: how many times in a row a step from one point is halved, its point having broken down, before
the start is given up."""
_QUIET = 4
"""Adam: iterations without a step gone back before the fit may stop for lack of progress."""


def _optax(model, start_theta, data, method, iterations, learning_rate, tol, L, bar, where=None) -> dict:
    """L-BFGS (optax, zoom line search) or Adam on the loss, batched over starts; a start whose run
    breaks down (a non-finite loss) stops there and is reported, its slot following a live start.
    ``where``, when given, holds the iteration under way and the lowest loss so far."""
    where = {} if where is None else where
    B, p = start_theta.shape
    dtype = model.scene.h.dtype

    def loss_fn(theta, start_theta, data):
        return jnp.mean(jnp.square((model.x_of(theta, start_theta) - data) / L))

    opt = optax.adam(learning_rate) if method == "adam" else optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(loss_fn) if method == "lbfgs" else None

    def update(theta, state, start_theta, data, scale):
        # optax's L-BFGS mixes int32 and int64 counters: allow it standard promotion even where a
        # user (or the test suite) runs JAX with strict promotion.
        with jax.numpy_dtype_promotion("standard"):
            if method == "lbfgs":
                value, grad = value_and_grad(theta, start_theta, data, state=state)
                updates, state = opt.update(
                    grad,
                    state,
                    theta,
                    value=value,
                    grad=grad,
                    value_fn=lambda th: loss_fn(th, start_theta, data),
                )
            else:  # Adam's step, shortened by a power of 2 (exact) after steps that broke down
                value, grad = jax.value_and_grad(loss_fn)(theta, start_theta, data)
                updates, state = opt.update(grad, state, theta)
                updates = updates * scale
            return optax.apply_updates(theta, updates), state, value

    update_all = jax.jit(jax.vmap(update))
    theta = jnp.zeros((B, p), dtype=dtype)
    with jax.numpy_dtype_promotion("standard"):
        state = jax.vmap(opt.init)(theta)
    run_start, run_data = jnp.asarray(start_theta, dtype=dtype), jnp.asarray(data, dtype=dtype)
    alive = np.ones(B, dtype=bool)
    failed: dict[int, str] = {}
    frozen: dict[int, np.ndarray] = {}
    rejected: list[dict] = []
    why_left = 8  # the first broken trials get their reason (a plain run each)
    # Adam: the scale of the next step; that of the step that reached the current point; steps in a
    # row from one point whose point broke down; whether the current point is one gone back to
    scale, made = np.ones(B), np.ones(B)
    halvings, retry = np.zeros(B, dtype=int), np.zeros(B, dtype=bool)
    last = None  # Adam: the previous iteration's point, state and loss, to go back to
    last_back = -_QUIET  # the last iteration that went back
    history = []
    it = 0
    for it in range(1, iterations + 1):
        where.update(iteration=it, loss=_lowest(history[-1]) if history else float("nan"))
        used = scale
        new_theta, new_state, value = computed(
            update_all, theta, state, run_start, run_data, jnp.asarray(scale, dtype=dtype)
        )
        value = np.asarray(value)
        broke = alive & ~(np.isfinite(value) & np.all(np.isfinite(np.asarray(new_theta)), axis=1))
        back = np.zeros(B, dtype=bool)
        if method == "adam" and last is not None:
            # the point this iteration reached broke down: refuse it, and step from the previous one
            # again, half as far (a broken run's loss is never used)
            back = broke & (halvings < _HALVINGS)
            broke &= ~back
            for b in np.flatnonzero(back):
                values = model.physical(np.asarray(run_start[b]), np.asarray(theta[b]))
                entry = dict(
                    start=int(b),
                    iteration=it - 1,
                    values=dict(zip(model.names, (float(v) for v in values))),
                    broke=True,
                    loss=float("nan"),
                )
                if why_left > 0:
                    entry["why"], entry["failure"] = model.why(values)
                    why_left -= 1
                rejected.append(entry)
        for b in np.flatnonzero(broke):  # say why, from a plain run at that start's trial values
            why = model.why(model.physical(np.asarray(run_start[b]), np.asarray(theta[b])))[0]
            if method == "adam" and last is not None:
                why += f" (as did every step from the point before it, shortened {_HALVINGS} times)"
            failed[int(b)] = f"iteration {it}: {why}"
            frozen[int(b)] = np.asarray(theta[b])
        alive &= ~broke
        if not alive.any():
            break
        if method == "adam":
            # Gone back: the step that reached the broken point, halved. At a point gone back to,
            # that halved step is under way. Else the step that reached this point did not break
            # down: the next may be twice the one under way (up to the full step).
            halvings = np.where(back, halvings + 1, np.where(retry, halvings, 0))
            scale = np.where(back, 0.5 * made, np.where(retry, scale, np.minimum(1.0, 2.0 * used)))
            made, retry = used, back
            if back.any():
                last_back = it
                mask = jnp.asarray(back)

                def pick(old, new):
                    return jnp.where(mask.reshape(mask.shape + (1,) * (new.ndim - 1)), old, new)

                new_theta = pick(last[0], new_theta)
                new_state = jax.tree_util.tree_map(pick, last[1], new_state)
                last = (
                    pick(last[0], theta),
                    jax.tree_util.tree_map(pick, last[1], state),
                    np.where(back, last[2], value),
                )
                value = last[2]
            else:
                last = (theta, state, value)
        # A broken start is frozen (its values kept for the report) and its slot follows a live
        # start, so that no NaN enters the batch (a NaN member would keep L-BFGS's line search,
        # which runs to the slowest member under vmap, going to its bound every iteration).
        src = jnp.asarray(np.where(alive, np.arange(B), int(np.flatnonzero(alive)[0])))
        theta = new_theta[src]
        state = jax.tree_util.tree_map(lambda a: a[src], new_state)
        run_start, run_data = run_start[src], run_data[src]
        value = np.where(alive, value, np.nan)
        history.append(value)
        if bar is not None:
            bar.update(1)
            bar.set_postfix(loss=f"{np.nanmin(value):.3e}")
        live = value[alive]
        if np.all(live < tol) or (  # converged, or no start improved by 1e-9 in 3 iterations
            len(history) > 3
            and it - last_back >= _QUIET
            and np.all(np.abs(history[-4][alive] - live) <= 1e-9 * live)
        ):
            break
    theta = np.array(theta)
    for b, th in frozen.items():
        theta[b] = th
    # live slots kept their own starts and data; the final point's residuals and Jacobian
    r, J, ok = model.residuals_and_jacobian(theta, start_theta, data)
    ok &= alive
    if method == "adam" and last is not None and np.any(alive & ~ok):
        # Adam's last step reached a point that breaks down: the fit is the point before it
        back = alive & ~ok
        theta = np.where(back[:, None], np.asarray(last[0]), theta)
        r, J, ok = model.residuals_and_jacobian(theta, start_theta, data)
        ok &= alive
    final = np.where(ok, _loss(np.where(ok[:, None], r, 0.0), L), np.nan)
    with np.errstate(invalid="ignore"):  # NaN where a start failed
        state = np.where(ok, np.where(final <= tol, "converged", "iterations"), "failed").astype(object)
    for b in np.flatnonzero(alive & ~ok):
        failed[int(b)] = f"at its final point: {model.why(model.physical(start_theta[b], theta[b]))[0]}"
    history.append(final)
    return dict(
        theta=theta,
        r=r,
        J=J,
        state=state,
        failed=failed,
        rejected=rejected,
        history=np.stack(history),
        iterations=it,
        taken=np.full(B, it),
    )


def _finish(
    model, run, start_theta, data, L, wall, method, noise, max_correlation, max_relative_std, warn=True
):
    """The ``Fit`` of a finished run: the best start, its uncertainty, and what to warn of or refuse
    (``warn=False``, for a batch of fits: no warning issued, a blocked fit's reason in ``warning``)."""
    names = model.names
    state, failed = run["state"], run["failed"]
    final = run["history"][-1]
    if np.all(state == "failed"):
        if all(_NO_RUN in msg for msg in failed.values()):
            reason, todo = _out_of_range(model)
            advice = f"{reason[0].upper()}{reason[1:]}: {todo}."
        else:
            advice = "Reduce dt, choose starts nearer the data, or raise pad if the slab leaves the grid."
        raise CalibrationError(
            "calibrate: every start broke down: "
            + "; ".join(f"start {b}, {msg}" for b, msg in sorted(failed.items()))
            + f". {advice}"
        )
    best = int(np.nanargmin(np.where(state == "failed", np.nan, final)))
    theta = run["theta"]
    phys_all = model.physical(start_theta, theta)
    fitted = {n: float(phys_all[best, i]) for i, n in enumerate(names)}
    r, J = run["r"][best], run["J"][best]
    if method != "lm" and state[best] == "iterations":
        state[best] = _optax_converged(model, theta[best], start_theta[best], data[best], r, J)
    for b in np.flatnonzero(state == "blocked"):  # another start that could not go on: say why
        if b != best:
            values_b = {n: float(phys_all[b, i]) for i, n in enumerate(names)}
            failed[int(b)] = _blocked_message(model, run, int(b), values_b, final[b], lead="")
    edge = _at_edge(model, theta[best], start_theta[best], r, J)
    blocked = None
    if state[best] == "blocked" and edge is None:  # at the edge, the trials past it are refused values
        blocked = _blocked_message(model, run, best, fitted, final[best])
        if warn:
            raise CalibrationError(blocked)
    u = uncertainty(model.scene, names, fitted, r, J_theta=J, noise=noise, offs=model.offsets)
    if edge is not None:  # no minimum inside the range: the Gaussian about it describes nothing
        warning = edge
    else:
        at_fit = type(model.scene)(**{**model.scene.parameter_values(), **fitted})
        warning = identifiability(
            at_fit,
            u,
            np.asarray(model.t_data),
            max_correlation=max_correlation,
            max_relative_std=max_relative_std,
        )
    if state[best] in ("iterations", "stalled"):
        why = (
            f"the fit did not converge in {int(run['taken'][best])} iterations"
            if state[best] == "iterations"
            else "the fit stalled (no trial step lowered the loss)"
        )
        more = f"{why} (loss {final[best]:.6g}): raise iterations, or start nearer the data"
        warning = more if warning is None else f"{more}; and {warning}"
    if blocked is not None:
        warning = blocked if warning is None else f"{blocked}; and {warning}"
    if warning is not None and warn:
        warnings.warn(warning, CalibrationWarning, stacklevel=3)
    return Fit(
        fitted=fitted,
        loss=float(final[best]),
        iterations=int(run["taken"][best]),
        history=run["history"],
        starts_fitted={n: phys_all[:, i].copy() for i, n in enumerate(names)},
        wall_s=wall,
        failed_starts=dict(failed),
        method=method,
        converged=bool(state[best] == "converged"),
        names=names,
        std=u["std"],
        covariance=u["covariance"],
        covariance_theta=u["covariance_theta"],
        correlation=u["correlation"],
        condition=u["condition"],
        sigma=u["sigma"],
        noise_given=noise is not None,
        weakest=u["weakest"],
        warning=warning,
        offsets=dict(model.offsets),
        rejected=list(run["rejected"]),
        residuals=np.asarray(r),
        best_start=best,
    )


def _out_of_range(model) -> tuple[str, str]:
    """Why a fit is pulled out of the scene's range, and what to do: the data want values the scene
    does not allow, with the constants not fitted held at theirs.

    Returns:
        ``(reason, todo)``, each a clause.
    """
    others = [n for n in fittable(model.scene) if n not in model.names]
    held = f" ({', '.join(others)})" if others else ""
    return (
        f"the data pull the fit out of {type(model.scene).__name__}'s range",
        f"check the data and the constants not fitted{held}, or fit other constants",
    )


def _at_edge(model, theta, start_theta, r, J) -> str | None:
    """Whether the fit ran into the bound of a fitted value, in words (``None``: it did not).

    A fitted value ``p`` is at its bound ``p_off`` when ``p - p_off`` is more than ``_EDGE_SHRINK``
    times smaller than its scale (the larger of the start's ``p - p_off`` and ``|p_off|``, so that a
    start next to the bound counts as well), and the Gauss-Newton step from there (``dp = (p - p_off)
    dtheta``, so a ``theta`` step below -1 crosses the bound) would take it past the bound: the loss
    falls all the way to the bound, and the fit has no minimum inside the range (``exp`` in the fit's
    variables would reach the bound itself, which the scene refuses).

    Args:
        model: the fit's ``_Model``.
        theta: the best start's ``theta``, relative to its start (0 at the start).
        start_theta: its start, ``ln(p_start - p_off)``.
        r: its residuals.
        J: their Jacobian in ``theta``.

    Returns:
        ``None``, or a sentence naming each value at its bound and what to check.
    """
    J, r = np.asarray(J, float), np.asarray(r, float)
    norms = np.linalg.norm(J, axis=0)
    scaled = J / np.where(norms > 0, norms, 1.0)  # columns of one size: a vanishing one keeps its rank
    step = -np.linalg.lstsq(scaled, r, rcond=None)[0]
    with np.errstate(divide="ignore"):
        step = np.where(norms > 0, step / np.where(norms > 0, norms, 1.0), -np.inf)
    phys = model.physical(start_theta, theta)
    start = model.physical(start_theta, np.zeros_like(theta))
    gap = np.asarray(phys, float) - model.off
    scale = np.maximum(np.asarray(start, float) - model.off, np.abs(model.off))
    at = [i for i in range(len(model.names)) if gap[i] < scale[i] / _EDGE_SHRINK and step[i] < -1.0]
    if not at:
        return None
    where = "; ".join(
        f"{model.names[i]} = {float(phys[i])!r} (must be > {model.off[i]:g}; {model.names[i]} - "
        f"{model.off[i]:g} fell from {start[i] - model.off[i]:.3g} to {phys[i] - model.off[i]:.3g})"
        for i in at
    )
    reason, todo = _out_of_range(model)
    return (
        f"the fit ran into the edge of the allowed range: {where}. The loss falls all the way to the "
        "edge, so the fit has no minimum inside the range, and the standard errors describe no "
        f"minimum: {reason}; {todo}"
    )


def _optax_converged(model, theta, start_theta, data, r, J) -> str:
    """After L-BFGS or Adam: ``"converged"`` if a Gauss-Newton step would gain less than 1e-6 of the
    cost; else try it (capped at 0.5 in ``theta``), then a quarter and a sixteenth of it: ``"blocked"``
    if every one of their runs breaks down, ``"iterations"`` if not."""
    step = _gauss_newton_step(r, J)
    cost = 0.5 * float(r @ r)
    if -0.5 * float((J.T @ r) @ step) <= 1e-6 * cost:
        return "converged"
    for factor in (1.0, 0.25, 0.0625):
        _, ok = model.residuals((theta + factor * step)[None], start_theta[None], data[None])
        if ok[0]:
            return "iterations"
    return "blocked"


def _gauss_newton_step(r, J, cap=0.5):
    """The Gauss-Newton step in ``theta``, shortened to at most ``cap`` in every component."""
    step = -np.linalg.lstsq(J.T @ J, J.T @ r, rcond=None)[0]
    big = float(np.max(np.abs(step)))
    return step * (cap / big) if big > cap else step


def _blocked_message(
    model, run, best, fitted, loss, lead="calibrate: the fit cannot reach its best point: "
) -> str:
    """Why start ``best`` stopped where every step toward a lower loss is a run that breaks down, and
    what to change."""
    broken = [e for e in run["rejected"] if e["start"] == best and e["broke"]]
    if broken:
        values = broken[-1]["values"]
    else:  # an L-BFGS or Adam fit: the Gauss-Newton step from the best point is the broken trial
        theta = run["theta"][best]
        step = 0.0625 * _gauss_newton_step(run["r"][best], run["J"][best])
        start = np.log(np.array(list(fitted.values())) - model.off) - theta
        values = dict(zip(model.names, (float(v) for v in model.physical(start, theta + step))))
    # the point and the trial past it written to as many digits as tell them apart (6 at least)
    digits = next(
        (d for d in range(6, 17) if any(f"{fitted[k]:.{d}g}" != f"{values[k]:.{d}g}" for k in fitted)), 17
    )
    where = ", ".join(f"{k}={v:.{digits}g}" for k, v in fitted.items())
    if broken and ("why" not in broken[-1] or digits > 6):
        broken[-1]["why"], broken[-1]["failure"] = model.why(np.array(list(values.values())), digits)
    if broken:
        why, failure = broken[-1]["why"], broken[-1].get("failure")
    else:
        why, failure = model.why(np.array(list(values.values())), digits)
    advice = "choose starts nearer the data, or reduce dt"
    if failure is None and model.refused(np.array(list(values.values()))) is not None:
        reason, todo = _out_of_range(model)
        advice = f"{todo} ({reason})"
    elif failure is not None and failure["status"] & LEFT_GRID:
        scene = model.scene
        sc = type(scene)(**{**scene.parameter_values(), **values})
        reach = sc.max_reach() if hasattr(sc, "max_reach") else None
        if reach is not None and pad_for(scene, 1.1 * reach) > scene.pad:
            advice = (
                f"raise pad (now {scene.pad}): the slab can reach x = {reach:.4g} at those values; "
                f"pad >= {pad_for(scene, 1.1 * reach)} holds it"
            )
        else:  # the particles' stencils, not the slab's extent, reach past the grid
            advice = f"raise pad (now {scene.pad}), e.g. to {int(np.ceil(1.5 * scene.pad))}"
    return (
        f"{lead}it stopped at {where} (loss {loss:.6g}), and "
        f"every step toward a lower loss is a run that breaks down; the last: {why}. To go on, {advice}."
    )


def uncertainty(scene, names, fitted, r, *, J_theta, noise=None, offs=None) -> dict:
    """The Gauss-Newton uncertainty at a fitted point.

    Args:
        scene: the scene (for ``offsets``).
        names: the fitted names.
        fitted: name to the fitted value.
        r: residuals ``x_model - x_data``, ``(n,)``.
        J_theta: ``d r / d theta``, ``(n, p)``, ``theta = ln(p - p_off)``.
        noise: the measurement noise; ``None``: ``sigma^2 = sum r^2 / (n - rank)`` (``rank = p``
            unless ``J^T J`` is singular).
        offs: name to ``p_off`` (default: ``offsets(scene, names)``).

    Returns:
        A dict: ``std`` (name to the standard error), ``covariance``, ``covariance_theta``,
        ``correlation``, ``condition``, ``sigma``, ``weakest`` (name to the component of the weakest
        direction in ``d ln p``), ``strongest`` (the best-determined one), ``relative_std`` (name to
        ``std / |value|``). Where ``J^T J`` is singular, the standard error of a constant the data
        do not determine (its unit vector not orthogonal to the null space) is ``inf`` and its
        correlations NaN, while a determined one's comes from the pseudo-inverse; all are NaN when
        the noise cannot be estimated (``n <= rank`` and no ``noise``; ``identifiability`` says why
        in words).

    Raises:
        ValueError: ``names`` empty or not a sequence of names, ``r`` or ``J_theta`` not finite or
            of shapes other than ``(n,)`` and ``(n, len(names))``, ``fitted`` lacking a name or
            holding a value that is not finite or not above its bound, or ``noise`` not one number
            > 0.
    """
    names = tuple(_names(names, "names"))
    if not names:
        raise ValueError("names must name at least one fitted parameter, got none")
    offs = offsets(scene, names) if offs is None else offs
    check_finite("r", r)
    check_finite("J_theta", J_theta)
    r, Jt = np.asarray(r, float), np.asarray(J_theta, float)
    if r.ndim != 1 or Jt.shape != (r.size, len(names)):
        raise ValueError(
            f"r must be 1D (n,) and J_theta (n, {len(names)}) for the {len(names)} names, got shapes "
            f"{r.shape} and {Jt.shape}"
        )
    missing = [k for k in names if k not in fitted]
    if missing:
        raise ValueError(f"fitted must hold a value for every name; missing: {', '.join(missing)}")
    if noise is not None:
        check_scalar("noise", noise, " (one standard deviation, in the units of the data)")
        check_positive("noise", noise)
    n, p = Jt.shape
    value = np.array([fitted[k] for k in names])
    D = value - np.array([offs[k] for k in names])  # d p / d theta
    for k, v, d in zip(names, value, D):
        if not (np.isfinite(v) and d > 0):
            raise ValueError(f"fitted[{k!r}] must be finite and > {offs[k]:g} (its bound), got {float(v)!r}")
    A = Jt.T @ Jt
    J_rel = Jt * (value / D)  # d r / d ln p
    w, V = np.linalg.eigh(J_rel.T @ J_rel)
    condition = float(w[-1] / w[0]) if w[0] > 0 else float("inf")
    precision = float(jnp.finfo(scene.h.dtype).eps)
    regular = w[0] > _cuts(precision)[0] * max(w[-1], 1e-300)
    if regular:
        A_inv, rank = np.linalg.inv(A), p
    else:
        A_inv, rank = _inverse_where_determined(Jt, precision)
    if noise is not None:
        sigma = float(noise)
    elif n > rank:
        sigma = float(np.sqrt(r @ r / (n - rank)))
    else:
        sigma = float("nan")
    with np.errstate(invalid="ignore"):  # inf * 0 where sigma = 0 and a constant is not determined
        C_theta = sigma**2 * A_inv
    if not regular:
        C_theta[np.diag_indices(p)] = np.where(np.isinf(np.diag(A_inv)), np.inf, np.diag(C_theta))
    C_phys = C_theta * np.outer(D, D)
    std = np.sqrt(np.abs(np.diag(C_phys)))
    with np.errstate(invalid="ignore", divide="ignore"):
        s_theta = np.sqrt(np.diag(C_theta))
        corr = C_theta / np.outer(s_theta, s_theta)
        if not np.all(np.isfinite(corr)):
            # sigma = 0 (residuals exactly zero), or a constant not determined: the correlation does
            # not depend on sigma (NaN where a constant is not determined)
            s_unit = np.sqrt(np.diag(A_inv))
            corr = A_inv / np.outer(s_unit, s_unit)
    weakest, strongest = V[:, 0], V[:, -1]
    weakest = weakest * np.sign(weakest[np.argmax(np.abs(weakest))])
    strongest = strongest * np.sign(strongest[np.argmax(np.abs(strongest))])
    return dict(
        std={k: float(s) for k, s in zip(names, std)},
        relative_std={k: float(s / abs(v)) for k, s, v in zip(names, std, value)},
        covariance=C_phys,
        covariance_theta=C_theta,
        correlation=corr,
        condition=condition,
        sigma=sigma,
        weakest={k: float(c) for k, c in zip(names, weakest)},
        strongest={k: float(c) for k, c in zip(names, strongest)},
        eigenvalues=w,
    )


def _cuts(precision: float) -> tuple[float, float]:
    """How small a squared singular value of ``J`` (relative to the largest) counts as zero, and how
    large a component along the null space still counts as orthogonal: ``1e-14`` and ``1e-6`` for a
    Jacobian of float64 runs, scaled with ``precision`` (the machine epsilon of the runs' float type)
    and its square root: ``5.4e-6`` and ``0.023`` for float32, whose round-off leaves proportional
    columns 1e-7 to 1e-6 apart."""
    ratio = precision / float(np.finfo(np.float64).eps)
    return 1e-14 * ratio, 1e-6 * float(np.sqrt(ratio))


def _inverse_where_determined(J, precision: float) -> tuple[np.ndarray, int]:
    """``(J^T J)^-1`` where the data determine it, for a singular ``J^T J``.

    From the singular value decomposition of ``J`` with its columns scaled to unit length. A
    constant is determined when its unit vector is orthogonal to the null space (the right singular
    vectors whose squared singular values are at most ``1e-14`` of the largest in float64): its
    component along them is at most ``1e-6`` (both cuts scaled to the runs' precision: ``_cuts``).
    Its variance, and the covariance of two determined constants, are then those of any generalised
    inverse; this is the pseudo-inverse's.

    Args:
        J: ``(n, p)``.
        precision: the machine epsilon of the float type of the runs that gave ``J``.

    Returns:
        ``(P, rank)``: the pseudo-inverse of ``J^T J`` with ``inf`` on the diagonal and NaN off it for
        the constants the data do not determine, and the rank of ``J``.
    """
    s = np.linalg.norm(J, axis=0)
    seen = s > 0
    s = np.where(seen, s, 1.0)
    _, S, Vt = np.linalg.svd(J / s, full_matrices=False)
    S = np.concatenate([S, np.zeros(Vt.shape[0] - S.size)])
    singular, null = _cuts(precision)
    keep = S**2 > singular * max(S[0] ** 2, 1e-300)
    determined = seen & (np.linalg.norm(Vt[~keep], axis=0) <= null)
    P = (Vt[keep].T / S[keep] ** 2) @ Vt[keep] / np.outer(s, s)
    P = np.where(np.outer(determined, determined), P, np.nan)
    P[np.diag_indices_from(P)] = np.where(determined, np.diag(P), np.inf)
    return P, int(keep.sum())


def _and(names) -> str:
    """``"a"``, ``"a and b"``, ``"a, b and c"``."""
    names = list(names)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def identifiability(
    scene, u: dict, t_data, *, max_correlation=MAX_CORRELATION, max_relative_std=MAX_RELATIVE_STD
) -> str | None:
    """Whether the data determine the fitted constants, in words (``None``: they do).

    Args:
        scene: the scene, at the fitted values (or the model's, for the gas slab's turnaround).
        u: what ``uncertainty`` returned.
        t_data: the observation times.
        max_correlation: the largest acceptable magnitude of a correlation.
        max_relative_std: the largest acceptable relative standard error.

    Returns:
        ``None``, or a sentence: which bound is crossed, the combination the data fix and the
        direction they cannot see, and what to observe (for the gas slab observed only before its
        first turnaround: how long).
    """
    names = tuple(u["std"])
    p = len(names)
    rel = u["relative_std"]
    corr = np.asarray(u["correlation"])
    problems = []
    if not np.isfinite(u["sigma"]):
        return (
            f"the noise cannot be estimated from {np.asarray(t_data).size} observations for {p} "
            "constants: give noise, or observe more often"
        )
    std = u["std"]
    unknown = [k for k in names if not np.isfinite(std[k])]
    if unknown:  # J^T J singular: no standard error, so no correlation either
        errors = "standard error of {} is" if len(unknown) == 1 else "standard errors of {} are"
        problems.append(
            f"the {errors.format(_and(unknown))} infinite (J^T J is singular: some combination of the "
            f"constants leaves the loss unchanged), so the correlations of {_and(unknown)} are undefined"
        )
    pairs = [
        (abs(float(corr[i, j])), names[i], names[j])
        for i in range(p)
        for j in range(i + 1, p)
        if names[i] not in unknown
        and names[j] not in unknown
        and (not np.isfinite(corr[i, j]) or abs(float(corr[i, j])) > max_correlation)
    ]
    for c, a, b in pairs:  # enough digits to tell the correlation from 1
        if not np.isfinite(c):
            problems.append(f"the correlation of {a} and {b} is undefined")
            continue
        digits = 4 if not c < 1.0 else min(8, max(4, int(-np.log10(1.0 - c)) + 2))
        problems.append(f"{a} and {b} are correlated {c:.{digits}f} (beyond {max_correlation:g})")
    loose = [k for k in names if k not in unknown and not rel[k] <= max_relative_std]
    if loose:
        problems.append(
            "relative standard error "
            + ", ".join(f"{k} {100 * rel[k]:.3g}%" for k in loose)
            + f" (above {100 * max_relative_std:g}%)"
        )
    if not problems:
        return None
    weak = u["weakest"]
    see = " : ".join(f"{weak[k]:.3g}" for k in names)
    text = (
        "the data do not determine the constants: "
        + "; ".join(problems)
        + f". The loss barely changes along d ln {' : d ln '.join(names)} = {see}"
    )
    if p >= 2:
        s = u["strongest"]
        top = max(names, key=lambda k: abs(s[k]))
        combo = " ".join([top] + [f"{k}^{s[k] / s[top]:.3g}" for k in names if k != top])
        text += f"; they fix the combination {combo} best"
    t_end = float(np.max(np.asarray(t_data)))
    if hasattr(scene, "turnaround_estimate"):
        t_turn = scene.turnaround_estimate()
        if t_end < t_turn:
            text += (
                f". The data end at t = {t_end:.4g}, before the free surface's first turnaround "
                f"(t ~ {t_turn:.3g} at the fitted values): observe past it, to t ~ {1.5 * t_turn:.3g}"
            )
            return text
    return text + ". Observe longer or more often, measure with less noise, or fit fewer constants"


@dataclasses.dataclass
class Information:
    """The Fisher information of an observation plan: the free-surface position at times ``ts``, each
    with Gaussian noise ``noise``, at given constants. Sub-plans (an earlier end, fewer samples, other
    noise) come from the same Jacobian.

    Attributes:
        names: the constants, the order of the matrices.
        values: their values.
        ts: the plan's times.
        jacobian: ``d x_R(t_i) / d p_j``, ``(len(ts), p)``, physical units.
        noise: the plan's noise level.
        precision: the machine epsilon of the float type of the runs that gave ``jacobian`` (float64's
            by default): how far apart its round-off leaves columns that are really proportional,
            for the decision of what the plan determines.
    """

    names: tuple
    values: dict
    ts: np.ndarray
    jacobian: np.ndarray
    noise: float
    precision: float = float(np.finfo(np.float64).eps)

    def _rows(self, t_end, samples):
        if t_end is not None:
            check_scalar("t_end", t_end)
            check_finite("t_end", t_end)
            if not float(t_end) >= float(self.ts[0]):
                raise ValueError(
                    f"t_end must be at or after the plan's first time, {float(self.ts[0]):.6g}, got {t_end!r}"
                )
        idx = np.flatnonzero(self.ts <= (np.inf if t_end is None else t_end * (1 + 1e-12)))
        if samples is not None:
            check_int("samples", samples, 2)
            if samples < idx.size:
                idx = idx[np.round(np.linspace(0, idx.size - 1, samples)).astype(int)]
        return idx

    def fisher(self, t_end: float | None = None, samples: int | None = None, noise: float | None = None):
        """The Fisher information ``J^T J / noise^2`` of the plan (or of its part up to ``t_end``,
        thinned to ``samples`` evenly spread times, at another ``noise``).

        Args:
            t_end: the end of the observation window (``None``: the whole plan).
            samples: how many of the window's times to keep, evenly spread (``None``: all).
            noise: the noise level (``None``: the plan's).

        Returns:
            ``(p, p)``, physical units.
        """
        if noise is not None:
            check_scalar("noise", noise, " (one standard deviation, in the units of the data)")
            check_real("noise", noise)
        s = self.noise if noise is None else float(noise)
        check_positive("noise", s)
        J = self.jacobian[self._rows(t_end, samples)]
        return J.T @ J / s**2

    def std(self, t_end: float | None = None, samples: int | None = None, noise: float | None = None) -> dict:
        """The standard errors a fit of this plan would have (Cramer-Rao): ``sqrt(diag(I^-1))``.

        Args:
            t_end: the end of the observation window (``None``: the whole plan).
            samples: how many of the window's times to keep (``None``: all).
            noise: the noise level (``None``: the plan's).

        Returns:
            Name to the expected standard error (``inf`` for a constant the plan cannot determine:
            where the information is singular, one whose unit vector is not orthogonal to its null
            space).
        """
        self.fisher(t_end, samples, noise)  # checks the window and the noise
        s = self.noise if noise is None else float(noise)
        P, _ = _inverse_where_determined(self.jacobian[self._rows(t_end, samples)] / s, self.precision)
        return {k: float(v) for k, v in zip(self.names, np.sqrt(np.diag(P)))}

    def correlation(self, t_end: float | None = None, samples: int | None = None) -> np.ndarray:
        """The correlation matrix a fit of this plan would have (independent of the noise level).

        Args:
            t_end: the end of the observation window.
            samples: how many of the window's times to keep.

        Returns:
            ``(p, p)``.

        Raises:
            ValueError: the plan (or its window) does not determine the constants: their standard
                errors are infinite (``std``), so their correlations are undefined.
        """
        self.fisher(t_end, samples, 1.0)  # checks the window
        C, rank = _inverse_where_determined(self.jacobian[self._rows(t_end, samples)], self.precision)
        if rank < len(self.names):
            raise ValueError(
                f"this plan does not determine {_and(self.names)}: the Fisher information is singular, "
                "so the standard errors are infinite (std) and the correlations undefined; observe "
                "longer or more often, or determine fewer constants"
            )
        s = np.sqrt(np.diag(C))
        return C / np.outer(s, s)


def information(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    ts,
    fit: Sequence[str] = ("gamma", "P0"),
    *,
    dt,
    noise: float = 1.0,
    **simulate_kwargs,
) -> Information:
    """The Fisher information of observing the free surface at ``ts``, at the scene's constants.

    One forward-mode Jacobian through one run: before any experiment, it says how well a plan (how
    long, how often, how precisely) would determine each constant.

    Args:
        scene: the scene, at the constants expected.
        interpolator: the MPM method of the model.
        ts: the plan's observation times (``>= 0``, increasing).
        fit: the constants to determine.
        dt: the model's time step.
        noise: the measurement noise (standard deviation, units of ``x``).
        **simulate_kwargs: passed to ``simulate``.

    Returns:
        An ``Information``: ``fisher()``, ``std()``, ``correlation()``, for the plan or part of it.

    Raises:
        ValueError: a ``scene`` or ``interpolator`` that is not jaxmpm's, bad names, times (not a
            non-empty 1D array of finite times from ``>= 0``, increasing) or noise.
        CalibrationError: the run at the scene's constants breaks down.
    """
    _check_parts(scene, interpolator)
    check_keywords("information", simulate_kwargs, simulate, refused=_TRAJECTORY_SETS)
    _check_concrete(scene)
    names = tuple(_names(fit))
    _check_names(scene, names)
    check_scalar("noise", noise, " (one standard deviation, in the units of the data)")
    check_positive("noise", noise)
    check_finite("ts", ts)
    ts = np.asarray(ts, dtype=float)
    if ts.ndim != 1 or ts.size < 1 or ts[0] < 0 or np.any(np.diff(ts) <= 0):
        raise ValueError(
            f"ts must be a non-empty 1D array of times from >= 0, increasing, got {brief(ts.tolist())}"
        )
    model = _Model(scene, interpolator, names, jnp.asarray(ts, dtype=scene.h.dtype), dt, simulate_kwargs)
    value = np.array([float(getattr(scene, n)) for n in names])
    start_theta = np.log(value - model.off)[None]
    r, J, ok = model.residuals_and_jacobian(np.zeros((1, len(names))), start_theta, np.zeros((1, ts.size)))
    if not ok[0]:
        raise CalibrationError(f"information: {model.why(value)[0]}")
    J_phys = J[0] / (value - model.off)
    return Information(
        names=names,
        values=dict(zip(names, value.tolist())),
        ts=ts,
        jacobian=J_phys,
        noise=float(noise),
        precision=float(jnp.finfo(scene.h.dtype).eps),
    )


def profile(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    t_data,
    x_data,
    fit: Fit,
    alphas,
    *,
    dt,
    direction: dict | None = None,
    **simulate_kwargs,
) -> dict:
    """The loss along a direction through a fit's best point, all points in one ``vmap``-ed call.

    The points are ``ln p = ln p_fit + alpha * d`` (``d``: ``fit.weakest`` by default, a unit vector in
    ``d ln p``), so ``alpha = 0.1`` moves about 10% along it. A short window shows a valley (the loss
    hardly changes), a long one a bowl.

    Args:
        scene: the model's scene.
        interpolator: the MPM method of the model.
        t_data: the observation times.
        x_data: the observed positions.
        fit: the fit (its ``fitted`` values and ``weakest`` direction).
        alphas: the steps along the direction.
        dt: the model's time step.
        direction: name to component in ``d ln p`` (default ``fit.weakest``).
        **simulate_kwargs: passed to ``simulate``.

    Returns:
        A dict: ``alpha``, ``loss`` (NaN where the run broke down or the scene refuses the values, and
        ``ok`` False there), ``ok``, and each name to its values along the line.

    Raises:
        ValueError: a ``scene`` or ``interpolator`` that is not jaxmpm's, ``fit`` not a ``Fit``,
            ``alphas`` empty or not finite, bad data (as for ``calibrate``), or a point along the
            line at or below a bound ``p_off``.
    """
    _check_parts(scene, interpolator)
    check_keywords("profile", simulate_kwargs, simulate, refused=_TRAJECTORY_SETS)
    _check_concrete(scene)
    if not isinstance(fit, Fit):
        raise ValueError(f"fit must be the Fit that calibrate returned, got {brief(fit)}")
    names = tuple(fit.fitted)
    direction = fit.weakest if direction is None else _check_direction(direction, names)
    d = np.array([float(direction.get(n, 0.0)) for n in names])
    check_finite("alphas", alphas)
    if np.size(alphas) == 0:
        raise ValueError("alphas must hold at least one step along the direction, got an empty array")
    alphas = np.asarray(alphas, dtype=float).reshape(-1)
    t_data, x_data = _check_data(scene, t_data, x_data)
    values = np.array([fit.fitted[n] for n in names]) * np.exp(alphas[:, None] * d[None, :])
    model = _Model(scene, interpolator, names, t_data, dt, simulate_kwargs)
    below = np.argwhere(~(values - model.off > 0))
    if below.size:
        i, j = (int(k) for k in below[0])
        raise ValueError(
            f"alphas[{i}] = {float(alphas[i])!r} takes {names[j]} to {values[i, j]:.6g}, at or below its "
            f"bound {model.off[j]:g}: take smaller steps along the direction"
        )
    start_theta = np.log(values - model.off)
    data = np.broadcast_to(np.asarray(x_data), (alphas.size, x_data.shape[0]))
    r, ok = model.residuals(np.zeros_like(start_theta), start_theta, data)
    loss = np.where(ok, _loss(np.where(ok[:, None], r, 0.0), _scale(scene, x_data)), np.nan)
    return dict(alpha=alphas, loss=loss, ok=ok, **{n: values[:, i] for i, n in enumerate(names)})


def _check_direction(direction, names) -> dict:
    """``profile``'s ``direction``: a dict from the fit's names to real numbers, not all zero.

    Raises:
        ValueError: not a dict, a name the fit did not fit, a component that is not one finite real
            number, or every component zero (no line).
    """
    if not isinstance(direction, dict):
        raise ValueError(
            f"direction must be a dict from the fitted names ({', '.join(names)}) to components in "
            f"d ln p, such as {{{names[0]!r}: 1.0}}, got {brief(direction)}"
        )
    for k, v in direction.items():
        if k not in names:
            raise ValueError(f"direction names {k!r}, which the fit did not fit; fitted: {', '.join(names)}")
        check_finite(f"direction[{k!r}]", v)
        check_scalar(f"direction[{k!r}]", v)
    if not any(float(v) for v in direction.values()):
        raise ValueError(f"direction must have a component that is not zero, got {direction!r}")
    return direction


def _bar(progress, total):
    from .long_run import show_progress

    if not show_progress(progress):
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="calibrate", unit="it", dynamic_ncols=True)
