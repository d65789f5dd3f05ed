"""The noise floor of a bundle: the measurement noise (one standard deviation, output units), estimated from the
data themselves, with the estimate that was used.

In order of preference:

1. ``declared_sigma``: the bundle declares each output sample's standard uncertainty (``output_sigma``, e.g. the
   spread of repeated readings a magnetic-measurement system reports): their RMS over the evaluation runs;
2. ``off_state`` / ``dwell``: samples where the input is held (an off-state run, the holds of a step run, any
   dwell): the robust spread (MAD) of the output's first differences divided by √2 — slow changes (friction
   along the angle after it is removed, creep, drift) hardly change from one sample to the next;
3. ``repeated_runs``: runs that repeat the same input sample for sample: the spread of the difference of their
   outputs (offset removed) divided by √2;
4. ``residual_high_frequency``: the same first-difference estimate on the model's residual (the model error is
   smooth from sample to sample; the noise is not) — used when the data hold nothing better.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

__all__ = ["NoiseFloor", "from_data", "from_residual", "METHODS"]

METHODS = ("declared_sigma", "off_state", "dwell", "repeated_runs", "residual_high_frequency")
_MIN_SAMPLES = 20


@dataclass(frozen=True)
class NoiseFloor:
    """``sigma`` (output units), the ``method`` (one of :data:`METHODS`), how many samples (or differences) it
    rests on and a sentence for reports."""

    sigma: float
    method: str
    samples: int
    detail: str

    def to_dict(self) -> dict[str, Any]:
        return {"sigma": self.sigma, "method": self.method, "samples": self.samples, "detail": self.detail}


def _robust_sigma_of_differences(d: np.ndarray) -> float:
    mad = float(np.median(np.abs(d - np.median(d))))
    sigma = 1.4826 * mad / math.sqrt(2.0)
    if sigma == 0.0:
        # Quantised or noise-free data: the plain spread of the differences.
        sigma = float(np.std(d)) / math.sqrt(2.0)
    return sigma


def _held_differences(u: np.ndarray, y: np.ndarray, span: float) -> np.ndarray:
    """Output first differences between consecutive samples at one held input."""
    held = np.abs(np.diff(u)) <= 1e-9 * max(span, 1e-300)
    return np.diff(y)[held]


def from_data(runs: Sequence[Any], evaluation: Sequence[Any], *, slow: Callable[[Any], np.ndarray] | None = None
              ) -> NoiseFloor | None:
    """The noise floor from the data alone, or None when they hold no estimate (then use :func:`from_residual`).

    ``runs``: every run of the bundle; ``evaluation``: the evaluation runs; ``slow(run)``: a known slowly varying
    part of the output to remove first (the actuator's seal friction along the angle), or None."""
    sig = [r.output_sigma for r in evaluation if r.output_sigma is not None]
    if sig:
        s = np.concatenate(sig)
        if s.size and np.all(np.isfinite(s)) and float(np.max(s)) > 0:
            return NoiseFloor(float(np.sqrt(np.mean(s * s))), "declared_sigma", int(s.size),
                              "RMS of the output uncertainties the bundle declares")
    span = max((float(np.ptp(r.input)) for r in runs), default=0.0)

    def output(r: Any) -> np.ndarray:
        y = r.output
        return y - slow(r) if slow is not None else y

    off = [r for r in runs if r.kind == "off_state"]
    for method, group in (("off_state", off), ("dwell", list(runs))):
        diffs = [_held_differences(r.input, output(r), span) for r in group]
        d = np.concatenate(diffs) if diffs else np.zeros(0)
        if d.size >= _MIN_SAMPLES:
            where = "the off-state run" if method == "off_state" else "samples at a held input (dwells)"
            return NoiseFloor(_robust_sigma_of_differences(d), method, int(d.size),
                              f"robust spread of output first differences over {where}, divided by √2")
    pairs = []
    for i, a in enumerate(runs):
        for b in runs[i + 1:]:
            if a.input.size == b.input.size and np.allclose(a.input, b.input, rtol=0.0, atol=1e-9 * max(span, 1e-300)):
                pairs.append(output(a) - output(b))
    if pairs:
        d = np.concatenate([p - np.median(p) for p in pairs])
        if d.size >= _MIN_SAMPLES:
            mad = float(np.median(np.abs(d)))
            return NoiseFloor(1.4826 * mad / math.sqrt(2.0), "repeated_runs", int(d.size),
                              "robust spread of the output difference between runs with the same input, "
                              "divided by √2")
    return None


def from_residual(residuals: Sequence[np.ndarray]) -> NoiseFloor:
    """The high-frequency part of the model's residual (per-run arrays): robust spread of its first differences
    divided by √2."""
    d = np.concatenate([np.diff(np.asarray(r, float)) for r in residuals if np.size(r) > 1]) \
        if residuals else np.zeros(0)
    if d.size == 0:
        return NoiseFloor(float("nan"), "residual_high_frequency", 0, "no residual to estimate the noise from")
    return NoiseFloor(_robust_sigma_of_differences(d), "residual_high_frequency", int(d.size),
                      "robust spread of the model residual's first differences, divided by √2 (no off-state run, "
                      "dwell, repeated run or declared uncertainty in the data)")
