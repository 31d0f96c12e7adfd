"""Gas slab against the atmosphere: the calibration scene."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._checks import check_positive, is_concrete
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
    cells: int = eqx.field(static=True, default=32)
    ppc: int = eqx.field(static=True, default=2)
    pad: int = eqx.field(static=True, default=192)

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
