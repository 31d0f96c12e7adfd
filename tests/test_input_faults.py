"""Bad input, found by hand and by a seeded fuzz: every case ends with exit status 2 and one line on
stderr naming the parameter (the library: a ValueError naming it), never a traceback."""

import json
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import usage

import jaxmpm as jm
import jaxmpm._memory
import jaxmpm._simulate
from jaxmpm import calibrate as cal
from jaxmpm.cli import main

TS = np.linspace(0.0, 12e-3, 60)


@pytest.fixture
def data(tmp_path):
    """A good trajectory file (60 rows), and a writer of bad ones."""
    good = tmp_path / "traj.csv"
    good.write_text("t,x_free\n" + "".join(f"{t!r},{1 + t!r}\n" for t in TS.tolist()))

    def write(name, content):
        path = tmp_path / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        return str(path)

    return str(good), write


# -- calibrate --data ---------------------------------------------------------------------------------

ROWS = "".join(f"{t!r},{1 + t!r}\n" for t in TS.tolist())


@pytest.mark.parametrize(
    "content, match",
    [
        (bytes(range(256)) * 10, "is not a CSV text file (it holds NUL bytes"),
        (
            "t,x_free\n0,1\n1e-3,caf\u00e9\n".encode("latin-1"),
            "is not a CSV text file (line 3, byte 21, is not UTF-8 text)",
        ),
        (b"\x89PNG\r\n\x1a\n" + bytes(range(128, 256)), "is not a CSV text file"),
        ("", "is empty; it needs a header with the columns t,x_free"),
        ("time,x\n0,1\n1,2\n", "needs a header with the columns t,x_free; its header is 'time,x'"),
        ("t,x_free\n", "has 0 row(s) of t,x_free; need at least 2"),
        ("t,x_free\n0,1\n", "has 1 row(s) of t,x_free; need at least 2"),
        ("t,x_free\n0,1\n1e-3,abc\n", "line 3: x_free is not a number, got 'abc'"),
        ("t,x_free\n0,1\none,2\n", "line 3: t is not a number, got 'one'"),
        ("t,x_free\n0,1\n1e-3\n", "line 3: no value in column x_free"),
        ("t,x_free\n0,1\n2e-3,1\n1e-3,1\n", "line 4: t must increase, got t=0.001 after t=0.002"),
        ("t,x_free\n0,1\n0,1\n", "line 3: t must increase"),
        ("t,x_free\n-1e-3,1\n1e-3,1\n", "line 2: t must start at >= 0, got t=-0.001"),
        ("t,x_free\n0,1\n1e-3,1e999\n", "line 3: x_free is 1e999; non-finite values are not allowed"),
        (
            "t,x_free\n0,1\n1e6,2\n",
            "t reaches 1e+06, 1.04e+11 model steps of dt = 9.64e-06, more than 2147483647",
        ),
        (
            "t,x_free\n0,1\n1e4,2\n",
            "t reaches 10000, 1.04e+09 model steps of dt = 9.64e-06: the run (64 particles",
        ),
        (
            "t,x_free\n" + ROWS.replace(f",{1 + TS.tolist()[30]!r}\n", ",nan\n"),
            "line 32: x_free is nan; non-finite",
        ),
        ("t,x_free\n0,1\n1e-3,2,7\n", "line 3: more fields than the header's 2 (t,x_free)"),
        ('t,x_free\n0,1\n1e-3,"2\n', "is not a CSV text file (unexpected end of data)"),
    ],
    ids=[
        "binary",
        "latin-1",
        "png",
        "empty",
        "columns",
        "header-only",
        "one-row",
        "cell",
        "t-cell",
        "missing-cell",
        "decreasing",
        "repeated-t",
        "negative-t",
        "inf",
        "too-many-steps",
        "too-much-memory",
        "nan-row",
        "extra-field",
        "open-quote",
    ],
)
def test_calibrate_data_faults(capsys, data, content, match):
    _, write = data
    path = write("bad.csv", content)
    line = usage(capsys, ["calibrate", "gas-slab", "--data", path], match)
    assert "bad.csv" in line


def test_calibrate_data_that_is_good_reads_crlf_bom_blank_lines_and_extra_columns(data):
    from jaxmpm.cli.calibrate import read_trajectory

    _, write = data
    path = write("ok.csv", b"\xef\xbb\xbf x_free , t ,note\r\n1,0,a\r\n\r\n2,1e-3,b\r\n")
    t, x = read_trajectory(path)
    assert t.tolist() == [0.0, 1e-3] and x.tolist() == [1.0, 2.0]


def test_calibrate_data_with_an_odd_name_or_a_huge_field(capsys, data):
    _, write = data
    path = write("we{i}rd.csv", bytes(range(256)))
    assert "we{i}rd.csv is not a CSV text file" in usage(
        capsys, ["calibrate", "gas-slab", "--data", path], ""
    )
    path = write("field.csv", "t,x_free\n0," + "1" * 200_000 + "\n")
    usage(capsys, ["calibrate", "gas-slab", "--data", path], "is not a CSV text file (field larger than")


def test_calibrate_unreadable_data(capsys, tmp_path):
    usage(capsys, ["calibrate", "gas-slab", "--data", str(tmp_path / "nosuch.csv")], "cannot read")
    usage(capsys, ["calibrate", "gas-slab", "--data", str(tmp_path)], "cannot read")


def test_calibrate_refuses_a_column_named_twice(capsys, tmp_path):
    data = tmp_path / "twice.csv"
    data.write_text("t,x_free,t\n0,1,0\n0.002,1.9414,0.0001\n0.004,2.8827,0.0002\n")
    usage(capsys, ["calibrate", "gas-slab", "--data", str(data)], "has 2 columns named 't'; it needs one")


@pytest.mark.slow
def test_calibrate_names_a_trial_point_the_fit_reached_as_the_fits_not_the_users(capsys, tmp_path):
    """Data no gas slab can follow drive the fit's trial points to P0 = p_atm (exp underflows), a
    scene that does not exist: that trial is rejected as a broken run would be, not reported as
    the user's bad input, and numpy's overflow warnings stay quiet."""
    data = tmp_path / "negative.csv"
    data.write_text("t,x_free\n0,-5\n0.002,-6\n")
    rc = main(["calibrate", "gas-slab", "--no-progress", "--data", str(data), "--json"])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "Traceback" not in captured.err and "error:" not in captured.err
    assert "RuntimeWarning" not in captured.err and "P0 must be > p_atm" not in captured.err
    fit = json.loads(captured.out)
    assert fit["std"]["gamma"] is None or not np.isfinite(fit["std"]["gamma"])  # nothing determined


def test_calibrate_refuses_data_far_beyond_any_start_unless_the_grid_is_given(capsys, tmp_path):
    """x_free in the wrong units (1e6) would size a grid of millions of cells for every trial run."""
    data = tmp_path / "far.csv"
    data.write_text("t,x_free\n0,1\n0.002,1e6\n")
    line = usage(capsys, ["calibrate", "gas-slab", "--data", str(data)], "--data: x_free reaches 1e+06")
    assert "more than 100 times as far as any start's slab can go" in line
    pad = jm.scenes.gas_slab.pad_for(jm.GasSlab(), 1.25e6)
    assert f"a grid of {pad:,} cells beyond the slab" in line and "give pad=N" in line
    assert pad == 39_999_972  # h = 1/32: the 1.25 of headroom over 1e6, less the slab, plus 4


# -- calibrate --fit and --start ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--start", "nosuch=1"], "--start: nosuch is not fitted (fitted: gamma, P0)"),
        (["--fit", "gamma", "--start", "P0=2e5"], "--start: P0 is not fitted (fitted: gamma)"),
        (
            ["--fit", "h"],
            "--fit: h is the grid spacing, not a material constant; fittable: P0, gamma, p_atm, rho0",
        ),
        (["--fit", "dt"], "--fit: dt is the model's time step, not a material constant; fittable: P0"),
        (["--fit", "cells"], "--fit: cells is structural (an integer), not a material constant; fittable"),
        (["--fit", "kappa"], "--fit: unknown parameter 'kappa'; fittable: P0, gamma, p_atm, rho0"),
        (["--fit", ","], "--fit: name at least one parameter; fittable"),
        (["--fit", "gamma,gamma"], "--fit: gamma is given twice"),
        (["--fit", "gamma,"], "--fit: an empty item in 'gamma,' (a comma too many?)"),
        (["--fit", "gamma,,P0"], "--fit: an empty item in 'gamma,,P0' (a comma too many?)"),
        (["--start", "gamma=1.5,"], "--start: an empty item in 'gamma=1.5,' (a comma too many?)"),
        (["--start", "gamma=1.5,gamma=1.6"], "--start: gamma is given twice: 'gamma=1.5' and 'gamma=1.6'"),
        (["--start", "gamma=nan"], "--start: gamma must be finite, got nan"),
        (["--start", "gamma=1e999"], "--start: gamma must be finite, got 1e999"),
        (["--start", "gamma=0.5"], "--start: gamma must be > 1"),
        (["--start", "gamma"], "--start takes NAME=VALUE"),
        (["--start", "gamma=x"], "--start takes NAME=VALUE"),
        (["--iterations", "0"], "--iterations must be an integer >= 1, got 0"),
        (["--dt", "-1"], "dt must be > 0"),
    ],
)
def test_calibrate_fit_and_start_faults(capsys, data, extra, match):
    good, _ = data
    usage(capsys, ["calibrate", "gas-slab", "--data", good, *extra], match)


def test_calibrate_start_and_scene_parameter_given_both(capsys, data):
    good, _ = data
    argv = ["calibrate", "gas-slab", "gamma=1.5", "--data", good, "--start", "gamma=1.6"]
    usage(capsys, argv, "--start: gamma is also given as a scene parameter")


def test_calibrate_library_refuses_h_dt_and_bad_data_before_tracing():
    sc = jm.GasSlab(cells=4, h=0.25, pad=8)
    t, x = np.linspace(0.0, 1e-3, 5), np.ones(5)
    with pytest.raises(
        ValueError, match="h is the grid spacing, not a material constant; it cannot be fitted"
    ):
        cal.calibrate(sc, jm.CPDI(), t, x, fit=("h",), dt=1e-5)
    with pytest.raises(ValueError, match="dt is the model's time step, not a material constant"):
        cal.calibrate(sc, jm.CPDI(), t, x, fit=("gamma", "dt"), dt=1e-5)
    with pytest.raises(ValueError, match="fit names a parameter twice"):
        cal.calibrate(sc, jm.CPDI(), t, x, fit=("gamma", "gamma"), dt=1e-5)
    with pytest.raises(ValueError, match="x_data must be finite; entry 2 is nan"):
        cal.calibrate(sc, jm.CPDI(), t, np.where(np.arange(5) == 2, np.nan, x), dt=1e-5)
    with pytest.raises(ValueError, match="t_data must start at >= 0 and increase"):
        cal.calibrate(sc, jm.CPDI(), t[::-1], x, dt=1e-5)
    assert cal.fittable(sc) == ("P0", "gamma", "p_atm", "rho0")


# -- a name given twice, for every command ------------------------------------------------------------

RUN = ["--interpolator", "spq", "--dt", "1e-5", "--steps", "1"]


@pytest.mark.parametrize(
    "argv, match",
    [
        (
            ["run", "gas-expansion", "beta=100", "beta=300", *RUN],
            "beta is given twice: 'beta=100' and 'beta=300'",
        ),
        (["run", "gas-expansion", "beta=100", "beta=100", *RUN], "beta is given twice"),
        (["run", "gas-expansion", "--grad", "beta,beta", *RUN], "beta is given twice"),
        (
            ["ensemble", "gas-slab", "--vary", "gamma=1.3:1.5", "--vary", "gamma=1.2:1.4", "--members", "2"],
            "--vary: gamma is given twice",
        ),
        (
            ["ensemble", "gas-slab", "gamma=1.4", "--vary", "gamma=1.3:1.5", "--members", "2"],
            "--vary: gamma is also given as a fixed scene parameter",
        ),
        (["calibrate", "gas-slab", "P0=2e5", "P0=3e5", "--data", "x.csv"], "P0 is given twice"),
    ],
)
def test_a_name_given_twice_is_refused(capsys, argv, match):
    usage(capsys, argv, match)


# -- ensemble -----------------------------------------------------------------------------------------

ENS = ["ensemble", "gas-slab", "cells=4", "h=0.25", "pad=8", "--vary", "gamma=1.3:1.5"]


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--members", "3", "--seed", "-1"], "--seed must be an integer >= 0, got -1"),
        (["--members", "0"], "--members must be an integer >= 1, got 0"),
        (["--members", "3", "--cfl", "0"], "--cfl must be > 0, got 0.0"),
        (["--members", "3", "--cfl", "nan"], "--cfl must be finite, got nan"),
        (["--members", "3", "--t-end", "inf"], "--t-end must be finite, got inf"),
        (["--members", "3", "--t-end", "-1"], "--t-end must be > 0"),
        (["--members", "3", "--t-end", "1e300"], "steps, more than 2147483647"),
        (["--members", "3", "--max-steps", "0"], "--max-steps must be an integer >= 1, got 0"),
        (["--members", "3", "--dt", "1e-5", "--steps", "-1"], "steps must be an integer >= 0"),
    ],
)
def test_ensemble_faults(capsys, extra, match):
    usage(capsys, ENS + extra, match)


def test_ensemble_refuses_a_range_with_an_end_the_scene_refuses(capsys):
    """A range's ends are checked whether or not --dt and --steps are given (with them, only the
    drawn values were, so a bad range passed when no draw fell in its bad part)."""
    for timing in ([], ["--dt", "1e-5", "--steps", "2"]):
        argv = ["ensemble", "gas-expansion", "--members", "4", "--vary", "h=0:1", *timing]
        usage(capsys, argv, "--vary: h must be > 0, got 0.0 (at h=0, an end of the range h=0:1)")


def test_ensemble_refuses_more_members_than_memory_before_allocating(capsys, monkeypatch):
    argv = ["ensemble", "gas-slab", "--vary", "gamma=1.3:1.5", "--members", "100000000"]
    usage(capsys, argv, "--members 100000000: 100,000,000 members of the run (64 particles, 417 grid nodes)")
    usage(capsys, argv + ["--dt", "1e-5", "--steps", "10"], "TB of memory, more than the")
    monkeypatch.setattr(jaxmpm._memory, "available_bytes", lambda: 1_000_000)  # 1 MB: the library's check
    sc = jm.GasSlab(cells=4, h=0.25, pad=8)
    with pytest.raises(ValueError, match="1,000 members of the run .* of memory, more than the 1 MB"):
        jm.ensemble(sc, jm.CPDI(), {"gamma": np.full(1000, 1.4)}, dt=1e-5, steps=2)


def test_ensemble_exits_3_when_every_member_broke_down_and_0_when_one_finished(capsys):
    # dt = 1e-4 on h = 0.25 is beyond the stable limit where c = sqrt(1.4 P0) > 2500, P0 > 4.5e6
    argv = [
        "ensemble",
        "gas-slab",
        "cells=4",
        "h=0.25",
        "pad=8",
        "--members",
        "2",
        "--dt",
        "1e-4",
        "--steps",
        "3",
    ]
    assert main(argv + ["--vary", "P0=4e7:5e7", "--json"]) == 3
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["ok"] == 0 and out["failed"] == 2 and all("failure" in r for r in out["results"])
    (line,) = captured.err.strip().splitlines()
    assert line.startswith("jaxmpm: every member of the ensemble broke down (2 of 2); member 0 (P0=")
    assert "at step 1" in line and "Traceback" not in captured.err
    assert main(argv + ["--vary", "P0=4e7:5e7"]) == 3  # the table too
    captured = capsys.readouterr()
    assert "0 ok, 2 failed" in captured.out and len(captured.err.strip().splitlines()) == 1
    # seed 31 draws P0 = 9.1e6 (too stiff) and 8.6e5 (fine): one finished, so 0, the failure listed
    assert main(argv + ["--vary", "P0=2e5:1e7", "--seed", "31", "--json"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["ok"] == 1 and out["failed"] == 1 and "failure" in out["results"][0]
    assert captured.err == ""


# -- scene parameters that are not numbers ------------------------------------------------------------

CONTINUOUS = [
    (name, p) for name, cls in jm.SCENES.items() for p, v in cls.parameters().items() if isinstance(v, float)
]


@pytest.mark.parametrize("scene, param", CONTINUOUS, ids=[f"{s}-{p}" for s, p in CONTINUOUS])
@pytest.mark.parametrize(
    "bad", ["abc", None, 1 + 2j, "1.5", object()], ids=["abc", "None", "complex", "str", "object"]
)
def test_every_scene_names_a_parameter_that_is_not_a_number(scene, param, bad):
    with pytest.raises(ValueError, match=f"^{param} must be a real number, got "):
        jm.SCENES[scene](**{param: bad})


def test_not_a_number_message_and_what_still_converts():
    with pytest.raises(ValueError, match="^beta must be a real number, got 'abc'$"):
        jm.GasExpansion(beta="abc")
    with pytest.raises(ValueError, match=r"^beta must be a real number, got 'xxxx.*\.\.\..*xxx'$"):
        jm.GasExpansion(beta="x" * 10_000)  # shortened: one readable line
    for ok in (250, np.float32(250.0), np.int64(250), jnp.asarray(250.0), np.asarray(250.0)):
        beta = jm.GasExpansion(beta=ok).beta
        assert beta.dtype == jnp.float64 and float(beta) == 250.0
    with pytest.raises(ValueError, match="^beta must be finite, got nan$"):
        jm.GasExpansion(beta=float("nan"))
    with pytest.raises(ValueError, match="^P0 must be a real number, got 'x'$"):  # a material too
        jm.AdiabaticGas(P0="x", gamma=1.4, p_atm=1e5)


def test_scene_parameters_still_pass_through_jit_vmap_and_grad():
    def f(beta):
        return jm.GasExpansion(beta=beta).beta * 2.0

    assert float(jax.grad(f)(3.0)) == 2.0
    assert float(jax.jit(f)(3.0)) == 6.0
    np.testing.assert_array_equal(np.asarray(jax.vmap(f)(jnp.asarray([1.0, 2.0]))), [2.0, 4.0])
    g = jax.grad(lambda gamma: jm.GasSlab(gamma=gamma).wave_speed)(1.4)
    assert np.isfinite(float(g))


# -- the fuzz -----------------------------------------------------------------------------------------


class _WouldRun(Exception):
    """Raised where a run would be compiled: the input was accepted."""


@pytest.fixture
def no_runs(monkeypatch):
    """Stop every command where its run would be compiled (the checks before it all run)."""

    def stop(*args, **kwargs):
        raise _WouldRun

    class _Compiled:
        lower = staticmethod(stop)
        __call__ = staticmethod(stop)

    monkeypatch.setattr(jaxmpm._simulate, "_run_scan_jit", _Compiled())
    monkeypatch.setattr(sys.modules["jaxmpm.ensemble"], "_run_batch", stop)
    monkeypatch.setattr(cal, "simulate", stop)


NAMES = ["beta", "h", "P0", "gamma", "p_atm", "rho0", "cells", "ppc", "pad", "dim", "E", "nu", "A"]
ODD_NAMES = [
    "",
    "bogus",
    "BETA",
    "\u03b2",
    " beta",
    "beta ",
    "x" * 300,
    "=",
    "-",
    "--",
    "\u202egamma",
    "\x00",
]
VALUES = [
    "1",
    "0",
    "-0",
    "-1",
    "2",
    "2.5",
    "1e999",
    "-1e999",
    "1e-320",
    "1e308",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "",
    "=",
    "==3",
    "abc",
    "true",
    "0x10",
    "1_0",
    "\uff13",  # a fullwidth 3, which int() and float() read
    "\u00e9",
    " 1 ",
    "9" * 5000,
    "1e3",
    "3e5",
    "1.4",
    "x" * 10_000,
]
RAW = ["=", "==3", "=1", "beta", "beta==3", "beta=1=2", "", "--", "-x", "--bogus", "\u2014beta=1"]


def _item(rng) -> str:
    r = rng.random()
    if r < 0.15:
        return str(rng.choice(RAW))
    name = str(rng.choice(NAMES if r < 0.75 else ODD_NAMES))
    value = str(rng.choice(VALUES))
    if name in ("cells", "ppc", "pad", "dim") and value.strip().lstrip("-").isdigit() and len(value) < 5:
        value = str(rng.choice(["1", "2", "3", "0", "-1", value]))  # small: a run would stay small
    return f"{name}={value}"


def _argv(rng, data: str) -> list[str]:
    command = str(rng.choice(["run", "calibrate", "ensemble"]))
    scene = str(
        rng.choice(
            ["gas-slab", "gas-expansion", "vibrating-bar", "nosuch", ""], p=[0.4, 0.3, 0.2, 0.05, 0.05]
        )
    )
    items = [_item(rng) for _ in range(int(rng.choice([0, 0, 1, 2, 3])))]
    if rng.random() < 0.3 and items:  # a repeated name
        items.append(items[0])
    if command == "run":
        tail = [
            "--interpolator",
            "spq",
            "--dt",
            str(rng.choice(["1e-5", "0", "-1", "nan", "1e999"])),
            "--steps",
            "1",
        ]
    elif command == "calibrate":
        tail = ["--data", data, "--iterations", "1", "--no-progress"]
        if rng.random() < 0.5:
            tail += [
                "--fit",
                ",".join(str(n) for n in rng.choice(NAMES + ODD_NAMES, size=int(rng.integers(1, 3)))),
            ]
        if rng.random() < 0.5:
            tail += ["--start", ",".join(_item(rng) for _ in range(int(rng.integers(1, 3))))]
    else:
        good = ["gamma=1.3:1.5", "P0=2e5:3e5", "beta=100:200", "E=1e6:2e6"]
        vary = [str(rng.choice(good)) if rng.random() < 0.6 else _item(rng).replace("=", "=1:", 1)]
        vary += [_item(rng)] if rng.random() < 0.3 else []
        tail = [a for v in vary for a in ("--vary", v)]
        tail += [
            "--members",
            str(rng.choice(["1", "2", "0", "-3"])),
            "--seed",
            str(rng.choice(["0", "-1", "7"])),
        ]
        tail += ["--dt", "1e-5", "--steps", "1"]
    return [command, scene, *items, *tail]


@pytest.mark.slow
def test_fuzz_assignments_end_in_a_status_and_one_line(capsys, data, no_runs):
    good, _ = data
    rng = np.random.default_rng(20240611)
    seen = {0: 0, 2: 0, "accepted": 0}
    for _ in range(300):
        argv = _argv(rng, good)
        try:
            rc = main(argv)
        except _WouldRun:
            rc = "accepted"
        except BaseException as e:  # noqa: BLE001 - any escape is the failure being looked for
            pytest.fail(f"jaxmpm {argv!r} raised {type(e).__name__}: {e}")
        captured = capsys.readouterr()
        assert rc in (0, 2, 3, "accepted"), (argv, rc)
        assert "Traceback" not in captured.err, argv
        if rc in (2, 3):
            lines = captured.err.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith("jaxmpm:"), (argv, captured.err)
        seen[rc] = seen.get(rc, 0) + 1
    assert seen[2] > 100 and seen["accepted"] > 10, seen  # the fuzz reaches both sides


def test_an_empty_start_is_refused(capsys, data):
    _, write = data
    path = write("ok.csv", "t,x_free\n0,1\n1e-3,1.01\n")
    usage(
        capsys,
        ["calibrate", "gas-slab", "--data", path, "--start="],
        "--start takes NAME=VALUE[,NAME=VALUE...], got an empty value",
    )
