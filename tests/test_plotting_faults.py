"""The figures under faults: ``profile_grid`` and ``time_series`` name a panel key, a panel's curves, a
curve's style and ``logy`` that do not fit, in one line and before anything is drawn or written; a
panel with no curves is drawn empty, without a legend (and without matplotlib's warning of one)."""

import warnings

import numpy as np
import pytest
from helpers import raw

from jaxmpm import plotting

X = np.arange(3.0)


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


def _grid(panels, path, **kwargs):
    return raw(plotting.profile_grid)(panels, ylabel="y", title="t", path=path, **kwargs)


def _series(series, path, **kwargs):
    return raw(plotting.time_series)(series, ylabel="y", title="t", path=path, **kwargs)


KEY = r"^a key of panels must be a \(row, column\) tuple of two labels, got "
GRID_CURVES = r"^panels\[\('r', 'c'\)\] must be a list of curves \(label, X, y, style\), got "

BAD_PANELS = [
    ({"ab": [("l", X, X, {})]}, KEY + r"'ab'$"),
    ({("a", "b", "c"): [("l", X, X, {})]}, KEY + r"\('a', 'b', 'c'\)$"),
    ({("a",): [("l", X, X, {})]}, KEY + r"\('a',\)$"),
    ({7: [("l", X, X, {})]}, KEY + r"7$"),
    ({("r", "c"): None}, GRID_CURVES + r"None$"),
    ({("r", "c"): "curve"}, GRID_CURVES + r"'curve'$"),
    ({("r", "c"): [("l", X, X)]}, GRID_CURVES + r"a curve of 3 entries \('l', "),
    ({("r", "c"): [None]}, GRID_CURVES + r"a curve None$"),
    (
        {("r", "c"): [("l", X, X, None)]},
        r"^the style of curve 'l' in panels\[\('r', 'c'\)\] must be a dict of line properties "
        r"\(\{\} for matplotlib's defaults\), got None$",
    ),
    (
        {("r", "c"): [("l", X, X, "o-")]},
        r"^the style of curve 'l' in panels\[\('r', 'c'\)\] must be a dict of line properties "
        r"\(\{\} for matplotlib's defaults\), got 'o-'$",
    ),
]


@pytest.mark.parametrize(
    "panels, match",
    BAD_PANELS,
    ids=["string key", "3-tuple key", "1-tuple key", "int key", "None curves", "string curves",
         "3-entry curve", "None curve", "None style", "string style"],
)  # fmt: skip
def test_profile_grid_names_a_panel_that_does_not_fit_before_drawing(tmp_path, panels, match):
    with pytest.raises(ValueError, match=match) as info:
        _grid(panels, tmp_path / "f.png")
    assert "\n" not in str(info.value)
    assert _files(tmp_path) == []


SERIES_CURVES = r"^series\['a'\] must be a list of curves \(label, t, y\), got "

BAD_SERIES = [
    ({"a": None}, SERIES_CURVES + r"None$"),
    ({"a": [("l", X)]}, SERIES_CURVES + r"a curve of 2 entries \('l', "),
    ({"a": [("l", X, X, {})]}, SERIES_CURVES + r"a curve of 4 entries \('l', "),
    ({"a": ["l"]}, SERIES_CURVES + r"a curve 'l'$"),
]


@pytest.mark.parametrize("series, match", BAD_SERIES, ids=["None", "2 entries", "4 entries", "string"])
def test_time_series_names_a_panel_that_does_not_fit_before_drawing(tmp_path, series, match):
    with pytest.raises(ValueError, match=match) as info:
        _series(series, tmp_path / "f.png")
    assert "\n" not in str(info.value)
    assert _files(tmp_path) == []


@pytest.mark.parametrize("logy", ["no", 1, None, np.float64(0.0)])
def test_time_series_refuses_a_logy_that_is_not_a_bool(tmp_path, logy):
    with pytest.raises(ValueError, match=r"^logy must be True or False, got ") as info:
        _series({"a": [("l", X, X + 1)]}, tmp_path / "f.png", logy=logy)
    assert "\n" not in str(info.value)
    assert _files(tmp_path) == []


def test_time_series_takes_a_numpy_bool_for_logy(tmp_path):
    assert _series({"a": [("l", X, X + 1)]}, tmp_path / "f.png", logy=np.bool_(False)).exists()


def test_a_panel_with_no_curves_is_drawn_empty_without_a_legend(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib warns of a legend with no curves
        assert _series({"a": [], "b": [("l", X, X + 1)]}, tmp_path / "s.png").exists()
        assert _series({"a": []}, tmp_path / "e.png", logy=False).exists()
        assert _grid({("r", "c"): [], ("r", "d"): [("l", X, X, {})]}, tmp_path / "g.png").exists()
    assert _files(tmp_path) == ["e.png", "g.png", "s.png"]
