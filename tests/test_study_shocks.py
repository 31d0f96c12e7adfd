"""The studies' shock cases: the convergence study's shock tube and Noh rungs, and the stability
study's stiff shock tube."""

import json

import numpy as np
import pytest

from jaxmpm.studies import convergence, stability

pytestmark = pytest.mark.slow


def test_convergence_study_writes_the_shock_tables(tmp_path):
    out = convergence.main(str(tmp_path), small=True, methods=("CPDI",), scenes=["shock-tube (Sod)", "noh"])
    assert {"shock_runs", "shock_orders", "energy_drift"} <= set(
        out
    ) and "orders" not in out  # the smooth rungs did not run
    sod, noh = out["shock_orders"]
    assert sod["scene"] == "shock-tube (Sod)" and noh["scene"] == "noh" and sod["transfer"] == "FLIP"
    assert sod["rho_L1_order"] > 0.5 and sod["u_L1_order"] > 0.5  # CPDI converges on Sod
    assert abs(sod["energy_drift_finest"]) < 2e-3
    assert abs(noh["shock_cells_finest"]) < 2 and abs(noh["plateau_rho_finest"] / 4 - 1) < 0.05
    text = (tmp_path / "shocks.md").read_text()
    assert "| CPDI | FLIP |" in text and "shock - t/3 (cells)" in text
    saved = json.loads((tmp_path / "shocks.json").read_text())
    assert len(saved["runs"]) == 2 * len(convergence.shock_cases(True)[0].cells)
    assert not (tmp_path / "orders.md").exists()
    drift = out["energy_drift"]  # no viscosity, no walls: CPDI's energy error falls with refinement
    assert [r["cells"] for r in drift] == list(convergence.shock_cases(True)[0].cells)
    assert all(r["status"] == "ok" for r in drift) and abs(drift[-1]["energy_drift"]) < abs(
        drift[0]["energy_drift"]
    )
    assert "**Energy without dissipation**" in text


def test_stiff_shock_tube_names_every_breakdown():
    results = stability.shock_sweep("MPQ", small=True)
    assert [r["cfl"] for r in results] == list(stability.CFLS)
    for r in results:
        assert r["verdict"] != "SILENT NON-FINITE"
        if r["status"]:
            assert r["verdict"].startswith("broken at step") and r["fail_step"] >= 1
        else:
            assert np.isfinite(r["L1_rel"]) and r["verdict"] in ("accurate", "inaccurate")
            assert r["L1_rel"] == max(r["rho_L1_rel"], r["u_L1_rel"], r["p_L1_rel"])
    assert stability.shock_markdown(results).count("| MPQ |") == 1
