"""The scene interface: geometry, material, boundary conditions and (if known) the exact solution."""

import abc
import dataclasses
import numbers
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._checks import check_int, check_positive, is_concrete
from .._util import ONE_VALUE, check_real_fields
from ..grid import Grid
from ..materials import AbstractEOS, AbstractMaterial
from ..particles import Body, seed_box
from ..regions import Layout, Region, initial_sound_speed, layout, seed_regions


def _check_particle_sizes(h, rho0, ppc, dim, region: int | None = None) -> None:
    """Refuse a cell size and density whose particle volume ``(h / ppc)^dim`` or mass overflows to
    infinity or underflows to 0 in float64 (a run of them gave NaN and infinite diagnostics with a
    healthy status). Tracers pass.

    Args:
        h, rho0, ppc, dim: the scene's cell size, a density, particles per cell and axis, dimension.
        region: the region whose density ``rho0`` is (named in the message), or ``None``.

    Raises:
        ValueError: naming ``h`` and ``rho0`` (and the region) and the volume or mass they give.
    """
    if not (is_concrete(h) and is_concrete(rho0)):
        return
    with np.errstate(over="ignore", under="ignore"):
        volume = (np.float64(h) / ppc) ** dim
        mass = np.float64(rho0) * volume
    if not (np.isfinite(mass) and mass > 0 and volume > 0):
        whose = "" if region is None else f"region {region}'s "
        raise ValueError(
            f"h={float(h):.6g} and {whose}rho0={float(rho0):.6g} give particles of volume {volume:.3g} and "
            f"mass {mass:.3g} ({ppc} per cell and axis, {dim}D), beyond float64's range: choose units in "
            "which both are finite and not 0"
        )


def check_point(X: object, dim: int) -> Array:
    """One reference position ``X`` of a scene's ``exact`` or ``smooth``: an array of shape ``(dim,)``
    (the shape is known for tracers too, so this holds under ``jax.vmap`` over particles).

    Args:
        X: the position given.
        dim: the scene's dimension.

    Returns:
        ``X`` as an array.

    Raises:
        ValueError: ``X`` is not of shape ``(dim,)`` (a number in 1D: ``[X]`` is the position; several
            positions: ``jax.vmap`` over them).
    """
    if np.shape(X) != (dim,):
        raise ValueError(
            f"X must be one reference position of shape ({dim},), got shape {np.shape(X)} "
            "(several: jax.vmap over them)"
        )
    return jnp.asarray(X)


class AbstractScene(eqx.Module):
    """A body on ``[0, cells h]^dim`` with ``ppc`` particles per cell and axis, padded by ``pad`` cells.

    Concrete scenes are final: they implement the abstract members below and nothing else.

    Continuous parameters are float array fields (differentiable, vmappable), each one number where
    the scene is built (several values are for ``jax.vmap``, whose tracers pass); ``cells``, ``ppc``
    and ``pad`` are static integers >= 1. Optional physics is declared by Python structure, not by
    flags, so that the compiled step holds only what the scene needs. Every scene declares each of
    these, ``None`` where it has no such part:

    - ``body_force``: ``None`` or a method ``(X, t) -> b`` (Lagrangian, per unit mass);
    - ``traction``: ``None`` or a method ``t -> faces`` giving one entry per face, ``(low, high)`` of
      axis 0, then of axis 1, ... (in 1D ``(left, right)``), each ``None`` or the traction vector
      per unit reference area, ``P N`` (``P`` the first Piola stress, ``N`` the outward reference
      normal; in 1D ``sigma n``), uniform over the face. Which entries are ``None`` is structure: it
      must not depend on ``t`` or on the array parameters;
    - ``exact``: ``None`` or a method ``(X, t) -> dict(x, v, F, sigma)`` for one particle;
    - ``initial_position``: ``None`` (the body starts undeformed, ``x = X``, ``F = I``) or a method
      ``X -> x`` for a body that starts deformed: centres, corners and traction points are mapped
      by it and ``F = dx/dX`` at the centres;
    - ``smooth``: ``None`` (the exact solution is smooth everywhere) or a method ``(X, t) -> bool``
      marking the particles away from fronts, where errors are expected to converge;
    - ``regions``: ``None`` (one body filling the box, of ``material()`` at ``rho0``, starting at
      ``initial_velocity``) or a method ``() -> tuple[Region, ...]`` (``jaxmpm.regions``): a body
      made of regions, each a shape with its own material, density, velocity and energy. Its
      ``layout()`` says which particle belongs to which region, from the shapes alone.

    Attributes:
        name: the name the scene is known by (``SCENES``, the command line, a saved run).
        description: one line for listings.
        dim: number of space dimensions, 1, 2 or 3 (a scene with several takes it as a static field,
            ``GasExpansion(dim=2)``; a 1D scene declares ``dim: ClassVar[int] = 1``).
        left, right: the low and high faces of every axis: ``"free"`` (artificial cells may be added
            there), ``"wall"`` (node velocity zero) or ``"symmetry"`` (a plane of symmetry, or
            roller: the normal velocity component is zero).
        h: grid spacing (the body is ``cells h`` wide along each axis).
        rho0: initial density.
        cells: cells the body fills along each axis (static).
        ppc: particles per cell along each axis (static).
        pad: cells of grid beyond the body on each side (static).
    """

    name: eqx.AbstractClassVar[str]
    description: eqx.AbstractClassVar[str]
    dim: eqx.AbstractVar[int]
    left: eqx.AbstractVar[str]
    right: eqx.AbstractVar[str]
    body_force: eqx.AbstractVar[Callable | None]
    traction: eqx.AbstractVar[Callable | None]
    exact: eqx.AbstractVar[Callable | None]
    initial_position: eqx.AbstractVar[Callable | None]
    smooth: eqx.AbstractVar[Callable | None]
    regions: eqx.AbstractVar[Callable | None]

    h: eqx.AbstractVar[Float[Array, ""]]
    rho0: eqx.AbstractVar[Float[Array, ""]]
    cells: eqx.AbstractVar[int]
    ppc: eqx.AbstractVar[int]
    pad: eqx.AbstractVar[int]

    def __post_init__(self):
        """Check what every later check relies on, on the values as given: before the converters
        (which cannot name the field) and before every ``__check_init__`` (a subclass's runs first and
        computes with the parameters).

        Raises:
            ValueError: a continuous parameter is not a real number ("beta must be a real number, got
                'abc'") or is an array with a shape (one scene is one number per parameter: several
                values are for ``jax.vmap``, whose tracers pass); ``cells``, ``ppc`` or ``pad`` is not
                an integer >= 1.
        """
        check_real_fields(self, ONE_VALUE)
        for name in ("cells", "ppc", "pad"):
            check_int(name, getattr(self, name), 1)

    def __check_init__(self):
        if (
            isinstance(self.dim, bool)
            or not isinstance(self.dim, numbers.Integral)
            or self.dim not in (1, 2, 3)
        ):
            raise ValueError(f"dim must be 1, 2 or 3, got {self.dim!r}")
        if self.regions is not None:  # laid out on the host now, before anything else is computed
            from .._memory import check_lattice  # here: _memory imports the step, which imports scenes

            check_lattice(self.cells, self.ppc, self.pad, self.dim)
        check_positive("h", self.h)
        check_positive("rho0", self.rho0)
        _check_particle_sizes(self.h, self.rho0, self.ppc, self.dim)
        self.material()  # a material checks its own parameters (gamma > 1, P0 > 0, E > 0, ...)
        if self.regions is not None:
            regions = self.regions()
            if not isinstance(regions, tuple) or not all(isinstance(r, Region) for r in regions):
                raise ValueError(
                    f"{type(self).__name__}.regions must return a tuple of Region, got {regions!r}"
                )
            for k, r in enumerate(regions):
                _check_particle_sizes(self.h, r.rho0, self.ppc, self.dim, region=k)
            self.layout()  # shapes with no particle, overlapping regions, regions off the grid

    @abc.abstractmethod
    def material(self) -> AbstractMaterial | AbstractEOS:
        """The constitutive model, built from the scene's parameters (of a scene of regions: the
        material of its first region; each region carries its own).

        Returns:
            The material.
        """

    @abc.abstractmethod
    def initial_velocity(self, X: Float[ArrayLike, " dim"]) -> Float[Array, " dim"]:
        """Velocity of the material point at reference position ``X`` at ``t = 0``.

        Args:
            X: reference position of one material point.

        Returns:
            Its velocity.
        """

    @property
    def length(self) -> Float[Array, ""]:
        """The body's width along each axis, ``cells h``."""
        return self.cells * self.h

    @property
    def wave_speed(self) -> Float[Array, ""]:
        """The material's sound speed at rest (``F = I``); of a scene of regions, the fastest region's."""
        if self.regions is None:
            return self.material().sound_speed(jnp.eye(self.dim, dtype=self.h.dtype), self.rho0)
        return jnp.max(jnp.stack([initial_sound_speed(r, self.dim) for r in self.regions()]))

    def layout(self) -> Layout | None:
        """Which particles the regions keep and where each belongs (``None`` for one region).

        Returns:
            The static ``jaxmpm.regions.Layout``, or ``None``.
        """
        if self.regions is None:
            return None
        return layout((self.cells,) * self.dim, self.ppc, tuple(r.shape for r in self.regions()), self.pad)

    def grid(self) -> Grid:
        """The background grid: ``cells + 2 pad + 1`` nodes along each axis from ``-pad h``.

        Returns:
            The ``Grid``.
        """
        if self.dim == 1:
            x_min = jnp.reshape(-self.pad * self.h, (1,))
            return Grid(x_min=x_min, h=self.h, n_nodes=self.cells + 2 * self.pad + 1)
        x_min = jnp.broadcast_to(-self.pad * self.h, (self.dim,))
        return Grid.box(x_min, self.h, (self.cells + 2 * self.pad + 1,) * self.dim)

    def body(self) -> Body:
        """The body's particles, seeded by ``particles.seed_box`` (a scene of regions: by
        ``regions.seed_regions``, on the lattice points inside its regions).

        Returns:
            The ``Body``.
        """
        if self.regions is None:
            return seed_box((self.cells,) * self.dim, self.ppc, self.h, self.rho0)
        rho0 = jnp.stack([r.rho0 for r in self.regions()])
        return seed_regions(self.layout(), self.h, rho0.astype(self.h.dtype))

    @classmethod
    def parameters(cls) -> dict[str, object]:
        """Every parameter with its default.

        Returns:
            Parameter name to default: floats for continuous ones, ints, strings and bools for
            structural ones.
        """
        out = {}
        for f in dataclasses.fields(cls):
            if isinstance(f.default, (int, float, str)):
                out[f.name] = f.default
        return out

    def parameter_values(self) -> dict[str, object]:
        """This scene's parameters as plain Python values (floats, ints, strings and bools).

        Every parameter is there, static ones included, so that ``type(scene)(**values)`` builds the
        same scene (a saved run, an ensemble and a fit rebuild it so), with one exception that changes
        nothing: ``dim`` is left out where it is 1 and its default is 1, so that a 1D run of a scene
        with a ``dim`` field reads as a run of a 1D scene (which has no ``dim`` parameter). A scene
        whose default is 2 (``axis-aligned``) keeps ``dim=1``.

        Returns:
            Parameter name to value.
        """
        defaults = self.parameters()
        return {
            k: (getattr(self, k) if isinstance(v, (int, str)) else float(getattr(self, k)))
            for k, v in defaults.items()
            if not (k == "dim" and getattr(self, k) == 1 and v == 1)
        }
