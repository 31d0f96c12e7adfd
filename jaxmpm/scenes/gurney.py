"""An explosive driving metal: the open-faced sandwich of Gurney's formula in 1D, and the cylinder in 2D."""

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_finite, check_greater, check_positive, python_bool, python_int
from .._util import as_float, static_fraction
from ..explosives import BURNS, EXPLOSIVES, JWL, JWLIsentrope, ProgrammedBurn, cj_energy, cj_state
from ..geometry import Ball, Box
from ..materials import MIE_GRUNEISEN, STRENGTH, ElasticPlastic, MieGruneisen
from ..particles import Body, State
from ..regions import Region
from ._base import AbstractScene
from .detonation import (
    EXPLOSIVE_NAMES,
    PRODUCTS,
    _check_burn_width,
    _check_gamma_law_ranges,
    _check_gamma_law_state,
    explosive_eos,
)
from .shock_tube import check_split, seeded_split


def gurney_sandwich(sqrt_2E: Float[ArrayLike, ""], M_over_C: Float[ArrayLike, ""]) -> Float[Array, ""]:
    """The plate's terminal velocity of an open-faced sandwich (a charge with one plate, the other face
    free), by Gurney's energy balance with a linear velocity profile in the products (Kennedy, "The
    Gurney model of explosive output for driving metal", in Zukas & Walters, "Explosive effects and
    applications", 1998):

        ``V = sqrt(2E) ((1 + 2 M/C)^3 + 1) / (6 (1 + M/C)) + M/C)^(-1/2)``.

    Args:
        sqrt_2E: the explosive's Gurney velocity ``sqrt(2E)``.
        M_over_C: the plate's mass over the charge's, per unit area.

    Returns:
        ``V``.
    """
    sqrt_2E, r = jnp.asarray(sqrt_2E), jnp.asarray(M_over_C)
    return sqrt_2E / jnp.sqrt(((1.0 + 2.0 * r) ** 3 + 1.0) / (6.0 * (1.0 + r)) + r)


def gurney_cylinder(sqrt_2E: Float[ArrayLike, ""], M_over_C: Float[ArrayLike, ""]) -> Float[Array, ""]:
    """The terminal velocity of a metal cylinder driven by the explosive it holds, by Gurney's energy
    balance (Kennedy, as for ``gurney_sandwich``):

        ``V = sqrt(2E) (M/C + 1/2)^(-1/2)``.

    Args:
        sqrt_2E: the explosive's Gurney velocity ``sqrt(2E)``.
        M_over_C: the cylinder's mass over the charge's, per unit length.

    Returns:
        ``V``.
    """
    return jnp.asarray(sqrt_2E) / jnp.sqrt(jnp.asarray(M_over_C) + 0.5)


GURNEY_VELOCITIES: dict[str, float] = {"compb": 2700.0, "tnt": 2440.0, "petn": 2930.0, "pbx9404": 2900.0}
"""The Gurney velocities ``sqrt(2E)`` (m/s) of the JWL rows of ``jaxmpm.explosives.EXPLOSIVES``: R. R.
Kennedy's (1970), as tabulated by P. W. Cooper, "Explosives Engineering" (1996): Comp B 2.70 mm/us at
1.717 g/cm^3, TNT 2.44 at 1.63, PETN 2.93 at 1.76 and PBX-9404 2.90 at 1.84. The Gurney scenes take
their ``sqrt_2E`` from here when it is not given."""

GURNEY_EXPLOSIVES = EXPLOSIVE_NAMES + ("jwl",)
"""The Gurney scenes' ``explosive`` choices: ``Detonation``'s, and ``"jwl"`` of the scene's own constants."""


def _fraction(x: object) -> float:
    """``split`` as a Python float (a static parameter: it fixes which particles are the charge's)."""
    return static_fraction(x, "split")


class AbstractGurney(AbstractScene):
    """A charge of explosive driving metal: the explosive's and the metal's parameters, shared by
    ``GurneySlab`` and ``GurneyCylinder``.

    The explosive is a ``jaxmpm.explosives.ProgrammedBurn`` with the products of ``Detonation``
    (``explosive``, ``products``, ``D``, ``gamma``, ``rho0``, ``burn``), lit at the origin; or, with
    ``explosive="jwl"``, a JWL of the scene's own constants ``A, B, R1, R2, w`` (SI; Comp B's by
    default) at density ``rho0``, whose detonation energy ``E0`` is not given but implied by the
    detonation speed ``D`` (``jaxmpm.explosives.cj_energy``: the EOS's CJ state has speed ``D``), so
    that a fit of the JWL constants to the metal's velocity keeps the EOS consistent with the measured
    ``D``. The metal is ``MieGruneisen`` of ``MIE_GRUNEISEN[metal]``, at rest at its reference density.

    Attributes:
        sqrt_2E: the explosive's Gurney velocity (m/s), for ``gurney_velocity``. Not given (NaN, the
            default), a JWL row's is ``GURNEY_VELOCITIES[explosive]`` (TNT's 2440 m/s, say), and that
            of ``"gamma-law"`` and ``"jwl"`` is Comp B's 2700 m/s, as their default constants are
            Comp B's: give it where they are another explosive's.
        D, gamma, rho0: the gamma-law products (with ``explosive="gamma-law"``; ``D`` and ``rho0`` also
            with ``"jwl"``).
        A, B, R1, R2, w: the JWL constants (with ``explosive="jwl"``; Pa for ``A`` and ``B``): ``A``
            and ``B`` finite, ``R1``, ``R2`` and ``w`` > 0, checked whichever explosive runs.
        burn_width: the burn's length in particle sizes, >= 1.
        explosive: as for ``Detonation``, or ``"jwl"`` (static).
        products, burn: as for ``Detonation`` (static).
        metal: a key of ``MIE_GRUNEISEN`` (static).
        strength: the metal's elastic-perfectly-plastic deviatoric stress (``ElasticPlastic`` of
            ``STRENGTH[metal]``; static). Without it the metal is hydrodynamic, as Gurney's formula
            assumes.
    """

    sqrt_2E: Float[Array, ""] = eqx.field(converter=as_float, default=math.nan)
    D: Float[Array, ""] = eqx.field(converter=as_float, default=7980.0)
    gamma: Float[Array, ""] = eqx.field(converter=as_float, default=3.0)
    rho0: Float[Array, ""] = eqx.field(converter=as_float, default=1717.0)
    burn_width: Float[Array, ""] = eqx.field(converter=as_float, default=1.5)
    A: Float[Array, ""] = eqx.field(converter=as_float, default=EXPLOSIVES["compb"]["A"])
    B: Float[Array, ""] = eqx.field(converter=as_float, default=EXPLOSIVES["compb"]["B"])
    R1: Float[Array, ""] = eqx.field(converter=as_float, default=EXPLOSIVES["compb"]["R1"])
    R2: Float[Array, ""] = eqx.field(converter=as_float, default=EXPLOSIVES["compb"]["R2"])
    w: Float[Array, ""] = eqx.field(converter=as_float, default=EXPLOSIVES["compb"]["w"])
    explosive: str = eqx.field(static=True, default="compb")
    products: str = eqx.field(static=True, default="full")
    burn: str = eqx.field(static=True, default="time")
    metal: str = eqx.field(static=True, default="steel-4340")
    strength: bool = eqx.field(static=True, default=False, converter=python_bool)

    def __post_init__(self):
        """The scene's checks of the values as given (``AbstractScene.__post_init__``), then the Gurney
        velocity of the explosive where ``sqrt_2E`` is not given (NaN): ``GURNEY_VELOCITIES`` of a JWL
        row, Comp B's for ``"gamma-law"`` and ``"jwl"`` (and for an unknown ``explosive``, which
        ``__check_init__`` refuses).
        """
        super().__post_init__()
        if isinstance(self.sqrt_2E, float) and math.isnan(self.sqrt_2E):
            known = isinstance(self.explosive, str) and self.explosive in GURNEY_VELOCITIES
            self.sqrt_2E = GURNEY_VELOCITIES[self.explosive if known else "compb"]

    def __check_init__(self):
        """Check the explosive's and the metal's parameters, each by its own name.

        Raises:
            ValueError: a static choice is not one of those allowed; ``sqrt_2E`` or ``D`` is not finite
                and > 0; ``gamma`` is not finite and > 1; ``rho0`` is not finite and > 0; ``D`` or
                ``gamma`` is outside the range where the gamma law's CJ state is finite in the float
                dtype, or (``explosive="gamma-law"``) that CJ state or detonation energy is not
                finite and > 0, as ``Detonation`` checks them; ``burn_width`` is below 1; ``A`` or
                ``B`` is not finite, or ``R1``, ``R2`` or ``w`` not finite and > 0 (whichever explosive
                runs). Tracers are not checked.
        """
        if not isinstance(self.strength, bool):
            raise ValueError(f"strength must be true or false, got {self.strength!r}")
        for name, value, allowed in (
            ("explosive", self.explosive, GURNEY_EXPLOSIVES),
            ("products", self.products, PRODUCTS),
            ("burn", self.burn, BURNS),
            ("metal", self.metal, tuple(MIE_GRUNEISEN)),
        ):
            if value not in allowed:
                raise ValueError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
        check_positive("sqrt_2E", self.sqrt_2E)
        check_positive("D", self.D)
        check_greater("gamma", self.gamma, 1.0)
        check_positive("rho0", self.rho0)
        _check_gamma_law_ranges(self.D, self.gamma)
        if self.explosive == "gamma-law":
            _check_gamma_law_state(self.D, self.gamma, self.rho0)
        _check_burn_width(self.burn_width)
        # The JWL constants are checked whichever explosive runs (as JWL checks them: A and B finite,
        # R1, R2 and w > 0): a bad value is refused, not kept in the run's parameters unused.
        check_finite("A", self.A)
        check_finite("B", self.B)
        check_positive("R1", self.R1)
        check_positive("R2", self.R2)
        check_positive("w", self.w)

    def _metal(self) -> tuple[MieGruneisen | ElasticPlastic, Float[Array, ""]]:
        row = MIE_GRUNEISEN[self.metal]
        eos = MieGruneisen(**row)
        metal = ElasticPlastic(eos, **STRENGTH[self.metal]) if self.strength else eos
        return metal, jnp.asarray(row["rho_ref"], dtype=self.h.dtype)

    def _explosive(self):
        if self.explosive == "jwl":
            full = JWL(self.rho0, self.A, self.B, self.R1, self.R2, self.w)
            e0 = cj_energy(full, self.rho0, self.D)
            cj = cj_state(full, self.rho0, e0)
            products = JWLIsentrope.from_jwl(full, e0) if self.products == "isentrope" else full
            rho0 = self.rho0
        else:
            rho0, products, e0, cj = explosive_eos(
                self.explosive, self.products, self.D, self.gamma, self.rho0
            )
        burn = ProgrammedBurn(
            reactant=None,
            products=products,
            D=cj["D"],
            points=jnp.zeros((1, self.dim), dtype=self.h.dtype),
            width=self.burn_width * self.h / self.ppc,
            J_CJ=cj["J_CJ"],
            burn=self.burn,
        )
        return burn, rho0, e0, cj

    def cj(self) -> dict[str, Array]:
        """The explosive's CJ state (``Detonation.cj``).

        Returns:
            ``dict(D, P_CJ, J_CJ, u_CJ, c_CJ, rho_CJ, e_CJ)``.
        """
        return self._explosive()[3]

    def material(self):
        return self._explosive()[0]

    def initial_velocity(self, X):
        return jnp.zeros_like(X)

    def charge_density(self) -> Float[Array, ""]:
        """The explosive's density (``rho0``, or the JWL row's).

        Returns:
            ``rho0`` of the charge.
        """
        return self._explosive()[1]

    def metal_density(self) -> Float[Array, ""]:
        """The metal's reference density.

        Returns:
            ``rho_ref`` of ``MIE_GRUNEISEN[metal]``.
        """
        return self._metal()[1]


class GurneySlab(AbstractGurney):
    """A slab of explosive lit at its free back face ``X = 0``, driving a metal plate on its far face.

    The setup of Uintah's MPM Gurney input: explosive on ``[0, charge]``, ``charge = split L`` (where
    the split falls on a particle domain's edge; ``split``), then ``plate`` of metal on ``[charge,
    L]``. Both ends are free.
    The products push the plate, which rings and tends to a terminal velocity; Gurney's formula for an
    open-faced sandwich, ``gurney_velocity``, estimates it from the explosive's Gurney constant
    ``sqrt_2E`` and the mass ratio (a model accurate to a few per cent). For Comp B (``sqrt(2E) = 2.70``
    km/s) on 4 cm, driving 1 cm of 4340 steel, ``M/C = 1.137`` and ``V = 1358`` m/s.

    ``plate_velocity(state, body)`` is the plate's mean (momentum over mass) velocity. The products
    escape from the free back face at several km/s: ``pad`` (cells of grid beyond the body on each
    side) must hold them until the end of the run.

    Attributes:
        L: charge and plate together (m).
        split: the charge's share of ``L`` (static, in ``(0, 1)``; a particle centre at the split is
            the charge's; given inside a particle's domain, the charge ends at the domain's far edge,
            and ``charge``, ``plate`` and ``mass_ratio`` are those of the body seeded).
        cells: cells across charge and plate together (``h = L / cells``; static).
        ppc, pad: as for every scene.
        sqrt_2E, D, gamma, rho0, A, B, R1, R2, w, burn_width, explosive, products, burn, metal, strength:
            as for ``AbstractGurney``.
    """

    name: ClassVar[str] = "gurney-slab"
    description: ClassVar[str] = (
        "1D open-faced sandwich: a charge lit at its free face drives a metal plate (Gurney: 1358 m/s)"
    )
    dim: ClassVar[int] = 1
    left: ClassVar[str] = "free"
    right: ClassVar[str] = "free"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    L: Float[Array, ""] = eqx.field(converter=as_float, default=0.05)
    split: float = eqx.field(static=True, converter=_fraction, default=0.8)
    cells: int = eqx.field(static=True, default=200, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=800, converter=python_int)

    def __check_init__(self):
        check_positive("L", self.L)
        if not 0.0 < self.split < 1.0:
            raise ValueError(f"split must be a fraction of L in (0, 1), got {self.split!r}")
        check_split("split", self.split, self.cells, self.ppc)

    @property
    def h(self) -> Float[Array, ""]:
        """The grid spacing ``L / cells``."""
        return self.L / self.cells

    @property
    def charge(self) -> Float[Array, ""]:
        """The seeded charge's thickness, ``split L`` where ``split`` falls on a particle domain's
        edge, else to the edge after the last particle at or before it (``seeded_split``)."""
        return seeded_split(self.split, self.cells, self.ppc) * self.L

    @property
    def plate(self) -> Float[Array, ""]:
        """The seeded plate's thickness, ``L`` less the charge's (``(1 - split) L`` on an edge)."""
        return (1.0 - seeded_split(self.split, self.cells, self.ppc)) * self.L

    def regions(self) -> tuple[Region, Region]:
        """The charge (lit at ``X = 0``, with its detonation energy) and the plate, both at rest.

        Returns:
            ``(charge, plate)``.
        """
        burn, rho0, e0, _ = self._explosive()
        metal, rho_metal = self._metal()
        k = self.split * self.cells
        charge = Box(0.0, k)
        return (
            Region(charge, burn, rho0, 0.0, e0),
            Region(Box(k, float(self.cells)) - charge, metal, rho_metal, 0.0, 0.0),
        )

    @property
    def mass_ratio(self) -> Float[Array, ""]:
        """``M / C``: the plate's mass per unit area over the charge's."""
        return self.metal_density() * self.plate / (self.charge_density() * self.charge)

    def gurney_velocity(self) -> Float[Array, ""]:
        """Gurney's terminal plate velocity of this sandwich (``gurney_sandwich``).

        Returns:
            ``V`` (m/s).
        """
        return gurney_sandwich(self.sqrt_2E, self.mass_ratio)

    def plate_velocity(self, state: State, body: Body) -> Float[Array, ""]:
        """The plate's velocity: its momentum over its mass.

        Args:
            state: the state.
            body: the reference configuration (``body.region`` 1 is the plate).

        Returns:
            ``sum m v / sum m`` over the plate's particles.
        """
        w = jnp.where(body.region == 1, body.m, 0.0)
        return jnp.sum(w * state.v[:, 0]) / jnp.sum(w)


class GurneyCylinder(AbstractGurney):
    """A cylinder of explosive lit on its axis, driving the metal tube around it: a cross-section in 2D.

    A disk of explosive of radius ``radius`` (``AbstractGurney``) fills a metal ring of thickness
    ``thickness``, both centred at the origin and at rest; the detonation spreads from the centre.
    Only the quarter ``X_a >= 0`` is simulated, with planes of symmetry at ``X_a = 0``; the ring's
    outer surface is free. The products drive the ring outwards; Gurney's formula for a cylinder,
    ``gurney_velocity``, estimates the velocity it tends to. For Comp B (``sqrt(2E) = 2.70`` km/s) of
    radius 4 cm in a 4340 steel tube 4-5 cm, ``M/C = 2.559`` and ``V = 1544`` m/s.

    ``ring_velocity(state, body)`` is the ring's radial velocity (radial momentum over mass), and
    ``ring_radius`` its mean radius. The ring reaches twice its radius at about 40 us: ``pad`` must hold
    it.

    Attributes:
        R: the ring's outer radius (m).
        split: the charge's radius over ``R`` (static, in ``(0, 1)``; a particle centre at the split is
            the charge's).
        cells: cells across charge and ring together (``h = R / cells``; static).
        ppc: particles per cell along each axis (static).
        pad: cells of grid beyond ``cells h`` on each side (static).
        sqrt_2E, D, gamma, rho0, A, B, R1, R2, w, burn_width, explosive, products, burn, metal, strength:
            as for ``AbstractGurney``.
    """

    name: ClassVar[str] = "gurney-cylinder"
    description: ClassVar[str] = (
        "2D cross-section: a charge lit on its axis drives a metal tube (quarter; Gurney: 1544 m/s)"
    )
    dim: ClassVar[int] = 2
    left: ClassVar[str] = "symmetry"
    right: ClassVar[str] = "free"
    body_force: ClassVar[None] = None
    traction: ClassVar[None] = None
    exact: ClassVar[None] = None
    initial_position: ClassVar[None] = None
    smooth: ClassVar[None] = None

    R: Float[Array, ""] = eqx.field(converter=as_float, default=0.05)
    split: float = eqx.field(static=True, converter=_fraction, default=0.8)
    cells: int = eqx.field(static=True, default=20, converter=python_int)
    ppc: int = eqx.field(static=True, default=2, converter=python_int)
    pad: int = eqx.field(static=True, default=24, converter=python_int)

    def __check_init__(self):
        check_positive("R", self.R)
        if not 0.0 < self.split < 1.0:
            raise ValueError(f"split must be a fraction of R in (0, 1), got {self.split!r}")
        k = self.split * self.cells
        if not 1.0 <= k <= self.cells - 1.0:
            raise ValueError(
                f"the charge and the ring must each be at least a cell across: split * cells = {k:.6g} "
                f"of cells = {self.cells} (raise cells)"
            )

    @property
    def h(self) -> Float[Array, ""]:
        """The grid spacing ``R / cells``."""
        return self.R / self.cells

    @property
    def radius(self) -> Float[Array, ""]:
        """The charge's radius, ``split R``."""
        return self.split * self.R

    @property
    def thickness(self) -> Float[Array, ""]:
        """The ring's thickness, ``(1 - split) R``."""
        return (1.0 - self.split) * self.R

    def regions(self) -> tuple[Region, Region]:
        """The charge (lit at the centre, with its detonation energy) and the ring, both at rest.

        Returns:
            ``(charge, ring)``.
        """
        burn, rho0, e0, _ = self._explosive()
        metal, rho_metal = self._metal()
        k = self.split * self.cells
        zero = (0.0, 0.0)
        charge = Ball(zero, k)
        return (
            Region(charge, burn, rho0, zero, e0),
            Region(Ball(zero, float(self.cells)) - charge, metal, rho_metal, zero, 0.0),
        )

    @property
    def mass_ratio(self) -> Float[Array, ""]:
        """``M / C``: the ring's mass per unit length over the charge's."""
        ring = 1.0 - self.split**2
        return self.metal_density() * ring / (self.charge_density() * self.split**2)

    def gurney_velocity(self) -> Float[Array, ""]:
        """Gurney's terminal velocity of this cylinder (``gurney_cylinder``).

        Returns:
            ``V`` (m/s).
        """
        return gurney_cylinder(self.sqrt_2E, self.mass_ratio)

    def ring_velocity(self, state: State, body: Body) -> Float[Array, ""]:
        """The ring's radial velocity: its radial momentum over its mass.

        Args:
            state: the state.
            body: the reference configuration (``body.region`` 1 is the ring).

        Returns:
            ``sum m (v . x / |x|) / sum m`` over the ring's particles.
        """
        w = jnp.where(body.region == 1, body.m, 0.0)
        v_r = jnp.sum(state.v * state.x, axis=-1) / jnp.linalg.norm(state.x, axis=-1)
        return jnp.sum(w * v_r) / jnp.sum(w)

    def ring_radius(self, state: State, body: Body) -> Float[Array, ""]:
        """The ring's mean radius (mass-weighted), to follow its expansion.

        Args:
            state: the state.
            body: the reference configuration.

        Returns:
            ``sum m |x| / sum m`` over the ring's particles.
        """
        w = jnp.where(body.region == 1, body.m, 0.0)
        return jnp.sum(w * jnp.linalg.norm(state.x, axis=-1)) / jnp.sum(w)
