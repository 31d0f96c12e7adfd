"""What the experiments' command lines share: ``argparse`` types and the checks made before computing.

A module, not a script: the scripts of ``experiments/`` import it as ``from _entry import ...``, which
works where a script is run as ``python experiments/NAME.py`` (Python puts the script's folder first
on ``sys.path``). Importing it computes nothing and changes no global configuration.
"""

import argparse
import pathlib

import jaxmpm as jm


def positive(text: str, what: str = "an integer >= 1") -> int:
    """``text`` as an integer >= 1 (an ``argparse`` type).

    Args:
        text: the command line's word.
        what: what the value is, for the usage error (``"{what}, got {text!r}"``).

    Raises:
        argparse.ArgumentTypeError: ``text`` is not an integer, or is below 1.
    """
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{what}, got {text!r}")
    return value


def interpolators(text: str) -> list[str]:
    """``text``, comma-separated keys of ``jaxmpm.INTERPOLATORS``, as a list (an ``argparse`` type).

    Raises:
        argparse.ArgumentTypeError: a name is not a key of ``jaxmpm.INTERPOLATORS`` (all such names
            are listed).
    """
    names = text.split(",")
    bad = [name for name in names if name not in jm.INTERPOLATORS]
    if bad:
        raise argparse.ArgumentTypeError(
            f"{', '.join(map(repr, bad))}: comma-separated interpolators, of {', '.join(jm.INTERPOLATORS)}"
        )
    return names


def check_particles(parser: argparse.ArgumentParser, n: int, dim: int) -> None:
    """Exit with a usage error (``parser.error``, status 2) unless ``n`` particles (``--n``) make the
    benchmark's scene in ``dim`` dimensions (``benchmarks.bench._scene``: two per cell in 1D,
    ``(2 k)^dim`` in 2D and 3D).

    Needs the checkout's root on ``sys.path`` (for ``benchmarks``): the scripts put it there first.
    """
    from benchmarks.bench import cells_of

    if dim == 1 and n % 2:
        parser.error(f"argument --n: in 1D an even particle count (two per cell), got {n}")
    if dim > 1 and cells_of(n, dim) is None:
        parser.error(
            f"argument --n: in {dim}D a particle count (2 k)^{dim} (k^{dim} cells of {2**dim}), got {n}"
        )


def refuse_existing(parser: argparse.ArgumentParser, option: str, paths, overwrite: bool) -> None:
    """Exit with a usage error (``parser.error``, status 2), before anything is computed, where a file
    of ``paths`` is already there (unless ``overwrite``) or is a folder, or where the folder of one is
    a file.

    Args:
        parser: the script's parser, whose ``error`` prints the usage and the message.
        option: the option or argument that names the files, for the message (``"--out"``).
        paths: the files the script will write (``str`` or ``pathlib.Path``).
        overwrite: whether ``--overwrite`` was passed: an existing file may be replaced.
    """
    for path in map(pathlib.Path, paths):
        if path.is_dir():
            parser.error(f"{option}: {path} is a folder, where this script writes a file")
        if any(parent.exists() and not parent.is_dir() for parent in path.parents):
            parser.error(f"{option}: cannot write {path}: a folder of it is a file")
        if path.exists() and not overwrite:
            parser.error(f"{option}: {path} exists; pass --overwrite to replace it")


def refuse_existing_in(parser: argparse.ArgumentParser, folder: str, names, overwrite: bool) -> None:
    """Exit with a usage error (``parser.error``, status 2), before anything is computed, where
    ``folder`` (the argument ``OUT_DIR``) is a file, or where a file ``names`` of it cannot be written
    or is there already and not ``overwrite`` (``refuse_existing``).

    Args:
        parser: the script's parser.
        folder: the folder the script writes its files to.
        names: the names of those files in ``folder``.
        overwrite: whether ``--overwrite`` was passed.
    """
    out = pathlib.Path(folder)
    if out.exists() and not out.is_dir():
        parser.error(f"OUT_DIR: {out} is a file, not a folder")
    refuse_existing(parser, "OUT_DIR", [out / name for name in names], overwrite)
