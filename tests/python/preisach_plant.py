"""An independent discretised Preisach plant for tests: relay hysterons on a threshold grid, smooth density."""
from __future__ import annotations

import numpy as np


class PreisachPlant:
    """``n`` thresholds per axis on [-1, 1] (cell midpoints); output span about ±``scale``.

    ``output_map`` (optional) makes the plant non-congruent: output = g(Preisach output).
    """

    def __init__(self, n: int = 200, scale: float = 300.0, output_map=None):
        self.n = n
        h = 2.0 / n
        t = -1.0 + (np.arange(n) + 0.5) * h
        alpha, beta = np.meshgrid(t, t, indexing="ij")
        hc, hi = (alpha - beta) / 2, (alpha + beta) / 2
        mu = np.exp(-(((hc - 0.25) / 0.18) ** 2)) * np.exp(-((hi / 0.3) ** 2)) + 0.05
        mu = np.where(beta <= alpha, mu, 0.0)
        self.weight = mu * scale / mu.sum()
        self.alpha_t = t
        self.state = -np.ones((n, n))
        self.u = -1.0
        self.output_map = output_map

    def _raw(self) -> float:
        return float((self.weight * self.state).sum())

    def step(self, u: float) -> float:
        if u > self.u:
            rows = (self.alpha_t > self.u) & (self.alpha_t <= u)
            self.state[rows, :] = 1.0
        elif u < self.u:
            cols = (self.alpha_t >= u) & (self.alpha_t < self.u)
            self.state[:, cols] = -1.0
        self.u = u
        y = self._raw()
        return float(self.output_map(y)) if self.output_map else y

    def run(self, inputs) -> np.ndarray:
        return np.array([self.step(float(u)) for u in inputs])


def edge_grid(n: int) -> np.ndarray:
    return -1.0 + 2.0 * np.arange(n + 1) / n


def first_order_curves(n: int = 200, count: int = 21, output_map=None):
    """Ascending curves from evenly spaced reversal minima (after positive saturation) and descending curves from
    maxima (after negative saturation), sampled on the threshold-cell edges."""
    grid = edge_grid(n)
    stride = n // (count - 1)
    asc, desc = [], []
    for c in range(count - 1):
        mi = c * stride
        p = PreisachPlant(n, output_map=output_map)
        p.step(1.0)
        p.step(grid[mi])
        u = grid[mi:]
        asc.append((u, p.run(u)))
        ma = n - c * stride
        p = PreisachPlant(n, output_map=output_map)
        p.step(-1.0)
        p.step(grid[ma])
        u = grid[: ma + 1][::-1]
        desc.append((u, p.run(u)))
    return asc, desc
