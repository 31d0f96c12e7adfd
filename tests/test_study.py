"""The talk's study at a small size: it writes its table, data and figures, and says what the talk says."""

import csv

import numpy as np
import pytest

import jaxmpm as jm
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


def test_study_talk_whose_runs_all_break_down_marks_them_in_table_and_figures(tmp_path, capsys, monkeypatch):
    """A step 10 times the stable one breaks every run at its first step: the table shows "-" for
    their errors at the late time, and each late figure is drawn with its panels empty and a note
    naming every run left out (drawing them raised 'panels must be a non-empty dict')."""
    from jaxmpm.studies import talk

    monkeypatch.setattr(talk, "DT", 1e-3)
    result = talk.main(str(tmp_path), small=True)
    late = [r for r in result["table"] if r["t"] == talk.TIMES[-1]]
    assert len(late) == len(METHODS) * 2 and all(r["status"] == "broke down at step 1" for r in late)
    table = (tmp_path / "table.md").read_text()
    assert table.count("| - | - | - | - | - | - | broke down at step 1 |") == len(METHODS) * 2
    assert "nan" not in table
    for q in ("F", "x", "v"):
        assert (tmp_path / f"{q}_t0.00125.png").stat().st_size > 10_000


def test_profile_grid_writes_a_note_under_the_grid(tmp_path):
    import matplotlib.image
    import numpy as np

    from jaxmpm import plotting

    X = np.linspace(0.0, 1.0, 5)
    panels = {("a", "SPQ"): [("beta = 1", X, X, {})], ("a", "MPQ"): []}
    plain = plotting.profile_grid(panels, ylabel="y", title="t", path=tmp_path / "plain.png")
    noted = plotting.profile_grid(
        panels, ylabel="y", title="t", path=tmp_path / "noted.png", note="Not drawn: MPQ broke down"
    )
    a, b = matplotlib.image.imread(plain), matplotlib.image.imread(noted)
    assert a.shape == b.shape
    rows = a.shape[0] // 10  # the bottom tenth: the x labels without the note, the note under them

    def ink(image):  # pixels that are not white
        return int(np.sum(np.any(image[..., :3] < 0.9, axis=-1)))

    assert ink(b[-rows:]) > ink(a[-rows:]) + 100


def test_sensitivity_figure_draws_a_curve_for_every_interpolator(monkeypatch, tmp_path):
    """The sensitivity study's figure takes one colour per interpolator of the registry (every one of
    ``METHODS``, with and without artificial cells), so a new interpolator cannot break the study."""
    import matplotlib.colors as mcolors
    import numpy as np

    from jaxmpm.studies import sensitivity

    figures = []
    real = sensitivity.save_figure

    def save(fig, path, dpi):
        figures.append(fig)
        return real(fig, path, dpi)

    monkeypatch.setattr(sensitivity, "save_figure", save)

    values = np.array([50.0, 100.0, 200.0])
    results = [
        dict(
            method=name,
            artificial_cells=ac,
            param="beta",
            values=values,
            error=1e-3 * values,
            derivative=1e-6 * (values - 100.0),
            status=np.zeros(3, dtype=np.int32),
        )
        for name in METHODS
        for ac in (0, 1)
    ]
    labels = [name + suffix for name in METHODS for suffix in ("", " + AC")]  # 2 * len(METHODS)
    path = tmp_path / "sensitivity_beta.png"
    sensitivity.figure(results, "beta", path, "s")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(figures) == 1
    for ax in figures[0].axes:  # the error and its derivative: a curve per method and setting each
        curves = [line for line in ax.get_lines() if line.get_label() in labels]
        assert sorted(line.get_label() for line in curves) == sorted(labels)
        colour = {line.get_label(): mcolors.to_hex(line.get_color()) for line in curves}
        dashed = {line.get_label(): line.get_linestyle() == "--" for line in curves}
        for name in METHODS:  # one colour per interpolator, the same with and without AC
            assert colour[name] == colour[name + " + AC"]
            assert not dashed[name] and dashed[name + " + AC"]
        assert len({colour[name] for name in METHODS}) == len(METHODS)


def test_convergence_orders_fit_what_finished_and_give_no_finest_pair_past_a_breakdown():
    """Errors falling by 4 per halving of h are order 2; where the finest run broke down (NaN) the fit
    is over the others, and the finest pair has no order: the coarser pair is not the finest."""
    import math

    from jaxmpm.studies.convergence import fit_order

    h = [1 / 16, 1 / 32, 1 / 64, 1 / 128]
    assert fit_order(h, [1e-2, 2.5e-3, 6.25e-4, 1.5625e-4]) == pytest.approx((2.0, 2.0), rel=1e-12)
    fit, pair = fit_order(h, [1e-2, 2.5e-3, 6.25e-4, math.nan])
    assert fit == pytest.approx(2.0, rel=1e-12) and math.isnan(pair)
    fit, pair = fit_order(h, [1e-2, math.nan, 6.25e-4, 1.5625e-4])  # a coarser breakdown: the pair stands
    assert fit == pytest.approx(2.0, rel=1e-12) and pair == pytest.approx(2.0, rel=1e-12)
    assert all(math.isnan(v) for v in fit_order(h, [1e-2, math.nan, math.nan, math.nan]))


def test_convergence_main_refuses_unknown_names_before_it_runs(tmp_path):
    """An unknown scene ran nothing and returned {}; an unknown method raised KeyError('cpdi') after
    the runs before it."""
    from jaxmpm.studies import convergence

    out = tmp_path / "out"
    with pytest.raises(ValueError, match=r"^scenes: 'riemann' is not one of \['manufactured"):
        convergence.main(str(out), small=True, scenes=["riemann"])
    with pytest.raises(ValueError, match=r"^methods: 'cpdi' is not one of \['SPQ', "):
        convergence.main(str(out), small=True, methods=("cpdi",))
    with pytest.raises(ValueError, match=r"^transfers must be a sequence of names, one or more of"):
        convergence.main(str(out), small=True, transfers="FLIP")
    assert not out.exists()


def test_work_precision_figure_names_its_resolutions_and_the_runs_it_leaves_out(tmp_path, monkeypatch):
    """The title's resolutions are the runs' (it read 16 to 1024 cells for --small), and a run that broke
    down is named in its method's legend entry instead of vanishing from the curve."""
    import math

    from jaxmpm.studies import work_precision

    drawn = {}
    monkeypatch.setattr(work_precision.OUTPUTS, "figure", lambda fig, path, dpi: drawn.update(fig=fig))
    rows = [
        dict(method="SPQ", cells=16, wall_s=0.1, x_rms_abs=1e-3),
        dict(method="SPQ", cells=64, wall_s=0.4, x_rms_abs=math.nan),
        dict(method="MPQ", cells=16, wall_s=0.2, x_rms_abs=2e-3),
        dict(method="MPQ", cells=64, wall_s=0.8, x_rms_abs=5e-4),
    ]
    work_precision.figure(rows, tmp_path / "wp.png")
    ax = drawn["fig"].axes[0]
    assert ax.get_title() == "Work-precision: neo-Hookean, A = 0.05, 16 to 64 cells"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["SPQ (not shown, broke down: 64 cells)", "MPQ"]


def test_multid_first_steps_report_a_breakdown_in_the_table(monkeypatch):
    """A first step beyond the stable limit is reported as such in the study's table (with throw left
    on it raised SimulationError out of the study)."""
    from jaxmpm.studies import multid

    monkeypatch.setattr(multid, "DT", 1e-3)
    rows = multid.first_steps((2,))
    assert len(rows) == 2 * len(METHODS) and all(r["failure"] is not None for r in rows)
    lines = multid.first_step_markdown(rows)
    assert len(lines) == 4 + len(rows)
    assert "| 2 | spq | 0 | broke down at step 1: time step beyond the stable limit" in lines[4]
    assert all(line.endswith("| - | - |") for line in lines[4:])


def test_multid_blast_gap_figure_names_a_breakdown(monkeypatch, tmp_path):
    """The blast's corner-gap curves of a run that broke down stop at its last good frame, and their
    legend says at which step it broke down (it named only the method)."""
    from jaxmpm.studies import multid

    blast = jm.Blast
    monkeypatch.setattr(jm, "Blast", lambda **kw: blast(**{**kw, "P0": 1e7}))  # a 100:1 charge breaks
    b = multid.blast(60, 10, cells=4)
    steps = {name: b[name]["failure"]["step"] for name in ("cpdi", "mpq")}
    legends = {}

    def save(fig, path):
        for ax in fig.axes:
            if ax.get_legend() is not None:
                legends[path.name] = [t.get_text() for t in ax.get_legend().get_texts()]
        return path

    monkeypatch.setattr(multid, "_save", save)
    aligned = [dict(interpolator="mpq", cells=8, failure=None, x_rms_abs=1e-3, order_fit=float("nan"))]
    multid._figures(dict(blast=b, axis_aligned_2d=aligned), tmp_path)
    assert legends["blast_gap.png"] == [
        f"CPDI: its own domains (broke down at step {steps['cpdi']})",
        f"MPQ: its own domains (broke down at step {steps['mpq']})",
        f"MPQ: parallelograms from x, F (broke down at step {steps['mpq']})",
    ]


def test_sensitivity_figure_names_the_values_whose_runs_broke_down(monkeypatch, tmp_path):
    """A run of the sensitivity sweep that broke down is a gap in its curve (NaN, never a number), and
    the legend names its parameter value (the gap was unexplained)."""
    from jaxmpm.studies import sensitivity

    r = sensitivity.sweep("SPQ", 0, "beta", [200.0, 3e4], cells=4)
    assert r["status"][0] == 0 and r["status"][1] != 0
    assert np.isfinite(r["error"][0]) and np.isnan(r["error"][1]) and np.isnan(r["derivative"][1])
    legends = []

    def save(fig, path, dpi):
        legends.extend(t.get_text() for t in fig.axes[0].get_legend().get_texts())

    monkeypatch.setattr(sensitivity, "save_figure", save)
    sensitivity.figure([r], "beta", tmp_path / "f.png", "s")
    assert legends == ["SPQ (broke down at beta = 30000)"]
