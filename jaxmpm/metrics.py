"""Errors and diagnostics over the real particles (SPEC section 7)."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .particles import Body, State
from .scenes import AbstractScene


def exact_fields(scene: AbstractScene, body: Body, t) -> dict[str, Array] | None:
    """The exact ``x, v, F, sigma`` at every real particle's ``X`` at time ``t`` (or ``None``)."""
    if scene.exact is None:
        return None
    return jax.vmap(scene.exact, in_axes=(0, None))(body.X, t)


def separation(state: State, body: Body) -> Float[Array, " n_minus_1"]:
    """Domain separation of neighbours, ``(x_{p+1} - x_p - (F_{p+1} + F_p) r0) / (2 r0)`` (SPEC 3).

    Zero when neighbouring domains touch; positive for a gap, negative for an overlap.
    """
    x = state.x[:, 0]
    F = state.F[:, 0, 0]
    r0 = body.r0[:, 0]
    r0_mean = 0.5 * (r0[1:] + r0[:-1])
    return (x[1:] - x[:-1] - (F[1:] * r0[1:] + F[:-1] * r0[:-1])) / (2.0 * r0_mean)


def _max(a):
    return jnp.max(a) if a.size else jnp.nan


def _rms(a):
    return jnp.sqrt(jnp.mean(jnp.square(a))) if a.size else jnp.nan


def errors(scene: AbstractScene, state: State, body: Body) -> dict[str, Array | None]:
    """Errors against the scene's exact solution, over real particles only.

    ``F_*_rel`` are relative errors ``|F - F_exact| / |F_exact|``, also split into particles seeded
    in the boundary cells (first and last cell of the body) and the interior. ``x``, ``v`` and
    ``sigma`` errors are absolute. Errors are ``None`` for a scene with no exact solution, and the
    interior ones are ``None`` when the body has no interior cell. ``separation_max`` is always set.
    """
    sep = jnp.max(jnp.abs(separation(state, body))) if body.n > 1 else jnp.zeros((), state.x.dtype)
    out: dict[str, Array | None] = dict(separation_max=sep)
    ex = exact_fields(scene, body, state.t)
    names = (
        "F_max_rel",
        "F_rms_rel",
        "F_max_rel_boundary",
        "F_rms_rel_boundary",
        "F_max_rel_interior",
        "F_rms_rel_interior",
        "x_max_abs",
        "x_rms_abs",
        "v_max_abs",
        "sigma_max_abs",
    )
    if ex is None:
        out.update({k: None for k in names})
        return out
    F_err = jnp.linalg.norm((state.F - ex["F"]).reshape(body.n, -1), axis=1) / jnp.linalg.norm(
        ex["F"].reshape(body.n, -1), axis=1
    )
    bmask = jax.device_get(body.boundary) if not isinstance(body.boundary, jax.core.Tracer) else None
    out["F_max_rel"] = jnp.max(F_err)
    out["F_rms_rel"] = _rms(F_err)
    if bmask is None:
        b = body.boundary
        out["F_max_rel_boundary"] = jnp.max(jnp.where(b, F_err, 0.0))
        out["F_rms_rel_boundary"] = jnp.sqrt(
            jnp.sum(jnp.where(b, F_err**2, 0.0)) / jnp.maximum(jnp.sum(b), 1)
        )
        out["F_max_rel_interior"] = jnp.max(jnp.where(b, 0.0, F_err))
        out["F_rms_rel_interior"] = jnp.sqrt(
            jnp.sum(jnp.where(b, 0.0, F_err**2)) / jnp.maximum(jnp.sum(~b), 1)
        )
    else:
        fb, fi = F_err[bmask], F_err[~bmask]
        out["F_max_rel_boundary"] = _max(fb)
        out["F_rms_rel_boundary"] = _rms(fb)
        out["F_max_rel_interior"] = _max(fi) if fi.size else None
        out["F_rms_rel_interior"] = _rms(fi) if fi.size else None
    dx = jnp.linalg.norm(state.x - ex["x"], axis=1)
    out["x_max_abs"] = jnp.max(dx)
    out["x_rms_abs"] = _rms(dx)
    out["v_max_abs"] = jnp.max(jnp.linalg.norm(state.v - ex["v"], axis=1))
    out["sigma_max_abs"] = jnp.max(jnp.abs(state.sigma - ex["sigma"]))
    return out


def diagnostics(scene: AbstractScene, state: State, body: Body) -> dict[str, Array]:
    """Total mass, momentum, kinetic, internal and total energy of the real particles.

    Internal energy is ``sum_p V0_p W(F_p)`` with the material's stored energy ``W``.
    """
    mat = scene.material()
    kinetic = 0.5 * jnp.sum(body.m * jnp.sum(jnp.square(state.v), axis=1))
    internal = jnp.sum(body.V0 * jax.vmap(mat.energy_density)(state.F))
    return dict(
        mass=jnp.sum(body.m),
        momentum=jnp.sum(body.m[:, None] * state.v, axis=0)[0],
        energy_kinetic=kinetic,
        energy_internal=internal,
        energy=kinetic + internal,
    )
