"""Gas slab against the atmosphere: the calibration scene."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._checks import check_positive, is_concrete, python_int
from .._util import as_float
from ..materials import AdiabaticGas
from ..particles import Body
from ._base import AbstractScene


class GasSlab(AbstractScene):
    """Gas at rest on ``[0, L]`` at pressure ``P0`` against the atmosphere ``p_atm < P0``.

    Wall at 0; free surface at ``L`` with zero gauge traction (the stress is gauge, ``-(P - p_atm)``,
    so the free end carries nothing). The slab expands and oscillates about
    ``F_eq = (P0 / p_atm)^(1 / gamma)``. There is no closed form: the observable is the free-surface
    trajectory ``x_R(t)`` (``free_surface``), and ``jaxmpm.reference`` gives an independent fine
    solution. The defaults are in SI: a 1 m slab of gas at 3 bar and 1 kg/m^3 in 1 bar, sound speed
    648 m/s, so a wave crosses it in 1.5 ms.

    Attributes:
        P0: initial absolute pressure (Pa), > p_atm.
        gamma: adiabatic exponent.
        p_atm: ambient pressure (Pa), > 0.
        h, rho0, cells, ppc, pad: as for every scene (``pad`` leaves room for the expansion).
    """

    name: ClassVar[str] = "gas-slab"
    description: ClassVar[str] = (
        "1D gas slab at P0 against p_atm: wall at 0, free surface at L (calibration scene)"
    )
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "wall"
    right: ClassVar[str] = "free"
    regions: ClassVar[None] = None
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    P0: Float[Array, ""] = eqx.field(converter=as_float, default=3.0e5)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float, default=1.0e5)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 32)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    cells: int = eqx.field(static=True, default=32, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=192, converter=python_int)

    def __check_init__(self):
        check_positive("p_atm", self.p_atm)
        if is_concrete(self.P0) and is_concrete(self.p_atm) and not float(self.P0) > float(self.p_atm):
            raise ValueError(
                f"P0 must be > p_atm (the slab expands), got P0={float(self.P0)}, p_atm={float(self.p_atm)}"
            )

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)

    def initial_velocity(self, X):
        return jnp.zeros_like(X)

    @property
    def F_eq(self) -> Float[Array, ""]:
        """The equilibrium stretch ``(P0 / p_atm)^(1 / gamma)``, about which the slab oscillates."""
        return (self.P0 / self.p_atm) ** (1.0 / self.gamma)

    def max_reach(self, t: float | None = None) -> float:
        """The farthest the free surface can go (by time ``t``): an upper bound from energy and speed.

        The slab's energy per unit reference length, ``W(F) = P0 F^(1 - gamma) / (gamma - 1) + p_atm
        F``, is convex in ``F``; conserved energy and Jensen's inequality give ``W(x_R / L) <= W(1)``,
        so ``x_R <= L F_max`` with ``F_max`` the larger root of ``W(F) = W(1)``. By time ``t`` the free
        surface has also moved at most ``2 c0 t / (gamma - 1)``, the escape speed of a gas expanding
        into vacuum. The exact solution stays below both (the reference's first maximum is 4.10 m
        for the defaults, the bound 4.32 m); a dissipative numerical solution too. Needs concrete
        parameters (not traced).

        Args:
            t: a time (``None``: for all time).

        Returns:
            ``min(L F_max, L + 2 c0 t / (gamma - 1))``, in the units of ``h``.
        """
        P0, g, pa = float(self.P0), float(self.gamma), float(self.p_atm)
        L = float(self.length)
        reach = L * _root_above_equilibrium(P0, g, pa)
        if t is not None:
            c0 = float(np.sqrt(g * P0 / float(self.rho0)))
            reach = min(reach, L + 2.0 * c0 * float(t) / (g - 1.0))
        return reach

    def turnaround_estimate(self) -> float:
        """When the free surface first stops: the time a uniformly stretching slab takes to reach ``F_max``.

        With the velocity linear in ``X`` (``v = X dF/dt``) the slab is one oscillator,
        ``rho0 L^2 / 3 d^2F/dt^2 = P0 F^-gamma - p_atm``; its time from ``F = 1`` to ``F_max`` (a
        quadrature) estimates the first turnaround of ``x_R``. The estimate is about 10% early (7.5 ms
        against the reference's 8.4 ms for the defaults): a guide for how long to observe, not a result.
        Needs concrete parameters.

        Returns:
            The time, in the scene's units.
        """
        P0, g, pa, rho0 = float(self.P0), float(self.gamma), float(self.p_atm), float(self.rho0)
        L = float(self.length)
        F_max = _root_above_equilibrium(P0, g, pa)

        def W(F):
            return P0 / (g - 1.0) * F ** (1.0 - g) + pa * F if g != 1.0 else -P0 * np.log(F) + pa * F

        # F = 1 + (F_max - 1) sin^2(phi) takes the inverse-square-root ends of the integrand away
        phi = np.linspace(0.0, np.pi / 2, 4001)[1:-1]
        F = 1.0 + (F_max - 1.0) * np.sin(phi) ** 2
        dF = (F_max - 1.0) * np.sin(2.0 * phi)
        speed = np.sqrt(np.maximum(6.0 / (rho0 * L * L) * (W(1.0) - W(F)), np.finfo(float).tiny))
        y = dF / speed
        return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(phi)))


def _root_above_equilibrium(P0: float, gamma: float, p_atm: float) -> float:
    """The stretch ``F > F_eq`` at which ``W(F) = W(1)`` (``W`` as in ``GasSlab.max_reach``)."""

    def excess(F):  # W(F) - W(1)
        if gamma == 1.0:
            return -P0 * np.log(F) + p_atm * (F - 1.0)
        return P0 / (gamma - 1.0) * (F ** (1.0 - gamma) - 1.0) + p_atm * (F - 1.0)

    lo = (P0 / p_atm) ** (1.0 / gamma)  # the minimum of W: excess < 0 there
    hi = 2.0 * lo
    while excess(hi) < 0.0:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if excess(mid) < 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return hi


def pad_for(scene: GasSlab, x_max: float, margin: int = 4) -> int:
    """The ``pad`` whose grid holds a free surface at ``x_max``, with ``margin`` cells to spare.

    Args:
        scene: the gas slab (its ``h`` and length).
        x_max: the farthest position the grid must hold.
        margin: cells beyond ``x_max`` (the widest stencil, CPDI's or GIMP's, needs 2).

    Returns:
        The smallest such ``pad`` (at least 1).
    """
    h, L = float(scene.h), float(scene.length)
    return max(1, int(np.ceil((float(x_max) - L) / h - 1e-9)) + int(margin))


def free_surface(
    x: Float[Array, "*batch n 1"],
    F: Float[Array, "*batch n 1 1"],
    corners: Float[Array, "*batch nc 1"] | None,
    body: Body,
) -> Float[Array, "*batch"]:
    """The free-surface position: the last particle's right domain edge (its tracked corner under MPQ).

    Args:
        x: particle centres, with any leading axes (a saved history, an ensemble).
        F: deformation gradients, with the same leading axes.
        corners: MPQ's tracked corners, with the same leading axes, or ``None`` (not tracked).
        body: the reference configuration.

    Returns:
        ``x_R``, with the leading axes of ``x``.
    """
    if corners is not None:
        return corners[..., body.corner_ids[-1, 1], 0]
    return x[..., -1, 0] + F[..., -1, 0, 0] * body.r0[-1, 0]
