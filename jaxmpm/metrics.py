"""Errors and diagnostics over the real particles: errors against an exact solution, the domain
separation of neighbours, and the totals of mass, momentum and energy."""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from .materials import AbstractEOS
from .particles import Body, State, parallelogram_corners
from .scenes import AbstractScene

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
    """
    if scene.exact is None:
        return ("separation_max",)
    return ("separation_max",) + tuple(k for k in EXACT_ERRORS if scene.cells > 2 or k not in INTERIOR_ERRORS)


def exact_fields(scene: AbstractScene, body: Body, t: Float[ArrayLike, ""]) -> dict[str, Array] | None:
    """The exact fields at every real particle.

    Args:
        scene: the scene.
        body: the reference configuration.
        t: time.

    Returns:
        ``dict(x, v, F, sigma)`` at every particle's ``X`` at time ``t``, each with a leading
        particle axis; ``None`` for a scene with no exact solution.
    """
    if scene.exact is None:
        return None
    return _exact_fields(scene, body.X, t)


@eqx.filter_jit
def _exact_fields(scene, X, t):
    # compiled: an exact solution made by autodiff (manufactured scenes) costs seconds op by op
    return jax.vmap(scene.exact, in_axes=(0, None))(X, t)


def implied_corners(state: State, body: Body) -> Float[Array, "n corners dim"]:
    """Each particle's domain corners as its ``x`` and ``F`` imply them.

    Args:
        state: the state.
        body: the reference configuration.

    Returns:
        ``x_p + F diag(r0) s_c`` (``particles.parallelogram_corners``; in 1D ``x_p -/+ F r0``).
    """
    return parallelogram_corners(body.r0, state.x, state.F)


def domain_corners(state: State, body: Body) -> Float[Array, "n corners dim"]:
    """Each particle's own domain corners.

    Args:
        state: the state.
        body: the reference configuration.

    Returns:
        MPQ's tracked corners where the run tracks them (one copy for all the particles that meet
        at a corner), else those ``x`` and ``F`` imply (``implied_corners``).
    """
    if state.corners is not None:
        return body.particle_corners(state.corners)
    return implied_corners(state, body)


def corner_gap(corners: Float[Array, "n corners dim"], body: Body) -> Float[Array, " nc"]:
    """How far apart the particles' copies of each corner of the reference lattice are.

    At every corner, the largest distance of a particle's copy from the copies' mean, over the
    half-length ``r0``. Zero where neighbouring domains meet (MPQ's tracked corners, always); in 1D
    the magnitude of ``separation``. A gap and an overlap both count.

    Args:
        corners: each particle's corners (``domain_corners``).
        body: the reference configuration.

    Returns:
        The gap at each corner of ``body.X_corners``.
    """
    return _safe_sqrt(_corner_gap_sq(corners, body))


def _corner_gap_sq(corners, body):
    ids = body.corner_ids.reshape(-1)
    nc = body.X_corners.shape[0]
    c = corners.reshape(-1, corners.shape[-1])
    count = jax.ops.segment_sum(jnp.ones_like(c[:, 0]), ids, num_segments=nc)
    mean = jax.ops.segment_sum(c, ids, num_segments=nc) / count[:, None]
    dev = jnp.sum(jnp.square(c - mean[ids]), axis=1) / jnp.square(jnp.min(body.r0))
    return jax.ops.segment_max(dev, ids, num_segments=nc)


def separation(state: State, body: Body) -> Float[Array, " n_minus_1"]:
    """Domain separation of neighbours, ``(x_{p+1} - x_p - (F_{p+1} + F_p) r0) / (2 r0)``.

    The violation of the consistency condition between neighbours ``x_{p+1} - x_p = (F_{p+1} + F_p)
    r0`` (Bonifasi-Lista, Brannon & Wiskin 2013): zero when neighbouring domains touch; positive for
    a gap, negative for an overlap. 1D; in 2D and 3D use ``corner_gap``.

    Args:
        state: the state.
        body: the reference configuration.

    Returns:
        The separation of each pair of neighbours.

    Raises:
        ValueError: the run is not 1D.
    """
    if state.x.shape[1] != 1:
        raise ValueError("separation is the 1D diagnostic; in 2D and 3D use corner_gap")
    x = state.x[:, 0]
    F = state.F[:, 0, 0]
    r0 = body.r0[:, 0]
    r0_mean = 0.5 * (r0[1:] + r0[:-1])
    return (x[1:] - x[:-1] - (F[1:] * r0[1:] + F[:-1] * r0[:-1])) / (2.0 * r0_mean)


def _safe_sqrt(x):
    """``sqrt`` whose derivative at 0 is 0 instead of NaN (an exact solution has zero error)."""
    positive = x > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), 0.0)


def _sq_rel(a, b, n):
    """Per-particle squared relative error ``|a - b|^2 / |b|^2`` (no ``abs``: smooth at a = b)."""
    return jnp.sum(jnp.square(a - b).reshape(n, -1), axis=1) / jnp.sum(jnp.square(b).reshape(n, -1), axis=1)


def _sq_abs(a, b, n):
    return jnp.sum(jnp.square(a - b).reshape(n, -1), axis=1)


def _max_rms(sq, mask=None):
    """``(max, rms)`` of ``sqrt(sq)`` over the particles in ``mask`` (all if ``None``)."""
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
    """
    if scene.smooth is None:
        return None
    return jax.vmap(scene.smooth, in_axes=(0, None))(body.X, t)


def errors(
    scene: AbstractScene, state: State, body: Body, where: Bool[Array, " n"] | None = None
) -> dict[str, Array | None]:
    """Errors against the scene's exact solution, over real particles only.

    With ``where`` (a boolean per particle, e.g. ``smooth_mask(scene, body, t)``), every error
    against the exact solution is taken over those particles only; ``separation_max`` stays global.

    ``F_*_rel`` are relative errors ``|F - F_exact| / |F_exact|``, also split into particles seeded
    in the boundary cells (first and last cell of the body) and the interior. ``x``, ``v`` and
    ``sigma`` errors are absolute. Errors are ``None`` for a scene with no exact solution, and the
    interior ones are ``None`` when the body has no interior cell. ``separation_max`` is always set:
    in 1D the largest ``|separation|``, in 2D and 3D the largest ``corner_gap`` of the domains that
    ``x`` and ``F`` imply.

    Every entry is differentiable, with derivative 0 (not NaN) where an error is exactly zero.

    Args:
        scene: the scene.
        state: the state.
        body: the reference configuration.
        where: one bool per particle, or ``None`` for all.

    Returns:
        Error name (``"separation_max"`` and ``EXACT_ERRORS``) to value or ``None``.
    """
    n = body.n
    if state.x.shape[1] > 1:  # the implied parallelograms' largest corner gap
        sep = _safe_sqrt(jnp.max(_corner_gap_sq(implied_corners(state, body), body)))
    elif n > 1:
        sep = _safe_sqrt(jnp.max(jnp.square(separation(state, body))))
    else:
        sep = jnp.zeros((), state.x.dtype)
    out: dict[str, Array | None] = dict(separation_max=sep)
    ex = exact_fields(scene, body, state.t)
    if ex is None:
        out.update(dict.fromkeys(EXACT_ERRORS))
        return out
    F_sq = _sq_rel(state.F, ex["F"], n)
    w = where
    and_w = (lambda m: m) if w is None else (lambda m: m & w)
    out["F_max_rel"], out["F_rms_rel"] = _max_rms(F_sq, w)
    b = body.boundary
    out["F_max_rel_boundary"], out["F_rms_rel_boundary"] = _max_rms(F_sq, and_w(b))
    has_interior = isinstance(b, jax.core.Tracer) or not bool(jnp.all(b))
    if has_interior:
        out["F_max_rel_interior"], out["F_rms_rel_interior"] = _max_rms(F_sq, and_w(~b))
    else:
        out["F_max_rel_interior"] = out["F_rms_rel_interior"] = None
    out["x_max_abs"], out["x_rms_abs"] = _max_rms(_sq_abs(state.x, ex["x"], n), w)
    out["v_max_abs"], out["v_rms_abs"] = _max_rms(_sq_abs(state.v, ex["v"], n), w)
    out["sigma_max_abs"], _ = _max_rms(_sq_abs(state.sigma, ex["sigma"], n), w)
    return out


def _momentum(p):
    total = jnp.sum(p, axis=0)
    return total[0] if p.shape[1] == 1 else total


def diagnostics(scene: AbstractScene, state: State, body: Body) -> dict[str, Array]:
    """Total mass, momentum, kinetic, internal and total energy of the real particles.

    ``momentum`` is a number in 1D and a vector of ``dim`` components in 2D and 3D.

    Internal energy is ``sum_p V0_p W(F_p)`` with the material's stored energy ``W``, and
    ``sum_p m_p e_p`` on the particles of a material with an energy equation (``AbstractEOS``).

    Args:
        scene: the scene (its material).
        state: the state.
        body: the reference configuration.

    Returns:
        ``dict(mass, momentum, energy_kinetic, energy_internal, energy)``.
    """
    kinetic = 0.5 * jnp.sum(body.m * jnp.sum(jnp.square(state.v), axis=1))
    if scene.regions is None:
        internal = jnp.sum(body.V0 * jax.vmap(scene.material().energy_density)(state.F))
    else:
        lay = scene.layout()
        internal = jnp.zeros((), dtype=body.m.dtype)
        for k, region in enumerate(scene.regions()):
            idx = lay.index(k)
            if isinstance(region.material, AbstractEOS):
                internal = internal + jnp.sum(body.m[idx] * state.e[idx])
            else:
                internal = internal + jnp.sum(
                    body.V0[idx] * jax.vmap(region.material.energy_density)(state.F[idx])
                )
    return dict(
        mass=jnp.sum(body.m),
        momentum=_momentum(body.m[:, None] * state.v),
        energy_kinetic=kinetic,
        energy_internal=internal,
        energy=kinetic + internal,
    )


def pressure_error(
    scene: AbstractScene, state: State, body: Body, where: Bool[Array, " n"] | None = None
) -> Array | None:
    """The RMS relative pressure error ``|p - p_exact| / |p_exact|`` against the scene's exact solution.

    Args:
        scene: the scene.
        state: the state.
        body: the reference configuration.
        where: one bool per particle (e.g. ``smooth_mask``), or ``None`` for all.

    Returns:
        The error, or ``None`` for a scene without an exact solution.
    """
    ex = exact_fields(scene, body, state.t)
    if ex is None:
        return None
    dim = state.F.shape[-1]
    p_ex = -jnp.trace(ex["sigma"], axis1=1, axis2=2) / dim
    sq = jnp.square((pressure(state) - p_ex) / jnp.where(p_ex == 0, 1.0, p_ex))
    return _max_rms(sq, where)[1]


def density(state: State, body: Body) -> Float[Array, " n"]:
    """Each particle's current density ``m / (V0 det F)``.

    Args:
        state: the state.
        body: the reference configuration.

    Returns:
        ``rho``.
    """
    return body.m / (body.V0 * jax.vmap(jnp.linalg.det)(state.F))


def pressure(state: State) -> Float[Array, " n"]:
    """Each particle's pressure ``-tr(sigma) / dim`` (the viscous pressure included).

    Args:
        state: the state.

    Returns:
        ``p``.
    """
    return -jnp.trace(state.sigma, axis1=1, axis2=2) / state.F.shape[-1]


EULER_FIELDS = ("rho", "u", "p", "e")
"""The fields ``euler_errors`` compares: density, velocity, pressure, specific internal energy."""


def euler_errors(scene: AbstractScene, state: State, body: Body) -> dict[str, Array] | None:
    """L1 errors of density, velocity, pressure and specific internal energy against an exact solution
    of the Euler equations, ``sum_p |f_p - f(x_p, t)| V_p`` (``V_p = V0_p det F_p``, the norm of
    ``int |f - f_exact| dx`` sampled at the particles; 1D).

    The exact solution is the scene's ``solution(x, t)`` (``ShockTube``, ``Noh``), evaluated at the
    particles' current positions: a Lagrangian method is compared where its particles are.

    Args:
        scene: the scene.
        state: the state (``t > 0``; its ``e`` set).
        body: the reference configuration.

    Returns:
        ``dict(rho_L1, u_L1, p_L1, e_L1)``, or ``None`` for a scene without an exact Euler solution or a
        run without an energy equation.
    """
    if not hasattr(scene, "solution") or state.e is None or state.x.shape[1] != 1:
        return None
    ex = scene.solution(state.x[:, 0], state.t)
    V = body.V0 * state.F[:, 0, 0]
    num = dict(rho=density(state, body), u=state.v[:, 0], p=pressure(state), e=state.e)
    return {f"{k}_L1": jnp.sum(jnp.abs(num[k] - ex[k]) * V) for k in EULER_FIELDS}
