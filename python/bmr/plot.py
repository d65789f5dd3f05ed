"""One figure style for everything bmr draws (paper figures, diagnosis, prediction, calibration), so that figures
side by side in a report share fonts, line weights and colours, and a reference signal is never hidden.

Use :func:`figure` inside :func:`style` (or let :func:`figure` apply the style itself), draw measured data with the
colours of :data:`COLORS`, draw the reference with :func:`reference_line` (on top, black, dashed) and finish with
:func:`save` (a PNG file) or :func:`png_base64` (for self-contained HTML). matplotlib is imported lazily and always
with the non-interactive Agg backend: importing bmr never opens a window.
"""
from __future__ import annotations

import base64
import io
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Sequence

__all__ = ["COLORS", "DPI", "RC", "SIZES", "figure", "legend_outside", "png_base64", "reference_line", "save",
           "style", "thin"]

DPI = 110
"""Resolution of saved figures (dots per inch)."""

SIZES = {
    "wide": (7.0, 3.3),  # time series
    "tall": (7.0, 4.4),  # time series with a legend row
    "square": (5.0, 4.2),  # loops and curve families
    "panel3": (11.0, 3.2),  # three panels side by side
}
"""Figure sizes in inches by layout."""

COLORS = {
    "reference": "black",
    "measured": "0.6",
    "nominal": "tab:red",
    "extended": "tab:blue",
    "model": "tab:blue",
    "alternative": "tab:orange",
    "third": "tab:green",
    "limit": "tab:red",
}
"""Colours by role: the same role has the same colour in every figure."""

RC = {
    "font.size": 9.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 9.0,
    "legend.fontsize": 8.0,
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "lines.linewidth": 0.8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "grid.linewidth": 0.5,
    "legend.framealpha": 0.9,
    "figure.dpi": DPI,
    "savefig.dpi": DPI,
    "figure.constrained_layout.use": True,
}
"""matplotlib settings of the bmr style."""


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@contextmanager
def style() -> Iterator[Any]:
    """Apply the bmr style for the duration of the block; yields ``matplotlib.pyplot``."""
    plt = _pyplot()
    with plt.rc_context(RC):
        yield plt


def figure(layout: str = "wide", *, nrows: int = 1, ncols: int = 1, height: float | None = None, **kwargs: Any
           ) -> tuple[Any, Any]:
    """A new figure in the bmr style: ``layout`` one of :data:`SIZES` (``height`` overrides its height in inches);
    returns ``(fig, axes)`` like ``plt.subplots``."""
    if layout not in SIZES:
        raise ValueError(f"unknown figure layout {layout!r}; use one of {', '.join(SIZES)}")
    plt = _pyplot()
    w, h = SIZES[layout]
    with plt.rc_context(RC):
        fig, axes = plt.subplots(nrows, ncols, figsize=(w, height if height is not None else h), **kwargs)
    # The figure keeps the style's layout engine; fonts are taken from rcParams when artists are created, so
    # callers draw inside ``style()`` (``save`` and ``png_base64`` do not need it).
    return fig, axes


def reference_line(ax: Any, x: Any, y: Any, label: str = "reference", **kwargs: Any) -> Any:
    """The reference signal drawn on top of every trace (black, dashed), so that it stays visible."""
    opts = {"color": COLORS["reference"], "ls": "--", "lw": 1.0, "zorder": 5, "label": label}
    opts.update(kwargs)
    return ax.plot(x, y, **opts)[0]


def legend_outside(ax: Any, handles: Sequence[Any] | None = None, labels: Sequence[str] | None = None,
                   ncol: int | None = None) -> Any:
    """A legend in one row above the axes, where it cannot cover data."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    elif labels is None:
        labels = [h.get_label() for h in handles]
    n = len(handles)
    return ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.01, 1.0, 0.2), mode="expand",
                     ncol=ncol or min(n, 3), borderaxespad=0.0, frameon=False)


def thin(*arrays: Any, n: int = 6000) -> list[Any]:
    """Every k-th sample so that a figure stays light (no smoothing: the data stay honest)."""
    k = max(1, -(-len(arrays[0]) // n))
    return [a[::k] for a in arrays]


def save(fig: Any, path: str | Path) -> Path:
    """Write ``fig`` as PNG to ``path`` atomically (a reader never sees a half-written figure) and close it."""
    from bmr.data.files import write_atomic

    plt = _pyplot()
    try:
        return write_atomic(path, lambda fh: fig.savefig(fh, format="png"))
    finally:
        plt.close(fig)


def png_base64(fig: Any) -> str:
    """``fig`` as a base64 PNG (for self-contained HTML), closed afterwards."""
    plt = _pyplot()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")
