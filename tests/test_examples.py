"""Every example in README.md and docs/*.md runs as written.

Each fenced ```python block and each command line of a fenced ```bash, ```sh or ```console block
is taken from the pages as mkdocs renders them (``--8<--`` snippet includes followed; a block that
several pages show, such as the README's commands, runs once). Each runs in a fresh temporary
directory as its working directory, as a reader would run it:

- a page's Python blocks, in order, as one script file (later blocks continue earlier ones: they use
  ``jm``, ``np`` and the scenes defined before), with ``MPLBACKEND=Agg`` and ``JAXMPM_PROGRESS=0``;
- a shell block's command lines one after another in the same directory (``jaxmpm resume run.npz``
  reads what the line before it wrote), each through ``bash -c`` with the test process's PATH, so
  the ``jaxmpm`` of the environment under test.

Both inherit the rest of the test process's environment. The ordinary examples keep the suite's
XLA flags (``tests/conftest.py``: compilation at optimisation level 0, which they are mostly made
of); the long ones, mostly running, drop them and run as a reader runs them.
Each must exit with status 0, and where a page states what its example prints, print it (``STATED``).

Left out, each with its reason in ``EXCLUDED``: the install lines and the test command itself, which
are what CI runs (``.ci/run``), and ``mkdocs serve``. Marked ``examples_long`` and run only with
``JAXMPM_LONG_EXAMPLES=1``: the examples of ``LONG`` (full studies, the benchmark, a fit with a large
ensemble; each over about 10 s, minutes for most). They are a check of their own, for a release or a
change to a study, not part of every CI run (``.ci/run`` says why)::

    JAXMPM_LONG_EXAMPLES=1 bash .ci/run   # or, in an installed environment:
    JAXMPM_LONG_EXAMPLES=1 python -m pytest -q -n 2 -m examples_long tests/test_examples.py

Every other example runs in the ordinary suite (marked slow: not in ``-m "not slow"``).
"""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = ["README.md"] + sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs").glob("*.md"))
SNIPPET_BASES = (ROOT / "docs", ROOT)  # mkdocs.yml: pymdownx.snippets base_path [docs, .]
SHELLS = ("bash", "sh", "shell", "console")

pytestmark = pytest.mark.slow

# Segments of a command line (split at `&&`) that are not run, and why.
EXCLUDED = {
    r"python3? -m venv\b.*": "installing: CI creates the environment (.ci/run); this test runs in it",
    r"(\.|source) \S*/activate": "installing: CI creates the environment (.ci/run); this test runs in it",
    r"(python3? -m )?pip install\b.*": "installing: CI installs the package itself (.ci/run)",
    r"(\w+=\S+ )*python3? -m pytest\b.*": "the test suite itself: CI runs it (.ci/run), and this test is "
    "part of it",
    r"python3? experiments/suite_time\.py\b.*": "the report of a run of the test suite with its logging "
    "plugin (the line before it, the suite itself, is not run here)",
    r"mkdocs serve\b.*": "a server, it runs until stopped; CI builds the same site (mkdocs build --strict)",
    r"srun\b.*": "a cluster's launcher: CI has no cluster; docs/scale.md's next example and "
    "tests/test_multiprocess.py run the same with two local processes",
}

# The long examples: they run only when JAXMPM_LONG_EXAMPLES=1 (marker `examples_long`). A key is
# the start of a shell command line as written on its page, or "python:" and a page (its Python
# blocks), or "shell:" and a page (its shell blocks' other lines). A long
# command line runs after its block's other lines (it may read what they wrote); the same long
# command on two pages (its `--out` and comment aside) runs once.
LONG = {  # over about 10 s each, single process on 2 cores
    "jaxmpm study talk --out": "the talk's full study",
    "jaxmpm study convergence --out": "the full convergence study",
    "jaxmpm study work-precision --out": "the full work-precision study",
    "jaxmpm study stability --out": "the full stability map",
    "jaxmpm study multid --out": "the full 2D and 3D study",
    "jaxmpm study detonation --out": "the full detonation study",
    "jaxmpm study blast --out": "the full blast study",
    "jaxmpm study gurney --out": "the full Gurney cylinder study",
    "python:docs/detonation.md": "the Gurney slab to 30 us, and a fit of the products to a plate's velocity",
    "jaxmpm bench --out": "the full benchmark",
    "jaxmpm bench --sizes 65536,262144,1048576 --sizes-2d 102400": "the 2D and 3D benchmark (half an hour)",
    "jaxmpm run axis-aligned dim=3": "a 3D run of 4,096 particles: its compilation",
    "python:docs/calibration.md": "a fit with two starts, and a 1,024-member ensemble",
}
OPT_IN = LONG
LONG_ENABLED = os.environ.get("JAXMPM_LONG_EXAMPLES") == "1"

# What a page says its example prints: (page, a line of the example) -> what the output must contain,
# a regular expression, or (a regular expression capturing a number, the stated value, relative
# tolerance: the page rounds).
STATED = {
    ("docs/multid.md", "print(jm.errors"): [(r"^([-+.e\d]+)$", 3.66e-3, 2e-3)],  # 3.66e-3
    ("docs/gradients.md", "print(names)"): [r"\('beta', 'h', 'P0', 'gamma', 'p_atm', 'rho0', 'dt'\)"],
    ("docs/command-line.md", "jaxmpm calibrate"): [
        (r'"gamma": ([.\d]+)', 1.406, 5e-4),
        (r'"P0": ([.\d]+)', 3.019e5, 5e-4),
    ],
}


def check_stated(case, out: str) -> None:
    for (page, line), expected in STATED.items():
        if page != case.page or line not in case.code:
            continue
        for item in expected:
            if isinstance(item, str):
                assert re.search(item, out, re.M), f"{case.id}: the page says the output has {item!r}:\n{out}"
            else:
                pattern, value, rtol = item
                m = re.search(pattern, out, re.M)
                assert m, f"{case.id}: no {pattern!r} in the output:\n{out}"
                assert abs(float(m.group(1)) - value) <= rtol * abs(value), (case.id, m.group(0), value)


@dataclasses.dataclass(frozen=True)
class Block:
    page: str
    lang: str
    line: int  # first line of the code, in the page (1-based; of the included file for a snippet)
    code: str


def _resolve(name: str) -> Path:
    for base in SNIPPET_BASES:
        if (base / name).is_file():
            return base / name
    raise FileNotFoundError(f"snippet {name!r} not found under docs/ or the repository root")


def _snippet(spec: str) -> list[str]:
    """The lines ``--8<-- "spec"`` includes: a whole file, ``file:name`` (a section between
    ``[start:name]`` and ``[end:name]``) or ``file:start:end`` (1-based lines, end optional)."""
    name, _, rest = spec.partition(":")
    lines = _resolve(name).read_text().splitlines()
    if not rest:
        return lines
    if re.fullmatch(r"-?\d*(:-?\d*)?", rest):
        start, _, end = rest.partition(":")
        return lines[int(start or 1) - 1 : int(end) if end else None]
    begin = next(i for i, s in enumerate(lines) if f"--8<-- [start:{rest}]" in s)
    end = next(i for i, s in enumerate(lines) if f"--8<-- [end:{rest}]" in s)
    return lines[begin + 1 : end]


def _expanded(lines: list[str], depth: int = 0) -> list[str]:
    out = []
    for s in lines:
        m = re.fullmatch(r'(\s*)--8<--\s+"([^"]+)"\s*', s)
        if m and depth < 8:
            out += [m.group(1) + t for t in _expanded(_snippet(m.group(2)), depth + 1)]
        else:
            out.append(s)
    return out


def blocks(page: str) -> list[Block]:
    """The fenced code blocks of ``page``, with its snippet includes in place."""
    lines = _expanded((ROOT / page).read_text().splitlines())
    found, i = [], 0
    while i < len(lines):
        m = re.match(r"(\s*)(`{3,}|~{3,})\s*([\w+-]*)", lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.groups()
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            j += 1
        body = [s[len(indent) :] if s.startswith(indent) else s.lstrip() for s in lines[i + 1 : j]]
        found.append(Block(page, lang.lower(), i + 2, "\n".join(body) + "\n"))
        i = j + 1
    return found


def command_lines(block: Block) -> list[str]:
    """A shell block's command lines: ``\\`` continuations joined, comment-only lines dropped, and
    for ``console`` only the lines after a ``$`` prompt."""
    out, current = [], None
    for s in block.code.splitlines():
        if current is None:
            if block.lang == "console":
                if not s.startswith("$ "):
                    continue
                s = s[2:]
            if not s.strip() or s.lstrip().startswith("#"):
                continue
            current = ""
        if s.rstrip().endswith("\\"):
            current += s.rstrip()[:-1].strip() + " "
        else:
            out.append((current + s.strip()).strip())
            current = None
    return out


def runnable(line: str) -> str:
    """``line`` less its excluded ``&&`` segments (installing, the test suite, a server)."""
    keep = []
    for part in line.split("&&"):
        part = part.strip()
        if not any(re.fullmatch(p, part) for p in EXCLUDED):
            keep.append(part)
    return " && ".join(keep)


def long_reason(line: str) -> str | None:
    lines = {k: why for k, why in OPT_IN.items() if not k.startswith(("python:", "shell:"))}
    return next((why for start, why in lines.items() if line.startswith(start)), None)


def _same_command(line: str) -> str:
    """What makes two long command lines the same run: the command less its comment and `--out`."""
    return re.sub(r"--out \S+", "--out", line.split("#")[0]).strip()


@dataclasses.dataclass(frozen=True)
class Case:
    id: str
    page: str
    kind: str  # "python" or "shell"
    code: str  # the script, or the command lines joined by newlines
    first: str  # the example's first line, for the report


def _short(page: str) -> str:
    return page.removeprefix("docs/")


def _collect() -> tuple[list[Case], list[Case]]:
    """(ordinary cases, long cases), each block once (the first page that shows it)."""
    seen: set[tuple[str, str]] = set()
    seen_long: set[str] = set()
    cases, long_cases = [], []
    for page in PAGES:
        python, shell_index = [], 0
        for b in blocks(page):
            if (b.lang, b.code) in seen:
                continue
            seen.add((b.lang, b.code))
            if b.lang == "python":
                python.append(b)
            elif b.lang in SHELLS:
                shell_index += 1
                quick, before_long = [], []
                for line in command_lines(b):
                    line = runnable(line)
                    if not line:
                        continue
                    if long_reason(line):
                        if _same_command(line) in seen_long:
                            continue
                        seen_long.add(_same_command(line))
                        words = re.sub(r"\W+", "-", " ".join(line.split()[1:3])).strip("-")
                        cid = f"{_short(page)}:shell{shell_index}:{words}"
                        # After the block's quick lines before it: it may read what they wrote.
                        long_cases.append(Case(cid, page, "shell", "\n".join(quick + [line]), line))
                        before_long = list(quick)
                    else:
                        quick.append(line)
                if quick and f"shell:{page}" not in OPT_IN:
                    cid = f"{_short(page)}:shell{shell_index}@L{b.line}"
                    cases.append(Case(cid, page, "shell", "\n".join(quick), quick[0]))
                elif quick and quick != before_long:  # else a long case of the block runs them all
                    cid = f"{_short(page)}:shell{shell_index}@L{b.line}"
                    long_cases.append(Case(cid, page, "shell", "\n".join(quick), quick[0]))
        if python:
            script = "".join(f"# --- {page}, line {b.line}\n{b.code}" for b in python)
            lines = ",".join(f"L{b.line}" for b in python)
            first = python[0].code.strip().splitlines()[0]
            case = Case(f"{_short(page)}:python@{lines}", page, "python", script, first)
            (long_cases if f"python:{page}" in OPT_IN else cases).append(case)
    return cases, long_cases


CASES, LONG_CASES = _collect()


# tests/conftest.py's XLA flags: they make compilation fast and running slow.
SUITE_XLA_FLAGS = (
    "--xla_backend_optimization_level=0",
    "--xla_llvm_disable_expensive_passes=true",
    "--xla_cpu_use_fusion_emitters=false",
)


def _env(reader: bool) -> dict[str, str]:
    """The test process's own environment (PATH, so the jaxmpm under test), with no progress bars
    and no windows. The ordinary examples, mostly compilation, keep the suite's XLA flags; the long
    ones (studies and benchmarks, mostly running) get the reader's, without them."""
    env = dict(os.environ, MPLBACKEND="Agg", JAXMPM_PROGRESS="0")
    if reader:
        flags = [f for f in env.get("XLA_FLAGS", "").split() if f not in SUITE_XLA_FLAGS]
        env["XLA_FLAGS"] = " ".join(flags)
    return env


def _run(case: Case, cwd: Path, timeout: float, reader: bool = False) -> str:
    if case.kind == "python":
        (cwd / "example.py").write_text(case.code)
        proc = subprocess.run(
            [sys.executable, "example.py"],
            cwd=cwd,
            env=_env(reader),
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        numbered = "\n".join(f"{i + 1:4d}  {s}" for i, s in enumerate(case.code.splitlines()))
        assert proc.returncode == 0, (
            f"{case.id} failed:\n{numbered}\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}"
        )
        return proc.stdout
    out = []
    for line in case.code.splitlines():
        proc = subprocess.run(
            ["bash", "-c", "set -eo pipefail; " + line],
            cwd=cwd,
            env=_env(reader),
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        assert proc.returncode == 0, (
            f"{case.page}: `{line}` exited {proc.returncode}:\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}"
        )
        out.append(proc.stdout)
    return "".join(out)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_example(case, tmp_path):
    check_stated(case, _run(case, tmp_path, timeout=900))


@pytest.mark.examples_long
@pytest.mark.skipif(not LONG_ENABLED, reason="opt-in (LONG): set JAXMPM_LONG_EXAMPLES=1 to run")
@pytest.mark.parametrize("case", LONG_CASES, ids=[c.id for c in LONG_CASES])
def test_long_example(case, tmp_path):
    check_stated(case, _run(case, tmp_path, timeout=3600, reader=True))


def test_the_examples_are_found():
    """The extraction sees the examples (a fence or snippet it cannot read would drop them silently),
    every opt-in entry still names an example, and every STATED output a page's case."""
    assert any(c.page == "README.md" and c.kind == "python" for c in CASES)
    assert any("--steps 100000" in c.code for c in CASES), "the long-run command line"
    assert {c.page for c in CASES} >= {"README.md", "docs/getting-started.md", "docs/long-runs.md"}
    for key in OPT_IN:
        kind, _, page = key.partition(":")
        if kind in ("python", "shell"):
            assert any(c.page == page and c.kind == kind for c in LONG_CASES), f"{key!r} names no example"
        else:
            assert any(c.first.startswith(key) for c in LONG_CASES), f"{key!r} starts no example"
    for page, line in STATED:
        assert any(c.page == page and line in c.code for c in CASES + LONG_CASES), (page, line)
    # The README's commands appear on three pages and run once.
    assert sum(c.first.startswith("jaxmpm study talk") for c in LONG_CASES) == 1
