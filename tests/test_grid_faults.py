"""The grid under faults: ``Grid`` and ``Grid.box`` name ``x_min`` (1 to 3 finite real numbers), ``h``
(one positive finite number, not a bool) and ``shape`` (one integer >= 2 per entry of ``x_min``) that
do not fit, in one line, before anything is traced; a list or a Python number is taken where it is
unambiguous, and a traced spacing passes (the library differentiates with respect to it)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import float32, raw

import jaxmpm as jm


def box(x_min, h, shape):
    """``Grid.box`` without the suite's runtime type checks of its annotations (what a user runs)."""
    return raw(jm.Grid.box.__func__)(jm.Grid, x_min, h, shape)  # the classmethod's function, unbound


def _one_line(make, match):
    with pytest.raises(ValueError, match=match) as info:
        make()
    assert "\n" not in str(info.value)
    return str(info.value)


X_MIN = r"^x_min must be the position of node 0, 1 to 3 finite real numbers \(one per axis\), got "
H = r"^h must be the node spacing, one finite number > 0 \(not a bool\), got "

BAD_BOXES = [
    # x_min
    ((jnp.zeros(()), 0.1, (3,)), X_MIN + r"an array of shape \(\)$"),
    ((0.0, 0.1, (3,)), X_MIN + r"an array of shape \(\)$"),
    ((jnp.zeros((1, 2)), 0.1, (3, 3)), X_MIN + r"an array of shape \(1, 2\)$"),
    ((jnp.zeros(4), 0.1, (3, 3, 3, 3)), X_MIN + r"an array of shape \(4,\)$"),
    ((jnp.zeros(0), 0.1, ()), X_MIN + r"an array of shape \(0,\)$"),
    (([0.0, np.nan], 0.1, (3, 3)), X_MIN + r"\[ 0\. nan\]$"),
    ((["a", "b"], 0.1, (3, 3)), X_MIN + r"\['a', 'b'\]$"),
    (("ab", 0.1, (3, 3)), X_MIN + r"'ab'$"),
    ((None, 0.1, (3,)), X_MIN + r"None$"),
    (([True, False], 0.1, (3, 3)), X_MIN + r"\[True, False\]$"),
    # h
    ((jnp.zeros(2), jnp.array([0.1, 0.2]), (3, 3)), H + r"an array of shape \(2,\)$"),
    ((jnp.zeros(1), True, (3,)), H + r"True$"),
    ((jnp.zeros(1), np.bool_(True), (3,)), H + r"np.True_$"),
    ((jnp.zeros(1), "0.1", (3,)), H + r"'0.1'$"),
    ((jnp.zeros(1), None, (3,)), H + r"None$"),
    ((jnp.zeros(1), 1j, (3,)), H + r"1j$"),
    ((jnp.zeros(1), -0.1, (3,)), r"^h must be > 0, got -0\.1$"),
    ((jnp.zeros(1), np.inf, (3,)), r"^h must be finite, got inf$"),
    # shape
    ((jnp.zeros(2), 0.1, (4,)), r"^shape must give one node count per axis of x_min \(2\), got \(4,\)$"),
    ((jnp.zeros(1), 0.1, (3, 3)), r"^shape must give one node count per axis of x_min \(1\), got \(3, 3\)$"),
    ((jnp.zeros(1), 0.1, (3.7,)), r"^shape\[0\] must be an integer >= 2, got 3\.7$"),
    ((jnp.zeros(2), 0.1, (3, True)), r"^shape\[1\] must be an integer >= 2, got True$"),
    ((jnp.zeros(1), 0.1, 3), r"^shape must be a tuple of node counts, one per axis of x_min, got 3$"),
    ((jnp.zeros(1), 0.1, "3"), r"^shape must be a tuple of node counts, one per axis of x_min, got '3'$"),
]


@pytest.mark.parametrize(
    "args, match",
    BAD_BOXES,
    ids=[
        "x_min 0-d",
        "x_min float",
        "x_min 2-d",
        "x_min 4 axes",
        "x_min empty",
        "x_min nan",
        "x_min strings",
        "x_min string",
        "x_min None",
        "x_min bools",
        "h vector",
        "h True",
        "h np.True_",
        "h string",
        "h None",
        "h complex",
        "h negative",
        "h inf",
        "shape of 1 for 2 axes",
        "shape of 2 for 1 axis",
        "shape 3.7",
        "shape True",
        "shape int",
        "shape string",
    ],
)
def test_grid_box_names_what_does_not_fit(args, match):
    _one_line(lambda: box(*args), match)


BAD_GRIDS = [
    (dict(x_min=jnp.zeros(2), h=0.1, n_nodes=4), r"^a Grid without shape is 1D: x_min must have 1 entry"),
    (dict(x_min=jnp.zeros(()), h=0.1, n_nodes=4), X_MIN + r"an array of shape \(\)$"),
    (dict(x_min=jnp.zeros(1), h=jnp.ones(1), n_nodes=4), H + r"an array of shape \(1,\)$"),
    (dict(x_min=jnp.zeros(1), h=True, n_nodes=4), H + r"True$"),
    (dict(x_min=[np.inf], h=0.1, n_nodes=4), X_MIN + r"\[inf\]$"),
]


@pytest.mark.parametrize(
    "kw, match", BAD_GRIDS, ids=["no shape, 2 axes", "x_min 0-d", "h vector", "h True", "x_min inf"]
)
def test_grid_names_what_does_not_fit(kw, match):
    _one_line(lambda: jm.Grid(**kw), match)


def test_grid_box_takes_lists_python_numbers_and_numpy_integers():
    want = jm.Grid.box(jnp.zeros(2), jnp.asarray(0.1), (3, 4))
    for got in (
        box([0.0, 0.0], 0.1, (3, 4)),
        box(np.zeros(2), np.float64(0.1), [np.int64(3), 4]),
        box([0, 0], 0.1, (3, 4)),  # integer positions, as floats
    ):
        assert got.axes == (3, 4) and got.dim == 2
        assert got.x_min.dtype == got.h.dtype == jnp.float64 and got.h.shape == ()
        np.testing.assert_array_equal(np.asarray(got.nodes()), np.asarray(want.nodes()))
    one = box([0.5], 1, (3,))
    assert one.shape is None and one.h.dtype == jnp.float64
    np.testing.assert_array_equal(np.asarray(one.nodes())[:, 0], [0.5, 1.5, 2.5])
    assert jm.Grid(x_min=[0.0], h=0.5, n_nodes=3).x_max.tolist() == [1.0]


def test_grid_takes_a_traced_spacing_and_position():
    x_max = jax.jit(lambda x, h: jm.Grid.box(x, h, (3, 5)).x_max)(jnp.zeros(2), jnp.asarray(0.5))
    assert x_max.tolist() == [1.0, 2.0]
    d = jax.grad(lambda h: jnp.sum(jm.Grid.box(jnp.zeros(2), h, (3, 5)).nodes()))(jnp.asarray(0.5))
    assert float(d) == float(np.sum(np.asarray(jm.Grid.box(jnp.zeros(2), 1.0, (3, 5)).nodes())))
    # a scene's grid under jax.grad with respect to its spacing
    d = jax.grad(lambda h: jm.GasExpansion(cells=2, h=h, pad=1).grid().x_max[0])(0.25)
    assert float(d) == 3.0


def test_grid_box_takes_python_numbers_in_float32_without_a_warning():
    """With float64 off (JAX's default), lists and Python numbers become float32 silently, as JAX makes
    them; an explicit float64 request would warn that it is truncated."""
    import warnings

    with float32():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            grids = [box([0.0, 0.0], 0.1, (3, 3)), raw(jm.Grid)(x_min=[0.0], h=0.1, n_nodes=5)]
            grids.append(box(np.zeros(1), np.float64(0.1), (4,)))  # NumPy float64 too
        for grid in grids:
            assert grid.x_min.dtype == jnp.float32 and jnp.asarray(grid.h).dtype == jnp.float32
