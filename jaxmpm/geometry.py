"""Solid shapes that seed bodies of particles: boxes, balls, shells, half-spaces and their combinations.

Conventions:

- A shape is a closed set: a point on its boundary is inside. ``Difference(a, b)`` removes the closed
  set ``b``, so a point on ``b``'s boundary is removed.
- A shape has no units of its own: its numbers are in whatever units the caller evaluates it in.
  jaxmpm's scenes of regions evaluate shapes in cells, at ``X / h`` on the lattice of particle
  centres, so a ``Ball((10, 10), 5)`` there is a disk of radius 5 cells.
- Shapes are evaluated with NumPy on a static seeding lattice, never traced by JAX: every parameter
  is a static Python float (a vector is a tuple of them) and ``inside`` takes and returns NumPy
  arrays.
- A vector parameter (a corner, a centre, a normal) is a number in 1D and a list or tuple of 2 or 3
  numbers in 2D and 3D; its length is the shape's ``dim``.

Shapes combine with operators: ``a | b`` is their union, ``a & b`` their intersection and ``a - b``
the points of ``a`` not in ``b``.
"""

import abc
from collections.abc import Callable

import equinox as eqx
import numpy as np
from jaxtyping import Bool, Float, Real

from ._checks import brief, check_finite, check_nonnegative, check_positive, is_bool, is_real


def _vector(name: str) -> Callable[[object], tuple[float, ...]]:
    """A converter of a vector parameter to a tuple of 1 to 3 floats (a scalar is a 1D vector)."""

    def convert(value: object) -> tuple[float, ...]:
        if not is_real(value) or is_bool(value):
            raise ValueError(f"{name} must be a real number or a list of 1 to 3 of them, got {brief(value)}")
        arr = np.asarray(value, dtype=np.float64)
        if arr.ndim == 0:
            arr = arr.reshape(1)
        if arr.ndim != 1 or not 1 <= arr.size <= 3:
            raise ValueError(
                f"{name} must be a real number or a list of 1 to 3 of them, got shape {arr.shape}"
            )
        return tuple(float(v) for v in arr)

    return convert


def _scalar(name: str) -> Callable[[object], float]:
    """A converter of a scalar parameter to a Python float."""

    def convert(value: object) -> float:
        if not is_real(value) or is_bool(value) or np.ndim(value) != 0:
            raise ValueError(f"{name} must be a real number, got {brief(value)}")
        return float(value)

    return convert


def _shape(name: str) -> Callable[[object], "AbstractShape"]:
    """A converter that checks a parameter is a shape."""

    def convert(value: object) -> AbstractShape:
        if not isinstance(value, AbstractShape):
            raise ValueError(f"{name} must be a shape (an AbstractShape), got {brief(value)}")
        return value

    return convert


def _shapes(value: object) -> tuple["AbstractShape", ...]:
    """The converter of ``shapes``: a tuple or list of shapes, as a tuple."""
    if not isinstance(value, (tuple, list)):
        raise ValueError(f"shapes must be a tuple or list of shapes, got {brief(value)}")
    for i, s in enumerate(value):
        if not isinstance(s, AbstractShape):
            raise ValueError(f"shapes[{i}] must be a shape (an AbstractShape), got {brief(s)}")
    return tuple(value)


def _check_same_dim(shapes: tuple["AbstractShape", ...]) -> None:
    """Raise a ValueError naming the dims if ``shapes`` are not all of one dim."""
    dims = sorted({s.dim for s in shapes})
    if len(dims) > 1:
        listed = ", ".join(str(d) for d in dims[:-1]) + f" and {dims[-1]}"
        raise ValueError(f"shapes must all have the same dim, got dims {listed}")


def _points(X: object, dim: int) -> np.ndarray:
    """``X`` as a float64 array of shape ``(n, dim)``, or a ValueError naming ``X``."""
    if not is_real(X):
        raise ValueError(f"X must be an array of real numbers of shape (n, {dim}), got {brief(X)}")
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != dim:
        raise ValueError(f"X must have shape (n, {dim}), got {X.shape}")
    return X


def _squared_distance(X: object, center: tuple[float, ...]) -> np.ndarray:
    """``|X - center|^2`` of each point."""
    return np.sum(np.square(_points(X, len(center)) - np.asarray(center)), axis=1)


def _ball_bounds(center: tuple[float, ...], radius: float) -> tuple[np.ndarray, np.ndarray]:
    c = np.asarray(center, dtype=np.float64)
    return c - radius, c + radius


def _members(shape: "AbstractShape", kind: type) -> tuple["AbstractShape", ...]:
    """The members of ``shape`` if it is a ``kind`` (a Union or an Intersection), else ``(shape,)``."""
    return shape.shapes if isinstance(shape, kind) else (shape,)


class AbstractShape(eqx.Module):
    """A closed set of points in 1, 2 or 3 dimensions, evaluated with NumPy.

    ``a | b``, ``a & b`` and ``a - b`` build a ``Union``, an ``Intersection`` and a ``Difference``;
    combining shapes of different ``dim`` raises a ValueError.

    Attributes:
        dim: the number of space dimensions, 1, 2 or 3.
    """

    dim: eqx.AbstractVar[int]

    @abc.abstractmethod
    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        """Which points lie in the shape (on its boundary counts as in).

        Args:
            X: the points, shape ``(n, dim)``.

        Returns:
            A bool array of shape ``(n,)``.

        Raises:
            ValueError: ``X`` is not an array of real numbers (a string, ``None``, a ragged list), or
                not of shape ``(n, dim)``.
        """

    @abc.abstractmethod
    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        """Per-axis lower and upper bounds of the shape, a box that holds it.

        Returns:
            ``(lo, hi)``, each of shape ``(dim,)``; an unbounded side is ``-inf`` or ``+inf``.
        """

    def __or__(self, other: object) -> "Union":
        if not isinstance(other, AbstractShape):
            return NotImplemented
        return Union(_members(self, Union) + _members(other, Union))

    def __and__(self, other: object) -> "Intersection":
        if not isinstance(other, AbstractShape):
            return NotImplemented
        return Intersection(_members(self, Intersection) + _members(other, Intersection))

    def __sub__(self, other: object) -> "Difference":
        if not isinstance(other, AbstractShape):
            return NotImplemented
        return Difference(self, other)


class Box(AbstractShape):
    """An axis-aligned box ``lo <= X <= hi`` componentwise (an interval in 1D).

    Attributes:
        lo: the lower corner; a number in 1D, a list or tuple of 2 or 3 numbers otherwise.
        hi: the upper corner, > ``lo`` along every axis.
    """

    lo: tuple[float, ...] = eqx.field(static=True, converter=_vector("lo"))
    hi: tuple[float, ...] = eqx.field(static=True, converter=_vector("hi"))

    def __check_init__(self):
        check_finite("lo", self.lo)
        check_finite("hi", self.hi)
        if len(self.lo) != len(self.hi):
            raise ValueError(
                f"lo and hi must have the same length (the dimension), got {len(self.lo)} and {len(self.hi)}"
            )
        if not all(h > lo for lo, h in zip(self.lo, self.hi)):
            raise ValueError(f"hi must be > lo along every axis, got lo={self.lo}, hi={self.hi}")

    @property
    def dim(self) -> int:
        """The number of space dimensions, ``len(lo)``."""
        return len(self.lo)

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        X = _points(X, self.dim)
        return np.all((X >= np.asarray(self.lo)) & (X <= np.asarray(self.hi)), axis=1)

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        return np.asarray(self.lo, dtype=np.float64), np.asarray(self.hi, dtype=np.float64)


class Ball(AbstractShape):
    """A ball ``|X - center| <= radius`` (a disk in 2D, an interval in 1D).

    Attributes:
        center: the centre; a number in 1D, a list or tuple of 2 or 3 numbers otherwise.
        radius: the radius, > 0.
    """

    center: tuple[float, ...] = eqx.field(static=True, converter=_vector("center"))
    radius: float = eqx.field(static=True, converter=_scalar("radius"))

    def __check_init__(self):
        check_finite("center", self.center)
        check_positive("radius", self.radius)

    @property
    def dim(self) -> int:
        """The number of space dimensions, ``len(center)``."""
        return len(self.center)

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        return _squared_distance(X, self.center) <= self.radius**2

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        return _ball_bounds(self.center, self.radius)


class Shell(AbstractShape):
    """A spherical shell ``inner <= |X - center| <= outer`` (an annulus in 2D, two intervals in 1D).

    Attributes:
        center: the centre; a number in 1D, a list or tuple of 2 or 3 numbers otherwise.
        inner: the inner radius, >= 0 (0 gives a ball).
        outer: the outer radius, > ``inner``.
    """

    center: tuple[float, ...] = eqx.field(static=True, converter=_vector("center"))
    inner: float = eqx.field(static=True, converter=_scalar("inner"))
    outer: float = eqx.field(static=True, converter=_scalar("outer"))

    def __check_init__(self):
        check_finite("center", self.center)
        check_nonnegative("inner", self.inner)
        check_finite("outer", self.outer)
        if not self.outer > self.inner:
            raise ValueError(f"outer must be > inner, got inner={self.inner}, outer={self.outer}")

    @property
    def dim(self) -> int:
        """The number of space dimensions, ``len(center)``."""
        return len(self.center)

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        d2 = _squared_distance(X, self.center)
        return (d2 >= self.inner**2) & (d2 <= self.outer**2)

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        return _ball_bounds(self.center, self.outer)


class HalfSpace(AbstractShape):
    """A closed half-space ``normal . X <= offset``.

    The normal is kept as given, not normalised: ``offset`` is in units of ``|normal|`` times length.

    Attributes:
        normal: the outward normal, nonzero; a number in 1D, a list or tuple of 2 or 3 numbers
            otherwise.
        offset: the right-hand side of ``normal . X <= offset``.
    """

    normal: tuple[float, ...] = eqx.field(static=True, converter=_vector("normal"))
    offset: float = eqx.field(static=True, converter=_scalar("offset"))

    def __check_init__(self):
        check_finite("normal", self.normal)
        check_finite("offset", self.offset)
        if not any(self.normal):
            raise ValueError(f"normal must be nonzero, got {self.normal}")

    @property
    def dim(self) -> int:
        """The number of space dimensions, ``len(normal)``."""
        return len(self.normal)

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        X = _points(X, self.dim)
        return np.sum(X * np.asarray(self.normal), axis=1) <= self.offset

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        lo = np.full(self.dim, -np.inf)
        hi = np.full(self.dim, np.inf)
        axes = [k for k, n in enumerate(self.normal) if n != 0.0]
        if len(axes) == 1:  # normal along one axis: that axis is bounded on one side
            k = axes[0]
            limit = self.offset / self.normal[k]
            if self.normal[k] > 0.0:
                hi[k] = limit
            else:
                lo[k] = limit
        return lo, hi


class Union(AbstractShape):
    """The points in any of ``shapes``.

    Attributes:
        shapes: a tuple (or list) of at least 1 shape, all of the same ``dim``.
    """

    shapes: tuple[AbstractShape, ...] = eqx.field(static=True, converter=_shapes)

    def __check_init__(self):
        if not self.shapes:
            raise ValueError("shapes must hold at least 1 shape, got 0")
        _check_same_dim(self.shapes)

    @property
    def dim(self) -> int:
        """The number of space dimensions, that of every member."""
        return self.shapes[0].dim

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        X = _points(X, self.dim)
        return np.logical_or.reduce([s.inside(X) for s in self.shapes], axis=0)

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        los, his = zip(*(s.bounds() for s in self.shapes))
        return np.min(los, axis=0), np.max(his, axis=0)


class Intersection(AbstractShape):
    """The points in every one of ``shapes``.

    Its bounds are the intersection of the members' bounds; where that is empty, ``lo > hi`` along
    some axis.

    Attributes:
        shapes: a tuple (or list) of at least 1 shape, all of the same ``dim``.
    """

    shapes: tuple[AbstractShape, ...] = eqx.field(static=True, converter=_shapes)

    def __check_init__(self):
        if not self.shapes:
            raise ValueError("shapes must hold at least 1 shape, got 0")
        _check_same_dim(self.shapes)

    @property
    def dim(self) -> int:
        """The number of space dimensions, that of every member."""
        return self.shapes[0].dim

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        X = _points(X, self.dim)
        return np.logical_and.reduce([s.inside(X) for s in self.shapes], axis=0)

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        los, his = zip(*(s.bounds() for s in self.shapes))
        return np.max(los, axis=0), np.min(his, axis=0)


class Difference(AbstractShape):
    """The points in ``a`` and not in ``b``; a point on ``b``'s boundary is in ``b``, so removed.

    Its bounds are those of ``a``.

    Attributes:
        a: the shape cut from.
        b: the shape removed, of the same ``dim`` as ``a``.
    """

    a: AbstractShape = eqx.field(static=True, converter=_shape("a"))
    b: AbstractShape = eqx.field(static=True, converter=_shape("b"))

    def __check_init__(self):
        if self.a.dim != self.b.dim:
            raise ValueError(f"a and b must have the same dim, got {self.a.dim} and {self.b.dim}")

    @property
    def dim(self) -> int:
        """The number of space dimensions, that of ``a`` and ``b``."""
        return self.a.dim

    def inside(self, X: Real[np.ndarray, "n dim"]) -> Bool[np.ndarray, " n"]:
        X = _points(X, self.dim)
        return self.a.inside(X) & ~self.b.inside(X)

    def bounds(self) -> tuple[Float[np.ndarray, " dim"], Float[np.ndarray, " dim"]]:
        return self.a.bounds()
