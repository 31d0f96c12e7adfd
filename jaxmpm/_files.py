"""Files written whole or not at all, and never over a file that is not the one being written."""

import errno
import os
import pathlib
import re
import secrets
from collections.abc import Callable
from typing import BinaryIO


def check_folder(path: pathlib.Path) -> None:
    """Refuse, naming it, a folder of ``path`` that is missing or is a file (a file, or the temporary
    file ``write_whole`` makes beside it, could not be made there).

    Args:
        path: the file to write.

    Raises:
        NotADirectoryError: the folder is a file.
        FileNotFoundError: there is no such folder.
    """
    folder = path.parent
    if not folder.is_dir():
        if folder.exists():
            raise NotADirectoryError(
                errno.ENOTDIR, f"Not a folder, cannot write {path.name} in it", str(folder)
            )
        raise FileNotFoundError(errno.ENOENT, f"No such folder to write {path.name} in", str(folder))


def temporary_of(name: str) -> str | None:
    """The file a temporary file of ``write_whole`` was for (``.NAME.<pid>-<hex>.tmp``: one left by a
    process killed mid-write).

    Args:
        name: a file name.

    Returns:
        ``NAME``, or ``None`` where ``name`` is not such a temporary file.
    """
    m = _TEMPORARY.match(name)
    return None if m is None else m["name"]


_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.\d+-[0-9a-f]{8}\.tmp$")


def write_whole(path: pathlib.Path, write: Callable[[BinaryIO], object], *, durable: bool = False) -> None:
    """Write ``path`` through a new temporary file beside it, renamed into place once written.

    The temporary file has a name of its own (made new: no existing file is written over). A write
    or rename that fails (a full disk, a folder at ``path``) removes it and raises, leaving what
    ``path`` held; an ``OSError`` with an error number names ``path`` and no other file (its
    ``filename``, and no ``filename2``): ``[Errno 28] No space left on device: 'run.npz'``.

    Args:
        path: the file to write.
        write: writes the contents to the open binary file it is given.
        durable: flush and ``fsync`` the file before the rename.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "xb") as f:
            write(f)
            if durable:
                f.flush()
                os.fsync(f.fileno())
    except OSError as e:
        tmp.unlink(missing_ok=True)
        _name(e, path)
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    try:
        os.replace(tmp, path)  # fails where path is a folder
    except OSError as e:
        tmp.unlink(missing_ok=True)
        _name(e, path)
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _name(e: OSError, path: pathlib.Path) -> None:
    """Make ``e`` name ``path``, the file the caller asked for, instead of the temporary file (and, for
    a rename, the pair of them). An ``OSError`` without an error number (``OSError("message")``) is
    left as it is: its text is its message, which a file name would replace with ``[Errno None]``.

    Args:
        e: the error of a write or rename.
        path: the file being written.
    """
    if e.errno is None:
        return
    e.filename = str(path)
    del e.filename2  # none: a filename2 of None would be printed as "... -> None"
