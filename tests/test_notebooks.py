"""The notebooks run top to bottom (at a small size) and compute what they tell the reader.

Each notebook is executed with one extra cell appended that prints, as JSON, the values the story
rests on; the test checks those values against numbers known independently of the notebook.
"""

import json
import pathlib

import numpy as np
import pytest

import jaxmpm as jm

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

pytestmark = pytest.mark.slow

NOTEBOOKS = pathlib.Path(__file__).parent.parent / "notebooks"
MARK = "NOTEBOOK-CHECK "

# The values each notebook exports, as Python expressions evaluated in its kernel after the last cell.
EXPORTS = {
    "talk.ipynb": {
        "growth": "{k: v.tolist() for k, v in growth.items()}",
        "grad": "float(g)",
        "central_difference": "float(fd)",
        "errors": "np.asarray(errs).tolist()",
    },
    "sensitivity.ipynb": {
        "grad_beta": "float(g['beta'])",
        "central_difference": "float(fd)",
        "sweeps": "len(results)",
        "variants": "len(variants)",
        "max_error_mpq_ac": "float(np.nanmax(mpq_ac['error']))",
        "max_error_spq": "float(np.nanmax(spq['error']))",
    },
    "calibration.ipynb": {
        "truth": "truth",
        "fitted": "{k: float(v) for k, v in fit.fitted.items()}",
        "converged": "[(n, float(gm), float(p)) for n, gm, p, _ in rows]",
        "std": "fit.std",
        "correlation": "float(fit.correlation[0, 1])",
        "expected_std": "{f'{1e3 * t:g}': s for t, s in expected.items()}",
        "expected_correlation": "[corr_short, corr_long]",
        "expected_as_data": "as_data",
        "t_turn": "t_turn",
        "t_peak": "t_peak",
        "short_warning": "fit_short.warning",
        "long_warning": "fit_long.warning",
        "short_correlation": "float(fit_short.correlation[0, 1])",
        "profile_ok": "{k: bool(p['ok'].all()) for k, p in profiles.items()}",
        "rise": "rise",
        "members": "members",
        "failures": "len(ens.failures())",
        "inside_data": "inside_data",
        "width_data": "width_data",
        "width_after": "width_after",
        "ensemble_start": "float(np.max(np.abs(x_free[:, 0] - 1.0)))",
    },
    "ensembles.ipynb": {
        "members": "members",
        "failures": "len(ens.failures())",
        "x_free_start": "x_free[:, 0].tolist()",
        "shape": "list(x_free.shape)",
        "saved_times": "len(ts)",
        "spread": "float(hi[k] - lo[k])",
        "median_peak": "float(med[k])",
    },
}


def run_notebook(name: str, monkeypatch) -> dict:
    monkeypatch.setenv("JAXMPM_NOTEBOOK_SMALL", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    path = NOTEBOOKS / name
    nb = nbformat.read(path, as_version=4)
    exports = ", ".join(f"{k!r}: {v}" for k, v in EXPORTS[name].items())
    nb.cells.append(nbformat.v4.new_code_cell(f"import json\nprint({MARK!r} + json.dumps({{{exports}}}))"))
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}
    )
    client.execute()  # raises CellExecutionError, with the failing cell's traceback, on any error
    text = "".join(o.get("text", "") for o in nb.cells[-1].get("outputs", []))
    line = next(ln for ln in text.splitlines() if ln.startswith(MARK))
    return json.loads(line[len(MARK) :])


def test_notebooks_are_all_checked():
    assert sorted(p.name for p in NOTEBOOKS.glob("*.ipynb")) == sorted(EXPORTS)


def test_talk_notebook(monkeypatch):
    out = run_notebook("talk.ipynb", monkeypatch)
    # 3 cells of 2 particles: the first and last two particles sit in boundary cells (5/8), the
    # middle two inside (1); artificial cells make every particle exact.
    for name in jm.INTERPOLATORS:
        np.testing.assert_allclose(
            out["growth"][name], [5 / 8, 5 / 8, 1, 1, 5 / 8, 5 / 8], rtol=0, atol=1e-12
        )
    np.testing.assert_allclose(out["growth"]["mpq + artificial cells"], np.ones(6), rtol=0, atol=1e-12)
    assert out["grad"] == pytest.approx(out["central_difference"], rel=1e-7)  # measured 7.9e-9
    errs = np.asarray(out["errors"])
    assert errs.shape == (4,) and np.all(np.isfinite(errs)) and np.all(errs > 0) and np.all(errs < 0.01)


def test_sensitivity_notebook(monkeypatch):
    out = run_notebook("sensitivity.ipynb", monkeypatch)
    assert out["grad_beta"] == pytest.approx(out["central_difference"], rel=1e-4)
    assert out["sweeps"] == out["variants"] * 2  # each method and artificial cells: beta and h
    assert out["max_error_mpq_ac"] < out["max_error_spq"]


def test_calibration_notebook(monkeypatch):
    out = run_notebook("calibration.ipynb", monkeypatch)
    # 1% noise on 31 samples: the constants come back within a few per cent
    for k, v in out["truth"].items():
        assert out["fitted"][k] == pytest.approx(v, rel=0.05)
    # fitted to the converged reference, the constants approach the truth as the grid is refined
    (_, g8, p8), (_, g16, p16) = out["converged"]
    assert abs(g16 / 1.4 - 1) < abs(g8 / 1.4 - 1) or abs(p16 / 3e5 - 1) < abs(p8 / 3e5 - 1)
    # the fit's standard errors: about half a per cent, and the truth within 3 of them
    for k, v in out["truth"].items():
        assert 0 < out["std"][k] < 0.02 * v
        assert abs(out["fitted"][k] - v) < 3 * out["std"][k]
    assert 0.9 < out["correlation"] < 0.99
    # experiment design at the truth: a window past the turnaround (12 ms) determines gamma tens of
    # times better than one that ends before it (3 ms), where gamma and P0 are all but one combination
    e = out["expected_std"]
    assert e["3"]["gamma"] > e["6"]["gamma"] > e["12"]["gamma"] > 0
    assert e["3"]["gamma"] > 20 * e["12"]["gamma"] and e["3"]["P0"] > 5 * e["12"]["P0"]
    c_short, c_long = out["expected_correlation"]
    assert abs(c_short) > 0.99 > abs(c_long)
    # and it predicts the standard errors the fit of section 1 reports, before any data
    for k in out["truth"]:
        assert out["expected_as_data"][k] == pytest.approx(out["std"][k], rel=0.1)
    # the turnaround estimate is about 10% before the reference's maximum (8.4 ms)
    assert 0.8 < out["t_turn"] / out["t_peak"] < 0.95
    # the short window's fit warns, naming the correlation and the turnaround; the long one does not
    assert out["short_warning"] is not None and out["long_warning"] is None
    assert "turnaround" in out["short_warning"] and "correlated" in out["short_warning"]
    assert abs(out["short_correlation"]) > 0.99
    # the profile along the weakest direction: a valley for the short window, a bowl for the long one
    assert all(out["profile_ok"].values())
    assert 1.0 <= out["rise"]["short"] < 3.0 and out["rise"]["long"] > 10 * out["rise"]["short"]
    # the ensemble drawn from the fit: every member ran; the band, widened by the noise, holds the data
    # at most times, and it widens after the data end (extrapolation)
    assert out["failures"] == 0
    assert out["ensemble_start"] < 1e-12  # every member starts at the slab's length, 1 m
    assert out["inside_data"] >= 0.8
    assert 0 < out["width_data"] < out["width_after"]


def test_ensembles_notebook(monkeypatch):
    out = run_notebook("ensembles.ipynb", monkeypatch)
    assert out["failures"] == 0
    assert out["shape"] == [out["members"], out["saved_times"]]
    np.testing.assert_allclose(out["x_free_start"], 1.0, rtol=0, atol=1e-12)  # the slab is 1 m long
    assert out["spread"] > 0 and out["median_peak"] > 1.0
