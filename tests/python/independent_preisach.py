"""An independently written Preisach plant and its own protocols, for identification tests on data bmr was not
tuned on (no bmr plant or protocol code is used here).

The plant: a smooth Preisach density over switching fields (``alpha`` up, ``beta`` down), a Gaussian in coercivity
``(alpha - beta)/2`` times a Gaussian in interaction field ``(alpha + beta)/2``, integrated once into an Everett
table on a fine grid (1000 cells per axis); a reversible part ``tanh``; the memory as a stack of reversal points
with wiping-out. Options make it behave like a bench: Gaussian output noise, continued switching after a reversal
(the switching field follows the drive with a first-order lag, so the output keeps moving the old way for a moment
and creeps during dwells), and a recording that starts from whatever state earlier, unrecorded excitation left.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
import pandas as pd

from bmr.data.bundle import Bundle, Run

LO, HI = -1.25, 1.25


class Plant:
    """Preisach plant on ``[LO, HI]`` with output about ±``scale``/2 (``scale``: major-loop height)."""

    def __init__(self, *, coercivity: float = 0.4, coercivity_width: float = 0.03, interaction_width: float = 0.1,
                 reversible: float = 0.05, scale: float = 1070.0, lag_s: float = 0.0, cells: int = 1000,
                 density: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> None:
        """``density(hc, hi)``: the Preisach density over coercivity and interaction field instead of the Gaussians;
        it may be negative somewhere (interacting particles), and then so may the Everett function."""
        g = np.linspace(LO, HI, cells + 1)
        c = 0.5 * (g[:-1] + g[1:])
        h = g[1] - g[0]
        alpha, beta = np.meshgrid(c, c, indexing="xy")  # [row = beta index, column = alpha index]
        hc, hi = (alpha - beta) / 2, (alpha + beta) / 2
        mu = (np.exp(-((hc - coercivity) / coercivity_width) ** 2) * np.exp(-((hi / interaction_width) ** 2))
              if density is None else density(hc, hi))
        self.signed = density is not None
        mass = np.where(beta < alpha, mu, np.where(beta == alpha, 0.5 * mu, 0.0)) * h * h
        # E[i, j]: mass with beta >= g_i and alpha < g_j (the rise from reversal g_i up to g_j, halved).
        col = np.cumsum(np.cumsum(mass, axis=1)[::-1], axis=0)[::-1]
        self.table = np.zeros((cells + 1, cells + 1))
        self.table[:cells, 1:] = col
        self.cells, self.h = cells, h
        self.k = 1.0
        self.reversible = reversible
        top = self.everett(LO, np.array([HI]))[0] / 2 + self._reversible(HI)
        self.k = scale / 2 / top
        self.lag_s = lag_s
        self.reset()

    def everett(self, beta: float, alpha: np.ndarray) -> np.ndarray:
        """Output rise from reversal minimum ``beta`` up to ``alpha`` (bilinear in the fine table)."""
        beta = min(max(beta, LO), HI)
        alpha = np.clip(np.asarray(alpha, dtype=float), LO, HI)
        fi = (beta - LO) / self.h
        i = min(int(fi), self.cells - 1)
        s = fi - i
        fj = (alpha - LO) / self.h
        j = np.minimum(fj.astype(int), self.cells - 1)
        t = fj - j
        e = self.table
        v = (1 - s) * ((1 - t) * e[i, j] + t * e[i, j + 1]) + s * ((1 - t) * e[i + 1, j] + t * e[i + 1, j + 1])
        return np.where(alpha > beta, v if self.signed else np.maximum(v, 0.0), 0.0) * 2 * self.k

    def _reversible(self, u: np.ndarray | float) -> np.ndarray | float:
        return self.k * self.reversible * float(self.table[0, self.cells]) * np.tanh(np.asarray(u) / 0.6)

    def reset(self) -> None:
        """Negative saturation."""
        self.stack = [(LO, -float(self.everett(LO, np.array([HI]))[0]) / 2)]
        self.x = LO

    def drive(self, u: np.ndarray, dt: float) -> np.ndarray:
        """Continue from the present state along drive ``u`` (sampled every ``dt`` s); returns the output."""
        u = np.clip(np.asarray(u, dtype=float), LO, HI)
        if self.lag_s > 0:
            a = math.exp(-dt / self.lag_s)
            eff = np.empty_like(u)
            x = self.x
            for i, v in enumerate(u):
                x = a * x + (1 - a) * v
                eff[i] = x
            u = eff
        out = np.empty_like(u)
        i, n = 0, u.size
        while i < n:
            rising = len(self.stack) % 2 == 1
            cur = self.x
            if (rising and u[i] < cur) or (not rising and u[i] > cur):
                # The drive turns at the present input: it becomes a reversal point.
                self.stack.append((cur, self._y(cur)))
                continue
            j = i
            while j + 1 < n and ((u[j + 1] >= u[j]) if rising else (u[j + 1] <= u[j])):
                j += 1
            k = i
            while k <= j:
                limit = self.stack[-2][0] if len(self.stack) >= 2 else (math.inf if rising else -math.inf)
                m = k
                while m <= j and ((u[m] <= limit) if rising else (u[m] >= limit)):
                    m += 1
                ref_u, ref_y = self.stack[-1]
                seg = u[k:m]
                if rising:
                    out[k:m] = ref_y + self.everett(ref_u, seg)
                else:
                    out[k:m] = ref_y - np.array([self.everett(x, np.array([ref_u]))[0] for x in seg])
                if m <= j:
                    del self.stack[-2:]  # wiped out: the older reversal pair no longer counts
                k = m
            self.x = float(u[j])
            i = j + 1
        return out + self._reversible(u)

    def _y(self, x: float) -> float:
        ref_u, ref_y = self.stack[-1]
        if len(self.stack) % 2 == 1:
            return ref_y + float(self.everett(ref_u, np.array([x]))[0])
        return ref_y - float(self.everett(x, np.array([ref_u]))[0])


# ------------------------------------------------------------------------------------------ protocols
def ramps(vertices: list[float], rate: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Piecewise linear in time through ``vertices`` at ``rate`` (input units per s), sampled at ``fs`` from t=0
    (vertices fall between samples, as on a bench)."""
    v = np.asarray(vertices, dtype=float)
    tv = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(v)) / rate)])
    t = np.arange(0.0, tv[-1], 1.0 / fs)
    return t, np.interp(t, tv, v)


def forc_vertices(family: str, curves: int = 21, opening: bool = True) -> list[float]:
    """First-order curves of one family: ascending ones from positive saturation down to each reversal and back
    up; descending ones mirrored. ``curves`` reversals evenly spaced, saturation excluded."""
    rev = np.linspace(LO, HI, curves + 1)[:-1]
    if family == "ascending":
        v = [0.0, HI, LO, HI] if opening else [HI]
        for m in rev[1:]:
            v += [float(m), HI]
    else:
        v = [0.0, LO, HI, LO] if opening else [LO]
        for m in -rev[1:]:
            v += [float(m), LO]
    return v


def multipeak_vertices(seed: int, peaks: int = 24) -> list[float]:
    """An opening to both ends, then random nested and un-nested reversals."""
    rng = np.random.default_rng(seed)
    v, x = [0.0, HI, LO], LO
    for k in range(peaks):
        x = float(rng.uniform(x + 0.1, HI)) if k % 2 == 0 else float(rng.uniform(LO, x - 0.1))
        v.append(x)
    return v + [0.0]


def run(name: str, kind: str, t: np.ndarray, u: np.ndarray, y: np.ndarray) -> Run:
    return Run(name, kind, pd.DataFrame({"t_s": t, "current_a": u, "theta_rad": np.zeros_like(t),
                                         "torque_nmm": y}))


def record(plant: Plant, name: str, kind: str, vertices: list[float], rng: np.random.Generator, *,
           rate: float = 0.5, fs: float = 500.0, noise: float = 1.5, fresh: bool = True) -> Run:
    """Drive the plant through ``vertices`` and record it with output noise (``fresh``: from negative saturation,
    else from whatever state the plant is in)."""
    if fresh:
        plant.reset()
    t, u = ramps(vertices, rate, fs)
    y = plant.drive(u, 1.0 / fs) + rng.normal(0.0, noise, u.size)
    return run(name, kind, t, u, y)


def unknown_start_runs(plant: Plant, rng: np.random.Generator) -> tuple[Run, Run]:
    """A training run that starts where unrecorded excitation left the plant and reaches positive saturation only
    in its last cycle (never negative saturation), and a held-out multi-peak run, also from an unrecorded state."""
    plant.reset()
    plant.drive(ramps([0.0, LO, 0.6, -0.2, 0.3], 0.5, 500.0)[1], 0.002)
    v = [0.0]
    for k in range(6):
        v += [0.9 - 0.05 * k, -0.8 + 0.1 * k]
    train = record(plant, "drift", "custom", v + [HI, -0.3], rng, fresh=False)
    plant.reset()
    plant.drive(ramps([0.0, 0.4, -0.5], 0.5, 500.0)[1], 0.002)
    held = record(plant, "multipeak", "multipeak", multipeak_vertices(5), rng, fresh=False)
    return train, held
