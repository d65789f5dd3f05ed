"""Where a run's hysteresis state is known and which input range it reaches.

A run starts from an unknown state; once the input has been to one saturation end and then the other, the state
is known (the major loop erases all memory). Samples before that are either not evaluated or need their initial
state estimated.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from bmr.data.signals import sample_noise

__all__ = ["SATURATION_TOL", "evaluation_start", "input_range_of", "sample_noise"]

# A run's state is known once its input is this close (fraction of the span) to a saturation end.
SATURATION_TOL = 0.002


def input_range_of(currents: Sequence[np.ndarray], window: int = 21) -> tuple[float, float]:
    """The saturation ends reached by measured inputs. A noisy input's single extreme samples overshoot the
    commanded end by several sigmas, and the extremes of a ``window``-sample running mean stay within half a window
    of steps of it; each end is the one of ``extreme ∓ 2.5 σ`` (``σ``: the input's sample noise; the extreme
    itself for exact inputs) and the running-mean extreme that lies further out."""
    lo, hi = math.inf, -math.inf
    for u in currents:
        u = np.asarray(u, dtype=float)
        if not u.size:
            continue
        w = max(1, min(window, u.size))
        mean = np.convolve(u, np.full(w, 1.0 / w), mode="valid")
        sigma = sample_noise(u)
        lo = min(lo, float(mean.min()), float(u.min()) + 2.5 * sigma)
        hi = max(hi, float(mean.max()), float(u.max()) - 2.5 * sigma)
    return lo, hi


def evaluation_start(u: np.ndarray, lo: float, hi: float, tol: float) -> int:
    """First sample from which the hysteresis state is known: the run has reached one saturation end and then
    the other (a real actuator's steel may not saturate within the current range, so one end alone does not erase
    the unknown initial state; the major loop does). Falls back to the one end reached, then to 0."""
    u = np.asarray(u, dtype=float)
    top = np.flatnonzero(u >= hi - tol)
    bottom = np.flatnonzero(u <= lo + tol)
    if top.size and bottom.size:
        return int(max(top[0], bottom[0]))
    if top.size or bottom.size:
        return int((top if top.size else bottom)[0])
    return 0
