"""Sod's shock tube and other Riemann problems of the Euler equations, with the exact solution."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_finite, check_positive, is_concrete, python_int
from .._util import as_float, static_fraction
from ..exact_euler import riemann_solution, riemann_waves, vacuum_generated
from ..geometry import AbstractShape, Box
from ..materials import IdealGas
from ..regions import Region
from ._base import AbstractScene


def check_split(name: str, fraction: float, cells: int, ppc: int) -> None:
    """Check that a tube of ``cells`` cells split at ``fraction`` of its length leaves a particle on each
    side (the centres lie at ``(i + 1/2) / ppc`` cells; one on the split belongs to the left side).

    Args:
        name: the parameter's name, for the message.
        fraction: where the tube splits, a fraction of its length in ``(0, 1)``.
        cells: the tube's cells.
        ppc: particles per cell.

    Raises:
        ValueError: a side would hold no particle (naming ``name``, the split in cells and the range
            that leaves both sides one).
    """
    cut = fraction * cells
    first, last = 0.5 / ppc, (cells * ppc - 0.5) / ppc
    if not first <= cut < last:
        side = "left" if cut < first else "right"
        raise ValueError(
            f"{name} = {fraction!r} leaves the {side} side without a particle: it splits the {cells} cells "
            f"at {cut:.6g} cells, and a particle on each side needs a split in [{first:.6g}, {last:.6g}) "
            f"cells (the particle centres of ppc = {ppc}; move {name} or raise cells)"
        )


def seeded_split(fraction: float, cells: int, ppc: int) -> float:
    """Where the two sides of a tube split at ``fraction`` of its length meet once seeded: at the edge
    of the last particle domain on the left side (the particles whose centres lie at or before the
    split, as ``split_tube`` assigns them), a fraction of the length. A split on a domain edge
    (``fraction cells ppc`` whole) is that same fraction; one inside a domain moves to the edge after
    the particle, whose whole mass the left side holds.

    Args:
        fraction: where the tube splits, a fraction of its length in ``(0, 1)``.
        cells: the tube's cells.
        ppc: particles per cell.

    Returns:
        ``n / (cells ppc)``, ``n`` the particles on the left side.
    """
    centres = (np.arange(cells * ppc) + 0.5) / ppc  # in cells, as the regions' shapes test them
    n = int(np.count_nonzero(centres <= fraction * cells))
    return n / (cells * ppc)


def split_tube(cells: int, x0: float) -> tuple[AbstractShape, AbstractShape]:
    """The two regions of a tube of ``cells`` cells split at the fraction ``x0`` of its length.

    The left region is ``[0, x0 cells]`` and the right ``[x0 cells, cells]``, in cells; a particle
    centre exactly on the split belongs to the left one.

    Args:
        cells: the tube's cells.
        x0: where it splits, a fraction of its length in ``(0, 1)``.

    Returns:
        ``(left, right)`` shapes.
    """
    cut = x0 * cells
    left = Box(0.0, cut)
    return left, Box(cut, float(cells)) - left


class ShockTube(AbstractScene):
    """Two ideal gases, ``(rho_l, u_l, p_l)`` and ``(rho_r, u_r, p_r)``, at ``x0 L``; walls at the ends.

    The gas carries internal energy (``jaxmpm.IdealGas``, ``e = p / ((gamma - 1) rho)``): a shock
    is a shock of the Euler equations, its jump fixed by the Rankine-Hugoniot conditions, and
    ``exact_euler`` gives the solution until the first wave reaches a wall (``t_valid``; for gas at
    rest at the walls: moving gas there is stopped at once, a wave the solution leaves out). MPM
    rings behind a shock; ``simulate(..., viscosity=jm.ArtificialViscosity())`` damps it and heats
    the gas.

    The defaults are Sod's problem (Sod 1978; Toro, "Riemann Solvers and Numerical Methods for Fluid
    Dynamics", Table 4.1, Test 1) on ``[0, 1]``: star state ``p* = 0.30313``, ``u* = 0.92745``,
    ``rho*_L = 0.42632``, ``rho*_R = 0.26557`` (Toro, Table 4.3), usually compared at ``t = 0.2``.

    Attributes:
        rho_l, u_l, p_l: the left state (density > 0, velocity, pressure > 0: ``p = 0`` is a vacuum,
            which the exact solver does not cover).
        rho_r, u_r, p_r: the right state.
        gamma: ratio of specific heats of both gases, > 1.
        x0: where the states meet, as a fraction of the tube's length ``L = cells h`` (static, in
            ``(0, 1)``; the regions are fixed by it and by ``cells``). A particle centre on it is the
            left state's; given inside a particle's domain, the states meet at the domain's far edge,
            and ``X0`` (the exact solution's) is there.
        h, cells, ppc, pad: as for every scene (``L = cells h``; the default ``h`` makes ``L = 1``).
    """

    name: ClassVar[str] = "shock-tube"
    description: ClassVar[str] = (
        "1D Euler shock tube (Sod by default): two ideal gases, energy equation, exact Riemann solution"
    )
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "wall"
    right: ClassVar[str] = "wall"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    rho_l: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    u_l: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    p_l: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    rho_r: Float[Array, ""] = eqx.field(converter=as_float, default=0.125)
    u_r: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    p_r: Float[Array, ""] = eqx.field(converter=as_float, default=0.1)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    x0: float = eqx.field(static=True, converter=static_fraction, default=0.5)
    h: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 400)
    cells: int = eqx.field(static=True, default=400, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=4, converter=python_int)

    def __check_init__(self):
        check_positive("rho_l", self.rho_l)
        check_positive("rho_r", self.rho_r)
        check_positive("p_l", self.p_l)
        check_positive("p_r", self.p_r)
        check_finite("u_l", self.u_l)
        check_finite("u_r", self.u_r)
        if not isinstance(self.x0, (int, float)) or not 0.0 < float(self.x0) < 1.0:
            raise ValueError(f"x0 must be a fraction of the tube's length in (0, 1), got {self.x0!r}")
        check_split("x0", self.x0, self.cells, self.ppc)
        args = self.states()
        if all(is_concrete(a) for a in args) and bool(vacuum_generated(*args)):
            raise ValueError(
                "the states generate a vacuum (u_r - u_l >= 2 (c_l + c_r) / (gamma - 1)); the exact "
                f"solver does not cover it, got u_l={float(self.u_l)}, u_r={float(self.u_r)}"
            )

    def states(self) -> tuple[Float[Array, ""], ...]:
        """The data in ``exact_euler``'s order.

        Returns:
            ``(rho_l, u_l, p_l, rho_r, u_r, p_r, gamma)``.
        """
        return (self.rho_l, self.u_l, self.p_l, self.rho_r, self.u_r, self.p_r, self.gamma)

    @property
    def rho0(self) -> Float[Array, ""]:
        """The left gas's density (each region carries its own, ``regions()``)."""
        return self.rho_l

    @property
    def X0(self) -> Float[Array, ""]:
        """Where the seeded states meet: ``x0 L`` where ``x0`` falls on a particle domain's edge, else
        the edge after the last particle at or before it (``seeded_split``)."""
        return seeded_split(self.x0, self.cells, self.ppc) * self.length

    def material(self):
        return IdealGas(gamma=self.gamma)

    def regions(self) -> tuple[Region, Region]:
        """The left and right gas, split at ``x0`` (in cells, ``split_tube``).

        Returns:
            ``(left, right)``.
        """
        left, right = split_tube(self.cells, self.x0)
        gas = IdealGas(gamma=self.gamma)
        return (
            Region(left, gas, self.rho_l, self.u_l, self.p_l / ((self.gamma - 1.0) * self.rho_l)),
            Region(right, gas, self.rho_r, self.u_r, self.p_r / ((self.gamma - 1.0) * self.rho_r)),
        )

    def initial_velocity(self, X):
        return jnp.where(X < self.X0, self.u_l, self.u_r) * jnp.ones_like(X)

    def waves(self) -> dict[str, Array]:
        """Star state and wave speeds (``exact_euler.riemann_waves``).

        Returns:
            Its dict.
        """
        return riemann_waves(*self.states())

    @property
    def t_valid(self) -> Float[Array, ""]:
        """When the first wave reaches a wall (the exact solution of the open tube holds until then);
        0 where the gas moves at a wall (``u_l`` or ``u_r`` not 0): the wall stops it at once, and
        the wave that starts there is not in the open tube's solution."""
        w = self.waves()
        first = jnp.minimum(self.X0 / -w["head_l"], (self.length - self.X0) / w["head_r"])
        return jnp.where((self.u_l == 0.0) & (self.u_r == 0.0), first, 0.0)

    def solution(self, x: Float[ArrayLike, "*shape"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact solution at Eulerian positions ``x`` (``exact_euler.riemann_solution``).

        Args:
            x: positions.
            t: time, > 0.

        Returns:
            ``dict(rho, u, p, e)``.
        """
        return riemann_solution(x, t, *self.states(), x0=self.X0)
