"""``jaxmpm study NAME``: run one of the studies in ``jaxmpm.studies`` and write its figures and tables."""

import importlib
import pathlib

import jax

from .._files import write_whole
from ..studies._output import Files
from ._common import CannotWrite, UsageError, writable_folder

STUDIES = {
    "talk": "talk",
    "convergence": "convergence",
    "work-precision": "work_precision",
    "stability": "stability",
    "multid": "multid",
    "detonation": "detonation",
    "blast": "blast",
    "gurney": "gurney",
}
"""The name on the command line of each study, and its module in ``jaxmpm.studies``."""

RELEASING = ("convergence", "stability")
"""Studies that compile a new program for each group of runs and call ``release()`` when a group is
done. The command drops JAX's caches there: every compiled XLA CPU program holds about 265 memory
maps, and past the process's limit (``vm.max_map_count``, 65,530 by default) compiling the next one
crashes."""

WITHOUT_FIGURES = ("convergence",)
"""Studies that write tables only; every other one draws figures with matplotlib."""

MARK = ".jaxmpm-study"
"""The file in a study's ``--out`` folder that names the study which writes there. Running that study
again replaces its own files (those its module's ``OUTPUTS`` names); a folder that holds any other
file is refused unless ``--overwrite``."""


def add_parser(subparsers) -> None:
    """Add the ``study`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser("study", help="run a study and write its figures and tables")
    p.add_argument(
        "name",
        choices=list(STUDIES),
        help="talk: the 2013 MPM workshop comparison; convergence: observed orders on the verification "
        "ladder; work-precision: error against run time; stability: the stiff and extreme map; multid: 2D "
        "and 3D (first step, axis-aligned orders, blast domain gaps, a 100k-particle 2D run); detonation: "
        "the planar detonation's F by interpolator, its convergence behind the front and the peak pressure "
        "against P_CJ by burn model; blast: the 2D disk and 3D sphere gas charges against their radial "
        "reference by interpolator and remedy (breakdowns, errors, smoothness) and the refined best "
        "CPDI; gurney: a charge driving its metal tube in 2D, the tube's velocity against Gurney's by "
        "resolution, interpolator and strength",
    )
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--small", action="store_true", help="a quick reduced version (for tests)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="write into an --out folder that holds files of something else (else refused)",
    )
    p.set_defaults(handler=command)


def command(args) -> int:
    """Run the study ``args.name`` into ``args.out``.

    Args:
        args: the parsed command line.

    Returns:
        The exit status, 0.

    Raises:
        UsageError: ``--out`` cannot be written, or holds files that this study does not write
            (unless ``--overwrite``); or the study draws figures and matplotlib is missing. All are
            found before the study starts.
        CannotWrite: the folder's mark or a file of the study cannot be written (a full disk): each
            is written whole, so the folder keeps, for each file, the previous run's version or the
            new one.
    """
    if args.name not in WITHOUT_FIGURES:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise UsageError(
                f"study {args.name} draws figures with matplotlib, which is not installed: "
                "pip install 'jaxmpm[figures]'"
            ) from None
    study = importlib.import_module(f"jaxmpm.studies.{STUDIES[args.name]}")
    _claim(args.out, args.name, study.OUTPUTS, args.overwrite)
    options = dict(release=jax.clear_caches) if args.name in RELEASING else {}
    try:
        study.main(out=args.out, small=args.small, **options)
    except OSError as e:  # a full disk: the files written before it are whole
        raise CannotWrite(str(e.filename) if e.filename else f"--out {args.out}", e) from None
    return 0


def _claim(folder, name: str, outputs, overwrite: bool) -> None:
    """Make ``folder`` the output folder of study ``name`` (``MARK``), once it is known that no file
    there belongs to something else: the folder is new or empty, or marked as this study's and holding
    only files the study writes (``outputs``, its module's ``OUTPUTS``), or ``overwrite`` is given.

    Temporary files left by a run of this study killed while it wrote (``Files.leftover``: of its files
    or of ``MARK``) are removed.
    """
    path = writable_folder(folder, "--out")
    mark = path / MARK
    owner = _owner(mark)
    if owner not in STUDIES:  # a file of that name that is not a study's mark is the user's
        owner = None
    try:
        names = sorted(p.name for p in path.iterdir() if p.name != MARK or (owner is None and p.exists()))
    except OSError as e:
        raise UsageError(f"--out {folder}: cannot list the folder ({e.strerror or e})") from None
    folders = [n for n in names if (n in outputs or n == MARK) and (path / n).is_dir()]
    if folders:  # a file of the study could not be written there: said before the study runs
        raise UsageError(
            f"--out {folder}: {folders[0]} is a folder, where the study writes a file of that name; "
            "move it, or choose another folder"
        )
    if owner == name:
        for leftover in [n for n in names if outputs.leftover(n) or _MARK_FILE.leftover(n)]:
            _remove(path / leftover, folder)
            names.remove(leftover)
        held = [n for n in names if n not in outputs]
    else:
        held = names
    if held and not overwrite:
        raise UsageError(
            f"--out {folder} already holds {_whose(held, name, owner)}; choose another folder, or pass "
            "--overwrite to write there anyway (a file of the same name as one of the study's is replaced)"
        )
    try:
        write_whole(mark, lambda f: f.write((name + "\n").encode()))
    except OSError as e:  # the folder took a probe file: a full disk, as for the study's own files
        raise CannotWrite(f"--out {folder}", e) from None


def _whose(held: list[str], name: str, owner: str | None) -> str:
    """The files ``held`` in the folder of study ``name`` that are not its own, as the refusal names
    them: in a folder marked as another study's (``owner``), those that study writes apart from the
    rest."""
    if owner is None or owner == name:
        return f"files that `jaxmpm study {name}` did not write ({_listed(held)})"
    outputs = importlib.import_module(f"jaxmpm.studies.{STUDIES[owner]}").OUTPUTS
    theirs = [n for n in held if n in outputs or outputs.leftover(n)]
    rest = [n for n in held if n not in theirs]
    if not theirs:
        return f"files ({_listed(rest)}), and is marked as the folder of `jaxmpm study {owner}`"
    whose = f"files that `jaxmpm study {owner}` wrote ({_listed(theirs)})"
    return f"{whose} and others ({_listed(rest)})" if rest else whose


def _listed(names: list[str]) -> str:
    return names[0] if len(names) == 1 else f"{names[0]} and {len(names) - 1} more"


_MARK_FILE = Files(MARK)


def _owner(mark: pathlib.Path) -> str | None:
    """The study ``mark`` names, or ``None`` where there is no mark or it cannot be read as one."""
    if not mark.is_file():
        return None
    try:
        return mark.read_text(encoding="utf-8").strip() or None
    except (OSError, UnicodeDecodeError):
        return None


def _remove(path: pathlib.Path, folder) -> None:
    """Remove ``path``, a temporary file of the study's own."""
    try:
        path.unlink(missing_ok=True)
    except OSError as e:
        raise UsageError(f"--out {folder}: cannot remove {path.name} there ({e.strerror or e})") from None
