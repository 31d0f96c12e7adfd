"""The talk's study at a small size: it writes its table, data and figures, and says what the talk says."""

import csv

import pytest

from jaxmpm.cli import main
from jaxmpm.studies._methods import METHODS

pytestmark = pytest.mark.slow


def test_study_talk_small(tmp_path, capsys):
    assert main(["study", "talk", "--out", str(tmp_path), "--small"]) == 0
    names = {p.name for p in tmp_path.iterdir()}
    assert {"table.md", "results.csv", "results.json", "separation.png"} <= names
    for t in ("0.0001", "0.00125"):
        for q in ("F", "x", "v"):
            assert f"{q}_t{t}.png" in names
            assert (tmp_path / f"{q}_t{t}.png").stat().st_size > 10_000
    rows = list(csv.DictReader(open(tmp_path / "results.csv")))
    assert len(rows) == len(METHODS) * 2 * 1 * 2  # methods x artificial cells x betas x times
    by = {(r["method"], r["artificial_cells"], r["t"]): r for r in rows}
    late = "0.00125"
    # The talk: MPQ with artificial cells is far more accurate than standard MPM at t = 0.00125.
    assert float(by[("MPQ", "1", late)]["F_max_rel"]) < float(by[("SPQ", "0", late)]["F_max_rel"]) / 5
    assert all(r["status"] == "ok" for r in rows)
    assert "| MPQ | 1 |" in (tmp_path / "table.md").read_text()


def test_sensitivity_figure_draws_a_curve_for_every_interpolator(tmp_path):
    """The sensitivity study's figure takes one colour per interpolator of the registry (every one of
    ``METHODS``, with and without artificial cells), so a new interpolator cannot break the study."""
    import numpy as np

    from jaxmpm.studies import sensitivity

    values = np.array([50.0, 100.0, 200.0])
    results = [
        dict(
            method=name,
            artificial_cells=ac,
            param="beta",
            values=values,
            error=1e-3 * values,
            derivative=1e-6 * (values - 100.0),
        )
        for name in METHODS
        for ac in (0, 1)
    ]
    path = tmp_path / "sensitivity_beta.png"
    sensitivity.figure(results, "beta", path, "s")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
