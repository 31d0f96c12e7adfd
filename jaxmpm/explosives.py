"""High explosives: detonation-product and reactant equations of state, Chapman-Jouguet states and a
programmed burn.

Every EOS is an ``AbstractEOS`` (``p = a(rho) + b(rho) e``, ``e`` the specific internal energy per unit
mass), every parameter an array field, so ``jax.grad`` reaches the JWL constants, the detonation
speed and the detonator positions. Units are any consistent set (SI in the command line); the table
``EXPLOSIVES`` is in SI.

- ``JWL``: the Jones-Wilkins-Lee products EOS, full form (with energy).
- ``JWLIsentrope``: the JWL principal isentrope, barotropic.
- ``GammaLawIsentrope``: the CJ isentrope of gamma-law products.
- ``Murnaghan``: the unreacted explosive, Uintah's form.
- ``ProgrammedBurn``: a reactant and its products mixed by a burn fraction ``lambda`` that a
  detonation front lit from fixed points or planes sets (time burn), compression sets (volume burn)
  or both.
- ``cj_state``: the Chapman-Jouguet state implied by a products EOS with energy, differentiable.
- ``EXPLOSIVES``, ``jwl``, ``check_cj_consistency``: tabulated JWL rows and their check.

References: B. M. Dobratz and P. C. Crawford, "LLNL Explosives Handbook", UCRL-52997 (1985);
W. Fickett and W. C. Davis, "Detonation: Theory and Experiment" (1979), ch. 2.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._checks import (
    brief,
    check_bool,
    check_finite,
    check_greater,
    check_int,
    check_less,
    check_positive,
    check_real,
    check_scalar,
    is_concrete,
    python_int,
)
from ._util import as_float, power
from .materials import AbstractEOS, AbstractStatelessEOS


class JWL(AbstractStatelessEOS):
    """Jones-Wilkins-Lee detonation products, full form with energy.

    With the relative volume ``V = rho0 / rho`` and the energy per reference volume ``E = rho0 e``,

        ``p = A (1 - w / (R1 V)) exp(-R1 V) + B (1 - w / (R2 V)) exp(-R2 V) + w E / V``,

    so ``a`` is the first two terms and ``b = w rho``. The detonation energy ``E0`` (per reference
    volume) is not a field: it is the initial energy the caller gives the products, ``e0 = E0 /
    rho0`` per unit mass (``jwl(name)`` returns both). No internal variables.

    Attributes:
        rho0: density of the unreacted explosive (the reference of ``V``).
        A: first pressure coefficient.
        B: second pressure coefficient.
        R1: first decay constant, > 0.
        R2: second decay constant, > 0.
        w: Grueneisen coefficient omega, > 0.
    """

    rho0: Float[Array, ""] = eqx.field(converter=as_float)
    A: Float[Array, ""] = eqx.field(converter=as_float)
    B: Float[Array, ""] = eqx.field(converter=as_float)
    R1: Float[Array, ""] = eqx.field(converter=as_float)
    R2: Float[Array, ""] = eqx.field(converter=as_float)
    w: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("rho0", self.rho0)
        check_finite("A", self.A)
        check_finite("B", self.B)
        check_positive("R1", self.R1)
        check_positive("R2", self.R2)
        check_positive("w", self.w)

    def pressure_terms(self, rho, z):
        del z
        V = self.rho0 / rho
        a = self.A * (1.0 - self.w / (self.R1 * V)) * jnp.exp(-self.R1 * V) + self.B * (
            1.0 - self.w / (self.R2 * V)
        ) * jnp.exp(-self.R2 * V)
        return a, self.w * rho

    def nonnegative_energy(self):
        return True


class JWLIsentrope(AbstractStatelessEOS):
    """The JWL principal isentrope, barotropic: ``p = A exp(-R1 V) + B exp(-R2 V) + C V^-(w + 1)``.

    ``V = rho0 / rho``; ``b = 0``, the energy plays no part. ``JWLIsentrope.from_jwl`` picks ``C`` so
    that the isentrope passes through the CJ point of a full-form ``JWL`` (the JWL isentropes are
    exactly this family, so it is also tangent to the Rayleigh line there). No internal variables.

    Attributes:
        rho0: density of the unreacted explosive (the reference of ``V``).
        A: first pressure coefficient.
        B: second pressure coefficient.
        R1: first decay constant, > 0.
        R2: second decay constant, > 0.
        w: Grueneisen coefficient omega, > 0.
        C: coefficient of the power term.
    """

    rho0: Float[Array, ""] = eqx.field(converter=as_float)
    A: Float[Array, ""] = eqx.field(converter=as_float)
    B: Float[Array, ""] = eqx.field(converter=as_float)
    R1: Float[Array, ""] = eqx.field(converter=as_float)
    R2: Float[Array, ""] = eqx.field(converter=as_float)
    w: Float[Array, ""] = eqx.field(converter=as_float)
    C: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("rho0", self.rho0)
        check_finite("A", self.A)
        check_finite("B", self.B)
        check_positive("R1", self.R1)
        check_positive("R2", self.R2)
        check_positive("w", self.w)
        check_finite("C", self.C)

    @classmethod
    def from_jwl(cls, products: JWL, e0, p0=0.0) -> "JWLIsentrope":
        """The principal isentrope of a full-form JWL, through its CJ point.

        ``C = (P_CJ - A exp(-R1 V_CJ) - B exp(-R2 V_CJ)) V_CJ^(w + 1)`` with the CJ state of
        ``cj_state(products, products.rho0, e0, p0)``; differentiable in every input.

        Args:
            products: the full-form JWL.
            e0: the detonation energy per unit mass, ``E0 / rho0``.
            p0: the pressure ahead of the detonation (default 0).

        Returns:
            The isentrope, with the same ``rho0, A, B, R1, R2, w``.
        """
        cj = cj_state(products, products.rho0, e0, p0)
        V = cj["J_CJ"]
        p_exp = products.A * jnp.exp(-products.R1 * V) + products.B * jnp.exp(-products.R2 * V)
        C = (cj["P_CJ"] - p_exp) * V ** (products.w + 1.0)
        return cls(products.rho0, products.A, products.B, products.R1, products.R2, products.w, C)

    def pressure_terms(self, rho, z):
        del z
        V = self.rho0 / rho
        p = self.A * jnp.exp(-self.R1 * V) + self.B * jnp.exp(-self.R2 * V)
        p = p + self.C * power(V, -(self.w + 1.0))
        return p, jnp.zeros_like(rho)

    def nonnegative_energy(self):
        return True


class GammaLawIsentrope(AbstractStatelessEOS):
    """Products on the CJ isentrope of a gamma-law detonation: ``p = p_CJ (V / V_CJ)^-gamma``.

    ``V = rho0 / rho``, ``p_CJ = rho0 D^2 / (gamma + 1)`` and ``V_CJ = gamma / (gamma + 1)`` (Fickett &
    Davis, sec. 2A); ``b = 0``, the energy plays no part. ``cj()`` gives the CJ state in closed form.
    No internal variables.

    Attributes:
        rho0: density of the unreacted explosive.
        D: detonation speed, > 0.
        gamma: exponent of the products' isentrope, > 1.
    """

    rho0: Float[Array, ""] = eqx.field(converter=as_float)
    D: Float[Array, ""] = eqx.field(converter=as_float)
    gamma: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("rho0", self.rho0)
        check_positive("D", self.D)
        check_greater("gamma", self.gamma, 1.0)

    def cj(self) -> dict[str, Float[Array, ""]]:
        """The CJ state in closed form.

        ``P_CJ = rho0 D^2 / (gamma + 1)``, ``J_CJ = gamma / (gamma + 1)``, ``u_CJ = D / (gamma + 1)``,
        ``c_CJ = gamma D / (gamma + 1)``, ``rho_CJ = rho0 / J_CJ``, and ``e_CJ = P_CJ / ((gamma - 1)
        rho_CJ)``, the energy of the ideal-gas products ``p = (gamma - 1) rho e`` that detonate with
        energy ``e0 = D^2 / (2 (gamma^2 - 1))`` (this isentrope itself carries no energy).

        Returns:
            A dict with keys ``D, P_CJ, J_CJ, u_CJ, c_CJ, rho_CJ, e_CJ``.
        """
        g1 = self.gamma + 1.0
        J = self.gamma / g1
        p = self.rho0 * self.D**2 / g1
        rho = self.rho0 / J
        return {
            "D": self.D,
            "P_CJ": p,
            "J_CJ": J,
            "u_CJ": self.D / g1,
            "c_CJ": self.gamma * self.D / g1,
            "rho_CJ": rho,
            "e_CJ": p / ((self.gamma - 1.0) * rho),
        }

    def pressure_terms(self, rho, z):
        del z
        g1 = self.gamma + 1.0
        V = self.rho0 / rho
        p = self.rho0 * self.D**2 / g1 * power(V * g1 / self.gamma, -self.gamma)
        return p, jnp.zeros_like(rho)

    def nonnegative_energy(self):
        return True


class Murnaghan(AbstractStatelessEOS):
    """Unreacted explosive, Murnaghan's EOS in Uintah's form: ``p = (J^-n - 1) / (n K)``, ``J = rho0 / rho``.

    ``K`` is a compressibility, the inverse of the bulk modulus at ``rho0`` (``dp/drho = 1 / (K rho0)``
    there, so the sound speed at rest is ``sqrt(1 / (K rho0))``); ``Murnaghan.from_bulk_modulus``
    takes the bulk modulus instead. ``b = 0``. No internal variables.

    Attributes:
        rho0: reference density.
        K: compressibility, 1 / bulk modulus, > 0.
        n: pressure derivative of the bulk modulus, > 0.
    """

    rho0: Float[Array, ""] = eqx.field(converter=as_float)
    K: Float[Array, ""] = eqx.field(converter=as_float)
    n: Float[Array, ""] = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("rho0", self.rho0)
        check_positive("K", self.K)
        check_positive("n", self.n)

    @classmethod
    def from_bulk_modulus(cls, rho0, K_bulk, n) -> "Murnaghan":
        """Murnaghan's EOS from the bulk modulus, ``K = 1 / K_bulk``.

        Args:
            rho0: reference density.
            K_bulk: bulk modulus at ``rho0``, > 0.
            n: pressure derivative of the bulk modulus, > 0.

        Returns:
            ``Murnaghan(rho0, 1 / K_bulk, n)``.

        Raises:
            ValueError: ``K_bulk`` is not finite or not > 0 (or ``rho0``, ``n`` not > 0).
        """
        check_positive("K_bulk", K_bulk)
        return cls(rho0, 1.0 / as_float(K_bulk), n)

    def pressure_terms(self, rho, z):
        del z
        J = self.rho0 / rho
        return (power(J, -self.n) - 1.0) / (self.n * self.K), jnp.zeros_like(rho)

    def nonnegative_energy(self):
        return True


# The CJ search: D^2 on the products' Hugoniot, scanned on a grid of J, then a bracketed Newton step
# on d(D^2)/dJ = 0 from the grid's minimum. The grid: _SCAN even points over (0, 1), then _NEAR
# points whose 1 - J falls geometrically from the last one's 1e-3 to 1e-6, for weak detonations
# (a gamma-law gas's 1 - J_CJ is about 0.6 sqrt(q) / c0 for a heat release q << c0^2).
_SCAN = 500
_NEAR = 60
_NEWTON = 40


def _hugoniot(products, rho0, e0, p0, J):
    """``(D^2, p, e, 1 - b dv / 2)`` at volume ratio ``J`` on the Hugoniot from ``(rho0, p0, e0)``."""
    rho = rho0 / J
    a, b = products.pressure_terms(rho, None)
    dv = (1.0 - J) / rho0
    e = (e0 + 0.5 * (a + p0) * dv) / (1.0 - 0.5 * b * dv)
    p = a + b * e
    return (p - p0) / (rho0 * (1.0 - J)), p, e, 1.0 - 0.5 * b * dv


def _d2(products, rho0, e0, p0, J):
    return _hugoniot(products, rho0, e0, p0, J)[0]


def _slope(products, rho0, e0, p0, J):
    """``d(D^2)/dJ`` and ``d2(D^2)/dJ2``."""
    f = jax.grad(_d2, argnums=4)
    g, h = jax.value_and_grad(f, argnums=4)(products, rho0, e0, p0, J)
    return g, h


def _stop(tree):
    return jax.tree.map(lambda x: jax.lax.stop_gradient(x) if eqx.is_array(x) else x, tree)


@eqx.filter_jit
def _cj_solve(products, rho0, e0, p0):
    dtype = rho0.dtype
    sp, sr, se, sq = _stop((products, rho0, e0, p0))
    near = 1.0 - np.logspace(np.log10(0.5 / _SCAN), -6.0, _NEAR + 1)[1:]
    grid = jnp.concatenate(
        [jnp.linspace(0.5 / _SCAN, 1.0 - 0.5 / _SCAN, _SCAN, dtype=dtype), jnp.asarray(near, dtype)]
    )
    last = grid.shape[0] - 1
    d2, _, _, denom = jax.vmap(lambda J: _hugoniot(sp, sr, se, sq, J))(grid)
    valid = (denom > 0) & (d2 > 0) & jnp.isfinite(d2)
    d2 = jnp.where(valid, d2, jnp.inf)
    i = jnp.argmin(d2)
    found = (i > 0) & (i < last) & valid[i]
    lo, hi = grid[jnp.maximum(i - 1, 0)], grid[jnp.minimum(i + 1, last)]

    def newton(_, carry):
        lo, hi, J = carry
        g, h = _slope(sp, sr, se, sq, J)
        lo = jnp.where(g < 0, J, lo)
        hi = jnp.where(g >= 0, J, hi)
        step = J - g / h
        ok = (h > 0) & (step >= lo) & (step <= hi)
        return lo, hi, jnp.where(ok, step, 0.5 * (lo + hi))

    _, _, J = jax.lax.fori_loop(0, _NEWTON, newton, (lo, hi, grid[i]))
    # One Newton step outside the loop, on the converged root held constant: the root's value is
    # unchanged and its first derivatives with respect to every parameter are exact (implicit function).
    J = jax.lax.stop_gradient(J)
    g, h = _slope(products, rho0, e0, p0, J)
    J = J - g / h
    d2, p, e, _ = _hugoniot(products, rho0, e0, p0, J)
    D = jnp.where(found, jnp.sqrt(jnp.maximum(d2, 0.0)), jnp.nan)
    u = D * (1.0 - J)
    return {"D": D, "P_CJ": p, "J_CJ": J, "u_CJ": u, "c_CJ": D - u, "rho_CJ": rho0 / J, "e_CJ": e}


def _check_stateless(name: str, eos: object, dim: int = 1) -> None:
    """Check an EOS that is read without internal variables (``pressure_terms(rho, None)``).

    Args:
        name: the parameter's name, for the message.
        eos: its value.
        dim: the dimension of the position its ``initial_internal`` is probed with.

    Raises:
        ValueError: ``eos`` is not an ``AbstractEOS``, or it has internal variables (a
            ``ProgrammedBurn``).
    """
    if not isinstance(eos, AbstractEOS):
        raise ValueError(
            f"{name} must be an AbstractEOS without internal variables (its pressure_terms is read with "
            f"z = None), got {type(eos).__name__}"
        )
    probe = jax.ShapeDtypeStruct((dim,), jnp.result_type(float))
    if jax.eval_shape(eos.initial_internal, probe) is not None:
        raise ValueError(f"{name} must have no internal variables ({type(eos).__name__} has some)")


def _check_one(caller: str, **values) -> None:
    """Check that each of ``values`` is one real number: ``caller`` solves for one explosive (tracers
    pass, so ``jax.vmap`` over it solves for several).

    Raises:
        ValueError: a value is not a real number, or is an array with a shape.
    """
    batch = f"; for several, jax.vmap over {caller}"
    for name, value in values.items():
        check_real(name, value)
        check_scalar(name, value, batch)


def cj_state(products: AbstractEOS, rho0, e0=0.0, p0=0.0) -> dict[str, Float[Array, ""]]:
    """The Chapman-Jouguet state of a detonation into ``(rho0, p0, e0)`` whose products follow ``products``.

    On the products' Hugoniot from the unreacted state, ``e = e0 + (p + p0) / 2 (1 / rho0 - 1 / rho)``,
    the pressure is explicit, ``e_H = (e0 + (a + p0) dv / 2) / (1 - b dv / 2)`` with ``dv = 1 / rho0 -
    1 / rho`` and ``p = a + b e``, and the Rayleigh line gives ``D^2 = (p - p0) / (rho0 (1 - J))``, ``J
    = rho0 / rho``. The CJ point is the minimum of ``D^2`` over ``J`` in ``(0, 1)`` (the Rayleigh line
    tangent to the Hugoniot): found by a scan of 500 even points, and 60 more with ``1 - J`` from
    ``1e-3`` down to ``1e-6`` for weak detonations, then a bracketed Newton iteration on
    ``d(D^2)/dJ = 0``; one more Newton step on the converged root held constant makes every output
    differentiable (exact first derivatives) with respect to the EOS's fields, ``rho0``, ``e0`` and
    ``p0``. ``u_CJ = D (1 - J_CJ)`` and ``c_CJ = D - u_CJ`` (the CJ condition; it equals
    ``products.sound_speed(rho_CJ, e_CJ)``).

    A barotropic EOS (``b = 0``) ignores the energy. One whose isentrope passes through a CJ point
    (``GammaLawIsentrope``, ``JWLIsentrope.from_jwl``) gives that point, the Rayleigh line being tangent
    to the isentrope there, but its ``e_CJ`` is only the Hugoniot energy ``e0 + P_CJ dv / 2``
    (``GammaLawIsentrope.cj`` has the closed form); one with ``D^2`` smallest at ``J -> 1``
    (``Murnaghan``: a sound wave, not a detonation) gives NaN.

    Args:
        products: the products' EOS, with energy and without internal variables (``pressure_terms`` is
            called with ``z = None``).
        rho0: density of the unreacted explosive.
        e0: its specific internal energy, the detonation energy per unit mass (``E0 / rho0`` for JWL).
        p0: its pressure (default 0).

    Returns:
        A dict of 0-d arrays with keys ``D`` (detonation speed), ``P_CJ``, ``J_CJ`` (``rho0 / rho_CJ``),
        ``u_CJ`` (particle speed), ``c_CJ`` (sound speed), ``rho_CJ`` and ``e_CJ`` (specific energy).
        Every value is NaN where the scan finds no interior minimum (no detonation, or one so weak
        that ``1 - J_CJ`` is under ``1e-6``: a gamma-law gas's heat release under about
        ``3e-12 c0^2``). The state is as precise as ``eps / (1 - J_CJ)``, relative.

    Raises:
        ValueError: ``products`` is not an ``AbstractEOS`` without internal variables; ``rho0``, ``e0``
            or ``p0`` is not one real number (an array: ``jax.vmap`` over ``cj_state`` solves several);
            or (concrete values) ``rho0`` is not finite or not > 0, or ``e0``, ``p0`` not finite.
    """
    _check_stateless("products", products)
    _check_one("cj_state", rho0=rho0, e0=e0, p0=p0)
    rho0, e0, p0 = as_float(rho0), as_float(e0), as_float(p0)
    check_positive("rho0", rho0)
    check_finite("e0", e0)
    check_finite("p0", p0)
    out = _cj_solve(products, rho0, e0, p0)
    nan = jnp.isnan(out["D"])
    return {k: jnp.where(nan, jnp.nan, v) for k, v in out.items()}


def check_cj_consistency(
    products: AbstractEOS, rho0, e0, D, P_CJ=None, rtol: float = 0.01
) -> dict[str, Float[Array, ""]]:
    """Check that the CJ state implied by ``products`` matches a given detonation speed (and pressure).

    Args:
        products: the products' EOS, with energy.
        rho0: density of the unreacted explosive.
        e0: the detonation energy per unit mass.
        D: the expected detonation speed.
        P_CJ: the expected CJ pressure, or ``None`` to check ``D`` only.
        rtol: the largest relative miss allowed.

    Returns:
        ``cj_state(products, rho0, e0)``. Under a transformation (traced values) nothing is checked.

    Raises:
        ValueError: the inputs are refused as by ``cj_state``, or ``D`` (``P_CJ``) is not one real
            number, or ``rtol`` is not one finite number > 0; or the implied ``D`` (or ``P_CJ``) misses
            the given one by more than ``rtol``, relative: one line with both values and the miss.
    """
    given = {"D": D} if P_CJ is None else {"D": D, "P_CJ": P_CJ}
    _check_one("check_cj_consistency", **given)  # products, rho0 and e0: cj_state checks them
    check_real("rtol", rtol)
    check_scalar("rtol", rtol)
    check_positive("rtol", rtol)
    cj = cj_state(products, rho0, e0)
    pairs = [("D", cj["D"], D)] + ([] if P_CJ is None else [("P_CJ", cj["P_CJ"], P_CJ)])
    for name, implied, given in pairs:
        if not (is_concrete(implied) and is_concrete(given)):
            continue
        implied, given = float(implied), float(given)
        miss = abs(implied - given) / abs(given) if given != 0 else float("inf")
        if not miss <= rtol:  # a NaN misses too
            raise ValueError(
                f"the EOS implies CJ {name} = {implied:.6g} but {name} = {given:.6g} was given: "
                f"relative miss {miss:.3g} > rtol {rtol:g} (a typo in the EOS constants, or other units?)"
            )
    return cj


def cj_energy(products: AbstractEOS, rho0, D, p0=0.0, iterations: int = 8) -> Float[Array, ""]:
    """The detonation energy per unit mass at which ``products`` imply the detonation speed ``D``.

    The constraint of a fit of products' constants to a measured ``D``: ``e0`` solves ``cj_state(products,
    rho0, e0, p0)["D"] = D``. ``D^2`` is nearly affine in ``e0`` (exactly, ``2 (gamma^2 - 1) e0``, for the
    gamma law), so Newton's iteration on ``D^2(e0) - D^2`` converges from the gamma law's ``e0 = D^2 /
    16`` (``gamma = 3``) in a few steps; one more step on the converged root held constant makes ``e0``
    differentiable with respect to ``D``, ``rho0``, ``p0`` and the EOS's fields (the implicit
    function's exact first derivatives).

    Args:
        products: the products' EOS, with energy (``b != 0``: a barotropic EOS ignores ``e0``).
        rho0: density of the unreacted explosive.
        D: the detonation speed to imply, > 0.
        p0: the unreacted pressure (default 0).
        iterations: Newton iterations before the differentiable one (static).

    Returns:
        ``e0`` (for JWL, ``E0 = rho0 e0`` per reference volume; negative for a ``D`` below the one the
        products imply at ``e0 = 0``). NaN under a transformation (traced values) where no ``e0`` gives
        a CJ state of speed ``D``.

    Raises:
        ValueError: ``products`` is not an ``AbstractEOS`` without internal variables; ``rho0``, ``D``
            or ``p0`` is not one real number; ``iterations`` is not an integer >= 1; ``D`` or ``rho0``
            is not finite or not > 0, or ``p0`` not finite; or (concrete values) no ``e0`` gives the
            products a CJ state of speed ``D``: the iteration ends where the CJ state's speed misses
            ``D`` (by more than the square root of the float dtype's epsilon, relative), its ``J_CJ``
            is not in ``(0, 1)``, or there is none (a ``D`` below the slowest detonation the products
            have, or a barotropic EOS).
    """
    _check_stateless("products", products)
    _check_one("cj_energy", rho0=rho0, D=D, p0=p0)
    check_int("iterations", iterations, 1)
    iterations = python_int(iterations)  # static: the length of the iteration
    D, rho0, p0 = as_float(D), as_float(rho0), as_float(p0)
    check_positive("D", D)
    check_positive("rho0", rho0)
    check_finite("p0", p0)
    e0 = _cj_energy(products, rho0, D, p0, iterations)
    if is_concrete(e0) and not math.isfinite(float(e0)):
        raise ValueError(
            f"D={float(D)!r} is the CJ detonation speed of these products at no detonation energy e0 "
            f"(rho0={float(rho0)!r}): Newton's iteration on e0 ends at a CJ state of another speed, or "
            "none; D must be at least the slowest detonation the products have, and their CJ speed "
            "must depend on e0 (not a barotropic EOS)"
        )
    return e0


@eqx.filter_jit
def _cj_energy(products, rho0, D, p0, iterations):
    def residual(e0):
        return jnp.square(_cj_solve(products, rho0, e0, p0)["D"]) / jnp.square(D) - 1.0

    def newton(e0, args):
        del args
        r, slope = jax.jvp(residual, (e0,), (jnp.ones_like(e0),))
        return e0 - r / slope, None

    e0 = jax.lax.stop_gradient(jnp.square(D) / 16.0)
    e0, _ = jax.lax.scan(newton, e0, None, length=iterations)
    e0 = jax.lax.stop_gradient(e0)
    slope = jax.lax.stop_gradient(jax.jvp(residual, (e0,), (jnp.ones_like(e0),))[1])
    cj = _cj_solve(products, rho0, e0, p0)
    r = jnp.square(cj["D"]) / jnp.square(D) - 1.0
    # The iterate is a root where its CJ state has speed D (r ~ 2 x the relative miss) and J_CJ in
    # (0, 1); elsewhere (D below every CJ speed of the products) the iteration wanders off and its
    # end is no detonation energy.
    miss, J = jax.lax.stop_gradient((r, cj["J_CJ"]))
    ok = (jnp.abs(miss) <= jnp.sqrt(jnp.finfo(miss.dtype).eps)) & (J > 0) & (J < 1)
    return jnp.where(ok, e0 - r / slope, jnp.nan)


EXPLOSIVES: dict[str, dict[str, float]] = {
    "tnt": dict(rho0=1630.0, A=371.2e9, B=3.231e9, R1=4.15, R2=0.95, w=0.30, E0=7.0e9, D=6930.0, P_CJ=21.0e9),
    "compb": dict(
        rho0=1717.0, A=524.2e9, B=7.678e9, R1=4.20, R2=1.10, w=0.34, E0=8.5e9, D=7980.0, P_CJ=29.5e9
    ),
    "petn": dict(
        rho0=1770.0, A=617.0e9, B=16.926e9, R1=4.40, R2=1.20, w=0.25, E0=10.1e9, D=8300.0, P_CJ=33.5e9
    ),
    "pbx9404": dict(
        rho0=1840.0, A=852.4e9, B=18.02e9, R1=4.60, R2=1.30, w=0.38, E0=10.2e9, D=8800.0, P_CJ=37.0e9
    ),
}
"""JWL constants of TNT, Composition B-3, PETN and PBX-9404 with their tabulated CJ detonation speed
and pressure, in SI (``rho0`` kg/m^3; ``A``, ``B``, ``P_CJ`` Pa; ``E0`` J/m^3, the detonation energy per
unit reference volume; ``D`` m/s), from B. M. Dobratz and P. C. Crawford, "LLNL Explosives Handbook",
UCRL-52997 (1985). The CJ state each row implies (``cj_state``) matches its ``D`` and ``P_CJ`` to 0.03%.
``jwl(name)`` builds the EOS."""


def jwl(name: str, check: bool = True) -> tuple[JWL, Float[Array, ""]]:
    """A tabulated explosive's JWL products and detonation energy.

    Args:
        name: a key of ``EXPLOSIVES`` (``"tnt"``, ``"compb"``, ``"petn"``, ``"pbx9404"``).
        check: whether to check that the row's implied CJ state matches its tabulated ``D`` and
            ``P_CJ`` to 1% (``check_cj_consistency``; one CJ solve).

    Returns:
        ``(JWL(rho0, A, B, R1, R2, w), e0)``, ``e0 = E0 / rho0`` the initial specific energy of the
        products.

    Raises:
        ValueError: ``name`` is not a known explosive (the message lists them; a value that is not a
            string is no name), ``check`` is not a bool, or the row fails its check.
    """
    if not isinstance(name, str) or name not in EXPLOSIVES:
        raise ValueError(f"unknown explosive {brief(name)}; known: {', '.join(sorted(EXPLOSIVES))}")
    check_bool("check", check)
    row = EXPLOSIVES[name]
    eos = JWL(*(row[k] for k in ("rho0", "A", "B", "R1", "R2", "w")))
    e0 = as_float(row["E0"]) / eos.rho0
    if check:
        check_cj_consistency(eos, eos.rho0, e0, row["D"], row["P_CJ"])
    return eos, e0


BURNS = ("time", "volume", "max")
"""The burn criteria of ``ProgrammedBurn``."""


def _as_points(x: object) -> Float[Array, "k dim"]:
    """Detonator positions as a ``(k, dim)`` array: a number is one 1D point, a vector one point."""
    check_real("points", x)
    p = jnp.asarray(x, dtype=jnp.result_type(float))
    if p.ndim == 0:
        return p.reshape(1, 1)
    if p.ndim == 1 and p.size:
        return p[None, :]
    if p.ndim != 2 or not 1 <= p.shape[1] <= 3:  # an empty vector gives no dimension
        raise ValueError(
            f"points must be an array (k, dim) with dim 1, 2 or 3 (for no point, an array of shape (0, dim) "
            f"beside planes or lines), got shape {p.shape}"
        )
    return p


def _as_rows(name: str):
    """A converter of detonator rows (``planes``: ``(n, c)``, the plane ``n . X = c``; ``lines``: ``(a,
    d)``, the line through ``a`` along ``d``) to an ``(m, k)`` array (one row may be given as a
    vector); ``None`` for none."""

    def convert(x: object) -> Float[Array, "m k"] | None:
        if x is None:
            return None
        check_real(name, x)
        p = jnp.asarray(x, dtype=jnp.result_type(float))
        return p[None, :] if p.ndim == 1 else p

    return convert


def _ramp(x, smooth: bool):
    x = jnp.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x) if smooth else x


class ProgrammedBurn(AbstractEOS):
    """A reactant and its detonation products, mixed by a burn fraction ``lambda`` that only grows.

    The pressure terms are the mixture's, ``(a, b) = (1 - lambda) (a_r, b_r) + lambda (a_p, b_p)``, with
    ``lambda`` the particle's internal variable (0 at ``t = 0``). The particle carries one specific
    energy ``e``: give the region the products' detonation energy from the start (``e0 = E0 / rho0``
    for a JWL); a reactant with ``b_r = 0`` (``Murnaghan``) ignores it.

    Over a step to ``t + dt``:

    - time burn: the detonation, lit at time ``t_d`` at the detonators, reaches ``X`` at the lighting
      time ``t_b = t_d + d(X) / D``, ``d`` the distance to the nearest detonator: a point ``X_k``
      (``|X - X_k|``), a plane ``n . X = c`` (``|n . X - c| / |n|``; a line in 2D) or a line through
      ``a`` along ``d`` (``|(X - a) - ((X - a) . d) d / |d|^2|``, a detonating cord in 3D): Huygens'
      straight-line burn, the earliest detonator winning; and
      ``F_time = ramp((t + dt - t_b) / (width / D))``; ``width`` is the burn's length (Uintah's
      ``ProgramBurn`` takes 1.5 particle sizes);
    - volume burn: ``F_volume = ramp((1 - J_new) / (1 - J_CJ))``, complete at the CJ compression;
    - ``burn="max"`` takes the larger of the two;

    and ``lambda_new = max(lambda_old, F)``. The ramp is ``clip(x, 0, 1)``; with ``smooth=True`` it is
    the C1 smoothstep ``3 x^2 - 2 x^3`` of the clipped ``x``, whose slope vanishes at both ends, so
    ``lambda`` is C1 in time and in ``J`` for one criterion and one detonator. What stays a kink in
    either case: the minimum over several detonators, the maximum of the two criteria (``"max"``) and
    the maximum with the old ``lambda``.

    Detonators are ``points``, ``planes`` and ``lines`` (in 1D a point is a plane; in 2D a line is a
    plane). A reactant ``None`` is inert: zero pressure (``a_r = b_r = 0``), the products alone scaled
    by ``lambda``. The wrapped EOSs must have no internal variables of their own.

    Attributes:
        reactant: the unreacted explosive's EOS, or ``None`` for an inert reactant of zero pressure.
        products: the products' EOS.
        D: detonation speed, > 0.
        points: detonator positions, ``(k, dim)``; one point may be given as a ``(dim,)`` vector, one
            1D point as a number; ``k = 0`` (an array ``(0, dim)``) with ``planes`` or ``lines``.
        width: the burn's length, > 0; the time burn lasts ``width / D``.
        J_CJ: the CJ volume ratio, in ``(0, 1)``, where the volume burn completes.
        t_d: detonation time (default 0).
        burn: ``"time"`` (default), ``"volume"`` or ``"max"``.
        smooth: whether the ramp is the C1 smoothstep (default ``False``: linear).
        planes: plane detonators, ``(m, dim + 1)`` rows ``(n, c)`` for ``n . X = c`` (``n`` not zero),
            or ``None`` (default).
        lines: line detonators (2D and 3D), ``(m, 2 dim)`` rows ``(a, d)`` for the line through ``a``
            along ``d`` (``d`` not zero), or ``None`` (default).
    """

    reactant: AbstractEOS | None
    products: AbstractEOS
    D: Float[Array, ""] = eqx.field(converter=as_float)
    points: Float[Array, "k dim"] = eqx.field(converter=_as_points)
    width: Float[Array, ""] = eqx.field(converter=as_float)
    J_CJ: Float[Array, ""] = eqx.field(converter=as_float)
    t_d: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    burn: str = eqx.field(static=True, default="time")
    smooth: bool = eqx.field(static=True, default=False)
    planes: Float[Array, "m dim1"] | None = eqx.field(converter=_as_rows("planes"), default=None)
    lines: Float[Array, "m dim2"] | None = eqx.field(converter=_as_rows("lines"), default=None)

    def __check_init__(self):
        if self.reactant is not None and not isinstance(self.reactant, AbstractEOS):
            raise ValueError(
                f"reactant must be an AbstractEOS or None (inert), got {type(self.reactant).__name__}"
            )
        if not isinstance(self.products, AbstractEOS):
            raise ValueError(f"products must be an AbstractEOS, got {type(self.products).__name__}")
        if self.burn not in BURNS:
            raise ValueError(f"burn must be one of {', '.join(map(repr, BURNS))}, got {self.burn!r}")
        if not isinstance(self.smooth, bool):
            raise ValueError(f"smooth must be a bool, got {self.smooth!r}")
        check_positive("D", self.D)
        check_positive("width", self.width)
        check_greater("J_CJ", self.J_CJ, 0.0)
        check_less("J_CJ", self.J_CJ, 1.0)
        check_finite("t_d", self.t_d)
        dim = self.points.shape[1]
        if self.planes is not None:
            if self.planes.ndim != 2 or self.planes.shape[1] != dim + 1:
                raise ValueError(
                    f"planes must be an array (m, dim + 1) of rows (n, c) with dim = {dim} (the points'), "
                    f"got shape {self.planes.shape}"
                )
            check_finite("planes", self.planes)
            if is_concrete(self.planes) and bool(jnp.any(jnp.all(self.planes[:, :-1] == 0.0, axis=1))):
                raise ValueError("planes: a plane's normal n must not be zero")
        if self.lines is not None:
            if dim < 2 or self.lines.ndim != 2 or self.lines.shape[1] != 2 * dim:
                raise ValueError(
                    f"lines must be an array (m, 2 dim) of rows (a, d) with dim = {dim} (the points') of 2 "
                    f"or 3, got shape {self.lines.shape}"
                )
            check_finite("lines", self.lines)
            if is_concrete(self.lines) and bool(jnp.any(jnp.all(self.lines[:, dim:] == 0.0, axis=1))):
                raise ValueError("lines: a line's direction d must not be zero")
        count = sum(0 if a is None else a.shape[0] for a in (self.points, self.planes, self.lines))
        if count < 1:
            raise ValueError("give at least one detonator: points (k >= 1), planes or lines")
        check_finite("points", self.points)
        for name, eos in (("reactant", self.reactant), ("products", self.products)):
            if eos is not None:
                _check_stateless(name, eos, self.points.shape[1])

    def lighting_time(self, X: Float[Array, " dim"]) -> Float[Array, ""]:
        """When the detonation reaches a particle: ``t_d + d(X) / D``, ``d`` the distance to the nearest
        detonator (point, plane or line).

        Args:
            X: the particle's reference position, of shape ``(dim,)`` (the detonators' dimension).

        Returns:
            ``t_b``.

        Raises:
            ValueError: ``X`` is not of shape ``(dim,)`` (checked on the shape, so under ``jax.jit``
                too).
        """
        dim = self.points.shape[1]
        if np.shape(X) != (dim,):
            raise ValueError(
                f"X must be one position of shape ({dim},) (the detonators' dimension), got shape "
                f"{np.shape(X)}"
            )

        def norm(r2):  # 0 gradient on a detonator, not NaN
            pos = r2 > 0
            return jnp.where(pos, jnp.sqrt(jnp.where(pos, r2, 1.0)), 0.0)

        distances = []
        if self.points.shape[0] > 0:
            distances.append(norm(jnp.sum(jnp.square(X[None, :] - self.points), axis=-1)))
        if self.planes is not None:
            n, c = self.planes[:, :-1], self.planes[:, -1]
            distances.append(jnp.abs(n @ X - c) / jnp.sqrt(jnp.sum(n * n, axis=1)))
        if self.lines is not None:
            dim = X.shape[0]
            a, d = self.lines[:, :dim], self.lines[:, dim:]
            r = X[None, :] - a
            along = jnp.sum(r * d, axis=1) / jnp.sum(d * d, axis=1)
            distances.append(norm(jnp.sum(jnp.square(r - along[:, None] * d), axis=1)))
        return self.t_d + jnp.min(jnp.concatenate(distances)) / self.D

    def burn_fraction(
        self, X: Float[Array, " dim"], t: Float[Array, ""], J: Float[Array, ""]
    ) -> Float[Array, ""]:
        """The burn criterion ``F`` at time ``t`` and volume ratio ``J``, before the max with ``lambda``.

        Args:
            X: the particle's reference position, of shape ``(dim,)``.
            t: time.
            J: volume ratio ``det F``.

        Returns:
            ``F_time``, ``F_volume`` or their maximum, as ``burn`` says.

        Raises:
            ValueError: ``X`` is not of shape ``(dim,)`` (``lighting_time``).
        """
        f_time = _ramp((t - self.lighting_time(X)) * self.D / self.width, self.smooth)
        f_volume = _ramp((1.0 - J) / (1.0 - self.J_CJ), self.smooth)
        if self.burn == "time":
            return f_time
        if self.burn == "volume":
            return f_volume
        return jnp.maximum(f_time, f_volume)

    def pressure_terms(self, rho, z):
        lam = z["lambda"]
        a_p, b_p = self.products.pressure_terms(rho, None)
        if self.reactant is None:
            return lam * a_p, lam * b_p
        a_r, b_r = self.reactant.pressure_terms(rho, None)
        return (1.0 - lam) * a_r + lam * a_p, (1.0 - lam) * b_r + lam * b_p

    def initial_internal(self, X):
        return {"lambda": jnp.zeros((), dtype=X.dtype)}

    def update_internal(self, z, X, t, dt, J_old, J_new):
        del J_old
        lam = z["lambda"]
        return {"lambda": jnp.maximum(lam, self.burn_fraction(X, t + dt, J_new).astype(lam.dtype))}

    def front_speed(self):
        """The detonation speed ``D``: the burn crosses a cell in ``h / D``, so the step resolves it.

        Returns:
            ``D``.
        """
        return self.D

    def nonnegative_energy(self):
        """``True``: the explosive's energy (the reactant's, then the products' from ``e0``) stays >= 0.

        Returns:
            ``True``.
        """
        return True
