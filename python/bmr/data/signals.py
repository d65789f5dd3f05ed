"""What a sampled signal says about itself: its white-noise level, its sample rate, the edges of a capture that
are not the experiment (an idle hold before it starts, a command jump as it ends) and the ends of a sensor's range
(an output held at its extreme while the input moves on)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from bmr._core import BmrError

__all__ = ["CaptureEdges", "OutputRails", "SampleRate", "capture_edges", "default_deadband", "nominal_sample_rate",
           "output_rails", "sample_noise", "sample_rate"]

# An idle hold is at least this many samples of a constant input; a command jump ends the run within this many
# steps of its end.
MIN_HOLD_SAMPLES = 10
END_JUMP_STEPS = 3
# A range end: the output's extreme held on at least this many consecutive samples while the input moves, where
# fewer than this share of the other samples repeat the sample before (the output resolves noise or signal there).
MIN_RAIL_SAMPLES = 5
MAX_REPEAT_SHARE = 0.2


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


@dataclass(frozen=True)
class CaptureEdges:
    """Samples at a capture's edges that are not the experiment: ``hold`` leading samples of an idle hold (the
    input constant before the excitation starts; the hold's last sample stays, it is the state the run starts
    from) and ``jump`` trailing samples from a command jump at the very end (the drive set back while the device
    lags: a transient no quasi-static model describes). ``hold_level`` is the held input."""

    hold: int = 0
    jump: int = 0
    hold_level: float = math.nan

    @property
    def any(self) -> bool:
        return bool(self.hold or self.jump)


def capture_edges(u: np.ndarray) -> CaptureEdges:
    """The idle hold at the start of input ``u`` (at least ``MIN_HOLD_SAMPLES`` samples within 4× the input's
    sample noise of its first value) and a command jump within its last ``END_JUMP_STEPS`` steps (a step above
    10 % of the input span and either 10× the 99th percentile of the run's other steps or 3× the largest of them:
    a switching excitation such as a PRBS has large steps of its own, but none like the drive set back to rest).
    A run that is all hold, or too short to tell, has no edges."""
    u = np.asarray(u, dtype=float)
    n = u.size
    if n < 2 * MIN_HOLD_SAMPLES or not np.all(np.isfinite(u)):
        return CaptureEdges()
    span = float(np.ptp(u))
    if span <= 0.0:
        return CaptureEdges()
    tol = max(4.0 * sample_noise(u), 1e-9 * span)
    moved = np.abs(u - u[0]) > tol
    first_move = int(np.argmax(moved))
    hold = first_move - 1 if first_move >= MIN_HOLD_SAMPLES else 0
    steps = np.abs(np.diff(u))
    tail = steps[-END_JUMP_STEPS:]
    k = int(np.argmax(tail))
    rest = steps[hold:-END_JUMP_STEPS]
    jump = 0
    if rest.size and tail[k] > 0.1 * span and tail[k] > min(10.0 * float(np.percentile(rest, 99)),
                                                            3.0 * float(rest.max())):
        jump = END_JUMP_STEPS - k  # the samples after the jump's step
    return CaptureEdges(hold, jump, float(u[0]) + 0.0 if hold else math.nan)  # + 0.0: no "-0"


@dataclass(frozen=True)
class OutputRails:
    """The ends of the output's measuring range seen in a recording: ``low`` / ``high`` the value an output is
    held at (None: that end not reached), ``samples`` how many samples sit there out of ``total``. A sensor at
    its range end reads the same value whatever the device does, so those samples say only that the output is
    at least (at most) that value: they are left out of identification, of fits and of scores."""

    low: float | None = None
    high: float | None = None
    samples: int = 0
    total: int = 0

    @property
    def any(self) -> bool:
        return self.low is not None or self.high is not None

    def mask(self, y: np.ndarray) -> np.ndarray:
        """Which samples of output ``y`` sit at a range end."""
        y = np.asarray(y, dtype=float)
        out = np.zeros(y.shape, dtype=bool)
        if self.low is not None:
            out |= y <= self.low
        if self.high is not None:
            out |= y >= self.high
        return out

    def describe(self, quantity: Any = None) -> str:
        fmt = (lambda v: quantity.format(v, 6)) if quantity is not None else (lambda v: f"{v:.6g}")
        ends = " and ".join(fmt(v) for v in (self.low, self.high) if v is not None)
        share = 100.0 * self.samples / self.total if self.total else 0.0
        return (f"the output is held at its range end ({ends}) on {self.samples} of {self.total} samples "
                f"({share:.2g} %) while the input moves: the sensor's limit; those samples are left out of "
                "identification, fits and scores")

    def to_dict(self) -> dict[str, Any]:
        return {"low": self.low, "high": self.high, "samples": self.samples, "total": self.total}


def _held_at(u: np.ndarray, y: np.ndarray, value: float) -> bool:
    """Whether ``y`` stays exactly at ``value`` on ``MIN_RAIL_SAMPLES`` consecutive samples while ``u`` moves."""
    at = np.flatnonzero(y == value)
    if at.size < MIN_RAIL_SAMPLES:
        return False
    # Stretches of consecutive indices.
    breaks = np.flatnonzero(np.diff(at) != 1)
    starts = np.r_[at[0], at[breaks + 1]]
    ends = np.r_[at[breaks], at[-1]]
    for a, b in zip(starts, ends):
        if b - a + 1 >= MIN_RAIL_SAMPLES and np.ptp(u[a:b + 1]) > 0.0:
            return True
    return False


def output_rails(pairs: Sequence[tuple[np.ndarray, np.ndarray]]) -> OutputRails:
    """The range ends of an output recorded with its input, ``pairs`` of ``(input, output)`` arrays (the runs of
    one bundle): the output's overall maximum (minimum) is a range end when some run holds it exactly on
    ``MIN_RAIL_SAMPLES`` consecutive samples while its input moves, and the output elsewhere resolves its noise
    (fewer than ``MAX_REPEAT_SHARE`` of the other samples repeat the sample before). A coarse or noise-free
    recording repeats values everywhere, so a held extreme there is not told from a flat saturation: no range
    end is claimed."""
    arrays = [(np.asarray(u, dtype=float), np.asarray(y, dtype=float)) for u, y in pairs]
    arrays = [(u, y) for u, y in arrays if y.size and u.shape == y.shape and np.all(np.isfinite(y))]
    if not arrays:
        return OutputRails()
    hi = max(float(y.max()) for _, y in arrays)
    lo = min(float(y.min()) for _, y in arrays)
    total = sum(y.size for _, y in arrays)
    if not hi > lo:
        return OutputRails(total=total)
    high = hi if any(_held_at(u, y, hi) for u, y in arrays) else None
    low = lo if any(_held_at(u, y, lo) for u, y in arrays) else None
    if high is None and low is None:
        return OutputRails(total=total)
    repeats = pairs_counted = 0
    for _, y in arrays:
        inside = (y > lo) & (y < hi)
        both = inside[1:] & inside[:-1]
        repeats += int(np.count_nonzero((y[1:] == y[:-1]) & both))
        pairs_counted += int(np.count_nonzero(both))
    if pairs_counted == 0 or repeats >= MAX_REPEAT_SHARE * pairs_counted:
        return OutputRails(total=total)
    rails = OutputRails(low, high, 0, total)
    return OutputRails(low, high, sum(int(np.count_nonzero(rails.mask(y))) for _, y in arrays), total)
