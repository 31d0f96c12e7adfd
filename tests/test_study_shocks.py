"""The studies' shock cases: the convergence study's shock tube, Noh and detonation rungs, and the
stability study's stiff shock tube and detonation against air."""

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


def test_convergence_study_gives_the_detonation_rows(tmp_path):
    out = convergence.main(str(tmp_path), small=True, methods=("CPDI",), scenes=["detonation"])
    case = next(c for c in convergence.shock_cases(True) if c.name == "detonation")
    runs, (order,) = out["shock_runs"], out["shock_orders"]
    assert [r["cells"] for r in runs] == list(case.cells) and out["energy_drift"] == []
    for r in runs:
        assert r["status"] == "ok" and r["smooth"] > 10 and "rho_L1" not in r
        assert all(np.isfinite(r[k]) and 0 < r[k] < 0.1 for k in convergence.DETONATION_ERRORS)
    assert runs[-1]["F_rms_rel"] < runs[0]["F_rms_rel"]  # CPDI converges on the CJ-Taylor wave
    # each particle starts with its detonation energy: kinetic plus internal is conserved but for the
    # burn's time error (measured -0.9% at 100 cells, CFL 0.3)
    assert all(-0.02 < r["energy_drift"] < 0.0 for r in runs)
    assert order["energy_drift_finest"] == runs[-1]["energy_drift"]
    assert order["scene"] == "detonation" and order["failures"] == ""
    for k in convergence.DETONATION_ERRORS:
        # first order: measured 0.93 (F) and 0.97 (p)
        assert 0.8 < order[f"{k}_order"] < 1.1 and order[f"{k}_finest"] == runs[-1][k]
    text = (tmp_path / "shocks.md").read_text()
    assert "**detonation**" in text and "| order F | order p |" in text and "| CPDI | FLIP |" in text
    assert "| p rms err (finest) | energy drift |" in text
    assert "**Energy without dissipation**" not in text
    saved = json.loads((tmp_path / "shocks.json").read_text())
    assert len(saved["runs"]) == len(case.cells) and saved["orders"][0]["F_rms_rel_order"] > 0.5


def test_shock_orders_never_fit_a_detonation_run_that_broke_down():
    rows = [
        dict(scene="detonation", method="M", transfer="FLIP", cells=n, h=1 / n, F_rms_rel=e, p_rms_rel=e)
        for n, e in ((50, 0.04), (100, 0.02), (200, float("nan")))
    ]
    rows[-1].update(F_max_rel=float("nan"), status="broke down at step 9, particle 3: F <= 0")
    for r in rows[:-1]:
        r.update(F_max_rel=2 * r["F_rms_rel"], status="ok")
    (o,) = convergence.shock_orders(rows)
    # the fit is over the runs that finished; the finest pair has no order, its finer run broke down
    assert o["F_rms_rel_order"] == pytest.approx(1.0) and np.isnan(o["p_rms_rel_order_finest"])
    assert np.isnan(o["F_rms_rel_finest"]) and o["failures"].startswith("200 cells: broke down at step 9")
    assert "energy_drift_finest" not in o and "rho_L1_order" not in o


def test_detonation_against_air_gives_a_status_per_run():
    scene, slab = stability.detonation_scene(100)
    air = scene.parts[1]
    p_air = float(air.material.pressure(air.rho0, air.energy))
    assert float(slab.cj()["P_CJ"]) / p_air == pytest.approx(1e5, rel=1e-12)
    assert scene.layout().box  # the body fills its box: artificial cells are allowed
    results = stability.detonation_sweep("CPDI", small=True)
    assert [(r["artificial_cells"], r["cfl"]) for r in results] == [
        (ac, c) for ac in (0, 1) for c in stability.CFLS
    ]
    for r in results:
        assert r["verdict"] != "SILENT NON-FINITE"
        if r["status"]:
            assert r["verdict"].startswith("broken at step") and r["fail_step"] >= 1
        else:
            assert r["verdict"] in ("accurate", "inaccurate") and r["undisturbed"] > 10
            assert np.isfinite(r["F_max_rel"]) and 0 < r["air_F_min"] < 0.5  # the air was shocked
    assert any(r["verdict"] == "accurate" for r in results)  # CPDI at a small CFL number
    table = stability.detonation_markdown(results)
    assert table.count("| CPDI | 0 |") == 1 and table.count("| CPDI | 1 |") == 1


def test_stability_tables_name_every_failed_quantity():
    """Every status bit has a table name (a run failing only on products in tension raised 'min()
    arg is an empty sequence' in the detonation table), and the cell is the lowest bit's."""
    from jaxmpm import status as st_bits

    assert set(stability.SHORT) == set(st_bits.QUANTITY)
    r = dict(method="MPQ", artificial_cells=0, cfl=0.5, status=st_bits.PRODUCTS_TENSION, fail_step=12)
    r["verdict"] = "broken at step 12 on particle 3: detonation products in tension"
    assert "| MPQ | 0 | tension@12 |" in stability.detonation_markdown([r])
    r2 = dict(r, status=st_bits.PRODUCTS_TENSION | st_bits.NEGATIVE_ENERGY)
    assert "| MPQ | 0 | e<0@12 |" in stability.detonation_markdown([r2])


@pytest.mark.parametrize(
    "given, used",
    [
        (None, ("FLIP",)),
        (("FLIP", "PIC", "APIC"), ("FLIP", "PIC", "APIC")),
        (["FLIP", "PIC", "APIC"], ("FLIP", "PIC", "APIC")),
        (["PIC"], ("PIC",)),
    ],
)
def test_the_shock_cases_run_the_transfers_given(tmp_path, monkeypatch, given, used):
    """The shock cases run FLIP unless ``transfers`` is given, then those it names, whether a tuple or a
    list (all three as a tuple ran FLIP alone)."""
    ran = []
    monkeypatch.setattr(
        convergence, "run_shock_case", lambda case, method, transfer: ran.append(transfer) or []
    )
    monkeypatch.setattr(convergence, "shock_orders", lambda rows: [])
    monkeypatch.setattr(convergence, "shock_markdown", lambda rows, cases: "")
    convergence.main(str(tmp_path), small=True, transfers=given, methods=("CPDI",), scenes=["noh"])
    assert tuple(ran) == used


@pytest.mark.parametrize("name", ["transfers", "methods", "scenes"])
def test_an_empty_list_of_names_is_refused(tmp_path, name):
    with pytest.raises(ValueError, match=rf"^{name} must be a sequence of names, one or more of"):
        convergence.main(str(tmp_path), small=True, **{name: []})
