"""The FORC diagram of an identified model: its Preisach density in the coordinates magnetometer users read.

A first-order reversal curve ``M(Hr, H)`` starts at positive saturation, falls to the reversal input ``Hr`` and
rises through ``H ≥ Hr``; the FORC density is ``ρ = -½ ∂²M/∂Hr∂H`` (output units per input unit squared), drawn
over the coercive axis ``Hc = (H − Hr)/2`` and the interaction axis ``Hu = (H + Hr)/2``. The curves are the
model's own (``Model.simulate`` in the core), so the diagram shows what the identification found, not the
measurement's noise."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bmr import plot
from bmr._core import BmrError

__all__ = ["ForcDensity", "forc_density", "forc_diagram"]


@dataclass(frozen=True)
class ForcDensity:
    """``rho[i, j]`` at reversal input ``hr[i]`` and input ``h[j]`` (NaN where ``h < hr``), in output units per
    input unit squared; ``hc``/``hu`` are the same points on the coercive and interaction axes."""

    hr: np.ndarray
    h: np.ndarray
    rho: np.ndarray

    @property
    def hc(self) -> np.ndarray:
        return 0.5 * (self.h[None, :] - self.hr[:, None])

    @property
    def hu(self) -> np.ndarray:
        return 0.5 * (self.h[None, :] + self.hr[:, None])


def forc_density(model: Any, points: int = 81) -> ForcDensity:
    """The model's FORC density on a ``points`` × ``points`` grid over its input range."""
    if not (isinstance(points, int) and points >= 5):
        raise BmrError(f"points must be an integer >= 5, got {points!r}")
    lo, hi = model.hysteresis.input_range
    grid = np.linspace(lo, hi, points)
    m = np.full((points, points), np.nan)
    for i, hr in enumerate(grid):
        # From positive saturation down to hr, then up through the grid above it.
        m[i, i:] = model.simulate(grid[i:], initial="positive")
    step = grid[1] - grid[0]
    # The mixed difference of each grid cell whose four corners are curves (h >= hr), at the cell's centre.
    rho = -0.5 * (m[1:, 1:] - m[1:, :-1] - m[:-1, 1:] + m[:-1, :-1]) / step ** 2
    centre = 0.5 * (grid[1:] + grid[:-1])
    return ForcDensity(centre, centre.copy(), rho)


def forc_diagram(model: Any, path: str | Path, *, points: int = 81, title: str = "") -> Path:
    """Write the FORC diagram of ``model`` as PNG to ``path``."""
    d = forc_density(model, points)
    q = model.quantities
    keep = np.isfinite(d.rho) & (d.hc > 0)
    hc, hu, rho = d.hc[keep], d.hu[keep], d.rho[keep]
    scale = float(np.percentile(np.abs(rho), 99.5)) if rho.size else 0.0
    scale = scale or 1.0  # the colour scale: the largest densities but a few isolated cells
    with plot.style():
        fig, ax = plot.figure("square")
        art = ax.tricontourf(hc, hu, np.clip(rho / scale, -0.999, 0.999), levels=np.linspace(-1.0, 1.0, 21),
                             cmap="RdBu_r")
        bar = fig.colorbar(art, ax=ax)
        bar.set_label(f"ρ / {scale:.3g} {q.output.unit}/{q.input.unit}²")
        ax.set_xlabel(f"Hc = (H − Hr)/2 ({q.input.unit})")
        ax.set_ylabel(f"Hu = (H + Hr)/2 ({q.input.unit})")
        ax.set_title(title or f"FORC diagram of the identified {q.output.name}")
        return plot.save(fig, path)
