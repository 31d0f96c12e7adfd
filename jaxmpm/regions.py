"""Bodies made of regions: shapes seeded with particles, each region with its own material and state.

A scene of regions seeds ``ppc`` particles per cell and axis on the lattice of its box ``[0, cells
h]^dim`` and keeps a particle where its centre lies inside one region's shape. The shapes are
evaluated in cells (``X / h``), on the lattice alone, so which particle belongs to which region is
part of the scene's structure: it does not depend on ``h`` or on any array parameter, and a run
compiles one set of indices per region. (A derivative with respect to ``h`` scales the whole body,
regions included.)

Every region has a material (an ``AbstractMaterial`` of ``F`` alone or an ``AbstractEOS`` with an
energy equation), a reference density, an initial velocity and, for an EOS, an initial specific
internal energy. The step computes each region's stress from its own particles only.

MPM's single velocity field makes regions that touch move as one body at their interface: they
stick (no slip, no separation), and momentum crosses the interface through the grid.
"""

import dataclasses
import hashlib

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._checks import check_finite, check_nonnegative, check_positive, check_real, is_concrete
from ._util import ONE_VALUE, as_float, check_real_fields, corner_signs, lattice
from .geometry import AbstractShape
from .materials import AbstractEOS, AbstractMaterial, ElasticPlastic
from .particles import Body


def _as_vector(x) -> Float[Array, " dim"]:
    return jnp.atleast_1d(jnp.asarray(x, dtype=as_float(0.0).dtype))


class Region(eqx.Module):
    """One region of a body: where it is, what it is made of, and its initial state.

    Attributes:
        shape: the region's shape, in cells (``X / h``).
        material: its material.
        rho0: its reference (initial) density.
        velocity: its initial velocity, ``(dim,)`` (a number in 1D); by default at rest, the zero
            vector of the shape's dimension.
        energy: its initial specific internal energy (an ``AbstractEOS`` material only; 0 for
            the models of ``F`` alone, which carry no energy): finite, and >= 0 where the material
            holds ``e >= 0`` in every state (``nonnegative_energy()``: an ideal gas, the explosives);
            below 0 where ``e`` is measured from a reference state it may go below (a Mie-Grueneisen
            solid started off its reference state).
    """

    shape: AbstractShape
    material: AbstractMaterial | AbstractEOS
    rho0: Float[Array, ""] = eqx.field(converter=as_float)
    velocity: Float[Array, " dim"] = eqx.field(converter=_as_vector, default=None)
    energy: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)

    def __post_init__(self):
        # Before the converters: rho0 and energy are one real number each, the velocity real numbers
        # (named here: the converters cannot name them), and a velocity not given is the shape's zero
        # vector. (A shape that is not a jaxmpm shape gets a number, and __check_init__ names it.)
        check_real_fields(self, ONE_VALUE)
        if self.velocity is None:
            dim = self.shape.dim if isinstance(self.shape, AbstractShape) else 1
            self.velocity = (0.0,) * dim
        else:
            check_real("velocity", self.velocity)

    def __check_init__(self):
        if not isinstance(self.shape, AbstractShape):
            raise ValueError(f"shape must be a jaxmpm.geometry shape, got {type(self.shape).__name__}")
        if not isinstance(self.material, (AbstractMaterial, AbstractEOS)):
            raise ValueError(
                f"material must be a jaxmpm material (AbstractMaterial or AbstractEOS), got "
                f"{type(self.material).__name__}"
            )
        check_positive("rho0", self.rho0)
        if isinstance(self.material, AbstractEOS) and self.material.nonnegative_energy():
            check_nonnegative("energy", self.energy)
        else:
            check_finite("energy", self.energy)
        if is_concrete(self.velocity) and not np.all(np.isfinite(np.asarray(self.velocity))):
            raise ValueError(f"velocity must be finite, got {np.asarray(self.velocity).tolist()}")
        if self.velocity.shape != (self.shape.dim,):
            raise ValueError(
                f"velocity must have {self.shape.dim} components (the shape's dimension), got "
                f"{self.velocity.shape[0]}"
            )
        if isinstance(self.material, AbstractMaterial) and is_concrete(self.energy) and float(self.energy):
            raise ValueError(
                f"energy applies to an AbstractEOS material only ({type(self.material).__name__} is a "
                f"function of F alone and carries no energy), got energy={float(self.energy)}"
            )


@dataclasses.dataclass(frozen=True, eq=False)
class Layout:
    """Which lattice points a body of regions keeps and to which region each belongs (static).

    Hashed by content, so a ``Layout`` can sit in the static part of a compiled function's inputs.

    Attributes:
        cells: cells of the box along each axis.
        ppc: particles per cell and axis.
        keep: lattice indices of the kept particles, in lattice order, ``(n,)``.
        region: region of each kept particle, ``(n,)``.
        counts: particles per region.
        box: whether the regions fill the whole box (every lattice point is kept).
    """

    cells: tuple[int, ...]
    ppc: int
    keep: np.ndarray
    region: np.ndarray
    counts: tuple[int, ...]
    box: bool

    def __post_init__(self):
        digest = hashlib.sha1(self.keep.tobytes() + self.region.tobytes()).hexdigest()
        object.__setattr__(self, "_digest", (self.cells, self.ppc, digest))

    def __hash__(self):
        return hash(self._digest)

    def __eq__(self, other):
        return isinstance(other, Layout) and self._digest == other._digest

    def index(self, k: int) -> slice | np.ndarray:
        """The particles of region ``k``: a slice where they are contiguous, else their indices.

        Args:
            k: the region.

        Returns:
            A ``slice`` or a static integer array.
        """
        idx = np.flatnonzero(self.region == k)
        if idx.size and idx[-1] - idx[0] + 1 == idx.size:
            return slice(int(idx[0]), int(idx[-1]) + 1)
        return idx


def layout(cells: tuple[int, ...], ppc: int, shapes: tuple[AbstractShape, ...], pad: int) -> Layout:
    """Assign the lattice's particle centres to the regions' shapes.

    Args:
        cells: cells of the box along each axis.
        ppc: particles per cell and axis.
        shapes: one shape per region, in cells.
        pad: cells of grid beyond the box on each side. A shape is cut to the box: only the
            lattice's particle centres inside it are the region's, so a shape may reach past the box
            (a ball about a corner of a quarter domain, say).

    Returns:
        The ``Layout``.

    Raises:
        ValueError: a shape of the wrong dimension, a region lying wholly outside the grid, a region
            with no particle (in the box), or a particle inside two regions (naming them).
    """
    dim = len(cells)
    if not shapes:
        raise ValueError("regions must hold at least one Region, got none")
    ip = lattice([c * ppc for c in cells])
    centres = (ip + 0.5) / ppc  # in cells
    inside = np.zeros((len(shapes), ip.shape[0]), dtype=bool)
    for k, shape in enumerate(shapes):
        if shape.dim != dim:
            raise ValueError(f"region {k}: its shape is {shape.dim}D but the scene is {dim}D")
        lo, hi = (np.asarray(b, dtype=float) for b in shape.bounds())
        if np.any(hi < -pad) or np.any(lo > np.asarray(cells) + pad):
            raise ValueError(
                f"region {k} lies outside the grid (its shape spans {lo.tolist()} to {hi.tolist()} cells; "
                f"the grid spans {-pad} to {[c + pad for c in cells]} cells)"
            )
        inside[k] = shape.inside(centres)
    counts = inside.sum(axis=1)
    for k, c in enumerate(counts):
        if c == 0:
            raise ValueError(
                f"region {k} holds no particle (no particle centre of the {ppc} per cell and axis on "
                f"[0, {list(cells)}] cells lies inside its shape)"
            )
    claims = inside.sum(axis=0)
    if np.any(claims > 1):
        p = int(np.argmax(claims > 1))
        both = np.flatnonzero(inside[:, p]).tolist()
        raise ValueError(
            f"regions {both} overlap: the particle at {centres[p].tolist()} cells is inside each of them"
        )
    keep = np.flatnonzero(claims == 1)
    region = np.argmax(inside[:, keep], axis=0).astype(np.int32)
    return Layout(
        cells=tuple(cells),
        ppc=ppc,
        keep=keep,
        region=region,
        counts=tuple(int(c) for c in counts),
        box=bool(keep.size == ip.shape[0]),
    )


def seed_regions(lay: Layout, h: Float[Array, ""], rho0: Float[Array, " regions"]) -> Body:
    """The body of a layout: the kept particles of the lattice, with their regions' densities.

    Particles sit at the centres of ``ppc`` equal sub-intervals of each cell along every axis, as
    ``particles.seed_box`` puts them, in lattice order (the last axis fastest); a particle's
    domain corners are the lattice corners around it, each stored once.

    Args:
        lay: the layout.
        h: cell size.
        rho0: reference density of each region.

    Returns:
        The ``Body``, ``region`` set.
    """
    d, ppc = len(lay.cells), lay.ppc
    counts = [c * ppc for c in lay.cells]
    ip = lattice(counts)[lay.keep]
    n = ip.shape[0]
    X = jnp.asarray((ip + 0.5) / ppc, dtype=h.dtype) * h
    r0 = jnp.full((n, d), 0.5 / ppc, dtype=h.dtype) * h
    V0 = 2.0 * r0[:, 0]
    for a in range(1, d):
        V0 = V0 * (2.0 * r0[:, a])
    cstride = np.asarray([int(np.prod([c + 1 for c in counts[a + 1 :]])) for a in range(d)])
    bits = (corner_signs(d) > 0).astype(np.int64)
    ids = ((ip[:, None, :] + bits[None, :, :]) * cstride[None, None, :]).sum(-1)
    used, ids = np.unique(ids, return_inverse=True)
    ids = ids.reshape(n, 2**d).astype(np.int32)
    corner_ip = np.stack(np.unravel_index(used, [c + 1 for c in counts]), axis=1)
    cell = ip // ppc
    boundary = np.any((cell == 0) | (cell == np.asarray(lay.cells)[None, :] - 1), axis=1)
    return Body(
        X=X,
        r0=r0,
        m=rho0[jnp.asarray(lay.region)] * V0,
        V0=V0,
        X_corners=jnp.asarray(corner_ip / ppc, dtype=h.dtype) * h,
        corner_ids=jnp.asarray(ids),
        boundary=jnp.asarray(boundary),
        region=jnp.asarray(lay.region),
        chain=d == 1 and np.array_equal(ids, np.arange(n)[:, None] + np.arange(2)[None, :]),
    )


def initial_sound_speed(region: Region, dim: int) -> Float[Array, ""]:
    """A region's sound speed in its initial state (at rest, ``F = I``), the speed the step's stability
    check uses: for an ``ElasticPlastic`` material the longitudinal elastic wave's,
    ``sqrt(c_eos^2 + 4 G / (3 rho0))``; for an EOS with a front (a programmed detonation) at least the
    front's speed.

    Args:
        region: the region.
        dim: number of space dimensions.

    Returns:
        The sound speed.
    """
    mat = region.material
    if isinstance(mat, AbstractEOS):
        z = mat.initial_internal(jnp.zeros((dim,), dtype=region.rho0.dtype))
        c = mat.sound_speed(region.rho0, region.energy, z)
        if isinstance(mat, ElasticPlastic):  # the longitudinal elastic wave, as in the step's check
            c = jnp.sqrt(c * c + 4.0 * mat.G / (3.0 * region.rho0))
        front = mat.front_speed()
        return c if front is None else jnp.maximum(c, front)
    return mat.sound_speed(jnp.eye(dim, dtype=region.rho0.dtype), region.rho0)
