"""Faults of ``jaxmpm study``: a user's file in a study's folder is refused before the study runs, a
full disk never leaves a partial file nor loses the previous run's, and a study never reports the
state of a run that broke down as finished, nor an exact error where the exact solution does not
hold."""

import errno
import importlib
import json
import re

import numpy as np
import pytest
from helpers import usage

import jaxmpm as jm
import jaxmpm._files
from jaxmpm.cli import main
from jaxmpm.cli.study import MARK, STUDIES
from jaxmpm.studies import multid, stability, talk
from jaxmpm.studies._output import Files

PNG_END = b"IEND\xaeB`\x82"  # the last chunk of a whole PNG


def test_every_study_names_the_files_it_writes():
    for name, module in STUDIES.items():
        outputs = importlib.import_module(f"jaxmpm.studies.{module}").OUTPUTS
        assert isinstance(outputs, Files) and outputs.names, name
    files = Files("table.md", "a.png")
    with pytest.raises(ValueError, match="notes.txt is not one of the study's files"):
        files.text("notes.txt", "x")
    assert files.leftover(".table.md.123-0123abcd.tmp") and not files.leftover(".notes.txt.1-0123abcd.tmp")
    assert not files.leftover(".table.md.tmp")
    with pytest.raises(ValueError, match="bare file name"):
        Files("sub/table.md")


@pytest.fixture
def ran(monkeypatch):
    """``talk.main`` replaced by a record of the folders it was given: the claim, not the study."""
    calls = []
    monkeypatch.setattr(talk, "main", lambda out, small: calls.append(out))
    return calls


def test_a_users_file_in_a_studys_own_folder_is_refused_before_it_runs(capsys, tmp_path, ran):
    out = tmp_path / "talk"
    out.mkdir()
    (out / MARK).write_text("talk\n")
    (out / "table.md").write_text("the study's table")  # the study's own: replaced on a rerun
    (out / "notes.txt").write_text("my notes")
    line = usage(capsys, ["study", "talk", "--small", "--out", str(out)], "--out")
    assert "notes.txt" in line and "--overwrite" in line and "did not write" in line
    assert ran == [] and (out / "notes.txt").read_text() == "my notes"
    (out / "more.txt").write_text("more")
    usage(capsys, ["study", "talk", "--small", "--out", str(out)], "(more.txt and 1 more)")  # sorted
    assert main(["study", "talk", "--small", "--out", str(out), "--overwrite"]) == 0
    assert ran == [str(out)] and (out / "notes.txt").read_text() == "my notes"
    assert (out / MARK).read_text() == "talk\n"
    (out / "notes.txt").unlink()
    (out / "more.txt").unlink()
    assert main(["study", "talk", "--small", "--out", str(out)]) == 0  # its own files only
    assert len(ran) == 2 and (out / "table.md").read_text() == "the study's table"


def test_a_folder_where_the_study_marks_its_folder_is_refused_before_it_runs(capsys, tmp_path, ran):
    out = tmp_path / "talk"
    (out / MARK).mkdir(parents=True)
    for extra in ([], ["--overwrite"]):
        usage(capsys, ["study", "talk", "--small", "--out", str(out), *extra], f"{MARK} is a folder")
    assert ran == [] and (out / MARK).is_dir()


def test_a_temporary_file_a_killed_run_left_is_the_studys_own(capsys, tmp_path, ran):
    out = tmp_path / "talk"
    out.mkdir()
    (out / MARK).write_text("talk\n")
    leftover = out / ".results.json.4242-0badcafe.tmp"
    leftover.write_text('{"ro')
    (out / f".{MARK}.4242-0badcafe.tmp").write_text("ta")
    assert main(["study", "talk", "--small", "--out", str(out)]) == 0
    assert not leftover.exists() and ran == [str(out)] and sorted(p.name for p in out.iterdir()) == [MARK]
    (out / ".notes.txt.4242-0badcafe.tmp").write_text("not the study's")
    usage(capsys, ["study", "talk", "--small", "--out", str(out)], ".notes.txt.4242-0badcafe.tmp")
    (out / MARK).write_text("convergence\n")  # another study's folder: its files are not talk's
    (out / ".notes.txt.4242-0badcafe.tmp").unlink()
    leftover.write_text('{"ro')
    line = usage(capsys, ["study", "talk", "--small", "--out", str(out)], "of `jaxmpm study convergence`")
    assert leftover.name in line and leftover.exists() and len(ran) == 1


class FullDisk:
    """``open`` for ``jaxmpm._files`` (where every study's file is written): files written through it
    take ``room`` bytes in all, and the write that would pass that fails with ENOSPC."""

    def __init__(self, room: int):
        self.room = room
        self.opened = []

    def __call__(self, path, mode):
        self.opened.append(path)
        f = open(path, mode)
        disk = self

        class Filling:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                f.close()

            def write(self, data):
                if len(data) > disk.room:
                    f.write(bytes(data[: disk.room]))
                    disk.room = 0
                    raise OSError(errno.ENOSPC, "No space left on device")
                disk.room -= len(data)
                return f.write(data)

            def __getattr__(self, name):
                return getattr(f, name)

        return Filling()


@pytest.mark.slow
def test_a_disk_that_fills_while_a_study_writes_leaves_whole_files(tmp_path, monkeypatch, capsys):
    """The talk's study (one interpolator) written, each of its files through a temporary file renamed
    into place, then rerun on a disk that fills half-way through its second figure: the error is the
    OSError (``jaxmpm`` says it in one line, status 74), every file of the first run is still there,
    each whole, the old one or the new one, and no temporary file is left."""
    monkeypatch.setattr(talk, "METHODS", {"MPQ": talk.METHODS["MPQ"]})
    out = tmp_path / "talk"
    roomy = FullDisk(10**9)
    monkeypatch.setattr(jaxmpm._files, "open", roomy, raising=False)
    talk.main(str(out), small=True)
    # every file written once, through a temporary file of write_whole's (".NAME.<pid>-<hex>.tmp")
    written = sorted(re.fullmatch(r"\.(.+)\.\d+-[0-9a-f]{8}\.tmp", p.name)[1] for p in roomy.opened)
    assert written == sorted(talk.OUTPUTS.names)
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(before) == set(talk.OUTPUTS.names)
    tables = ("table.md", "results.csv", "results.json")
    figures = [n for n in talk.OUTPUTS.names if n.endswith(".png")]
    room = sum(len(before[n]) for n in (*tables, figures[0])) + 1000  # 1000 bytes into the second figure
    disk = FullDisk(room)
    monkeypatch.setattr(jaxmpm._files, "open", disk, raising=False)
    with pytest.raises(OSError) as e:
        talk.main(str(out), small=True)
    assert e.value.errno == errno.ENOSPC and disk.room == 0
    assert e.value.filename == str(out / figures[1])  # the file, for `jaxmpm: error: cannot write FILE: ...`
    after = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(after) == set(before)  # nothing lost, no temporary file left
    for name in ("table.md", "results.csv"):  # written again before the disk filled: whole
        assert after[name].count(b"\n") == before[name].count(b"\n") and after[name].endswith(b"\n")
    assert len(json.loads(after["results.json"])["rows"]) == len(json.loads(before["results.json"])["rows"])
    assert after[figures[0]].endswith(PNG_END)
    for name in figures[1:]:  # the figure the disk filled on, and those after it: the first run's
        assert after[name] == before[name]
    monkeypatch.setattr(jaxmpm._files, "open", FullDisk(0), raising=False)
    with pytest.raises(OSError):  # full from the start: the first file fails, every file is the old one
        talk.main(str(tmp_path / "new"), small=True)
    assert list((tmp_path / "new").iterdir()) == []


@pytest.mark.slow
def test_a_full_disk_under_jaxmpm_study_is_one_line_naming_the_file(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(talk, "METHODS", {"MPQ": talk.METHODS["MPQ"]})
    monkeypatch.setattr(jaxmpm._files, "open", FullDisk(len("talk\n")), raising=False)  # the mark fits
    out = tmp_path / "talk"
    assert main(["study", "talk", "--small", "--out", str(out)]) == 74
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and re.fullmatch(
        rf"jaxmpm: error: cannot write {re.escape(str(out))}/[\w.]+: No space left on device", lines[0]
    ), lines


def test_a_disk_too_full_for_the_studys_mark_is_a_full_disk(tmp_path, monkeypatch, capsys, ran):
    monkeypatch.setattr(jaxmpm._files, "open", FullDisk(0), raising=False)
    out = tmp_path / "talk"
    assert main(["study", "talk", "--small", "--out", str(out)]) == 74
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"jaxmpm: error: cannot write --out {out}: No space left on device"]
    assert ran == [] and list(out.iterdir()) == []


def test_the_stability_map_gives_no_error_for_a_run_that_broke_down():
    """SPQ expanding to F = 2 finishes at CFL 0.1 and breaks down at 1.5, as does the strong
    compression: the error of a run that broke down is None (not that of its last good state), and its
    verdict names the step."""
    rows = {r["label"]: r for r in stability.cases(small=True)}
    members = [
        dict(rows["expand to F=2"], cfl=0.1),
        dict(rows["expand to F=2"], cfl=1.5),
        dict(rows["compress to F=0.05"], cfl=1.5),
    ]
    finished, *broken = stability.sweep("SPQ", 0, members)
    assert finished["status"] == 0 and np.isfinite(finished["F_max_rel"]) and finished["F_max_rel"] > 0
    assert finished["verdict"] in ("accurate", "inaccurate")
    for r in broken:
        assert r["status"] and r["F_max_rel"] is None and r["finite"]
        assert r["verdict"].startswith(f"broken at step {r['fail_step']} on particle")
        assert stability._code(r).endswith(f"@{r['fail_step']}")


@pytest.mark.slow
def test_the_stiff_shock_tube_is_measured_where_its_exact_solution_holds(monkeypatch):
    """The open tube's exact solution holds until the shock reaches the wall (``t_valid``): every
    finished run is measured before that, its shock several cells short of the wall."""
    for cells in (100, 200):  # the small and the full study's tube
        tube = jm.ShockTube(cells=cells, h=1.0 / cells, **stability.STIFF)
        assert stability.STIFF_T < 0.9 * float(tube.t_valid)
    measured = []
    euler_errors = jm.euler_errors

    def record(scene, state, body, **kw):
        measured.append(float(state.t) <= float(scene.t_valid))
        return euler_errors(scene, state, body, **kw)

    monkeypatch.setattr(jm, "euler_errors", record)
    results = stability.shock_sweep("CPDI", small=True)
    finished = [r for r in results if not r["status"]]
    assert measured == [True] * len(finished) and finished  # each one at a time the exact solution holds
    for r in results:
        keys = ("rho_L1_rel", "u_L1_rel", "p_L1_rel", "L1_rel")
        if r["status"]:
            assert all(r[k] is None for k in keys) and r["verdict"].startswith("broken at step")
        else:
            assert all(np.isfinite(r[k]) for k in keys) and r["L1_rel"] == max(r[k] for k in keys[:3])
    assert any(r["status"] for r in results)  # CFL >= 1 breaks down at the first step
    assert stability.shock_markdown(results).count("F<=0@1") >= 1


@pytest.mark.slow
def test_the_multid_large_run_gives_no_throughput_for_a_run_that_broke_down(monkeypatch):
    simulate_timed = jm.simulate_timed
    # a step far beyond the stable limit: every run breaks down at its first step
    monkeypatch.setattr(jm, "simulate_timed", lambda *a, dt, **kw: simulate_timed(*a, dt=1.0, **kw))
    rows = multid.large_2d(cells=4, steps=3)
    assert [r["interpolator"] for r in rows] == ["spq", "cpdi", "mpq"]
    for r in rows:
        assert r["failure"].endswith("at step 1"), r
        assert r["mparticle_steps_per_s"] is None and r["F_max_rel"] is None


def test_the_multid_tables_give_no_number_for_a_run_that_broke_down():
    blast = dict(
        t=[0.0, 1e-4],
        gap_own=[0.0, 0.5],
        gap_implied=[0.0, 0.7],
        steps_taken=14,
        failure=dict(step=15, quantities=["F <= 0 (the particle's domain inverted)"]),
        energy=None,
        params={},
        dt=1e-5,
    )
    result = dict(
        first_step=[],
        blast=dict(cpdi=dict(blast, failure=None, energy=5.7), mpq=blast),
        large_2d=[
            dict(
                interpolator="mpq",
                particles=4,
                steps=5,
                compile_s=1.0,
                run_s=0.1,
                mparticle_steps_per_s=None,
                failure="F <= 0 at step 3",
                F_max_rel=None,
            )
        ],
        machine="m",
        wall_s=1.0,
    )
    text = multid._markdown(result)
    assert "| cpdi | 14 | none | 0.5 | 0.7 | 5.7 |" in text
    assert "| mpq | 14 | step 15: F <= 0 (the particle's domain inverted) | - | - | - |" in text
    assert "| mpq | 4 | 5 | 1.00 | 0.10 | - | broken down: F <= 0 at step 3 |" in text


def test_the_multid_large_run_is_headed_by_its_particle_count():
    """The large 2D run's heading gives the particles it ran (1,024 with ``--small``, 99,856 in full),
    not 'about 100,000' whatever ran."""
    row = dict(interpolator="spq", steps=5, compile_s=1.0, run_s=0.1, mparticle_steps_per_s=0.2)
    blast = dict(t=[0.0], gap_own=[0.0], gap_implied=[0.0], steps_taken=1, failure=None, energy=1.0)
    blast.update(params={}, dt=1e-5)
    for particles, heading in ((1024, "1,024"), (99856, "99,856")):
        result = dict(
            first_step=[],
            blast=dict(cpdi=blast, mpq=blast),
            large_2d=[dict(row, particles=particles, failure=None, F_max_rel=0.1)],
            machine="m",
            wall_s=1.0,
        )
        text = multid._markdown(result)
        assert f"## 2D run of {heading} particles (gas expansion, artificial cells)" in text
        assert "about 100,000" not in text
