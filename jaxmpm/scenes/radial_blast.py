"""Round charges of gas in 2D and 3D: a disk and a sphere expanding against the atmosphere, with a 1D
radial reference."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_positive, is_concrete, python_int
from .._util import as_float
from ..geometry import Ball
from ..materials import AdiabaticGas
from ..regions import Region
from ._base import AbstractScene


class AbstractRadialBlast(AbstractScene):
    """A round charge of gas at ``P0`` (radius ``radius``, centred at the origin) expanding into the
    atmosphere at ``p_atm``: a disk in 2D (``BlastDisk``), a sphere in 3D (``BlastSphere``).

    The gas is ``AdiabaticGas`` at rest (gauge pressure ``P0 J^-gamma - p_atm``); the atmosphere acts as
    the ambient pressure on the free surface and carries no mass, as in ``Blast``. Only the quarter
    (octant) ``X_a >= 0`` is simulated, with planes of symmetry at ``X_a = 0``; the particles are the
    lattice points of ``[0, cells h]^dim`` inside the ball. The exact motion is radial, ``x = r(R, t) X /
    R``: no rotation, a radial velocity that depends on ``R = |X|`` alone and no folded domain, which
    ``jaxmpm.metrics`` measures (``angular_spread``, ``spurious_rotation``, ``folded_domains``), and
    ``reference`` solves it in 1D (``jaxmpm.reference.gas_radial``) for the radial profiles and the
    free-surface radius.

    The defaults (SI) are a 10:1 charge: gas at 10 bar and 1.5 kg/m^3 (sound speed ``c0`` = 966 m/s) of
    radius 0.5 m in 1 bar, 32 cells across the radius. The reference's free surface reaches 3.0 radii
    in 2D by two transits ``2 radius / c0`` (4.9 radii at 100:1; 2.3 radii for the sphere at 10:1), so
    ``pad`` (cells beyond ``cells h``) must hold it: a particle that reaches the grid's edge stops the
    run.

    Attributes:
        P0: charge pressure at ``J = 1`` (Pa), > p_atm.
        gamma: adiabatic exponent.
        p_atm: atmospheric pressure (Pa), > 0.
        rho0: the charge's density.
        radius: the charge's radius (m).
        cells: cells across the radius (``h = radius / cells``; static).
        ppc: particles per cell along each axis (static).
        pad: cells of grid beyond ``cells h`` on each side (static).
    """

    right: ClassVar[str] = "free"
    left: ClassVar[str] = "symmetry"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    P0: Float[Array, ""] = eqx.field(converter=as_float, default=1.0e6)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=1.4)
    p_atm: Float[Array, ""] = eqx.field(converter=as_float, default=1.0e5)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1.5)
    radius: Float[Array, ""] = eqx.field(converter=as_float, default=0.5)
    cells: int = eqx.field(static=True, default=32, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=72, converter=python_int)

    def __check_init__(self):
        check_positive("p_atm", self.p_atm)
        check_positive("radius", self.radius)
        if is_concrete(self.P0) and is_concrete(self.p_atm) and not float(self.P0) > float(self.p_atm):
            raise ValueError(
                f"P0 must be > p_atm (the charge expands), got P0={float(self.P0)}, p_atm={float(self.p_atm)}"
            )

    @property
    def h(self) -> Float[Array, ""]:
        """The grid spacing ``radius / cells``."""
        return self.radius / self.cells

    @property
    def centre(self) -> Float[Array, " dim"]:
        """The charge's centre, the origin (the corner of the simulated quarter)."""
        return jnp.zeros(self.dim, dtype=self.h.dtype)

    @property
    def c0(self) -> Float[Array, ""]:
        """The charge's sound speed ``sqrt(gamma P0 / rho0)``."""
        return jnp.sqrt(self.gamma * self.P0 / self.rho0)

    @property
    def transit_time(self) -> Float[Array, ""]:
        """The time a sound wave takes to cross the radius, ``radius / c0``."""
        return self.radius / self.c0

    def material(self):
        return AdiabaticGas(P0=self.P0, gamma=self.gamma, p_atm=self.p_atm)

    def regions(self) -> tuple[Region]:
        """The charge: the ball of radius ``cells`` (in cells) about the origin, of gas at rest.

        Returns:
            ``(charge,)``.
        """
        ball = Ball((0.0,) * self.dim, float(self.cells))
        return (Region(ball, self.material(), self.rho0, (0.0,) * self.dim, 0.0),)

    def initial_velocity(self, X):
        return jnp.zeros_like(X)

    def reference(self, ts: Float[ArrayLike, " nt"], cells: int = 1600, viscosity: bool = True, **kwargs):
        """The 1D radial reference of this charge (``jaxmpm.reference.gas_radial``).

        With its artificial viscosity (the default) the reference converges past the shock that the
        focusing rarefaction forms (after about a transit); at 1600 cells its radial profiles of ``v``
        and ``rho`` are within about 0.1% (L1) of the converged ones, its free surface within 1e-5.

        Args:
            ts: increasing times.
            cells: the reference's radial cells.
            viscosity: the reference's artificial viscosity.
            **kwargs: passed to ``gas_radial`` (tolerances, ``max_steps``).

        Returns:
            The ``RadialSolution``.
        """
        from ..reference import gas_radial  # diffrax only where a reference is asked for

        return gas_radial(
            self.P0,
            self.gamma,
            self.p_atm,
            self.rho0,
            self.radius,
            self.dim,
            ts,
            cells=cells,
            viscosity=viscosity,
            **kwargs,
        )


class BlastDisk(AbstractRadialBlast):
    """A disk of gas expanding against the atmosphere, in 2D (``AbstractRadialBlast``)."""

    name: ClassVar[str] = "blast-disk"
    description: ClassVar[str] = (
        "2D disk of gas at P0 expanding against p_atm (quarter, symmetry planes; 1D radial reference)"
    )
    dim: ClassVar[int] = 2


class BlastSphere(AbstractRadialBlast):
    """A sphere of gas expanding against the atmosphere, in 3D (an octant; ``AbstractRadialBlast``)."""

    name: ClassVar[str] = "blast-sphere"
    description: ClassVar[str] = (
        "3D sphere of gas at P0 expanding against p_atm (octant, symmetry planes; 1D radial reference)"
    )
    dim: ClassVar[int] = 3
