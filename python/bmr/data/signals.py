"""What a sampled signal says about itself: its white-noise level and its sample rate."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from bmr._core import BmrError

__all__ = ["SampleRate", "sample_noise", "sample_rate", "timestamp_resolution"]


def sample_noise(u: np.ndarray | Sequence[np.ndarray]) -> float:
    """White-noise standard deviation of ``u`` (one array, or several pooled) from its second differences (zero
    on ramps and holds, ``σ√6`` for white noise), with the median so that the corners of a protocol do not
    count."""
    arrays = [np.asarray(u, dtype=float)] if isinstance(u, np.ndarray) else [np.asarray(a, float) for a in u]
    d2 = [np.abs(np.diff(a, 2)) for a in arrays if a.size > 2]
    return float(np.median(np.concatenate(d2))) / (0.6745 * math.sqrt(6.0)) if d2 else 0.0


def timestamp_resolution(t: np.ndarray) -> float:
    """The coarsest decimal step (10⁻ᵏ s) that every timestamp is a whole multiple of, within round-off: 0.01 for
    times written with two decimals, 0.002 s steps give 0.001. Timestamps on no decimal grid give their
    round-off level."""
    t = np.asarray(t, dtype=float)
    scale = float(np.max(np.abs(t))) if t.size else 0.0
    floor = max(scale * 1e-15, 1e-300)
    for k in range(-3, 16):
        q = 10.0 ** -k
        if q < floor:
            break
        x = t / q
        if np.all(np.abs(x - np.round(x)) <= 1e-6):
            return q
    return floor


@dataclass(frozen=True)
class SampleRate:
    """A logging rate: ``hz`` rounded to what the timestamps resolve, the median step, and its spread (``irregular``
    when the 5-95 % range of the steps exceeds 1 % of the median)."""

    hz: float
    dt_s: float
    dt_min_s: float
    dt_max_s: float
    resolution_s: float
    irregular: bool

    def describe(self) -> str:
        from bmr.data.units import format_number

        text = f"{format_number(self.hz, 6)} Hz"
        if self.irregular:
            text += f" (irregular: steps {format_number(self.dt_min_s)}..{format_number(self.dt_max_s)} s)"
        return text


def sample_rate(times: Sequence[np.ndarray] | np.ndarray) -> SampleRate:
    """The sample rate of one or several time vectors (s): ``1 / median step``, rounded to the significant digits
    the timestamps' resolution supports (a 2 ms step logged in whole milliseconds is 500 Hz, not
    499.99999999999955 Hz)."""
    arrays = [np.asarray(times, dtype=float)] if isinstance(times, np.ndarray) else [np.asarray(t, float)
                                                                                   for t in times]
    steps = np.concatenate([np.diff(t) for t in arrays if t.size > 1]) if arrays else np.zeros(0)
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if steps.size == 0:
        raise BmrError("cannot infer a sample rate: fewer than two increasing timestamps")
    q = max(timestamp_resolution(t) for t in arrays if t.size)
    dt = float(np.median(steps))
    digits = int(np.clip(math.ceil(math.log10(max(dt / q, 1.0)) + 1e-9) + 1, 2, 12))
    hz = float(f"{1.0 / dt:.{digits}g}")
    lo, hi = (float(v) for v in np.quantile(steps, [0.05, 0.95]))
    return SampleRate(hz, dt, float(steps.min()), float(steps.max()), q, (hi - lo) > 0.01 * dt)
