"""Figures (matplotlib, from the ``figures`` extra). Imported only by what draws.

Figures are ``matplotlib.figure.Figure`` objects made directly, never through ``pyplot``: they need
no display backend (saving a PNG draws with Agg), change no global matplotlib state, and are freed
with their last reference.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Mapping

from ._checks import brief, check_bool
from ._files import check_folder, write_whole


def figure(**kwargs):
    """A new ``matplotlib.figure.Figure``, outside ``pyplot``.

    Args:
        **kwargs: passed to ``Figure`` (``figsize``, ...).

    Returns:
        The figure; add axes with ``fig.subplots(...)`` and write it with ``fig.savefig(path)``.

    Raises:
        ImportError: matplotlib is not installed.
    """
    try:
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - depends on the environment
        raise ImportError("figures need matplotlib: pip install 'jaxmpm[figures]'") from None
    return Figure(**kwargs)


def _target(path, overwrite) -> tuple[pathlib.Path, str]:  # overwrite: checked here
    """The file a figure is written to and its format, checked before anything is drawn.

    As ``Figure.savefig`` does, the format is the suffix of ``path`` (any case), or without one
    matplotlib's default (``savefig.format``, PNG), appended to the name.

    Args:
        path: the path given.
        overwrite: replace a file already there.

    Returns:
        ``(file, format)``.

    Raises:
        ValueError: ``path`` is not a file name, is a folder or its suffix is not a format
            matplotlib writes, or ``overwrite`` is not a bool.
        FileExistsError: the file exists and ``overwrite`` is ``False``.
        FileNotFoundError: its folder does not exist (``NotADirectoryError``: it is a file).
    """
    check_bool("overwrite", overwrite)
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise ValueError(f"path must be a file name (a str or os.PathLike), got {brief(path)}")
    from matplotlib import rcParams
    from matplotlib.backend_bases import FigureCanvasBase

    name = os.fspath(path)
    if isinstance(name, bytes):
        name = os.fsdecode(name)
    fmt = os.path.splitext(name)[1][1:].lower()
    if not fmt:
        fmt = rcParams["savefig.format"]
        name = name.rstrip(".") + "." + fmt
    supported = FigureCanvasBase.get_supported_filetypes()
    if fmt not in supported:
        raise ValueError(
            f"path must end in a figure format matplotlib writes ({', '.join(sorted(supported))}), got {name}"
        )
    target = pathlib.Path(name)
    if target.is_dir():
        raise ValueError(f"path {target} is a folder, not a file: name the file to write")
    if not overwrite and os.path.lexists(target):
        raise FileExistsError(f"{target} already exists: pass overwrite=True to replace it")
    check_folder(target)
    return target, fmt


def _check_panels(name: str, value, shape: str) -> None:
    """Refuse ``value`` unless it is a non-empty dict (of ``shape``, for the message)."""
    if not isinstance(value, Mapping) or not value:
        raise ValueError(f"{name} must be a non-empty dict {shape}, got {_show(value)}")


def _show(value) -> str:
    """``brief(value)`` on one line (the repr of an array may span several)."""
    return " ".join(brief(value).split())


def _check_curves(where: str, curves, entries: tuple[str, ...]) -> None:
    """Refuse ``curves`` (a panel's, named ``where``) unless it is a list or tuple of curves, each a
    tuple or list of ``len(entries)`` values (``entries`` names them, for the message)."""
    want = f"{where} must be a list of curves ({', '.join(entries)}), got"
    if not isinstance(curves, (list, tuple)):
        raise ValueError(f"{want} {_show(curves)}")
    for curve in curves:
        if not isinstance(curve, (list, tuple)):
            raise ValueError(f"{want} a curve {_show(curve)}")
        if len(curve) != len(entries):
            first = f" ({_show(curve[0])}, ...)" if curve else ""
            raise ValueError(f"{want} a curve of {len(curve)} entries{first}")


def _save(fig, target: pathlib.Path, fmt: str, dpi: int) -> None:
    """Write ``fig`` to ``target`` whole (``write_whole``: a temporary file renamed into place); an
    ``OSError`` (a full disk) leaves what ``target`` held and names it (``filename``)."""
    write_whole(target, lambda f: fig.savefig(f, dpi=dpi, format=fmt))


def profile_grid(
    panels,
    *,
    ylabel: str,
    title: str,
    path,
    exact_line: float | None = None,
    overwrite: bool = False,
    note: str | None = None,
) -> pathlib.Path:
    """A grid of along-the-bar profiles.

    Args:
        panels: ``{(row_label, col_label): [(label, X, y, style), ...]}``, at least one panel: each
            key a tuple of two labels, each curve a tuple of four whose ``style`` is a dict of
            matplotlib line properties (``{}`` for the defaults). A panel whose list is empty is
            drawn empty; the legend is that of the first panel, drawn where it has curves.
        ylabel: the y-axis label.
        title: the figure title.
        path: where to write the figure, in the format of its suffix (``.png``, ``.pdf``, ``.svg``,
            ...; without one, PNG and ``.png`` appended, as ``Figure.savefig`` does).
        exact_line: draw a dashed reference line at this y (the manufactured solution).
        overwrite: replace a file already at ``path`` (else it is refused).
        note: text written under the grid (what is not drawn, and why), or ``None``.

    Returns:
        The file written.

    Raises:
        ValueError: ``panels`` is not a non-empty dict, a key of it is not a tuple of two labels,
            a panel is not a list of curves of four entries or a curve's style is not a dict;
            ``path`` is not a file name, is a folder or its suffix not a format matplotlib writes;
            ``overwrite`` is not a bool, or ``note`` not a string or ``None``.
        FileExistsError: the file exists and ``overwrite`` is ``False`` (found before drawing).
        FileNotFoundError: the folder of ``path`` does not exist.
        OSError: the figure cannot be written (a full disk): the file keeps what it held, and the
            error names it (``filename``).
    """
    _check_panels("panels", panels, "{(row_label, col_label): [(label, X, y, style), ...]}")
    if note is not None and not isinstance(note, str):
        raise ValueError(f"note must be a string or None, got {note!r}")
    target, fmt = _target(path, overwrite)
    for key, curves in panels.items():
        if not isinstance(key, tuple) or len(key) != 2:
            raise ValueError(f"a key of panels must be a (row, column) tuple of two labels, got {_show(key)}")
        _check_curves(f"panels[{_show(key)}]", curves, ("label", "X", "y", "style"))
        for label, _, _, style in curves:
            if not isinstance(style, Mapping):
                raise ValueError(
                    f"the style of curve {_show(label)} in panels[{_show(key)}] must be a dict of line "
                    f"properties ({{}} for matplotlib's defaults), got {_show(style)}"
                )
    rows = list(dict.fromkeys(r for r, _ in panels))
    cols = list(dict.fromkeys(c for _, c in panels))
    fig = figure(figsize=(3.2 * len(cols), 2.8 * len(rows)))
    axes = fig.subplots(len(rows), len(cols), sharex=True, sharey="row", squeeze=False)
    for i, r in enumerate(rows):
        for j, c in enumerate(cols):
            ax = axes[i][j]
            for label, X, y, style in panels.get((r, c), []):
                ax.plot(X, y, label=label, **style)
            if exact_line is not None:
                ax.axhline(exact_line, color="k", lw=0.8, ls="--")
            if i == 0:
                ax.set_title(c)
            if j == 0:
                ax.set_ylabel(f"{r}\n{ylabel}")
            if i == len(rows) - 1:
                ax.set_xlabel("X / L")
            ax.grid(alpha=0.3)
    if axes[0][0].get_legend_handles_labels()[0]:
        axes[0][0].legend(fontsize=7)
    fig.suptitle(title)
    bottom = 0.0
    if note:
        lines = note.count("\n") + 1
        bottom = min(0.4, (0.16 * lines + 0.1) / fig.get_figheight())  # 0.16 inch a line of 7 pt
        fig.text(0.01, 0.01, note, fontsize=7, ha="left", va="bottom")
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    _save(fig, target, fmt, dpi=120)
    return target


def time_series(
    series, *, ylabel: str, title: str, path, logy: bool = True, overwrite: bool = False
) -> pathlib.Path:
    """Curves against time, one panel per key of ``series``.

    Args:
        series: ``{panel: [(label, t, y), ...]}``, at least one panel: each curve a tuple of
            three. A panel whose list is empty is drawn empty; the legend is that of the first
            panel, drawn where it has curves.
        ylabel: the y-axis label (of the first panel; the panels share it).
        title: the figure title.
        path: where to write the figure, in the format of its suffix (``.png``, ``.pdf``, ``.svg``,
            ...; without one, PNG and ``.png`` appended, as ``Figure.savefig`` does).
        logy: a logarithmic y axis (``True`` or ``False``).
        overwrite: replace a file already at ``path`` (else it is refused).

    Returns:
        The file written.

    Raises:
        ValueError: ``series`` is not a non-empty dict or a panel of it not a list of curves of
            three entries; ``logy`` or ``overwrite`` is not a bool; or ``path`` is not a file name,
            is a folder or its suffix not a format matplotlib writes.
        FileExistsError: the file exists and ``overwrite`` is ``False`` (found before drawing).
        FileNotFoundError: the folder of ``path`` does not exist.
        OSError: the figure cannot be written (a full disk): the file keeps what it held, and the
            error names it (``filename``).
    """
    _check_panels("series", series, "{panel: [(label, t, y), ...]}")
    check_bool("logy", logy)
    target, fmt = _target(path, overwrite)
    for panel, curves in series.items():
        _check_curves(f"series[{_show(panel)}]", curves, ("label", "t", "y"))
    fig = figure(figsize=(5.0 * len(series), 3.6))
    axes = fig.subplots(1, len(series), sharey=True, squeeze=False)
    for ax, (panel, curves) in zip(axes[0], series.items()):
        for label, t, y in curves:
            ax.plot(t, y, label=label)
        if logy:
            ax.set_yscale("log")
        ax.set_title(panel)
        ax.set_xlabel("t (s)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(ylabel)
    if axes[0][0].get_legend_handles_labels()[0]:
        axes[0][0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, target, fmt, dpi=120)
    return target
