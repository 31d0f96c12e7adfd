"""The files a study writes: named in advance, each written whole.

Every study module declares its files in ``OUTPUTS`` (a ``Files``) and writes them through it. Each
file goes through a temporary file beside it, renamed into place once written
(``jaxmpm._files.write_whole``): a write that fails (a full disk) leaves the file as it was, the
previous run's version or none, and raises. ``jaxmpm study`` reads ``OUTPUTS`` to tell the study's own
files in its ``--out`` folder from anything else there.
"""

from __future__ import annotations

import csv
import io
import pathlib
from collections.abc import Iterable

from jaxmpm._files import temporary_of, write_whole

"""The temporary file ``write_whole`` writes ``NAME`` through (``.NAME.<pid>-<8 hex digits>.tmp``):
left behind only by a process killed while it wrote."""


class Files:
    """The names of the files a study writes in its folder, and how it writes each one whole.

    Args:
        *names: the file names (no folders).

    Raises:
        ValueError: a name is empty, has a folder part, or is given twice.
    """

    def __init__(self, *names: str):
        for name in names:
            if not isinstance(name, str) or not name or pathlib.PurePath(name).name != name:
                raise ValueError(f"a study's file is a bare file name, got {name!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"a study's files are named once each, got {names}")
        self.names = tuple(names)

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def leftover(self, name: str) -> bool:
        """Whether ``name`` is a temporary file left by a write of one of these files that never
        finished (a process killed mid-write).

        Args:
            name: a file name.

        Returns:
            ``True`` for ``.NAME.<pid>-<hex>.tmp`` with ``NAME`` one of ``names``.
        """
        return temporary_of(name) in self.names

    def check(self, path) -> pathlib.Path:
        """``path`` as a ``Path``, once its name is known to be one of ``names``.

        Args:
            path: where the study writes.

        Returns:
            The path.

        Raises:
            ValueError: its name is not one of ``names`` (a study writing a file it did not declare).
        """
        path = pathlib.Path(path)
        if path.name not in self.names:
            raise ValueError(f"{path.name} is not one of the study's files ({', '.join(self.names)})")
        return path

    def text(self, path, text: str) -> pathlib.Path:
        """Write ``text`` (UTF-8) to ``path``, whole.

        Args:
            path: the file (its name one of ``names``).
            text: the contents.

        Returns:
            The path.

        Raises:
            ValueError: the name is not one of ``names``.
            OSError: the file cannot be written (it is left as it was).
        """
        return write_text(self.check(path), text)

    def csv(self, path, rows: Iterable[dict], fieldnames) -> pathlib.Path:
        """Write ``rows`` as CSV with a header of ``fieldnames`` to ``path``, whole (``None``: empty).

        Args:
            path: the file (its name one of ``names``).
            rows: one dict per line.
            fieldnames: the columns, in order.

        Returns:
            The path.

        Raises:
            ValueError: the name is not one of ``names``, or a row has a key not in ``fieldnames``.
            OSError: the file cannot be written (it is left as it was).
        """
        return write_text(self.check(path), csv_text(rows, fieldnames))

    def figure(self, fig, path, dpi: int) -> pathlib.Path:
        """Save the matplotlib figure ``fig`` to ``path``, whole, in the format of its suffix.

        Args:
            fig: the figure.
            path: the file (its name one of ``names``, with a suffix matplotlib writes).
            dpi: its resolution.

        Returns:
            The path.

        Raises:
            ValueError: the name is not one of ``names``.
            OSError: the file cannot be written (it is left as it was).
        """
        return save_figure(fig, self.check(path), dpi)


def write_text(path, text: str) -> pathlib.Path:
    """Write ``text`` (UTF-8) to ``path``, whole (``write_whole``).

    Args:
        path: the file.
        text: the contents.

    Returns:
        The path.

    Raises:
        OSError: the file cannot be written (it is left as it was); its ``filename`` is ``path``.
    """
    path = pathlib.Path(path)
    data = text.encode("utf-8")
    write_whole(path, lambda f: f.write(data))
    return path


def csv_text(rows: Iterable, fieldnames) -> str:
    """``rows`` as CSV text with a header of ``fieldnames`` (``None``: empty).

    Args:
        rows: one dict per line (``csv.DictWriter``'s rows), or one sequence per line when
            ``fieldnames`` is ``None`` (``csv.writer``'s, the header among them).
        fieldnames: the columns, in order, or ``None``.

    Returns:
        The text.

    Raises:
        ValueError: a row has a key not in ``fieldnames``.
    """
    buf = io.StringIO(newline="")
    if fieldnames is None:
        csv.writer(buf).writerows(rows)
    else:
        w = csv.DictWriter(buf, fieldnames=list(fieldnames))
        w.writeheader()
        w.writerows(rows)
    return buf.getvalue()


def save_figure(fig, path, dpi: int) -> pathlib.Path:
    """Save the matplotlib figure ``fig`` to ``path``, whole (``write_whole``), in the format of its
    suffix.

    Args:
        fig: the figure.
        path: the file, with a suffix matplotlib writes.
        dpi: its resolution.

    Returns:
        The path.

    Raises:
        OSError: the file cannot be written (it is left as it was); its ``filename`` is ``path``.
    """
    path = pathlib.Path(path)
    write_whole(path, lambda f: fig.savefig(f, dpi=dpi, format=path.suffix[1:].lower()))
    return path
