"""Solid shapes of jaxmpm.geometry: membership on and off boundaries, operators, bounds, validation."""

import itertools
import operator

import numpy as np
import pytest
from helpers import raw

from jaxmpm.geometry import (
    AbstractShape,
    Ball,
    Box,
    Difference,
    HalfSpace,
    Intersection,
    Shell,
    Union,
)


def pts(*points) -> np.ndarray:
    """Points as an ``(n, dim)`` float64 array; a bare number is a 1D point."""
    return np.array([np.atleast_1d(p) for p in points], dtype=np.float64)


def lattice(n: int, per_cell: int, dim: int) -> np.ndarray:
    """Centres ``(i + 0.5) / per_cell`` of a lattice covering ``[0, n]^dim``."""
    axis = (np.arange(n * per_cell) + 0.5) / per_cell
    return np.stack(np.meshgrid(*([axis] * dim), indexing="ij"), axis=-1).reshape(-1, dim)


# ---------------------------------------------------------------- Box


def test_box_1d_is_a_closed_interval():
    box = Box(1.0, 3)
    assert box.lo == (1.0,) and box.hi == (3.0,) and box.dim == 1
    assert box.inside(pts(1.0, 2.0, 3.0)).tolist() == [True, True, True]
    assert box.inside(pts(0.999, 3.001, -5.0)).tolist() == [False, False, False]


def test_box_2d_edges_and_corners():
    box = Box([0, 0], (2, 1))
    assert box.lo == (0.0, 0.0) and box.hi == (2.0, 1.0) and box.dim == 2
    assert all(isinstance(v, float) for v in box.lo + box.hi)
    on = pts((0, 0), (2, 1), (2, 0), (1, 1), (0, 0.5), (1, 0.5))
    off = pts((-1e-9, 0.5), (1, 1 + 1e-9), (2.5, 0.5), (1, -0.1), (3, 3))
    assert box.inside(on).all()
    assert not box.inside(off).any()


def test_box_3d():
    box = Box((0, 0, 0), (1, 2, 3))
    assert box.dim == 3
    corners = pts(*itertools.product((0, 1), (0, 2), (0, 3)))
    assert box.inside(corners).all()
    assert box.inside(pts((0.5, 1, 1.5))).tolist() == [True]
    assert not box.inside(pts((0.5, 1, 3.1), (0.5, -0.1, 1), (1.1, 1, 1))).any()


def test_box_accepts_integer_points_and_returns_bool():
    out = Box((0, 0), (1, 1)).inside(np.array([[0, 0], [2, 0]]))
    assert out.dtype == np.bool_ and out.shape == (2,)
    assert out.tolist() == [True, False]


def test_empty_point_set():
    out = Ball((0, 0), 1).inside(np.zeros((0, 2)))
    assert out.shape == (0,) and out.dtype == np.bool_


# ---------------------------------------------------------------- Ball


def test_ball_1d_is_an_interval():
    ball = Ball(2.0, 0.5)
    assert ball.center == (2.0,) and ball.radius == 0.5 and ball.dim == 1
    assert ball.inside(pts(1.5, 2.0, 2.5)).all()
    assert not ball.inside(pts(1.49, 2.51)).any()


def test_ball_2d_boundary_is_inside():
    ball = Ball((0, 0), 5)
    assert isinstance(ball.radius, float)
    on = pts((3, 4), (-4, 3), (5, 0), (0, -5), (0, 0))
    off = pts((3, 4.001), (5.001, 0), (3.6, 3.6))
    assert ball.inside(on).all()
    assert not ball.inside(off).any()


def test_ball_3d():
    ball = Ball((1, 1, 1), 3)
    assert ball.dim == 3
    assert ball.inside(pts((1, 1, 4), (1, 1, -2), (3, 3, 2), (1, 1, 1))).all()  # (2, 2, 1): |.| = 3
    assert not ball.inside(pts((1, 1, 4.01), (3, 3, 2.01), (3, 3, 3))).any()


# ---------------------------------------------------------------- Shell


def test_shell_1d_is_two_intervals():
    shell = Shell(0.0, 1.0, 2.0)
    assert shell.dim == 1
    assert shell.inside(pts(-2, -1.5, -1, 1, 1.5, 2)).all()
    assert not shell.inside(pts(0, 0.5, -0.99, 2.01, -2.01)).any()


def test_shell_2d_both_boundaries_are_inside():
    shell = Shell((0, 0), 3, 5)
    assert (shell.inner, shell.outer) == (3.0, 5.0)
    assert shell.inside(pts((3, 0), (0, -3), (3, 4), (-5, 0), (0, 4))).all()
    assert not shell.inside(pts((0, 0), (2.99, 0), (1, 1), (5.01, 0), (4, 4))).any()


def test_shell_3d_and_zero_inner_is_a_ball():
    shell = Shell((0, 0, 0), 1, 2)
    assert shell.dim == 3
    assert shell.inside(pts((1, 0, 0), (0, 0, 2), (1, 1, 1))).all()
    assert not shell.inside(pts((0.5, 0, 0), (0, 0, 2.01), (0, 0, 0))).any()
    X = lattice(4, 4, 3) - 2.0
    np.testing.assert_array_equal(Shell((0, 0, 0), 0, 1.5).inside(X), Ball((0, 0, 0), 1.5).inside(X))


# ---------------------------------------------------------------- HalfSpace


def test_halfspace_1d():
    below = HalfSpace(1.0, 2.0)  # x <= 2
    above = HalfSpace(-2.0, -2.0)  # -2x <= -2, x >= 1
    assert below.normal == (1.0,) and below.offset == 2.0 and below.dim == 1
    assert below.inside(pts(-100, 2)).all() and not below.inside(pts(2.001)).any()
    assert above.inside(pts(1, 100)).all() and not above.inside(pts(0.999)).any()


def test_halfspace_2d_normal_is_not_normalised():
    h = HalfSpace((1, 1), 2)  # x + y <= 2
    assert h.normal == (1.0, 1.0)
    assert h.inside(pts((1, 1), (2, 0), (0, 2), (-10, -10))).all()
    assert not h.inside(pts((1, 1.001), (2, 0.5))).any()
    assert HalfSpace((0, 3), 6).inside(pts((100, 2), (0, 2.1))).tolist() == [True, False]


def test_halfspace_3d():
    h = HalfSpace((0, 0, -1), 0)  # z >= 0
    assert h.inside(pts((5, -5, 0), (0, 0, 1))).all()
    assert not h.inside(pts((0, 0, -1e-9))).any()


# ---------------------------------------------------------------- combinations


def test_union_of_two_disks():
    u = Union((Ball((0, 0), 1), Ball((3, 0), 1)))
    assert u.dim == 2
    assert u.inside(pts((-1, 0), (1, 0), (2, 0), (4, 0), (3, 1))).all()
    assert not u.inside(pts((1.5, 0), (0, 1.1), (5, 0))).any()


def test_union_accepts_a_list_and_one_member():
    a = Ball((0, 0), 1)
    assert Union([a]).shapes == (a,)
    X = lattice(2, 4, 2) - 1.0
    np.testing.assert_array_equal(Union([a]).inside(X), a.inside(X))
    np.testing.assert_array_equal(Intersection([a]).inside(X), a.inside(X))


def test_intersection_of_a_box_and_a_halfspace():
    tri = Intersection((Box((0, 0), (2, 2)), HalfSpace((1, 1), 2)))
    assert tri.inside(pts((0, 0), (2, 0), (0, 2), (1, 1), (0.5, 0.5))).all()
    assert not tri.inside(pts((2, 2), (1.5, 1), (-0.1, 0))).any()


def test_difference_removes_the_boundary_of_b():
    ring = Difference(Ball((0, 0), 2), Ball((0, 0), 1))
    assert ring.dim == 2
    assert ring.inside(pts((2, 0), (1.5, 0), (0, -1.01))).all()
    assert not ring.inside(pts((1, 0), (0, -1), (0, 0), (2.01, 0))).any()  # (1, 0) is on b's boundary


def test_difference_1d_and_3d():
    cut = Difference(Box(0, 4), Box(1, 2))
    assert cut.inside(pts(0, 0.99, 2.01, 4)).all()
    assert not cut.inside(pts(1, 1.5, 2, 4.01)).any()
    hollow = Difference(Box((0, 0, 0), (2, 2, 2)), Ball((1, 1, 1), 0.5))
    assert hollow.inside(pts((0, 0, 0), (1, 1, 1.51))).all()
    assert not hollow.inside(pts((1, 1, 1), (1, 1, 1.5))).any()


def test_operators_build_the_combinations():
    a, b, c = Box((0, 0), (2, 2)), Ball((2, 2), 1), HalfSpace((1, 0), 1)
    assert isinstance(a | b, Union) and (a | b).shapes == (a, b)
    assert isinstance(a & b, Intersection) and (a & b).shapes == (a, b)
    assert isinstance(a - b, Difference) and (a - b).a == a and (a - b).b == b
    # chains flatten into one Union / Intersection
    assert (a | b | c).shapes == (a, b, c)
    assert (a & b & c).shapes == (a, b, c)
    assert (a | (b | c)).shapes == (a, b, c)
    X = lattice(4, 4, 2) - 0.5
    ia, ib, ic = a.inside(X), b.inside(X), c.inside(X)
    np.testing.assert_array_equal((a | b | c).inside(X), ia | ib | ic)
    np.testing.assert_array_equal((a & b & c).inside(X), ia & ib & ic)
    np.testing.assert_array_equal((a - b).inside(X), ia & ~ib)
    np.testing.assert_array_equal(((a | b) - c).inside(X), (ia | ib) & ~ic)
    np.testing.assert_array_equal(((a - c) & b).inside(X), ia & ~ic & ib)
    assert isinstance(a, AbstractShape) and isinstance(a | b, AbstractShape)


def test_operators_reject_non_shapes():
    a = Box((0, 0), (1, 1))
    with pytest.raises(TypeError):
        a | 1
    with pytest.raises(TypeError):
        a & "box"
    with pytest.raises(TypeError):
        a - None


@pytest.mark.parametrize("op", [operator.or_, operator.and_])
def test_operators_reject_mixed_dims(op):
    a, b = Box((0, 0), (1, 1)), Ball((0, 0, 0), 1)
    with pytest.raises(ValueError, match="shapes must all have the same dim, got dims 2 and 3"):
        op(a, b)


def test_difference_rejects_mixed_dims():
    with pytest.raises(ValueError, match="a and b must have the same dim, got 1 and 2"):
        Box(0, 1) - Ball((0, 0), 1)


def test_equal_shapes_compare_and_hash_equal():
    assert Box([0, 0], [1, 1]) == Box((0.0, 0.0), (1.0, 1.0))
    assert hash(Ball((1, 2), 3)) == hash(Ball([1.0, 2.0], 3.0))
    assert Ball((1, 2), 3) != Ball((1, 2), 4)


# ---------------------------------------------------------------- bounds


def assert_bounds(shape, lo, hi):
    got_lo, got_hi = shape.bounds()
    assert got_lo.dtype == np.float64 and got_hi.dtype == np.float64
    np.testing.assert_array_equal(got_lo, np.asarray(lo, dtype=np.float64))
    np.testing.assert_array_equal(got_hi, np.asarray(hi, dtype=np.float64))


def test_bounds_of_the_primitives():
    assert_bounds(Box(1, 3), [1], [3])
    assert_bounds(Box((0, -1, 2), (1, 1, 5)), [0, -1, 2], [1, 1, 5])
    assert_bounds(Ball(2, 0.5), [1.5], [2.5])
    assert_bounds(Ball((10, 10), 5), [5, 5], [15, 15])
    assert_bounds(Shell((0, 1, 2), 1, 3), [-3, -2, -1], [3, 4, 5])


def test_bounds_of_halfspaces():
    inf = np.inf
    assert_bounds(HalfSpace(2.0, 4.0), [-inf], [2])
    assert_bounds(HalfSpace(-2.0, 4.0), [-2], [inf])
    assert_bounds(HalfSpace((0, 2), 4), [-inf, -inf], [inf, 2])
    assert_bounds(HalfSpace((0, 0, -1), -3), [-inf, -inf, 3], [inf, inf, inf])
    assert_bounds(HalfSpace((1, 1), 2), [-inf, -inf], [inf, inf])  # oblique: unbounded


def test_bounds_of_combinations():
    inf = np.inf
    a, b = Box((0, 0), (2, 1)), Ball((3, 3), 1)
    assert_bounds(a | b, [0, 0], [4, 4])
    assert_bounds(a & Box((1, -1), (5, 0.5)), [1, 0], [2, 0.5])
    assert_bounds(a - b, [0, 0], [2, 1])
    assert_bounds(HalfSpace((1, 0), 1) & HalfSpace((0, -1), 0), [-inf, 0], [1, inf])
    assert_bounds(HalfSpace((1, 0), 1) | a, [-inf, -inf], [2, inf])
    lo, hi = (a & b).bounds()  # disjoint: an empty box
    assert np.any(lo > hi)


# ---------------------------------------------------------------- seeding lattice counts


def test_lattice_count_in_a_disk_matches_brute_force():
    X = lattice(20, 4, 2)
    ball = Ball((10, 10), 5)
    brute = sum(1 for x, y in X if (x - 10) ** 2 + (y - 10) ** 2 <= 25)
    assert ball.inside(X).sum() == brute
    assert 0.97 < brute / (np.pi * 25 * 16) < 1.03  # about pi r^2 particles per unit area of 16


def test_lattice_count_in_a_shell_is_the_outer_ball_minus_the_open_inner_ball():
    X = lattice(20, 4, 2)
    c = (10.125, 10.125)  # a lattice centre: lattice points lie exactly on both circles
    d2 = np.sum((X - np.asarray(c)) ** 2, axis=1)
    on_inner, on_outer = np.count_nonzero(d2 == 4.0), np.count_nonzero(d2 == 25.0)
    assert on_inner > 0 and on_outer > 0
    shell = Shell(c, 2, 5)
    inner_open = np.count_nonzero(d2 < 4.0)
    assert shell.inside(X).sum() == Ball(c, 5).inside(X).sum() - inner_open
    assert Ball(c, 5).inside(X).sum() == np.count_nonzero(d2 <= 25.0)
    ring = Ball(c, 5) - Ball(c, 2)  # removes the inner circle too
    assert ring.inside(X).sum() == shell.inside(X).sum() - on_inner


def test_lattice_count_in_a_box_3d():
    X = lattice(4, 2, 3)  # centres 0.25, 0.75, ..., 3.75
    assert Box((0, 0, 0), (1, 1, 1)).inside(X).sum() == 8
    assert Box((0.25, 0.25, 0.25), (1.75, 0.75, 3.75)).inside(X).sum() == 4 * 2 * 8


# ---------------------------------------------------------------- validation


def test_inside_rejects_points_of_another_dim():
    with pytest.raises(ValueError, match=r"X must have shape \(n, 2\), got \(3, 3\)"):
        Box((0, 0), (1, 1)).inside(np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"X must have shape \(n, 1\), got \(2, 2\)"):
        (Ball(0, 1) | Box(0, 1)).inside(np.zeros((2, 2)))


@pytest.mark.parametrize(
    "shape", [Box(0, 1), Ball(0, 1), Shell(0, 0.5, 1), HalfSpace(1, 0), Box(0, 1) - Ball(0, 0.5)], ids=repr
)
@pytest.mark.parametrize("X", ["a", None, [["a"]], [[1j]], [[0.5], [0.2, 0.1]]], ids=repr)
def test_inside_names_points_that_are_not_real_numbers(shape, X):
    # NumPy's "could not convert string to float" named no parameter (the suite's runtime type checks
    # refuse these first: raw is the call as a user makes it)
    with pytest.raises(ValueError, match=r"^X must be an array of real numbers of shape \(n, 1\), got "):
        raw(type(shape).inside)(shape, X)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (
            lambda: Box((0, 0), (1, 1, 1)),
            r"lo and hi must have the same length \(the dimension\), got 2 and 3",
        ),
        (lambda: Box(0, 0), r"hi must be > lo along every axis, got lo=\(0.0,\), hi=\(0.0,\)"),
        (
            lambda: Box((0, 0), (1, -1)),
            r"hi must be > lo along every axis, got lo=\(0.0, 0.0\), hi=\(1.0, -1.0\)",
        ),
        (lambda: Box((0, np.inf), (1, 1)), "lo must be finite"),
        (lambda: Box(0, np.nan), "hi must be finite"),
        (lambda: Box("a", 1), "lo must be a real number or a list of 1 to 3 of them, got 'a'"),
        (lambda: Box((0, 0, 0, 0), (1, 1, 1, 1)), r"lo must be .* 1 to 3 of them, got shape \(4,\)"),
        (lambda: Box([], []), r"lo must be .* 1 to 3 of them, got shape \(0,\)"),
        (lambda: Box([[0, 0]], [[1, 1]]), r"lo must be .* 1 to 3 of them, got shape \(1, 2\)"),
        (lambda: Box(None, 1), "lo must be a real number or a list of 1 to 3 of them, got None"),
        (lambda: Box(True, 2), "lo must be a real number or a list of 1 to 3 of them, got True"),
        (lambda: Box((0, False), (1, 1)), r"lo must be a real number .*, got \(0, False\)"),
        (lambda: Box(np.array([True]), 2), "lo must be a real number or a list of 1 to 3 of them"),
        (lambda: Ball((0, 0), True), "radius must be a real number, got True"),
        (lambda: Ball((0, 0), -1), "radius must be > 0, got -1.0"),
        (lambda: Ball((0, 0), 0), "radius must be > 0, got 0.0"),
        (lambda: Ball((0, 0), np.inf), "radius must be finite, got inf"),
        (lambda: Ball((0, np.nan), 1), "center must be finite"),
        (lambda: Ball((0, 0), (1, 2)), r"radius must be a real number, got \(1, 2\)"),
        (lambda: Ball((0, 0), "1"), "radius must be a real number, got '1'"),
        (lambda: Ball(1j, 1), "center must be a real number or a list"),
        (lambda: Shell((0, 0), -1, 2), "inner must be >= 0, got -1.0"),
        (lambda: Shell((0, 0), 2, 1), "outer must be > inner, got inner=2.0, outer=1.0"),
        (lambda: Shell((0, 0), 1, 1), "outer must be > inner, got inner=1.0, outer=1.0"),
        (lambda: Shell((0, 0), 1, np.inf), "outer must be finite, got inf"),
        (lambda: Shell((0, 0), np.nan, 1), "inner must be finite, got nan"),
        (lambda: Shell((np.inf, 0), 0, 1), "center must be finite"),
        (lambda: HalfSpace((0, 0), 1), r"normal must be nonzero, got \(0.0, 0.0\)"),
        (lambda: HalfSpace(0, 1), r"normal must be nonzero, got \(0.0,\)"),
        (lambda: HalfSpace((1, np.nan), 1), "normal must be finite"),
        (lambda: HalfSpace((1, 0), -np.inf), "offset must be finite, got -inf"),
        (lambda: HalfSpace((1, 0), None), "offset must be a real number, got None"),
        (lambda: Union(()), "shapes must hold at least 1 shape, got 0"),
        (lambda: Intersection([]), "shapes must hold at least 1 shape, got 0"),
        (lambda: Union(Box(0, 1)), "shapes must be a tuple or list of shapes, got Box"),
        (lambda: Union((Box(0, 1), 3)), r"shapes\[1\] must be a shape \(an AbstractShape\), got 3"),
        (
            lambda: Intersection((Box(0, 1), Ball((0, 0), 1))),
            "shapes must all have the same dim, got dims 1 and 2",
        ),
        (
            lambda: Union((Box(0, 1), Ball((0, 0), 1), Ball((0, 0, 0), 1))),
            "shapes must all have the same dim, got dims 1, 2 and 3",
        ),
        (lambda: Difference(Box(0, 1), "b"), r"b must be a shape \(an AbstractShape\), got 'b'"),
        (lambda: Difference(1.0, Box(0, 1)), r"a must be a shape \(an AbstractShape\), got 1.0"),
        (lambda: Difference(Box((0, 0), (1, 1)), Box(0, 1)), "a and b must have the same dim, got 2 and 1"),
    ],
)
def test_validation_messages(make, message):
    with pytest.raises(ValueError, match=message):
        make()
