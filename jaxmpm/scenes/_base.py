"""The scene interface: geometry, material, boundary conditions and (if known) the exact solution."""

import abc
import dataclasses
from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._checks import check_int, check_positive
from ..grid import Grid
from ..materials import AbstractMaterial
from ..particles import Body, seed_bar


class AbstractScene(eqx.Module):
    """A 1D body on ``[0, cells h]`` with ``ppc`` particles per cell, padded by ``pad`` cells.

    Continuous parameters are float array fields (differentiable, vmappable); ``cells``, ``ppc`` and
    ``pad`` are static. Optional physics is declared by Python structure, not by flags, so that the
    compiled step holds only what the scene needs:

    - ``body_force`` is ``None`` or a method ``(X, t) -> b`` (Lagrangian, per unit mass);
    - ``traction(t)`` returns ``(left, right)``, each ``None`` or the traction vector ``sigma n``;
    - ``left`` and ``right`` are ``"free"`` (artificial cells may be added there) or ``"wall"``
      (node velocity zero);
    - ``exact`` is ``None`` or a method ``(X, t) -> dict(x, v, F, sigma)`` for one particle;
    - ``initial_position`` is ``None`` (the body starts undeformed, ``x = X``, ``F = I``) or a method
      ``X -> x`` for a body that starts deformed: centres, corners and traction points are mapped
      by it and ``F = dx/dX`` at the centres;
    - ``smooth`` is ``None`` (the exact solution is smooth everywhere) or a method ``(X, t) -> bool``
      marking the particles away from fronts, where errors are expected to converge.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    left: ClassVar[str] = "free"
    right: ClassVar[str] = "free"
    body_force: ClassVar[Callable | None] = None
    exact: ClassVar[Callable | None] = None
    initial_position: ClassVar[Callable | None] = None
    smooth: ClassVar[Callable | None] = None

    h: eqx.AbstractVar[Float[Array, ""]]
    rho0: eqx.AbstractVar[Float[Array, ""]]
    cells: eqx.AbstractVar[int]
    ppc: eqx.AbstractVar[int]
    pad: eqx.AbstractVar[int]

    def __check_init__(self):
        check_int("cells", self.cells, 1)
        check_int("ppc", self.ppc, 1)
        check_int("pad", self.pad, 1)
        check_positive("h", self.h)
        check_positive("rho0", self.rho0)
        self.material()  # a material checks its own parameters (gamma > 1, P0 > 0, E > 0, ...)

    @abc.abstractmethod
    def material(self) -> AbstractMaterial:
        """The constitutive model, built from the scene's parameters."""

    @abc.abstractmethod
    def initial_velocity(self, X: Float[Array, " dim"]) -> Float[Array, " dim"]:
        """Velocity of the material point at reference position ``X`` at ``t = 0``."""

    def traction(self, t: Float[Array, ""]) -> tuple[Array | None, Array | None]:
        """Traction vectors ``sigma n`` at the left and right material boundary points (or ``None``)."""
        del t
        return None, None

    @property
    def length(self) -> Float[Array, ""]:
        return self.cells * self.h

    @property
    def wave_speed(self) -> Float[Array, ""]:
        """The material's sound speed at rest (``F = 1``; the scenes are 1D)."""
        return self.material().sound_speed(jnp.ones((1, 1), dtype=self.h.dtype), self.rho0)

    def grid(self) -> Grid:
        x_min = jnp.reshape(-self.pad * self.h, (1,))
        return Grid(x_min=x_min, h=self.h, n_nodes=self.cells + 2 * self.pad + 1)

    def body(self) -> Body:
        return seed_bar(self.cells, self.ppc, self.h, self.rho0)

    @classmethod
    def parameters(cls) -> dict[str, object]:
        """Every parameter with its default: floats for continuous ones, ints for structural ones."""
        out = {}
        for f in dataclasses.fields(cls):
            if isinstance(f.default, (int, float, str)) and not isinstance(f.default, bool):
                out[f.name] = f.default
        return out

    def parameter_values(self) -> dict[str, object]:
        """This scene's parameters as plain Python values (floats, ints and strings)."""
        return {
            k: (getattr(self, k) if isinstance(v, (int, str)) else float(getattr(self, k)))
            for k, v in self.parameters().items()
        }
