"""A scene carries only what it needs: the compiled step holds nothing else (STYLE)."""

import jax
import jax.numpy as jnp

import jaxmpm as jm


class NoTraction(jm.GasExpansion):
    def traction(self, t):
        return None, None


class WithBodyForce(NoTraction):
    def body_force(self, X, t):
        return -9.81 * jnp.ones_like(X)


def count(scene, artificial_cells=0, interpolator=None, transfer=None):
    model = jm.Model(scene, interpolator or jm.SPQ(), transfer or jm.FLIP(), artificial_cells)
    s = jm.setup(model)
    state = jm.initial_state(model, s)
    jaxpr = jax.make_jaxpr(lambda st: jm.step(model, s, st, jnp.asarray(1e-5)))(state)
    prims = [e.primitive.name for e in jaxpr.jaxpr.eqns]
    return len(prims), prims.count("scatter-add")


def test_step_holds_only_declared_physics():
    base, base_scatters = count(NoTraction())
    traction, traction_scatters = count(jm.GasExpansion())
    body, body_scatters = count(WithBodyForce())
    art, art_scatters = count(NoTraction(), artificial_cells=1)
    assert base < traction and base < body and base < art
    assert traction_scatters == base_scatters + 1  # the traction's one scatter
    assert body_scatters == base_scatters + 1  # the body force's one scatter
    assert art_scatters == base_scatters + 2  # artificial mass and momentum
    full, _ = count(WithBodyForce(), artificial_cells=1)
    assert full > body


def test_affine_and_corner_state_only_when_used():
    spq_flip, _ = count(NoTraction())
    spq_apic, _ = count(NoTraction(), transfer=jm.APIC())
    assert spq_apic > spq_flip
