"""The interface every interpolator implements (equinox's abstract/final pattern)."""

import abc
from typing import NamedTuple

import equinox as eqx
from jaxtyping import Array, Bool, Float, Int

from ..grid import Grid
from ..particles import Body


class Stencil(NamedTuple):
    """How a set of particles queries the grid in one step.

    ``phi_ip`` (mass, momentum, body force, particle update) lives on nodes ``idx`` with weights
    ``w``; ``dphi_ip`` (internal force, velocity gradient) lives on nodes ``gidx`` with weights
    ``dw``. The two use one index array where the interpolator allows it. Repeated node indices
    are allowed: scatters add them up.

    Attributes:
        idx: node indices of ``phi``.
        w: values of ``phi``.
        gidx: node indices of ``dphi`` (``None`` when gradients were not asked for).
        dw: values of ``dphi``.
        ok: whether the particle's query fits the interpolator's stencil (GIMP's domain may outgrow a
            fixed-width stencil); ``None`` when it always fits.
        S_c: the domain form's factors of ``dw`` (CPDI, MPQ, CPDI2 in 2D and 3D; ``None`` otherwise):
            each node's hat value at each domain corner, ``(n, corners, nodes)``, with
            ``dw[:, c * nodes + i] = S_c[:, c, i] g_c[:, c]``. The step contracts through them
            (``gradient_forces``, ``gradient_outer``): ``2^dim`` products a particle where ``dw``
            takes ``4^dim``.
        g_c: the corner vectors ``D^-T s_c`` of the domain form (``domain_gradient``), ``(n,
            corners, dim)``.
        base: in 1D, where each particle's ``idx`` are ``g`` runs of consecutive nodes (one run for
            SPQ and MPQ's ``phi``, one a corner for CPDI and CPDI2), the first node of each,
            ``(n, g)``; the grid's scatters and gathers then move each run as one window
            (``Grid.scatter``). ``None`` otherwise.
        gbase: the same for ``gidx``.
    """

    idx: Int[Array, "n k"]
    w: Float[Array, "n k"]
    gidx: Int[Array, "n kg"] | None
    dw: Float[Array, "n kg dim"] | None
    ok: Bool[Array, " n"] | None
    S_c: Float[Array, "n corners nodes"] | None = None
    g_c: Float[Array, "n corners dim"] | None = None
    base: Int[Array, "n g"] | None = None
    gbase: Int[Array, "n g"] | None = None


class AbstractInterpolator(eqx.Module):
    """How particles query the grid: weights, weight gradients, and the update of ``F``.

    Concrete interpolators are final: they implement the abstract members below and nothing else.

    Attributes:
        name: the name the interpolator is known by (``INTERPOLATORS``, ``--interpolator``, a saved
            run's metadata).
        tracks_corners: whether the particles' domain corners are part of the state (MPQ, CPDI2).
        stencil_width: grid nodes per axis that one particle's weights reach (their product over the
            axes is the stencil; for CPDI, MPQ and CPDI2, two corners per axis of two nodes each); it sizes
            the memory estimate of a run.
    """

    name: eqx.AbstractVar[str]
    tracks_corners: eqx.AbstractClassVar[bool]
    stencil_width: eqx.AbstractVar[int]

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

        Args:
            grid: the background grid.
            r0: initial half-lengths of the particle domains.
            x: particle centres.
            F: deformation gradients.
            corners: the particles' own ``2^dim`` tracked corners (MPQ, CPDI2; ``None`` otherwise).
            gradients: whether to compute ``dphi`` as well.

        Returns:
            The ``Stencil``.
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
        """The new deformation gradients (and the new tracked corners) from the new grid velocity.

        Args:
            grid: the background grid.
            body: the reference configuration.
            stencil: the step's stencil of the particles.
            F: deformation gradients at the start of the step.
            corners: the body's tracked corners (MPQ, CPDI2; ``None`` otherwise).
            v_new: the grid velocity at the end of the step.
            dt: the time step.

        Returns:
            ``(F_new, corners_new)``.
        """

    @abc.abstractmethod
    def extent(
        self,
        r0: Float[Array, "n dim"],
        x: Float[Array, "n dim"],
        F: Float[Array, "n dim dim"],
        corners: Float[Array, "n corners dim"] | None,
    ) -> tuple[Float[Array, "n dim"], Float[Array, "n dim"]]:
        """Lowest and highest point along each axis at which each particle queries the grid.

        Args:
            r0: initial half-lengths of the particle domains.
            x: particle centres.
            F: deformation gradients.
            corners: the particles' own ``2^dim`` tracked corners (MPQ, CPDI2; ``None`` otherwise).

        Returns:
            ``(lo, hi)``.
        """
