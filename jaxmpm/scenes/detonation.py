"""A planar detonation: a slab of explosive lit at ``X = 0``, products behind the exact CJ-Taylor wave."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._checks import check_finite, check_greater, check_positive, is_concrete, python_bool, python_int, show
from .._util import as_float
from ..exact_detonation import Isentrope, gamma_law_particles, isentrope_fan
from ..explosives import (
    BURNS,
    EXPLOSIVES,
    GammaLawIsentrope,
    JWLIsentrope,
    ProgrammedBurn,
    cj_state,
    jwl,
)
from ..geometry import Box
from ..materials import AbstractEOS, IdealGas
from ..regions import Region
from ._base import AbstractScene, check_point

EXPLOSIVE_NAMES = ("gamma-law",) + tuple(EXPLOSIVES)
"""The ``explosive`` choices: gamma-law products of the given ``D`` and ``gamma``, or a JWL row."""

PRODUCTS = ("isentrope", "full")
"""The ``products`` choices: on the CJ isentrope (barotropic) or the full EOS with its energy."""

ENDS = ("wall", "free")


def _ranges(dtype) -> dict[str, tuple[float, float]]:
    """The open intervals of ``D`` and ``gamma`` where the gamma law's CJ state is finite in ``dtype``.

    ``D`` enters squared (``P_CJ = rho0 D^2 / (gamma + 1)``, ``e0 = D^2 / (2 (gamma^2 - 1))``): it
    lies between the square roots of the smallest normal number and of the largest number. Above
    ``1 / eps`` (eps the dtype's machine epsilon) ``J_CJ = gamma / (gamma + 1)`` is within round-off
    of 1, where there is no compression and no CJ state.

    Args:
        dtype: the parameters' float dtype.

    Returns:
        ``{"D": (lo, hi), "gamma": (1, hi)}``.
    """
    info = np.finfo(dtype)
    return {
        "D": (float(np.sqrt(info.tiny)), float(np.sqrt(info.max))),
        "gamma": (1.0, float(1.0 / info.eps)),
    }


def _check_range(name: str, value, interval: tuple[float, float], why: str) -> None:
    """Check a concrete value against an open interval (a tracer passes).

    Args:
        name: the parameter's name, for the message.
        value: its value, finite.
        interval: ``(lo, hi)``.
        why: what the interval keeps finite, for the message.

    Raises:
        ValueError: ``value`` is not in ``(lo, hi)``.
    """
    lo, hi = interval
    if is_concrete(value) and not lo < float(value) < hi:
        raise ValueError(f"{name} must be in ({lo:.4g}, {hi:.4g}) ({why}), got {float(value)!r}")


def _check_gamma_law_ranges(D: Float[Array, ""], gamma: Float[Array, ""]) -> None:
    """Check ``D`` and ``gamma`` against the intervals of ``_ranges`` in ``D``'s dtype (tracers pass).

    Args:
        D: the detonation speed, finite and > 0.
        gamma: the products' exponent, finite and > 1.

    Raises:
        ValueError: ``D`` or ``gamma`` is outside its interval, named with what it keeps finite.
    """
    dtype = D.dtype
    ranges = _ranges(dtype)
    _check_range("D", D, ranges["D"], f"P_CJ and e0 are proportional to D^2, finite and > 0 in {dtype}")
    _check_range(
        "gamma",
        gamma,
        ranges["gamma"],
        f"a finite CJ state needs J_CJ = gamma / (gamma + 1) below 1 in {dtype}",
    )


def _bad(value, below_one: bool = False) -> bool:
    """Whether a derived quantity is not finite and > 0 (and < 1 with ``below_one``)."""
    return not (jnp.isfinite(value) and value > 0 and (not below_one or value < 1))


def _check_gamma_law_state(D: Float[Array, ""], gamma: Float[Array, ""], rho0: Float[Array, ""]) -> None:
    """Check the gamma law's CJ state and detonation energy: each finite and > 0 (``J_CJ < 1``) in the
    float dtype; tracers pass.

    Args:
        D: the detonation speed, in its range (``_check_gamma_law_ranges``).
        gamma: the products' exponent, in its range.
        rho0: the explosive's density, finite and > 0.

    Raises:
        ValueError: a quantity is out of the dtype's range, naming ``D``, ``gamma`` and ``rho0`` and
            the quantities.
    """
    if not all(is_concrete(v) for v in (D, gamma, rho0)):
        return
    _, _, e0, cj = explosive_eos("gamma-law", "isentrope", D, gamma, rho0)
    quantities = {k: cj[k] for k in ("P_CJ", "J_CJ", "u_CJ", "c_CJ", "rho_CJ", "e_CJ")}
    quantities["e0"] = e0
    wrong = [f"{k} = {float(v)!r}" for k, v in quantities.items() if _bad(v, below_one=k == "J_CJ")]
    if wrong:
        raise ValueError(
            f"D={float(D)!r}, gamma={float(gamma)!r} and rho0={float(rho0)!r} give the gamma law a CJ "
            f"state out of the {D.dtype} range ({', '.join(wrong)}); P_CJ = rho0 D^2 / (gamma + 1), e0 = "
            "D^2 / (2 (gamma^2 - 1)) and the rest must be finite and > 0"
        )


def explosive_eos(
    explosive: str, products: str, D: Float[Array, ""], gamma: Float[Array, ""], rho0: Float[Array, ""]
) -> tuple[Float[Array, ""], AbstractEOS, Float[Array, ""], dict[str, Array]]:
    """The products of an explosive: its density, its products EOS, its detonation energy, its CJ state.

    Args:
        explosive: ``"gamma-law"`` or a JWL row's name (``jaxmpm.explosives.EXPLOSIVES``).
        products: ``"isentrope"`` (the CJ isentrope, barotropic) or ``"full"`` (the ideal gas, or JWL
            with its energy).
        D: the gamma law's detonation speed (unused for a JWL row).
        gamma: the gamma law's exponent (unused for a JWL row).
        rho0: the gamma law's density (unused for a JWL row).

    Returns:
        ``(rho0, products, e0, cj)``: ``e0`` is the gamma law's detonation energy ``D^2 / (2
        (gamma^2 - 1))`` or the row's ``E0 / rho0``; ``cj`` the CJ state (closed form for the gamma
        law, implied by the full JWL EOS for a row).
    """
    if explosive == "gamma-law":
        iso = GammaLawIsentrope(rho0=rho0, D=D, gamma=gamma)
        e0 = jnp.square(D) / (2.0 * (jnp.square(gamma) - 1.0))
        eos = iso if products == "isentrope" else IdealGas(gamma=gamma)
        return rho0, eos, e0, iso.cj()
    full, e0 = jwl(explosive, check=False)
    cj = cj_state(full, full.rho0, e0)
    eos = JWLIsentrope.from_jwl(full, e0) if products == "isentrope" else full
    return full.rho0, eos, e0, cj


def _check_burn_width(value) -> None:
    """Check a programmed burn's ``burn_width`` (particle sizes): finite and >= 1, to round-off; a
    tracer passes.

    Args:
        value: the scene's ``burn_width``.

    Raises:
        ValueError: ``"burn_width must be >= 1 (the burn's length in particle sizes), got {value}"``.
    """
    check_finite("burn_width", value)
    if is_concrete(value) and not np.all(np.asarray(value) >= 1.0 - 1e-12):
        raise ValueError(
            f"burn_width must be >= 1 (the burn's length in particle sizes), got {show(np.asarray(value))}"
        )


class Detonation(AbstractScene):
    """A slab of explosive on ``[0, L]``, lit at ``X = 0`` at ``t = 0``; the far end is free.

    The explosive is a ``jaxmpm.explosives.ProgrammedBurn`` of an inert reactant (zero pressure) and
    its products: a particle at ``X`` is lit at ``t_b = X / D`` and its burn fraction ``lambda`` grows
    over ``burn_width`` particle sizes of travel of the front (``burn="time"``, Uintah's
    ``ProgramBurn``), with compression (``"volume"``, the beta burn), or by the larger of the two
    (``"max"``); ``smooth_burn=True`` makes the ramp C1. The stress is ``-lambda p_products I``.

    Products (``explosive``):

    - ``"gamma-law"`` (default): ``D``, ``gamma`` and ``rho0`` as given, ``p_CJ = rho0 D^2 / (gamma +
      1)``; ``products="isentrope"`` puts them on their CJ isentrope ``p = p_CJ (J / J_CJ)^-gamma``,
      ``products="full"`` makes them an ideal gas ``p = (gamma - 1) rho e`` with the detonation
      energy ``e0 = D^2 / (2 (gamma^2 - 1))``, whose CJ state is the same;
    - ``"tnt"``, ``"compb"``, ``"petn"``, ``"pbx9404"``: the JWL rows of ``jaxmpm.explosives.EXPLOSIVES``
      (their ``rho0``, and ``D`` the CJ speed their EOS implies; the scene's ``D``, ``gamma`` and
      ``rho0`` are not used); ``"isentrope"`` is the principal isentrope through the CJ point,
      ``"full"`` the JWL form with the energy ``e0 = E0 / rho0``.

    Every particle starts with ``e0`` (the gamma law's detonation energy, or the row's ``E0 / rho0``),
    so that the energy it keeps is the products' whether or not the pressure reads it.

    The exact solution (``exact``, ``jaxmpm.exact_detonation``) is the CJ front followed by the Taylor
    rarefaction, with a region at rest against the wall (``ends="wall"``) or a fan to the escape speed
    (``ends="free"``); it holds while the front is in the slab, ``t <= t_valid = L / D``. For gamma =
    3 at a wall ``F`` rises from ``3/4`` at the front to ``9/8`` at rest, where the pressure is ``8/27
    p_CJ``. ``smooth`` marks the particles the burn has finished with, farther than ``12 h`` behind the
    front, where errors are measured (``jaxmpm run`` reports them there).

    On the command line ``smooth=true|false`` sets ``smooth_burn`` (``smooth`` is the scene's marker
    of the particles away from the front). Units are SI on the command line.

    Attributes:
        D: detonation speed of the gamma-law products, > 0 (in float64 between 1.5e-154 and
            1.3e154, so that ``D^2`` is finite and > 0).
        gamma: their adiabatic exponent, > 1 (and below ``1 / eps``, 4.5e15 in float64, where
            ``J_CJ = gamma / (gamma + 1)`` is below 1).
        rho0: the explosive's density, > 0 (with ``D`` and ``gamma``: a finite CJ state).
        L: the slab's length (``h = L / cells``).
        burn_width: the burn's length in particle sizes (``h / ppc``), >= 1 (Uintah: 1.5).
        explosive: ``"gamma-law"`` or a JWL row's name (static).
        products: ``"isentrope"`` or ``"full"`` (static).
        ends: the lit end, ``"wall"`` or ``"free"`` (static).
        burn: ``"time"``, ``"volume"`` or ``"max"`` (static).
        smooth_burn: whether the burn's ramp is C1 (static).
        cells, ppc, pad: as for every scene.
    """

    name: ClassVar[str] = "detonation"
    description: ClassVar[str] = (
        "1D detonation of a slab lit at X = 0: programmed burn, gamma-law or JWL products, exact CJ-Taylor"
    )
    dim: ClassVar[int] = 1
    right: ClassVar[str] = "free"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    initial_position: ClassVar[None] = None

    D: Float[Array, ""] = eqx.field(converter=as_float, default=8000.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=3.0)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1875.0)
    L: Float[Array, ""] = eqx.field(converter=as_float, default=0.1)
    burn_width: Float[Array, ""] = eqx.field(converter=as_float, default=1.5)
    explosive: str = eqx.field(static=True, default="gamma-law")
    products: str = eqx.field(static=True, default="isentrope")
    ends: str = eqx.field(static=True, default="wall")
    burn: str = eqx.field(static=True, default="time")
    smooth_burn: bool = eqx.field(static=True, default=False, converter=python_bool)
    cells: int = eqx.field(static=True, default=200, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=4, converter=python_int)

    def __check_init__(self):
        """Check the parameters, each by its own name, before the CJ state and the lengths they give.

        Raises:
            ValueError: a static choice is not one of those allowed; ``D``, ``rho0`` or ``L`` is not
                finite and > 0; ``gamma`` is not finite and > 1; ``burn_width`` is below 1; ``D`` or
                ``gamma`` is outside the range where the gamma law's CJ state is finite in the float
                dtype (``_ranges``); the gamma law's CJ state or detonation energy is not finite and
                > 0 (naming ``D``, ``gamma`` and ``rho0``); ``h = L / cells``, the burn's length or
                ``t_valid = L / D`` is not finite and > 0 (naming ``L``, ``burn_width``, ``D``).
                Tracers are not checked.
        """
        for name, value, allowed in (
            ("explosive", self.explosive, EXPLOSIVE_NAMES),
            ("products", self.products, PRODUCTS),
            ("ends", self.ends, ENDS),
            ("burn", self.burn, BURNS),
        ):
            if value not in allowed:
                raise ValueError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
        if not isinstance(self.smooth_burn, bool):
            raise ValueError(f"smooth_burn must be true or false, got {self.smooth_burn!r}")
        check_positive("D", self.D)
        check_greater("gamma", self.gamma, 1.0)
        check_positive("rho0", self.rho0)
        check_positive("L", self.L)
        _check_burn_width(self.burn_width)
        _check_gamma_law_ranges(self.D, self.gamma)
        if self.explosive != "gamma-law":
            jwl(self.explosive)  # a row whose implied CJ state misses its tabulated D is refused
        self._check_derived()

    def _check_derived(self):
        """The gamma law's CJ state and energy, the cell size, the burn's length and ``t_valid``:
        each finite and > 0 (``J_CJ < 1``) in the float dtype, or a message naming the parameters
        that give it."""
        if not all(is_concrete(v) for v in (self.D, self.gamma, self.rho0, self.L, self.burn_width)):
            return
        dtype = self.D.dtype
        if self.explosive == "gamma-law":
            _check_gamma_law_state(self.D, self.gamma, self.rho0)
        h = self.h
        width = self.burn_width * h / self.ppc
        t_valid = self.L / self.speed
        if not all(is_concrete(v) for v in (h, width, t_valid)):
            return
        if _bad(h):
            raise ValueError(
                f"L={float(self.L)!r} gives a cell size h = L / cells = {float(h)!r} in {dtype} "
                f"(cells={self.cells}); it must be finite and > 0"
            )
        if _bad(width):
            raise ValueError(
                f"burn_width={float(self.burn_width)!r} with L={float(self.L)!r} gives the burn a length "
                f"burn_width h / ppc = {float(width)!r} in {dtype}; it must be finite and > 0"
            )
        if _bad(t_valid):
            raise ValueError(
                f"L={float(self.L)!r} and the front's speed {float(self.speed)!r} (D) give t_valid = L / D = "
                f"{float(t_valid)!r} in {dtype}; it must be finite and > 0"
            )

    @property
    def h(self) -> Float[Array, ""]:
        """The grid spacing ``L / cells``."""
        return self.L / self.cells

    @property
    def left(self) -> str:
        """The lit end: ``ends``."""
        return self.ends

    def _explosive(self) -> tuple[Float[Array, ""], AbstractEOS, Float[Array, ""], dict[str, Array]]:
        return explosive_eos(self.explosive, self.products, self.D, self.gamma, self.rho0)

    def cj(self) -> dict[str, Array]:
        """The CJ state of the explosive (closed form for the gamma law, implied by the JWL EOS for a row).

        Returns:
            ``dict(D, P_CJ, J_CJ, u_CJ, c_CJ, rho_CJ, e_CJ)``.
        """
        return self._explosive()[3]

    @property
    def speed(self) -> Float[Array, ""]:
        """The front's speed: ``D`` of the gamma law, the implied CJ speed of a JWL row."""
        return self.cj()["D"]

    @property
    def t_valid(self) -> Float[Array, ""]:
        """When the front reaches the free end, ``L / D`` (the exact solution holds until then)."""
        return self.L / self.speed

    def _burn(self, products, cj) -> ProgrammedBurn:
        return ProgrammedBurn(
            reactant=None,
            products=products,
            D=cj["D"],
            points=jnp.zeros((1, 1), dtype=self.L.dtype),
            width=self.burn_width * self.h / self.ppc,
            J_CJ=cj["J_CJ"],
            burn=self.burn,
            smooth=self.smooth_burn,
        )

    def material(self):
        _, products, _, cj = self._explosive()
        return self._burn(products, cj)

    def regions(self) -> tuple[Region]:
        """One region: the explosive filling the slab, at rest, with its detonation energy.

        Returns:
            ``(explosive,)``.
        """
        rho0, products, e0, cj = self._explosive()
        return (Region(Box(0.0, float(self.cells)), self._burn(products, cj), rho0, 0.0, e0),)

    def initial_velocity(self, X):
        return jnp.zeros_like(X)

    def exact_particles(self, X: Float[ArrayLike, "*n"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact CJ-Taylor solution at reference positions ``X`` (``jaxmpm.exact_detonation``).

        Args:
            X: reference positions.
            t: time, >= 0.

        Returns:
            ``dict(x, F, u, c, p, rho)``.
        """
        if self.explosive == "gamma-law":
            return gamma_law_particles(X, t, self.rho0, self.D, self.gamma, self.ends)
        rho0, _, e0, cj = self._explosive()
        full, _ = jwl(self.explosive, check=False)
        iso = Isentrope(JWLIsentrope.from_jwl(full, e0))
        return isentrope_fan(iso, rho0, cj["D"], cj["J_CJ"], end=self.ends, cj_tol=None).particles(X, t)

    def exact(self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact solution at one material point.

        Args:
            X: reference position, of shape ``(1,)`` (as every 1D scene's).
            t: time.

        Returns:
            ``dict(x, v, F, sigma)``.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)`` (a number ``X0``: ``[X0]`` is the position).
        """
        X = check_point(X, 1)
        s = self.exact_particles(X[0], t)
        return dict(
            x=jnp.reshape(s["x"], (1,)),
            v=jnp.reshape(s["u"], (1,)),
            F=jnp.reshape(s["F"], (1, 1)),
            sigma=jnp.reshape(-s["p"], (1, 1)),
        )

    def smooth(self, X: Float[ArrayLike, " 1"], t: Float[ArrayLike, ""]) -> Bool[Array, ""]:
        """Whether a particle is burnt and farther than ``12 h`` (reference length) behind the front.

        Args:
            X: reference position, of shape ``(1,)``.
            t: time.

        Returns:
            ``True`` in the products away from the front.

        Raises:
            ValueError: ``X`` is not of shape ``(1,)``.
        """
        X = check_point(X, 1)
        return X[0] < self.speed * t - 12.0 * self.h
