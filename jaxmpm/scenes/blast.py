"""A 2D (or 3D) blast: a charge of high-pressure gas expanding against the atmosphere."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._checks import check_positive, is_concrete, python_bool, python_int
from .._util import as_float
from ..materials import AdiabaticGas
from ._base import AbstractScene


class Blast(AbstractScene):
    """A square (cubic) charge of gas at ``P0`` expanding into the atmosphere at ``p_atm``, in a box.

    The charge is gas at rest with ``P = P0 J^-gamma - p_atm`` (gauge), ``P0 >> p_atm``. Its faces are
    free surfaces with zero gauge traction: the atmosphere acts as the ambient pressure on them, as
    in the 1D gas slab (``GasSlab``), and carries no mass. The box is the padded grid: a particle that
    reaches its edge stops the run (``pad`` makes the box). The charge expands fastest along its
    diagonals, which shears the domains near its corners: where CPDI's parallelograms, each built
    from its own ``F``, open gaps and overlaps, and MPQ's tracked corners stay common to neighbours.

    The defaults (SI) are a mild charge, 1.5 bar of gas at 1.5 kg/m^3 (sound speed 374 m/s) in a 1 m
    square against 1 bar, which every interpolator runs for 300 steps of ``dt = h / (4 c)`` with MUSL
    (``experiments/multid.py``); stronger charges break the 2D runs down at the charge's corners
    earlier than the 1D gas slab at the same pressure ratio (reported by the run's status).

    By default only the quarter (octant) ``[0, a]^dim`` of the charge ``[-a, a]^dim`` is simulated,
    with planes of symmetry at ``X_a = 0``; ``full=True`` simulates the whole charge, seeded on
    ``[0, cells h]^dim`` (centre at ``cells h / 2``), with every face free. A quarter run equals the
    matching part of a full run to round-off with SPQ, GIMP and MPQ; with CPDI it does not (its
    corners, built from a sheared ``F``, cross the plane, where a roller is not a mirror), and a full
    run keeps its total momentum at zero.

    Attributes:
        P0: charge pressure at ``J = 1`` (Pa), > p_atm.
        gamma: adiabatic exponent.
        p_atm: atmospheric pressure (Pa), > 0.
        h, rho0, cells, ppc, pad: as for every scene; ``cells h`` is the half-width ``a`` of the
            charge (or, with ``full``, its width).
        dim: 2 or 3 (1 is the gas slab) (static).
        full: simulate the whole charge instead of a quarter (static).
    """

    name: ClassVar[str] = "blast"
    description: ClassVar[str] = (
        "2D/3D blast: a gas charge at P0 expanding against p_atm (quarter, symmetry planes)"
    )
    right: ClassVar[str] = "free"
    regions: ClassVar[None] = None
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    P0: Float[Array, ""] = eqx.field(converter=as_float, default=1.5e5)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float, default=1.0e5)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 16)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.5)
    cells: int = eqx.field(static=True, default=8, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=24, converter=python_int)
    dim: int = eqx.field(static=True, default=2, converter=python_int)
    full: bool = eqx.field(static=True, default=False, converter=python_bool)

    def __check_init__(self):
        if self.dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3 for the blast (in 1D use gas-slab), got {self.dim!r}")
        if not isinstance(self.full, bool):
            raise ValueError(f"full must be True or False, got {self.full!r}")
        check_positive("p_atm", self.p_atm)
        if is_concrete(self.P0) and is_concrete(self.p_atm) and not float(self.P0) > float(self.p_atm):
            raise ValueError(
                f"P0 must be > p_atm (the charge expands), got P0={float(self.P0)}, p_atm={float(self.p_atm)}"
            )

    @property
    def left(self) -> str:
        """``"free"`` for the full charge, ``"symmetry"`` (the planes ``X_a = 0``) for a quarter."""
        return "free" if self.full else "symmetry"

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)

    def initial_velocity(self, X):
        return jnp.zeros_like(X)
