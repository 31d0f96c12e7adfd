"""Figures (matplotlib, from the ``figures`` extra). Imported only by what draws.

Figures are ``matplotlib.figure.Figure`` objects made directly, never through ``pyplot``: they need
no display backend (saving a PNG draws with Agg), change no global matplotlib state, and are freed
with their last reference.
"""

from __future__ import annotations


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


def profile_grid(panels, *, ylabel: str, title: str, path, exact_line: float | None = None) -> None:
    """A grid of along-the-bar profiles.

    Args:
        panels: ``{(row_label, col_label): [(label, X, y, style), ...]}``.
        ylabel: the y-axis label.
        title: the figure title.
        path: where to write the PNG.
        exact_line: draw a dashed reference line at this y (the manufactured solution).
    """
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
    axes[0][0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def time_series(series, *, ylabel: str, title: str, path, logy: bool = True) -> None:
    """Curves against time, one panel per key of ``series``.

    Args:
        series: ``{panel: [(label, t, y), ...]}``.
        ylabel: the y-axis label (of the first panel; the panels share it).
        title: the figure title.
        path: where to write the PNG.
        logy: a logarithmic y axis.
    """
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
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
