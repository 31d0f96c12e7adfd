"""The interface every interpolator implements (equinox's abstract/final pattern)."""

import abc
from typing import ClassVar, NamedTuple

import equinox as eqx
from jaxtyping import Array, Bool, Float, Int

from ..grid import Grid
from ..particles import Body


class Stencil(NamedTuple):
    """How a set of particles queries the grid in one step.

    ``phi_ip`` (mass, momentum, body force, particle update) lives on nodes ``idx`` with weights
    ``w``; ``dphi_ip`` (internal force, velocity gradient) lives on nodes ``gidx`` with weights
    ``dw``. The two share their index array where the interpolator allows it. Repeated node indices
    are allowed: scatters add them up.

    Attributes:
        idx: ``(n, k)`` node indices of ``phi``.
        w: ``(n, k)`` values of ``phi``.
        gidx: ``(n, kg)`` node indices of ``dphi`` (``None`` when gradients were not asked for).
        dw: ``(n, kg, dim)`` values of ``dphi``.
        ok: ``(n,)`` whether the particle's query fits the interpolator's stencil (GIMP's domain
            may outgrow a fixed-width stencil); ``None`` when it always fits.
    """

    idx: Int[Array, "n k"]
    w: Float[Array, "n k"]
    gidx: Int[Array, "n kg"] | None
    dw: Float[Array, "n kg dim"] | None
    ok: Bool[Array, " n"] | None


class AbstractInterpolator(eqx.Module):
    """How particles query the grid: weights, weight gradients, and the update of ``F``.

    Concrete interpolators are final and override only the abstract methods below.
    """

    name: ClassVar[str]
    tracks_corners: ClassVar[bool] = False

    @abc.abstractmethod
    def stencil(
        self,
        grid: Grid,
        r0: Float[Array, "n dim"],
        x: Float[Array, "n dim"],
        F: Float[Array, "n dim dim"],
        corners: Float[Array, "n corners dim"] | None,
        gradients: bool = True,
    ) -> Stencil:
        """``phi`` and (if ``gradients``) ``dphi`` of particles with half-lengths ``r0``.

        ``corners`` are the particles' own ``2^dim`` corners (MPQ only, ``None`` otherwise).
        """

    @abc.abstractmethod
    def update_F(
        self,
        grid: Grid,
        body: Body,
        stencil: Stencil,
        F: Float[Array, "n dim dim"],
        corners: Float[Array, "nc dim"] | None,
        v_new: Float[Array, "n_nodes dim"],
        dt: Float[Array, ""],
    ) -> tuple[Float[Array, "n dim dim"], Float[Array, "nc dim"] | None]:
        """The new deformation gradients (and MPQ's new corners) from the new grid velocity."""

    @abc.abstractmethod
    def extent(
        self,
        r0: Float[Array, "n dim"],
        x: Float[Array, "n dim"],
        F: Float[Array, "n dim dim"],
        corners: Float[Array, "n corners dim"] | None,
    ) -> tuple[Float[Array, "n dim"], Float[Array, "n dim"]]:
        """Lowest and highest point along each axis at which each particle queries the grid,
        ``(lo, hi)``, each ``(n, dim)``."""
