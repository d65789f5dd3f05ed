"""What a sampled signal says about itself: its white-noise level and its sample rate."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from bmr._core import BmrError

__all__ = ["SampleRate", "default_deadband", "nominal_sample_rate", "sample_noise", "sample_rate"]


def sample_noise(u: np.ndarray | Sequence[np.ndarray]) -> float:
    """White-noise standard deviation of ``u`` (one array, or several pooled) from its second differences (zero
    on ramps and holds, ``σ√6`` for white noise), with the median so that the corners of a protocol do not
    count."""
    arrays = [np.asarray(u, dtype=float)] if isinstance(u, np.ndarray) else [np.asarray(a, float) for a in u]
    d2 = [np.abs(np.diff(a, 2)) for a in arrays if a.size > 2]
    return float(np.median(np.concatenate(d2))) / (0.6745 * math.sqrt(6.0)) if d2 else 0.0


def default_deadband(inputs: Sequence[np.ndarray]) -> float:
    """The reversal dead-band of measured inputs: 1 % of their span, or 10× their sample noise (pooled over the
    arrays) if that is larger: reversals are moves back by more than noise and small slips."""
    span = float(max(np.max(u) for u in inputs) - min(np.min(u) for u in inputs))
    noise = sample_noise(list(inputs))
    return max(0.01 * span, 10.0 * noise, 1e-12 * max(span, 1.0))


def nominal_sample_rate(t_s: np.ndarray) -> float:
    """The logging rate (Hz) of a uniformly sampled time column, rounded to what its timestamps resolve: a log at
    500 Hz whose times are stored with finite precision gives 500.0, not 499.99999999999955. NaN for fewer than
    two samples."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 2 or not t[-1] > t[0]:
        return float("nan")
    span = float(t[-1] - t[0])
    rate = (t.size - 1) / span
    # Timestamp resolution: the coarsest decimal step that all times sit on (to within float round-off).
    scale = max(abs(float(t[0])), abs(float(t[-1])), span)
    # Times on no decimal grid (accumulated float steps): their round-off, which grows with the sample count.
    resolution = t.size * float(np.finfo(float).eps) * scale
    for d in range(-9, 16):
        step = 10.0 ** -d
        if step > span:
            continue
        # Allowed deviation: float round-off of the stored times, in units of the step.
        if np.all(np.abs(t / step - np.round(t / step)) <= max(1e-9, 8 * np.finfo(float).eps * scale / step)):
            resolution = step
            break
    # Relative precision of the rate: one timestamp step over the whole span.
    digits = max(3, min(15, int(math.floor(-math.log10(resolution / span)))))
    return float(f"{rate:.{digits}g}")


@dataclass(frozen=True)
class SampleRate:
    """A logging rate: ``hz`` rounded to what the timestamps resolve (:func:`nominal_sample_rate` of the longest
    run), the median step and the range of steps (``irregular`` when the 5-95 % range of the steps exceeds 1 % of
    the median)."""

    hz: float
    dt_s: float
    dt_min_s: float
    dt_max_s: float
    irregular: bool

    def describe(self) -> str:
        from bmr.data.units import format_number

        text = f"{format_number(self.hz, 6)} Hz"
        if self.irregular:
            text += f" (irregular: steps {format_number(self.dt_min_s)}..{format_number(self.dt_max_s)} s)"
        return text


def sample_rate(times: Sequence[np.ndarray]) -> SampleRate:
    """The sample rate of several runs' time vectors (s) and how regular their steps are."""
    arrays = [np.asarray(t, dtype=float) for t in times]
    steps = np.concatenate([np.diff(t) for t in arrays if t.size > 1]) if arrays else np.zeros(0)
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if steps.size == 0:
        raise BmrError("cannot infer a sample rate: fewer than two increasing timestamps")
    hz = nominal_sample_rate(max(arrays, key=lambda t: t.size))
    lo, hi = (float(v) for v in np.quantile(steps, [0.05, 0.95]))
    dt = float(np.median(steps))
    return SampleRate(hz, dt, float(steps.min()), float(steps.max()), (hi - lo) > 0.01 * dt)
