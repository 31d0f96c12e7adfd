"""Files written whole or not at all, and never over a file that is not the one being written."""

import os
import pathlib
import secrets
from collections.abc import Callable
from typing import BinaryIO


def write_whole(path: pathlib.Path, write: Callable[[BinaryIO], object], *, durable: bool = False) -> None:
    """Write ``path`` through a new temporary file beside it, renamed into place once written.

    The temporary file has a name of its own (made new: no existing file is written over). A write
    that fails (a full disk) removes it and raises, leaving what ``path`` held.

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
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)
