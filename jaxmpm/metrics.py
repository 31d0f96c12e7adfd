"""Errors and diagnostics over the real particles: errors against an exact solution, the domain
separation of neighbours, the totals of mass, momentum and energy, and the smoothness of a radially
expanding gas (angular spread of the radial velocity, spurious rotation, folded domains)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from ._checks import (
    any_traced,
    brief,
    check_bool,
    check_finite,
    check_int,
    check_nonnegative,
    check_scalar,
    is_bool,
    is_concrete,
    is_real,
    python_int,
    show,
)
from ._util import adjugate, corner_signs, det
from .materials import DEVIATORIC_KEYS, AbstractEOS
from .particles import Body, State, parallelogram_corners
from .scenes import SCENES, AbstractScene

EXACT_ERRORS = (
    "F_max_rel",
    "F_rms_rel",
    "F_max_rel_boundary",
    "F_rms_rel_boundary",
    "F_max_rel_interior",
    "F_rms_rel_interior",
    "x_max_abs",
    "x_rms_abs",
    "v_max_abs",
    "v_rms_abs",
    "sigma_max_abs",
)
"""The errors against an exact solution (``None`` for a scene without one)."""
INTERIOR_ERRORS = ("F_max_rel_interior", "F_rms_rel_interior")
"""The errors also ``None`` for a body with no interior cell (cells <= 2: every particle is in a
boundary cell)."""


def available_errors(scene: AbstractScene) -> tuple[str, ...]:
    """The names ``errors`` gives a number for (not ``None``) on ``scene``.

    Args:
        scene: the scene.

    Returns:
        The names of its finite errors.

    Raises:
        ValueError: ``scene`` is not a scene.
    """
    _check_scene(scene)
    if scene.exact is None:
        return ("separation_max",)
    return ("separation_max",) + tuple(k for k in EXACT_ERRORS if scene.cells > 2 or k not in INTERIOR_ERRORS)


def exact_fields(scene: AbstractScene, body: Body, t: Float[ArrayLike, ""]) -> dict[str, Array] | None:
    """The exact fields at every real particle.

    A scene whose exact solution holds for a while only declares until when, ``t_valid``
    (``VacuumExpansion``, ``Riemann``, ``Detonation``); at a concrete ``t`` past it there is none
    (``exact_holds``). ``ShockTube`` and ``Noh`` have no exact motion (their ``exact`` is ``None``,
    and so is the result): their exact Euler solution is ``euler_errors``'s.

    Args:
        scene: the scene.
        body: the reference configuration.
        t: time.

    Returns:
        ``dict(x, v, F, sigma)`` at every particle's ``X`` at time ``t``, each with a leading
        particle axis; ``None`` for a scene with no exact solution, or none at ``t``.

    Raises:
        ValueError: ``scene`` is not a scene, ``body`` is not a ``Body``, or a concrete ``t`` is not
            one finite number >= 0.
    """
    _check_scene(scene)
    _check_body(body)
    check_scalar("t", t)
    check_nonnegative("t", t)
    if scene.exact is None or not exact_holds(scene, t):
        return None
    return _exact_fields(scene, body.X, t)


def exact_holds(scene: AbstractScene, t: Float[ArrayLike, ""]) -> bool:
    """Whether the scene's exact solution holds at time ``t``: up to its ``t_valid`` (to round-off)
    where it declares one (the time a wave reaches what the solution leaves out: the wall of a
    vacuum expansion, an end of a shock tube or of a detonated slab).

    Args:
        scene: the scene.
        t: the time; traced (under ``jit`` or ``vmap``) it cannot be read and is taken as within.

    Returns:
        ``True`` where the scene has no ``t_valid``, ``t`` is traced, or ``t <= t_valid``; ``False``
        past it (and for a scene with no exact solution at all: neither an exact motion, ``exact``,
        nor an exact Euler solution, ``solution``).

    Raises:
        ValueError: ``scene`` is not a scene, or a concrete ``t`` is not a finite number.
    """
    _check_scene(scene)
    if is_concrete(t) and np.ndim(t) == 0 and not np.isfinite(float(t)):
        raise ValueError(f"t must be a finite number, got {float(t)!r}")
    if scene.exact is None and not hasattr(scene, "solution"):
        return False
    if getattr(type(scene), "t_valid", None) is None or not is_concrete(t) or np.ndim(t) != 0:
        return True
    t_valid = scene.t_valid
    if not is_concrete(t_valid):
        return True
    dtype = np.asarray(t).dtype
    eps = float(np.finfo(dtype if np.issubdtype(dtype, np.floating) else np.float64).eps)
    return float(t) <= float(t_valid) * (1.0 + 8.0 * eps)


@eqx.filter_jit
def _exact_fields(scene, X, t):
    # compiled: an exact solution made by autodiff (manufactured scenes) costs seconds op by op
    return jax.vmap(scene.exact, in_axes=(0, None))(X, t)


def implied_corners(state: State, body: Body, allow_broken: bool = False) -> Float[Array, "n corners dim"]:
    """Each particle's domain corners as its ``x`` and ``F`` imply them.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``x_p + F diag(r0) s_c`` (``particles.parallelogram_corners``; in 1D ``x_p -/+ F r0``).

    Raises:
        ValueError: ``state`` is not one run's ``State`` or is of a run that broke down (and
            ``allow_broken`` is ``False``), ``body`` is not a ``Body``, or the state and the body
            have different particle counts.
    """
    _check_state(state, "implied_corners()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    return parallelogram_corners(body.r0, state.x, state.F)


def domain_corners(state: State, body: Body, allow_broken: bool = False) -> Float[Array, "n corners dim"]:
    """Each particle's own domain corners.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        The tracked corners where the run tracks them (MPQ, CPDI2: one copy for all the particles that meet
        at a corner), else those ``x`` and ``F`` imply (``implied_corners``).

    Raises:
        ValueError: ``state`` is not one run's ``State`` or is of a run that broke down (and
            ``allow_broken`` is ``False``), ``body`` is not a ``Body``, or the state and the body
            have different particle counts.
    """
    _check_state(state, "domain_corners()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    if state.corners is not None:
        return body.particle_corners(state.corners)
    return parallelogram_corners(body.r0, state.x, state.F)


def corner_gap(corners: Float[Array, "n corners dim"], body: Body) -> Float[Array, " nc"]:
    """How far apart the particles' copies of each corner of the reference lattice are.

    At every corner, the largest distance of a particle's copy from the copies' mean, over the
    half-length ``r0``. Zero where neighbouring domains meet (tracked corners, always); in 1D
    the magnitude of ``separation``. A gap and an overlap both count.

    Args:
        corners: each particle's corners (``domain_corners``).
        body: the reference configuration.

    Returns:
        The gap at each corner of ``body.X_corners``.

    Raises:
        ValueError: ``body`` is not a ``Body``, or ``corners`` are not ``2^dim`` corners of each of
            its particles.
    """
    _check_body(body)
    _check_corners(corners, body)
    return _safe_sqrt(_corner_gap_sq(corners, body))


def _corner_gap_sq(corners, body):
    ids = body.corner_ids.reshape(-1)
    nc = body.X_corners.shape[0]
    c = corners.reshape(-1, corners.shape[-1])
    count = jax.ops.segment_sum(jnp.ones_like(c[:, 0]), ids, num_segments=nc)
    mean = jax.ops.segment_sum(c, ids, num_segments=nc) / count[:, None]
    dev = jnp.sum(jnp.square(c - mean[ids]), axis=1) / jnp.square(jnp.min(body.r0))
    return jax.ops.segment_max(dev, ids, num_segments=nc)


def separation(state: State, body: Body, allow_broken: bool = False) -> Float[Array, " n_minus_1"]:
    """Domain separation of neighbours, ``(x_{p+1} - x_p - (F_{p+1} + F_p) r0) / (2 r0)``.

    The violation of the consistency condition between neighbours ``x_{p+1} - x_p = (F_{p+1} + F_p)
    r0`` (Bonifasi-Lista, Brannon & Wiskin 2013): zero when neighbouring domains touch; positive for
    a gap, negative for an overlap. 1D; in 2D and 3D use ``corner_gap``.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        The separation of each pair of neighbours.

    Raises:
        ValueError: ``state`` is not one run's ``State`` (a ``Solution``, an ensemble's batch) or is of
            a run that broke down (and ``allow_broken`` is ``False``), ``body`` is not a ``Body``, the
            run is not 1D, or the state and the body have different particle counts.
    """
    _check_state(state, "separation()", allow_broken)
    _check_body(body)
    if state.x.shape[1] != 1:
        raise ValueError("separation is the 1D diagnostic; in 2D and 3D use corner_gap")
    _check_particles(state, body)
    return _separation(state.x, state.F, body.r0)


@jax.jit
def _separation(x, F, r0):
    # compiled: op by op, each call on a new particle count would compile its 7 operations
    x = x[:, 0]
    F = F[:, 0, 0]
    r0 = r0[:, 0]
    r0_mean = 0.5 * (r0[1:] + r0[:-1])
    return (x[1:] - x[:-1] - (F[1:] * r0[1:] + F[:-1] * r0[:-1])) / (2.0 * r0_mean)


def _safe_sqrt(x):
    """``sqrt`` whose derivative at 0 is 0 instead of NaN (an exact solution has zero error); NaN stays
    NaN (a state that is not finite has no error to report as 0)."""
    zero = x == 0
    return jnp.where(zero, 0.0, jnp.sqrt(jnp.where(zero, 1.0, x)))


def _sq_rel(a, b, n):
    """Per-particle squared relative error ``|a - b|^2 / |b|^2`` (no ``abs``: smooth at a = b)."""
    return jnp.sum(jnp.square(a - b).reshape(n, -1), axis=1) / jnp.sum(jnp.square(b).reshape(n, -1), axis=1)


def _sq_abs(a, b, n):
    return jnp.sum(jnp.square(a - b).reshape(n, -1), axis=1)


def _max_rms(sq, mask=None):
    """``(max, rms)`` of ``sqrt(sq)`` over the particles in ``mask`` (all if ``None``); both 0 for a
    mask that selects no particle."""
    if mask is None:
        return _safe_sqrt(jnp.max(sq)), _safe_sqrt(jnp.mean(sq))
    count = jnp.sum(mask).astype(sq.dtype)
    return (
        _safe_sqrt(jnp.max(jnp.where(mask, sq, 0.0))),
        _safe_sqrt(jnp.sum(jnp.where(mask, sq, 0.0)) / jnp.maximum(count, 1)),
    )


def smooth_mask(scene: AbstractScene, body: Body, t: Float[ArrayLike, ""]) -> Bool[Array, " n"] | None:
    """The particles away from fronts (``scene.smooth``).

    Args:
        scene: the scene.
        body: the reference configuration.
        t: time.

    Returns:
        One bool per particle, or ``None`` for a scene smooth everywhere.

    Raises:
        ValueError: ``scene`` is not a scene, or ``body`` is not a ``Body``.
    """
    _check_scene(scene)
    _check_body(body)
    if scene.smooth is None:
        return None
    return jax.vmap(scene.smooth, in_axes=(0, None))(body.X, t)


def _check_state(state, what: str, allow_broken) -> None:  # allow_broken: checked here
    """``state`` is one run's ``State`` (not a ``Solution``, ``None`` or an ensemble's batch), and
    not that of a run that broke down unless ``allow_broken``."""
    if not isinstance(state, State):
        if isinstance(getattr(state, "state", None), State):  # a Solution
            raise ValueError(
                f"state must be a jaxmpm State, got a {type(state).__name__}: pass solution.state and "
                "solution.body"
            )
        if getattr(state, "solution", None) is not None and hasattr(state, "member"):  # an Ensemble
            raise ValueError(
                f"state must be a jaxmpm State, got an {type(state).__name__}: measure each member "
                "(ensemble.member(i).state and .body)"
            )
        got = "None" if state is None else type(state).__name__
        raise ValueError(f"state must be a jaxmpm State (solution.state), got {got}")
    if state.x.ndim != 2:
        raise ValueError(
            f"{what} measures one run, and this state holds a batch (x of shape {tuple(state.x.shape)}): "
            "measure each member whose status is 0 (Ensemble.member(i), with its scene "
            "Ensemble.member_scene(scene, i)); under jax.vmap the status is not read, so leave out the "
            "members that broke down first"
        )
    _refuse_broken(state, allow_broken, f"{what} measures a finished run, and this state is")
    if is_concrete(state.t) and not float(state.t) >= 0.0:  # NaN fails too
        raise ValueError(
            f"{what} measures a state of a run, whose time t is finite and >= 0; this state has "
            f"t = {float(state.t)!r}"
        )


def _check_body(body) -> None:
    """``body`` is one run's ``Body`` (not a ``Solution``, ``None`` or an ensemble's batch)."""
    if not isinstance(body, Body):
        if isinstance(getattr(body, "body", None), Body):  # a Solution
            raise ValueError(
                f"body must be a jaxmpm Body, got a {type(body).__name__}: pass solution.state and "
                "solution.body"
            )
        got = "None" if body is None else type(body).__name__
        raise ValueError(
            f"body must be the run's reference configuration, a jaxmpm Body (solution.body), got {got}"
        )
    if body.X.ndim != 2:
        raise ValueError(
            f"body must be one run's Body, and this one holds a batch (X of shape {tuple(body.X.shape)}): "
            "measure each member whose status is 0 (Ensemble.member(i), with its scene "
            "Ensemble.member_scene(scene, i)); under jax.vmap the status is not read, so leave out the "
            "members that broke down first"
        )


_MEASURE_ANYWAY = "Pass allow_broken=True to measure that state anyway."


def _refuse_broken(state: State, allow_broken, what: str, then: str = _MEASURE_ANYWAY) -> None:
    """Raise where ``state`` is that of a run that broke down (a concrete, nonzero status), the
    message ending with ``then`` (what to do instead). ``allow_broken``: checked here.

    Under ``jax.jvp`` and ``jax.jacfwd`` the integer fields (status, steps) are concrete and the time
    is traced: the message names what is concrete."""
    check_bool("allow_broken", allow_broken)
    status = state.status
    if allow_broken or not is_concrete(status) or np.ndim(status) != 0 or int(status) == 0:
        return
    from . import status as st_bits

    failed = f" at step {int(state.fail_step)}" if is_concrete(state.fail_step) else ""
    last = ""
    if is_concrete(state.step):
        at = f" (t = {float(state.t):.6g})" if is_concrete(state.t) else ""
        last = f", at step {int(state.step)}{at}"
    raise ValueError(
        f"{what} of a run that broke down{failed} ({' and '.join(st_bits.describe(int(status)))}): "
        f"its state is the last good one{last}, not the run's end. {then}"
    )


def errors(
    scene: AbstractScene,
    state: State,
    body: Body,
    where: Bool[Array, " n"] | None = None,
    allow_broken: bool = False,
) -> dict[str, Array | None]:
    """Errors against the scene's exact solution, over real particles only.

    With ``where`` (a boolean per particle, e.g. ``smooth_mask(scene, body, t)``), every error
    against the exact solution is taken over those particles only; ``separation_max`` stays global.

    ``F_*_rel`` are relative errors ``|F - F_exact| / |F_exact|``, also split into particles seeded
    in the boundary cells (first and last cell of the body) and the interior. ``x``, ``v`` and
    ``sigma`` errors are absolute. Errors are ``None`` for a scene with no exact solution, and those
    of the boundary cells (the interior) are ``None`` when no particle measured is in them: the body
    has no interior cell, or ``where`` leaves none of the group. A ``where`` traced (under ``jit``)
    cannot be read, and a group it leaves empty then measures 0 (a max and an RMS over no particle),
    never NaN. ``separation_max`` is always set:
    in 1D the largest ``|separation|``, in 2D and 3D the largest ``corner_gap`` of the domains that
    ``x`` and ``F`` imply.

    Every entry is differentiable, with derivative 0 (not NaN) where an error is exactly zero.

    The state of a run that broke down (``state.status != 0``) is its last good one, not its end, and
    is refused unless ``allow_broken``. Traced (under ``jit`` or ``vmap``), the status cannot be read:
    check it beside the errors (``Solution.status``, ``Ensemble.status``).

    A scene whose exact solution holds for a while only (``t_valid``: ``VacuumExpansion``,
    ``Riemann``, ``Detonation``) has none past it: at a concrete ``state.t`` past ``t_valid`` the
    errors against it are ``None``, as for a scene with no exact solution (``exact_holds`` says
    which). ``ShockTube`` and ``Noh`` have no exact motion (``exact`` is ``None``): their errors
    here are ``None``, and ``euler_errors`` measures them against their exact Euler solution.

    Args:
        scene: the scene.
        state: the state (``solution.state``).
        body: the reference configuration (``solution.body``).
        where: one bool per particle (an array, or a list of them), or ``None`` for all.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        Error name (``"separation_max"`` and ``EXACT_ERRORS``) to value or ``None``.

    Raises:
        ValueError: ``scene`` is not a scene, ``state`` is not one run's ``State`` (a ``Solution``, an
            ensemble's batch, ``None``), ``body`` is not a ``Body``, the state is of a run that broke
            down (and ``allow_broken`` is ``False``), its time ``t`` is not finite and >= 0 (every
            measure refuses such a state), the state is not of the scene's dimension, the state and
            the body have different particle counts, or the body has not the particles the scene
            seeds (a run of another scene), ``where`` is not one bool per particle.
    """
    _check_scene(scene)
    _check_state(state, "errors()", allow_broken)
    _check_body(body)
    _check_run(scene, state, body, "errors()")
    where = _check_where(where, body)
    has_boundary, has_interior = _groups(body.boundary, where)
    exact = scene.exact is not None and exact_holds(scene, state.t)
    ex = _exact_fields(scene, body.X, state.t) if exact else None
    fields = (state.x, state.v, state.F, state.sigma)
    return _errors(fields, ex, body, where, has_boundary, has_interior)


def _groups(boundary, where) -> tuple[bool, bool]:
    """Whether the particles measured (``where``, or all for ``None``) include any of the boundary
    cells and any of the interior: ``(has_boundary, has_interior)``. Where ``boundary`` or ``where``
    is a tracer this cannot be read, and both are ``True`` (an empty group then measures 0)."""
    if not (is_concrete(boundary) and is_concrete(where)):
        return True, True
    b = np.asarray(boundary, dtype=bool)
    w = np.ones_like(b) if where is None else np.asarray(where, dtype=bool)
    return bool(np.any(b & w)), bool(np.any(~b & w))


@eqx.filter_jit
def _errors(fields, ex, body, where, has_boundary: bool, has_interior: bool):
    # One compiled program for each shape of the fields it reads (whatever the interpolator and
    # transfer), the exact solution apart (its own program for each scene). Op by op, a call on a new
    # particle count would compile each of its ~27 operations.
    x, v, F, sigma = fields
    n = body.n
    if x.shape[1] > 1:  # the implied parallelograms' largest corner gap
        sep = _safe_sqrt(jnp.max(_corner_gap_sq(parallelogram_corners(body.r0, x, F), body)))
    elif n > 1:
        sep = _safe_sqrt(jnp.max(jnp.square(_separation(x, F, body.r0))))
    else:
        sep = jnp.zeros((), x.dtype)
    out: dict[str, Array | None] = dict(separation_max=sep)
    if ex is None:
        out.update(dict.fromkeys(EXACT_ERRORS))
        return out
    F_sq = _sq_rel(F, ex["F"], n)
    w = where
    and_w = (lambda m: m) if w is None else (lambda m: m & w)
    out["F_max_rel"], out["F_rms_rel"] = _max_rms(F_sq, w)
    b = body.boundary
    if has_boundary:
        out["F_max_rel_boundary"], out["F_rms_rel_boundary"] = _max_rms(F_sq, and_w(b))
    else:
        out["F_max_rel_boundary"] = out["F_rms_rel_boundary"] = None
    if has_interior:
        out["F_max_rel_interior"], out["F_rms_rel_interior"] = _max_rms(F_sq, and_w(~b))
    else:
        out["F_max_rel_interior"] = out["F_rms_rel_interior"] = None
    out["x_max_abs"], out["x_rms_abs"] = _max_rms(_sq_abs(x, ex["x"], n), w)
    out["v_max_abs"], out["v_rms_abs"] = _max_rms(_sq_abs(v, ex["v"], n), w)
    out["sigma_max_abs"], _ = _max_rms(_sq_abs(sigma, ex["sigma"], n), w)
    return out


def _momentum(p):
    total = jnp.sum(p, axis=0)
    return total[0] if p.shape[1] == 1 else total


def diagnostics(
    scene: AbstractScene, state: State, body: Body, allow_broken: bool = False
) -> dict[str, Array]:
    """Total mass, momentum, kinetic, internal and total energy of the real particles.

    ``momentum`` is a number in 1D and a vector of ``dim`` components in 2D and 3D.

    Internal energy is ``sum_p V0_p W(F_p)`` with the material's stored energy ``W``, and
    ``sum_p m_p e_p`` on the particles of a material with an energy equation (``AbstractEOS``).

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        scene: the scene (its material).
        state: the state.
        body: the reference configuration.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``dict(mass, momentum, energy_kinetic, energy_internal, energy)``.

    Raises:
        ValueError: ``scene`` is not a scene, ``state`` is not one run's ``State`` (a ``Solution``, an
            ensemble's batch, ``None``), ``body`` is not a ``Body``, the state is of a run that broke
            down (and ``allow_broken`` is ``False``), the state is not of the scene's dimension, or the
            state and the body have different particle counts.
    """
    _check_scene(scene)
    _check_state(state, "diagnostics()", allow_broken)
    _check_body(body)
    _check_run(scene, state, body, "diagnostics()")
    return _diagnostics(scene, state.v, state.F, state.e, body)


@eqx.filter_jit
def _diagnostics(scene, v, F, e, body):
    # One compiled program for each scene and shape of the fields it reads, as ``errors`` (op by op:
    # 0.7 s on a new particle count).
    kinetic = 0.5 * jnp.sum(body.m * jnp.sum(jnp.square(v), axis=1))
    if scene.regions is None:
        internal = jnp.sum(body.V0 * jax.vmap(scene.material().energy_density)(F))
    else:
        lay = scene.layout()
        internal = jnp.zeros((), dtype=body.m.dtype)
        for k, region in enumerate(scene.regions()):
            idx = lay.index(k)
            if isinstance(region.material, AbstractEOS):
                internal = internal + jnp.sum(body.m[idx] * e[idx])
            else:
                internal = internal + jnp.sum(body.V0[idx] * jax.vmap(region.material.energy_density)(F[idx]))
    return dict(
        mass=jnp.sum(body.m),
        momentum=_momentum(body.m[:, None] * v),
        energy_kinetic=kinetic,
        energy_internal=internal,
        energy=kinetic + internal,
    )


def pressure_error(
    scene: AbstractScene,
    state: State,
    body: Body,
    where: Bool[Array, " n"] | None = None,
    allow_broken: bool = False,
) -> Array | None:
    """The RMS relative pressure error ``|p - p_exact| / |p_exact|`` against the scene's exact solution.

    Args:
        scene: the scene.
        state: the state.
        body: the reference configuration.
        where: one bool per particle (e.g. ``smooth_mask``), or ``None`` for all.
        allow_broken: measure the state of a run that broke down too (as for ``errors``).

    Returns:
        The error, or ``None`` for a scene without an exact solution.

    Raises:
        ValueError: as for ``errors``.
    """
    _check_scene(scene)
    _check_state(state, "pressure_error()", allow_broken)
    _check_body(body)
    _check_run(scene, state, body, "pressure_error()")
    where = _check_where(where, body)
    if scene.exact is None:
        return None
    _check_time(scene, state.t, "pressure_error() compares with", "the state's time t")
    ex = _exact_fields(scene, body.X, state.t)
    dim = state.F.shape[-1]
    p_ex = -jnp.trace(ex["sigma"], axis1=1, axis2=2) / dim
    sq = jnp.square((_pressure(state) - p_ex) / jnp.where(p_ex == 0, 1.0, p_ex))
    return _max_rms(sq, where)[1]


def density(state: State, body: Body, allow_broken: bool = False) -> Float[Array, " n"]:
    """Each particle's current density ``m / (V0 det F)``.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``rho``.

    Raises:
        ValueError: ``state`` is not one run's ``State`` (a ``Solution``, an ensemble's batch,
            ``None``) or is of a run that broke down (and ``allow_broken`` is ``False``), ``body`` is not
            a ``Body``, or the state and the body have different particle counts.
    """
    _check_state(state, "density()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    return body.m / (body.V0 * jax.vmap(jnp.linalg.det)(state.F))


def pressure(state: State, allow_broken: bool = False) -> Float[Array, " n"]:
    """Each particle's pressure ``-tr(sigma) / dim`` (the viscous pressure included).

    With the deviatoric stress of ``ElasticPlastic`` among the internal variables (``s_xx``, ...), the
    in-plane diagonal of the deviator is taken out first, ``p = -(tr(sigma) - sum_a s_aa) / dim``
    (``a < dim``): the mean of the full 3x3 stress, whose out-of-plane components ``sigma`` (1D, 2D)
    does not hold. Other particles carry zeros there.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``p``.

    Raises:
        ValueError: ``state`` is not one run's ``State`` (a ``Solution``, an ensemble's batch,
            ``None``) or is of a run that broke down (and ``allow_broken`` is ``False``).
    """
    _check_state(state, "pressure()", allow_broken)
    return _pressure(state)


def _pressure(state: State) -> Float[Array, " n"]:
    dim = state.F.shape[-1]
    trace = jnp.trace(state.sigma, axis1=1, axis2=2)
    if state.internal is not None and DEVIATORIC_KEYS[0] in state.internal:
        trace = trace - sum(state.internal[k] for k in DEVIATORIC_KEYS[:dim])
    return -trace / dim


EULER_FIELDS = ("rho", "u", "p", "e")
"""The fields ``euler_errors`` compares: density, velocity, pressure, specific internal energy."""


def euler_errors(
    scene: AbstractScene, state: State, body: Body, allow_broken: bool = False
) -> dict[str, Array] | None:
    """L1 errors of density, velocity, pressure and specific internal energy against an exact solution
    of the Euler equations, ``sum_p |f_p - f(x_p, t)| V_p`` (``V_p = V0_p det F_p``, the norm of
    ``int |f - f_exact| dx`` sampled at the particles; 1D).

    The exact solution is the scene's ``solution(x, t)`` (``ShockTube``, ``Noh``), evaluated at the
    particles' current positions: a Lagrangian method is compared where its particles are.

    Args:
        scene: the scene.
        state: the state (``t > 0``; its ``e`` set).
        body: the reference configuration.
        allow_broken: measure the state of a run that broke down too (as for ``errors``).

    Returns:
        ``dict(rho_L1, u_L1, p_L1, e_L1)``, or ``None`` for a scene without an exact Euler solution, a
        run without an energy equation, or a state past the time the exact solution holds (the
        scene's ``t_valid``, ``exact_holds``: a shock tube's waves reach its ends).

    Raises:
        ValueError: ``scene`` is not a scene, ``state`` is not one run's ``State`` (a ``Solution``, an
            ensemble's batch, ``None``) or is of a run that broke down (and ``allow_broken`` is
            ``False``), ``body`` is not a ``Body``, or the state and the body have different particle
            counts.
    """
    _check_scene(scene)
    _check_state(state, "euler_errors()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    if not hasattr(scene, "solution") or state.e is None or state.x.shape[1] != 1:
        return None
    if not exact_holds(scene, state.t):
        return None
    ex = scene.solution(state.x[:, 0], state.t)
    V = body.V0 * state.F[:, 0, 0]
    num = dict(rho=density(state, body, bool(allow_broken)), u=state.v[:, 0], p=_pressure(state), e=state.e)
    return {f"{k}_L1": jnp.sum(jnp.abs(num[k] - ex[k]) * V) for k in EULER_FIELDS}


# Smoothness of a radially expanding gas: an exact radial motion ``x = c + r(R, t) (X - c) / R``
# about a centre ``c`` (``R = |X - c|``) has a symmetric ``F`` (no rotation), a radial velocity that
# depends on ``R`` only, and unfolded particle domains. The measures below are how far a run is
# from each.


def _check_scene(scene) -> None:
    """``scene`` is a scene (an ``AbstractScene``), not ``None``, a scene's name or anything else."""
    if not isinstance(scene, AbstractScene):
        got = repr(scene) if scene is None or isinstance(scene, (str, int, float)) else type(scene).__name__
        if isinstance(scene, str) and scene in SCENES:
            got += f" (a scene's name: jm.SCENES[{scene!r}]() is the scene)"
        raise ValueError(
            f"scene must be a jaxmpm scene (an AbstractScene, such as jm.GasExpansion()), got {got}"
        )


def _check_particles(state: State, body: Body) -> None:
    if state.x.shape[0] != body.n:
        raise ValueError(f"the state has {state.x.shape[0]} particles and the body {body.n}")


def _check_run(scene: AbstractScene, state: State, body: Body, what: str) -> None:
    """One run's state (``_check_state``) of the scene's dimension and the body's particles, and a body
    of as many particles as the scene seeds (told where the scene's regions are concrete)."""
    if state.x.shape[1] != scene.dim:
        raise ValueError(f"the state is {state.x.shape[1]}D and the scene {scene.name} is {scene.dim}D")
    _check_particles(state, body)
    if scene.regions is None:
        seeded = (scene.cells * scene.ppc) ** scene.dim
    elif all(is_concrete(a) for a in jax.tree.leaves(scene)):
        seeded = len(scene.layout().keep)
    else:
        return
    if body.n != seeded:
        raise ValueError(
            f"{what}: the body has {body.n} particles, and {scene.name} seeds {seeded} ({scene.cells} "
            f"cells, ppc={scene.ppc}): measure a run with the scene it ran"
        )


def _check_where(where, body: Body):
    """``where``: ``None``, a tracer, or one bool per particle that selects at least one particle.

    Returns ``where``, a list or tuple of bools as a NumPy array (an array as it is)."""
    if where is None or isinstance(where, jax.core.Tracer):
        return where
    if not isinstance(where, (np.ndarray, jax.Array)):
        try:
            where = np.asarray(where)
        except (TypeError, ValueError):  # ragged lists, objects numpy refuses
            raise ValueError(
                f"where must be one bool per particle, shape ({body.n},), got {brief(where)}"
            ) from None
    if np.shape(where) != (body.n,) or np.asarray(where).dtype != np.bool_:
        raise ValueError(
            f"where must be one bool per particle, shape ({body.n},), got "
            f"{np.asarray(where).dtype} of shape {np.shape(where)}"
        )
    if not np.any(np.asarray(where)):
        raise ValueError("where selects no particle: there is nothing to measure")
    return where


def _check_time(scene: AbstractScene, t, what: str, name: str) -> None:
    """Refuse a concrete time ``t`` past the scene's ``t_valid`` (``exact_holds``)."""
    if not exact_holds(scene, t):
        raise ValueError(
            f"{what} the exact solution of {scene.name}, which holds up to t_valid = "
            f"{float(scene.t_valid):.6g}, and {name} = {float(t):.6g} is past it: measure a state at "
            "t <= scene.t_valid"
        )


def _check_corners(corners, body: Body) -> None:
    """``corners``: the ``2^dim`` corners of each of the body's particles, ``(n, 2^dim, dim)``."""
    n, d = body.r0.shape
    want = (n, 2**d, d)
    shape = np.shape(corners)
    if len(shape) == 3 and shape[0] == n and shape[2] == d and shape[1] != 2**d:
        raise ValueError(
            f"a particle has 2^dim = {2**d} corners in {d}D, got {shape[1]} (corners of shape {shape}; "
            "domain_corners(state, body) gives them)"
        )
    if shape != want:
        raise ValueError(
            f"corners must be the 2^dim corners of each particle, shape (n, 2^dim, dim) = {want} "
            f"(domain_corners(state, body)), got shape {np.shape(corners)}"
        )


def _centre(centre, like):
    """``centre`` as a ``(1, dim)`` array of ``like``'s dtype, checked where concrete: ``dim`` finite
    real numbers (one per axis of ``like``, whose last axis is the dimension)."""
    if not any_traced(centre):
        d = like.shape[-1]
        what = f"centre must be {d} finite real number{'s' if d > 1 else ''} (one per axis)"
        if not is_real(centre) or is_bool(centre):
            raise ValueError(f"{what}, got {brief(centre)}")
        if np.shape(centre) == like.shape[-1:] and not np.all(np.isfinite(np.asarray(centre))):
            raise ValueError(f"{what}, got {show(np.asarray(centre))}")
    c = jnp.asarray(centre, dtype=like.dtype)
    if c.shape != like.shape[-1:]:
        raise ValueError(f"centre must have {like.shape[-1]} components (the dimension), got shape {c.shape}")
    return c[None, :]


def reference_radius(body: Body, centre: Float[ArrayLike, " dim"]) -> Float[Array, " n"]:
    """Each particle's reference distance from the centre, ``R = |X - c|``.

    Args:
        body: the reference configuration.
        centre: the centre ``c`` of the expansion (the origin for ``Blast``'s quarter charge,
            ``cells h / 2`` along every axis for its full charge).

    Returns:
        ``R``; differentiable, with derivative 0 (not NaN) at ``X = c``.

    Raises:
        ValueError: ``body`` is not a ``Body``, or ``centre`` does not have ``dim`` components.
    """
    _check_body(body)
    return _safe_sqrt(jnp.sum(jnp.square(body.X - _centre(centre, body.X)), axis=1))


def radial_velocity(
    state: State, body: Body, centre: Float[ArrayLike, " dim"], allow_broken: bool = False
) -> Float[Array, " n"]:
    """Each particle's radial velocity about the centre, ``v_r = v . (x - c) / |x - c|``.

    Taken along the particle's current direction from ``c`` (0 for a particle at ``x = c``, where
    the direction is undefined). For an exact radial motion ``v_r`` is a function of ``R`` alone.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration (checked to hold the state's particles).
        centre: the centre ``c``.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``v_r``; differentiable, also at ``x = c``.

    Raises:
        ValueError: ``state`` is not one run's ``State`` or is of a run that broke down (and
            ``allow_broken`` is ``False``), ``body`` is not a ``Body``, the state and the body hold
            different numbers of particles, or ``centre`` does not have ``dim`` components.
    """
    _check_state(state, "radial_velocity()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    return _radial_velocity(state, centre)


def _radial_velocity(state: State, centre) -> Float[Array, " n"]:
    e = state.x - _centre(centre, state.x)
    r2 = jnp.sum(jnp.square(e), axis=1)
    positive = r2 > 0
    inv_r = jnp.where(positive, 1.0 / jnp.sqrt(jnp.where(positive, r2, 1.0)), 0.0)
    return jnp.sum(state.v * e, axis=1) * inv_r


def radial_bin(body: Body, centre: Float[ArrayLike, " dim"], bins: int) -> Int[Array, " n"]:
    """Each particle's bin of reference radius: ``bins`` equal bins over ``[0, max_p R_p]``.

    Bin ``k`` holds ``k R_max / bins <= R < (k + 1) R_max / bins``, the last bin also ``R = R_max``:
    the index is ``min(floor(R / R_max * bins), bins - 1)``.

    Args:
        body: the reference configuration.
        centre: the centre ``c``.
        bins: number of bins (static, >= 1; a Python or NumPy integer).

    Returns:
        The bin of each particle, in ``0 .. bins - 1``.

    Raises:
        ValueError: ``bins`` is not a positive integer, ``body`` is not a ``Body``, or ``centre`` does
            not have ``dim`` components.
    """
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
        raise ValueError(f"bins must be a positive integer, got {bins!r}")
    bins = int(bins)
    R = reference_radius(body, centre)
    R_max = jnp.max(R)
    k = jnp.floor(R / jnp.where(R_max > 0, R_max, 1.0) * bins)
    return jnp.clip(k, 0, bins - 1).astype(jnp.int32)


def angular_spread(
    state: State,
    body: Body,
    centre: Float[ArrayLike, " dim"],
    bins: int,
    threshold: float = 1e-3,
    detrend: bool = False,
    allow_broken: bool = False,
) -> dict[str, Array]:
    """The spread of the radial velocity over the particles at a common reference radius.

    Particles are binned by reference radius (``radial_bin``). In bin ``k``, with ``N_k``
    particles, mean ``m_k = sum_p v_r,p / N_k`` and standard deviation ``s_k = (sum_p (v_r,p -
    m_k)^2 / N_k)^(1/2)`` (every particle weighted alike, population form), the spread is
    ``s_k / |m_k|``.

    A bin of finite width holds particles at different ``R``, so ``s_k`` measures both the
    departure from radial symmetry (particles at one ``R`` in different directions moving apart)
    and the genuine variation of ``v_r(R)`` across the bin: for an exact radial motion the spread
    is that of ``v_r(R)`` over the bin's radii (for a uniform expansion ``v_r = a R``, ``std(R) /
    mean(R)`` over the bin), which goes to zero with the bin width ``R_max / bins``. It is exactly
    0 only where ``v_r`` is constant across each bin. With ``detrend=True`` the deviations are taken
    from the bin's least-squares line in ``R``, ``m_k + b_k (R - mean_k R)``, instead of from ``m_k``:
    the radial variation is removed to first order (exactly, where ``v_r`` is linear in ``R``), and
    what remains is the spread at equal radius.

    ``max`` and ``rms`` are taken over the counted bins: those with particles and with ``|m_k| >
    threshold * max_k |m_k|`` (a bin at rest, such as the particles near ``c`` where ``v_r -> 0``,
    has no meaningful relative spread). With no bin counted (every ``m_k = 0``) both are 0.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration.
        centre: the centre ``c``.
        bins: number of bins (static, >= 1).
        threshold: the smallest ``|m_k|`` counted, relative to the largest (static, ``0 <= threshold
            < 1``: at 1 or more no bin is counted).
        detrend: whether to take the deviations from the bin's line in ``R`` (static).
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``dict(per_bin, max, rms, counted)``: ``per_bin`` the spread of each bin (NaN where not
        counted), ``counted`` which bins count, ``max`` and ``rms`` over them. ``max`` and ``rms``
        are differentiable in the state, with derivative 0 (not NaN) where the spread is 0.

    Raises:
        ValueError: ``bins`` is not a positive integer, ``threshold`` is not a number in ``[0, 1)``,
            ``detrend`` is not a bool, ``state`` is not one run's ``State`` or is of a run that broke
            down (and ``allow_broken`` is ``False``), ``body`` is not a ``Body``, or the state and the
            body hold different numbers of particles.
    """
    check_scalar("threshold", threshold)
    check_finite("threshold", threshold)
    if is_concrete(threshold) and not 0.0 <= float(threshold) < 1.0:
        raise ValueError(
            f"threshold must be >= 0 and < 1 (the smallest |m_k| counted, relative to the largest), "
            f"got {float(threshold)!r}"
        )
    check_bool("detrend", detrend)
    _check_state(state, "angular_spread()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    bins = python_int(bins)
    k = radial_bin(body, centre, bins)
    vr = _radial_velocity(state, centre)
    count = jax.ops.segment_sum(jnp.ones_like(vr), k, num_segments=bins)
    n_k = jnp.maximum(count, 1.0)
    mean = jax.ops.segment_sum(vr, k, num_segments=bins) / n_k
    fit = mean[k]
    if detrend:
        R = reference_radius(body, centre)
        R_mean = jax.ops.segment_sum(R, k, num_segments=bins) / n_k
        dR = R - R_mean[k]
        Sxx = jax.ops.segment_sum(jnp.square(dR), k, num_segments=bins)
        Sxy = jax.ops.segment_sum(dR * vr, k, num_segments=bins)
        flat = Sxx <= count * jnp.square(1e-10 * jnp.max(R))  # one radius (to round-off): no line
        slope = jnp.where(flat, 0.0, Sxy / jnp.where(flat, 1.0, Sxx))
        fit = fit + slope[k] * dR
    var = jax.ops.segment_sum(jnp.square(vr - fit), k, num_segments=bins) / n_k
    mean_sq = jnp.square(mean)
    counted = (count > 0) & (mean_sq > threshold**2 * jnp.max(mean_sq))
    sq = jnp.where(counted, var / jnp.where(counted, mean_sq, 1.0), 0.0)
    n_counted = jnp.sum(counted).astype(sq.dtype)
    return dict(
        per_bin=jnp.where(counted, _safe_sqrt(sq), jnp.nan),
        max=_safe_sqrt(jnp.max(sq)),
        rms=_safe_sqrt(jnp.sum(sq) / jnp.maximum(n_counted, 1.0)),
        counted=counted,
    )


POLAR_ITERATIONS = 8
"""Scaled Newton iterations of ``polar_rotation``: 6 reach round-off in float64 for ``F`` of
condition number up to 1e6 (measured), 8 leave a margin."""


def polar_rotation(
    F: Float[Array, "n dim dim"], iterations: int = POLAR_ITERATIONS
) -> Float[Array, "n dim dim"]:
    """The rotation ``R`` of the polar decomposition ``F = R U`` (``U`` symmetric positive definite).

    Newton's iteration ``X <- (g X + X^-T / g) / 2`` from ``X = F``, scaled by ``g = (|X^-1| /
    |X|)^(1/2)`` in the Frobenius norm (Higham 1986, Computing the polar decomposition, SIAM J. Sci.
    Stat. Comput. 7, eq. 3.3), a fixed number of times in a loop: jit-able, and differentiable also where
    ``U`` has equal eigenvalues (``F = I``), where an SVD's or an eigendecomposition's derivative is
    NaN. ``X^-1 = adj X / det X`` in closed form. For ``det F < 0`` the iteration converges to the
    orthogonal factor with ``det R = -1`` (no rotation).

    Args:
        F: deformation gradients, ``det F != 0``.
        iterations: Newton iterations (static, >= 1).

    Returns:
        ``R``.

    Raises:
        ValueError: ``F`` is not a stack of square matrices of 1 to 3 rows, or ``iterations`` is not an
            integer >= 1.
    """
    shape = np.shape(F)
    if len(shape) != 3 or shape[1] != shape[2] or shape[1] not in (1, 2, 3):
        raise ValueError(
            f"F must be deformation gradients, shape (n, dim, dim) with dim 1, 2 or 3, got shape {shape}"
        )
    if is_concrete(iterations):
        count = iterations
        if isinstance(count, jax.Array) and count.ndim == 0 and jnp.issubdtype(count.dtype, jnp.integer):
            count = int(count)
        check_int("iterations", count, 1)

    def newton(_, X):
        X_inv = adjugate(X) / det(X)[:, None, None]
        g = jnp.sqrt(jnp.sqrt(jnp.sum(jnp.square(X_inv), axis=(1, 2)) / jnp.sum(jnp.square(X), axis=(1, 2))))
        return 0.5 * (g[:, None, None] * X + jnp.swapaxes(X_inv, 1, 2) / g[:, None, None])

    # a loop, not unrolled: XLA's fusion of the unrolled closed forms recomputes each iterate in every
    # use, and the compile time of its gradient grows exponentially with the iterations (0.6 s for 2,
    # 4.6 s for 4, 155 s for 8, measured on CPU at the test suite's optimisation level)
    return jax.lax.fori_loop(0, iterations, newton, F)


def rotation_angle(state: State, allow_broken: bool = False) -> Float[Array, " n"]:
    """The angle of the rotation ``R`` of each particle's ``F = R U`` (radians).

    In 2D the signed angle ``theta = atan2(F_10 - F_01, F_00 + F_11)``, exact for the polar
    rotation (``F = R(theta) U`` gives ``F_00 + F_11 = cos(theta) tr U`` and ``F_10 - F_01 =
    sin(theta) tr U``, ``tr U > 0``). In 3D the unsigned angle ``theta = atan2(|w|, (tr R - 1) /
    2)`` in ``[0, pi]`` of ``R = polar_rotation(F)``, with axial vector ``w = (R_21 - R_12, R_02 -
    R_20, R_10 - R_01) / 2 = sin(theta) n``: equal to ``arccos((tr R - 1) / 2)`` but accurate and
    differentiable near 0 and pi, where arccos' derivative is infinite. In 1D 0. Meaningful for
    ``det F > 0`` (a folded particle has no polar rotation).

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``theta``; differentiable, with derivative 0 (not NaN) in 3D at ``R = I``.

    Raises:
        ValueError: ``state`` is not one run's ``State`` or is of a run that broke down (and
            ``allow_broken`` is ``False``), or the run is not 1D, 2D or 3D.
    """
    _check_state(state, "rotation_angle()", allow_broken)
    return _rotation_angle(state.F)


def _rotation_angle(F: Float[Array, "n dim dim"]) -> Float[Array, " n"]:
    d = F.shape[-1]
    if d == 1:
        return jnp.zeros(F.shape[0], F.dtype)
    if d == 2:
        return jnp.arctan2(F[:, 1, 0] - F[:, 0, 1], F[:, 0, 0] + F[:, 1, 1])
    if d != 3:
        raise ValueError(f"rotation_angle is for 1D, 2D and 3D, got dim {d}")
    R = polar_rotation(F)
    w = 0.5 * jnp.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    cos = 0.5 * (R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2] - 1.0)
    return jnp.arctan2(_safe_sqrt(jnp.sum(jnp.square(w), axis=1)), cos)


def spurious_rotation(
    state: State, body: Body, where: Bool[Array, " n"] | None = None, allow_broken: bool = False
) -> dict[str, Array]:
    """The largest and RMS rotation angle of the particles, ``max_p |theta_p|`` and ``(sum_p
    theta_p^2 / n)^(1/2)`` (radians; ``rotation_angle``), zero for an exact radial motion (its
    ``F`` is symmetric).

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state.
        body: the reference configuration (checked to hold the state's particles).
        where: one bool per particle to take them over (an array, or a list of them), or ``None``
            for all.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``dict(max, rms)``, differentiable, with derivative 0 (not NaN) at ``F = I``.

    Raises:
        ValueError: ``state`` is not one run's ``State`` or is of a run that broke down (and
            ``allow_broken`` is ``False``), ``body`` is not a ``Body``, the state and the body hold
            different numbers of particles, or ``where`` is not one bool per particle.
    """
    _check_state(state, "spurious_rotation()", allow_broken)
    _check_body(body)
    _check_particles(state, body)
    where = _check_where(where, body)
    mx, rms = _max_rms(jnp.square(_rotation_angle(state.F)), where)
    return dict(max=mx, rms=rms)


def vorticity(state: State, allow_broken: bool = False) -> Float[Array, " n"]:
    """Each particle's vorticity from APIC's affine matrix ``C`` (``C_ab = dv_a / dx_b`` at the
    particle: ``sum_i v_i grad phi_ip^T``, ``transfers.APIC``).

    In 2D the signed ``omega = C_10 - C_01``; in 3D the magnitude ``|omega|`` of ``omega = (C_21 -
    C_12, C_02 - C_20, C_10 - C_01)``; in 1D 0. Twice the spin rate; zero for a radial motion.

    The state of a run that broke down is refused unless ``allow_broken`` (as for ``errors``).

    Args:
        state: the state of a run with ``transfer=APIC()``.
        allow_broken: measure the state of a run that broke down too.

    Returns:
        ``omega`` (2D) or ``|omega|`` (3D), differentiable (derivative 0, not NaN, at ``omega = 0``).

    Raises:
        ValueError: ``state`` is not one run's ``State`` or is of a run that broke down (and
            ``allow_broken`` is ``False``), or the state carries no velocity gradient (its ``C`` is
            ``None``: the transfer is not APIC).
    """
    _check_state(state, "vorticity()", allow_broken)
    C = state.C
    if C is None:
        raise ValueError(
            "vorticity needs the velocity gradient C that only APIC carries: run with transfer=APIC()"
        )
    d = C.shape[-1]
    if d == 1:
        return jnp.zeros(C.shape[0], C.dtype)
    if d == 2:
        return C[:, 1, 0] - C[:, 0, 1]
    w = jnp.stack([C[:, 2, 1] - C[:, 1, 2], C[:, 0, 2] - C[:, 2, 0], C[:, 1, 0] - C[:, 0, 1]], axis=1)
    return _safe_sqrt(jnp.sum(jnp.square(w), axis=1))


def corner_jacobians(corners: Float[Array, "n corners dim"], body: Body) -> Float[Array, "n corners"]:
    """The Jacobian of each particle's domain at each of its corners, relative to the reference.

    Corners are in the order of ``_util.corner_signs`` (the order of ``parallelogram_corners``,
    ``Body.particle_corners`` and ``domain_corners``): corner ``c`` lies at ``s_c`` of the
    reference cube ``[-1, 1]^dim``, ``+1`` along axis ``a`` where bit ``dim - 1 - a`` of ``c`` is
    set. In 2D: 0 ``(-,-)``, 1 ``(-,+)``, 2 ``(+,-)``, 3 ``(+,+)`` (a tensor-product order, not
    around the quadrilateral: going round is 0, 2, 3, 1); in 3D: 0 ``(-,-,-)``, 1 ``(-,-,+)``, 2
    ``(-,+,-)``, ..., 7 ``(+,+,+)``; in 1D: left, right.

    At corner ``c`` the edge along axis ``a`` runs to the corner ``c'`` that differs in bit ``dim -
    1 - a``, oriented as the reference axis: ``e_a = s_c,a (x_c - x_c')``. The corner's Jacobian is
    ``det[e_0, ..., e_dim-1] / prod_a (2 r0_a)``: in 2D the cross product of the two edges (signed
    area), in 3D their triple product, in 1D the length, each over its reference value. It is 1 for
    every corner of a reference domain, and ``det F`` at every corner of a parallelogram
    ``x_p + F diag(r0) s_c`` (CPDI's domains). It is the Jacobian of the multilinear map of the
    reference cube at the corner, over its reference value.

    Args:
        corners: each particle's corners (``domain_corners``: the tracked corners, or those ``x``
            and ``F`` imply).
        body: the reference configuration (``r0``).

    Returns:
        The Jacobian at each corner.

    Raises:
        ValueError: ``body`` is not a ``Body``, or ``corners`` are not the ``2^dim`` corners of each
            of its particles, shape ``(n, 2^dim, dim)``.
    """
    _check_body(body)
    _check_corners(corners, body)
    n, nc, d = corners.shape
    signs = corner_signs(d)
    per_corner = []
    for c in range(nc):
        edges = []
        for a in range(d):
            other = c ^ (1 << (d - 1 - a))
            e = corners[:, c] - corners[:, other]
            edges.append(e if signs[c, a] > 0 else -e)
        per_corner.append(det(jnp.stack(edges, axis=-1)))  # the edges as columns
    return jnp.stack(per_corner, axis=1) / jnp.prod(2.0 * body.r0, axis=1)[:, None]


def folded(corners: Float[Array, "n corners dim"], body: Body) -> Bool[Array, " n"]:
    """Whether each particle's domain is folded or inverted: its Jacobian (``corner_jacobians``) is
    ``<= 0`` (or not finite) at one of its corners at least.

    In 2D that is a signed corner area ``<= 0``, which for a quadrilateral is exact: the Jacobian of
    the bilinear map is affine in each reference coordinate, so it is positive over the whole
    domain iff it is at the 4 corners (a corner pushed across the opposite diagonal folds it, a
    parallelogram with ``det F <= 0`` is inverted). In 3D a triple product ``<= 0`` at one of the 8
    corners, necessary but not sufficient for a trilinear hexahedron to be unfolded everywhere. In
    1D a length ``<= 0``.

    Args:
        corners: each particle's corners, in the order of ``corner_signs`` (``domain_corners``).
        body: the reference configuration.

    Returns:
        One bool per particle.

    Raises:
        ValueError: as for ``corner_jacobians``.
    """
    return ~jnp.all(corner_jacobians(corners, body) > 0, axis=1)


def folded_domains(corners: Float[Array, "n corners dim"], body: Body) -> Int[Array, ""]:
    """The number of particles whose domain is folded or inverted (``folded``).

    Args:
        corners: each particle's corners, in the order of ``corner_signs`` (``domain_corners``).
        body: the reference configuration.

    Returns:
        The count.

    Raises:
        ValueError: as for ``corner_jacobians``.
    """
    return jnp.sum(folded(corners, body).astype(jnp.int32))
