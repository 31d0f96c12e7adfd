"""Figures (matplotlib, from the ``figures`` extra). Imported only by what draws."""

from __future__ import annotations


def pyplot():
    """``matplotlib.pyplot`` on the non-interactive Agg backend, with a clear error if missing."""
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - depends on the environment
        raise ImportError("figures need matplotlib: pip install 'jaxmpm[figures]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def profile_grid(panels, *, ylabel: str, title: str, path, exact_line: float | None = None):
    """A grid of along-the-bar profiles.

    Args:
        panels: ``{(row_label, col_label): [(label, X, y, style), ...]}``.
        ylabel: the y-axis label.
        title: the figure title.
        path: where to write the PNG.
        exact_line: draw a dashed reference line at this y (the manufactured solution).
    """
    plt = pyplot()
    rows = list(dict.fromkeys(r for r, _ in panels))
    cols = list(dict.fromkeys(c for _, c in panels))
    fig, axes = plt.subplots(
        len(rows),
        len(cols),
        figsize=(3.2 * len(cols), 2.8 * len(rows)),
        sharex=True,
        sharey="row",
        squeeze=False,
    )
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
    plt.close(fig)


def time_series(series, *, ylabel: str, title: str, path, logy: bool = True):
    """Curves against time, one panel per key of ``series``: ``{panel: [(label, t, y), ...]}``."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(series), figsize=(5.0 * len(series), 3.6), sharey=True, squeeze=False)
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
    plt.close(fig)
