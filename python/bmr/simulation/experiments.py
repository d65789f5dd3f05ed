"""The paper's experiment protocols on the virtual actuator and bundles of them (``bmr simulate``:
:func:`bmr.simulation.excitation.run_cli`).

Each protocol drives a :class:`bmr.VirtualActuator` (continuing from its current state) and returns a
:class:`bmr.Run`. Every run opens with an excursion to both saturations — nominal current
``0 → +full → −full → 0`` — so the steel state of both coils is known from the first saturation on; the run's
``meta["opening_end_s"]`` says where the protocol proper begins.

Units: current in A (nominal current: negative excites coil 1, positive coil 2), torque in N·mm, angles in rad,
time in s. Logged columns: ``t_s`` (from the run's start), ``current_a`` (commanded nominal current),
``theta_rad``, ``torque_nmm`` (measured), ``coil1_a``, ``coil2_a`` (converter currents) and, for tracking runs,
``reference_nmm``.

Logging rate: bundles are simulated and logged at :data:`BUNDLE_SAMPLE_RATE_HZ` (500 Hz) — fast enough for the
rotor harmonics (1 rev/s, lines up to 12 cycles/rev) and the coil field lag (ms), small enough that the full,
quasi-static experiment set of about 2 600 s (1 200 s multi-step, 200 s runs) writes in seconds.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from bmr._core import BmrError, ExcitationError, VirtualActuator
from bmr.data.bundle import Bundle, Run

FULL_CURRENT_A = 1.25
"""Saturating nominal current of the protocols (±10 units of 0.125 A on the paper's rig)."""
OPENING_RATE_A_PER_S = 0.5
"""Current rate of the opening excursion to both saturations."""
BUNDLE_SAMPLE_RATE_HZ = 500.0
"""Sample rate of simulated bundles."""
MULTIPEAK_SEED = 2013
"""Fixed seed of the multi-peak excitations in a bundle: the bundle seed changes only the noise."""

__all__ = [
    "BUNDLE_SAMPLE_RATE_HZ",
    "FULL_CURRENT_A",
    "custom",
    "experiment_count",
    "MULTIPEAK_SEED",
    "OPENING_RATE_A_PER_S",
    "first_order_ascending",
    "first_order_descending",
    "multi_step",
    "multipeak",
    "off_state",
    "opening_path",
    "ramp_path",
    "reference_multipeak",
    "reference_triangle",
    "simulate_bundle",
    "tracking",
    "triangle",
    "triangle_path",
]


# ---------------------------------------------------------------------------------------------------------------
# Paths


def ramp_path(start: float, vertices: Sequence[float], step: float) -> np.ndarray:
    """Samples of the piecewise-linear path from ``start`` (excluded) through ``vertices`` (each reached exactly).

    Each segment takes ``ceil(|Δ| / step)`` equal steps (``round`` when ``|Δ|`` is a whole number of steps, so
    paths on a grid stay on it). Zero-length segments are skipped.
    """
    if not (np.isfinite(step) and step > 0):
        raise ExcitationError(f"ramp step must be positive and finite, got {step!r}")
    parts = []
    a = float(start)
    for b in vertices:
        b = float(b)
        span = abs(b - a)
        if span == 0.0:
            continue
        q = span / step
        n = int(round(q)) if abs(q - round(q)) < 1e-9 else int(np.ceil(q))
        n = max(n, 1)
        k = np.arange(1, n + 1, dtype=float)
        seg = a + (b - a) * k / n
        seg[-1] = b
        parts.append(seg)
        a = b
    return np.concatenate(parts) if parts else np.empty(0)


def opening_path(sample_rate_hz: float, *, full_a: float = FULL_CURRENT_A,
                 rate_a_per_s: float = OPENING_RATE_A_PER_S) -> np.ndarray:
    """The opening excursion ``0 → +full → −full → 0`` (A) at ``rate_a_per_s``, sampled at ``sample_rate_hz``."""
    _check_positive("full_a", full_a)
    _check_positive("rate_a_per_s", rate_a_per_s)
    return ramp_path(0.0, [full_a, -full_a, 0.0], rate_a_per_s / sample_rate_hz)


def _check_positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and value > 0):
        raise ExcitationError(f"{name} must be a positive finite number, got {value!r}")


class _SplitMix64:
    """Tiny seeded generator (same algorithm as the simulator's seed expansion): stable across numpy versions."""

    _MASK = (1 << 64) - 1

    def __init__(self, seed: int) -> None:
        self.state = int(seed) & self._MASK

    def uniform(self) -> float:
        self.state = (self.state + 0x9E3779B97F4A7C15) & self._MASK
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & self._MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & self._MASK
        z ^= z >> 31
        return (z >> 11) / float(1 << 53)


def _multipeak_vertices(seed: int, duration_s: float, lo: float, hi: float, rate_range: tuple[float, float],
                        min_swing: float) -> list[tuple[float, float]]:
    """Random alternating peaks in [lo, hi] with log-uniform rates: ``[(peak, rate), ...]`` covering the duration."""
    r_lo, r_hi = float(rate_range[0]), float(rate_range[1])
    if not (0 < r_lo <= r_hi and np.isfinite(r_hi)):
        raise ExcitationError(f"rate range must satisfy 0 < low <= high, got {rate_range!r}")
    if not (hi > lo and 0 < min_swing < (hi - lo)):
        raise ExcitationError(f"multi-peak needs lo < hi and 0 < min_swing < hi - lo (got {lo}, {hi}, {min_swing})")
    rng = _SplitMix64(seed)
    value = 0.0 if lo <= 0.0 <= hi else lo
    rising = rng.uniform() < 0.5
    t = 0.0
    out: list[tuple[float, float]] = []
    while t < duration_s:
        # The next peak lies on the far side of the current value, at least min_swing away when possible.
        if rising and hi - value < min_swing:
            rising = False
        elif not rising and value - lo < min_swing:
            rising = True
        if rising:
            peak = value + min_swing + (hi - value - min_swing) * rng.uniform()
        else:
            peak = value - min_swing - (value - lo - min_swing) * rng.uniform()
        rate = r_lo * (r_hi / r_lo) ** rng.uniform()
        out.append((peak, rate))
        t += abs(peak - value) / rate
        value = peak
        rising = not rising
    return out


def _rate_path(start: float, peaks: Sequence[tuple[float, float]], sample_rate_hz: float,
               duration_s: float) -> np.ndarray:
    parts = []
    a = start
    for peak, rate in peaks:
        parts.append(ramp_path(a, [peak], rate / sample_rate_hz))
        a = peak
    path = np.concatenate(parts) if parts else np.zeros(0)
    n = int(round(duration_s * sample_rate_hz))
    return path[:n]


def reference_triangle(*, amplitude_nmm: float = 500.0, rate_nmm_per_s: float = 50.0, duration_s: float = 200.0,
                       sample_rate_hz: float = BUNDLE_SAMPLE_RATE_HZ, offset_nmm: float = 0.0) -> np.ndarray:
    """Triangle torque reference (N·mm) for the control experiments (fig 21): from ``offset`` up to
    ``offset + amplitude``, down to ``offset − amplitude``, … at ``rate_nmm_per_s`` for ``duration_s``."""
    _check_positive("amplitude_nmm", amplitude_nmm)
    _check_positive("rate_nmm_per_s", rate_nmm_per_s)
    _check_positive("duration_s", duration_s)
    return triangle_path(amplitude_nmm, rate_nmm_per_s, duration_s, sample_rate_hz) + offset_nmm


def reference_multipeak(seed: int = 0, *, amplitude_nmm: float = 500.0, duration_s: float = 200.0,
                        sample_rate_hz: float = BUNDLE_SAMPLE_RATE_HZ,
                        rate_range_nmm_per_s: tuple[float, float] = (20.0, 400.0),
                        min_swing_nmm: float = 40.0) -> np.ndarray:
    """Random multi-peak torque reference (N·mm) for the control experiments (fig 24): alternating peaks
    uniform within ±``amplitude_nmm`` (at least ``min_swing_nmm`` apart), each approached at a log-uniform rate
    from ``rate_range_nmm_per_s``; starts at 0; ``seed`` fixes it."""
    _check_positive("amplitude_nmm", amplitude_nmm)
    _check_positive("duration_s", duration_s)
    peaks = _multipeak_vertices(seed, duration_s, -amplitude_nmm, amplitude_nmm, rate_range_nmm_per_s,
                                min_swing_nmm)
    return _rate_path(0.0, peaks, sample_rate_hz, duration_s)


def triangle_path(amplitude: float, rate_per_s: float, duration_s: float, sample_rate_hz: float) -> np.ndarray:
    """Triangle wave ``0 → +A → −A → +A …`` at ``rate_per_s``, ``duration_s`` long (samples after t = 0)."""
    n = int(round(duration_s * sample_rate_hz))
    cycles = int(np.ceil(duration_s * rate_per_s / (4.0 * amplitude))) + 1
    vertices = [amplitude, -amplitude] * (2 * cycles)
    return ramp_path(0.0, vertices, rate_per_s / sample_rate_hz)[:n]


# ---------------------------------------------------------------------------------------------------------------
# Protocols


def _record(actuator: VirtualActuator, name: str, kind: str, current_a: np.ndarray, opening_len: int,
            meta: Mapping[str, Any] | None = None, reference_nmm: np.ndarray | None = None) -> Run:
    fs = actuator.sample_rate_hz
    start_s = actuator.time_s
    out = actuator.run(np.ascontiguousarray(current_a, dtype=float))
    n = len(current_a)
    columns = {
        "t_s": np.arange(n, dtype=float) / fs,
        "current_a": out["current_a"],
        "theta_rad": out["theta_rad"],
        "torque_nmm": out["torque_nmm"],
        "coil1_a": out["coil1_a"],
        "coil2_a": out["coil2_a"],
    }
    if reference_nmm is not None:
        columns["reference_nmm"] = np.asarray(reference_nmm, dtype=float)
    run_meta = {"start_s": float(start_s), "opening_end_s": float(opening_len / fs)}
    run_meta.update(meta or {})
    return Run(name, kind, pd.DataFrame(columns), run_meta)


def _with_opening(actuator: VirtualActuator, body: np.ndarray, opening_rate_a_per_s: float,
                  full_a: float) -> tuple[np.ndarray, int]:
    opening = opening_path(actuator.sample_rate_hz, full_a=full_a, rate_a_per_s=opening_rate_a_per_s)
    return np.concatenate([opening, body]), len(opening)


def off_state(actuator: VirtualActuator, *, duration_s: float = 60.0, name: str = "off_state",
              full_a: float = FULL_CURRENT_A, opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """Zero current with the motor on for ``duration_s`` (figs 11-12): the torque is seal friction (plus the
    tiny field torque of the two coils' remanence)."""
    _check_positive("duration_s", duration_s)
    body = np.zeros(int(round(duration_s * actuator.sample_rate_hz)))
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "off_state", cur, k, {"duration_s": float(duration_s)})


def multi_step(actuator: VirtualActuator, *, levels_a: Sequence[float] | None = None, duration_s: float = 1200.0,
               name: str = "multi_step", full_a: float = FULL_CURRENT_A,
               opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """Multi-step nominal current (fig 13): each level held for ``duration_s / len(levels_a)``. Default levels:
    0 up to +full, down to −full and back to 0 in steps of full/5."""
    if levels_a is None:
        step = full_a / 5.0
        up = [step * k for k in range(0, 6)]
        down = [full_a - step * k for k in range(1, 11)]
        back = [-full_a + step * k for k in range(1, 6)]
        levels_a = up + down + back
    levels = np.asarray(levels_a, dtype=float)
    if levels.ndim != 1 or levels.size == 0 or not np.all(np.isfinite(levels)):
        raise ExcitationError("levels_a must be a non-empty sequence of finite currents (A)")
    _check_positive("duration_s", duration_s)
    fs = actuator.sample_rate_hz
    hold = max(1, int(round(duration_s * fs / levels.size)))
    body = np.repeat(levels, hold)
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "multi_step", cur, k,
                   {"levels_a": levels.tolist(), "hold_s": hold / fs})


def _reversal_grid(reversals: int, full_a: float) -> np.ndarray:
    if not (isinstance(reversals, (int, np.integer)) and 2 <= reversals <= 1001):
        raise ExcitationError(f"reversals must be an integer in [2, 1001], got {reversals!r}")
    return np.linspace(-full_a, full_a, int(reversals))


def _forc_step(reversals: int, full_a: float, rate_a_per_s: float, fs: float) -> float:
    # Grid-aligned step: a whole number of steps between adjacent reversals, so every sample of every curve lies
    # on one common current grid.
    spacing = 2.0 * full_a / (reversals - 1)
    per_cell = max(1, int(np.ceil(spacing / (rate_a_per_s / fs))))
    return spacing / per_cell


def first_order_ascending(actuator: VirtualActuator, *, reversals: int = 21, full_a: float = FULL_CURRENT_A,
                          rate_a_per_s: float = 0.25, name: str = "first_order_ascending",
                          opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """First-order ascending curves (fig 14): from +full down to each reversal minimum of an even grid of
    ``reversals`` points in [−full, +full], then up to +full, at ``rate_a_per_s``. Samples lie on a common
    current grid (a whole number of steps between reversals)."""
    _check_positive("rate_a_per_s", rate_a_per_s)
    _check_positive("full_a", full_a)
    grid = _reversal_grid(reversals, full_a)
    step = _forc_step(reversals, full_a, rate_a_per_s, actuator.sample_rate_hz)
    vertices = [full_a]
    for m in grid[:-1]:
        vertices += [m, full_a]
    body = ramp_path(0.0, vertices, step)
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "first_order_ascending", cur, k,
                   {"reversals_a": grid.tolist(), "rate_a_per_s": float(rate_a_per_s)})


def first_order_descending(actuator: VirtualActuator, *, reversals: int = 21, full_a: float = FULL_CURRENT_A,
                           rate_a_per_s: float = 0.25, name: str = "first_order_descending",
                           opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """First-order descending curves (fig 15): from −full up to each reversal maximum of an even grid of
    ``reversals`` points, then down to −full, at ``rate_a_per_s`` (samples on a common current grid)."""
    _check_positive("rate_a_per_s", rate_a_per_s)
    _check_positive("full_a", full_a)
    grid = _reversal_grid(reversals, full_a)
    step = _forc_step(reversals, full_a, rate_a_per_s, actuator.sample_rate_hz)
    vertices = [-full_a]
    for m in grid[::-1][:-1]:
        vertices += [m, -full_a]
    body = ramp_path(0.0, vertices, step)
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "first_order_descending", cur, k,
                   {"reversals_a": grid[::-1].tolist(), "rate_a_per_s": float(rate_a_per_s)})


def triangle(actuator: VirtualActuator, *, amplitude_a: float = FULL_CURRENT_A, rate_a_per_s: float = 0.125,
             duration_s: float = 200.0, name: str = "triangle", full_a: float = FULL_CURRENT_A,
             opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """Triangle nominal current (figs 18-19): ``0 → +amplitude → −amplitude …`` at ``rate_a_per_s``."""
    _check_positive("amplitude_a", amplitude_a)
    _check_positive("rate_a_per_s", rate_a_per_s)
    _check_positive("duration_s", duration_s)
    body = triangle_path(amplitude_a, rate_a_per_s, duration_s, actuator.sample_rate_hz)
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "triangle", cur, k,
                   {"amplitude_a": float(amplitude_a), "rate_a_per_s": float(rate_a_per_s)})


def multipeak(actuator: VirtualActuator, *, seed: int = MULTIPEAK_SEED, duration_s: float = 200.0,
              full_a: float = FULL_CURRENT_A, rate_range_a_per_s: tuple[float, float] = (0.05, 2.5),
              min_swing_a: float = 0.1, name: str = "multipeak",
              opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """Random multi-peak nominal current: alternating peaks within ±full (at least ``min_swing_a`` apart), each
    approached at a log-uniform rate from ``rate_range_a_per_s`` — higher-order reversals at many rates.
    ``seed`` fixes the excitation (not the noise, which the actuator's seed fixes)."""
    _check_positive("duration_s", duration_s)
    peaks = _multipeak_vertices(seed, duration_s, -full_a, full_a, rate_range_a_per_s, min_swing_a)
    body = _rate_path(0.0, peaks, actuator.sample_rate_hz, duration_s)
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "multipeak", cur, k,
                   {"excitation_seed": int(seed), "rate_range_a_per_s": [float(r) for r in rate_range_a_per_s]})


def custom(actuator: VirtualActuator, current_a: Sequence[float] | np.ndarray, *, name: str = "custom",
           full_a: float = FULL_CURRENT_A, opening_rate_a_per_s: float = OPENING_RATE_A_PER_S) -> Run:
    """Any excitation (kind ``custom``): the opening excursion, then ``current_a`` (A) sample by sample."""
    body = np.asarray(current_a, dtype=float)
    if body.ndim != 1 or body.size == 0:
        raise ExcitationError("current_a must be a non-empty 1-D array of currents (A)")
    bad = np.flatnonzero(~np.isfinite(body))
    if bad.size:
        raise ExcitationError(f"current_a[{int(bad[0])}] = {body[bad[0]]!r} is not finite")
    cur, k = _with_opening(actuator, body, opening_rate_a_per_s, full_a)
    return _record(actuator, name, "custom", cur, k)


def tracking(actuator: VirtualActuator, compensator: Any, reference_nmm: np.ndarray, *, name: str = "tracking",
             opening_reference_nmm: float | None = None, opening_duration_s: float = 10.0) -> Run:
    """Open-loop torque tracking (figs 21-25): ``reference_nmm`` (N·mm, one value per sample) is driven through
    ``compensator`` in the loop and the commanded current goes to the actuator.

    ``compensator.run(torque_ref_nmm, theta_rad)`` must return a dict with ``"current_a"``; it is given the
    encoder angles of the very samples it commands (the rotor angle does not depend on the current). The run
    opens with a torque reference excursion to ``±opening_reference_nmm`` (default ``max(1000, 2.5 ×
    max|reference|)``) and back to the first reference value — beyond reach, so the compensator saturates the
    current both ways and starts, like the plant, from a known state. ``reference_nmm`` is logged for every
    sample, opening included.
    """
    ref = np.asarray(reference_nmm, dtype=float)
    if ref.ndim != 1 or ref.size < 2:
        raise ExcitationError("reference_nmm must be a 1-D array of at least 2 torques (N·mm)")
    bad = np.flatnonzero(~np.isfinite(ref))
    if bad.size:
        raise ExcitationError(f"reference_nmm[{int(bad[0])}] = {ref[bad[0]]!r} is not finite")
    _check_positive("opening_duration_s", opening_duration_s)
    fs = actuator.sample_rate_hz
    reach = max(1000.0, 2.5 * float(np.max(np.abs(ref)))) if opening_reference_nmm is None else opening_reference_nmm
    _check_positive("opening_reference_nmm", reach)
    rate = 4.0 * reach / opening_duration_s
    opening = ramp_path(0.0, [reach, -reach, ref[0]], rate / fs)
    full_ref = np.concatenate([opening, ref])
    theta = actuator.theta_ahead(full_ref.size)
    out = compensator.run(full_ref, theta)
    try:
        current = np.asarray(out["current_a"], dtype=float)
    except (KeyError, TypeError, IndexError):
        raise BmrError("compensator.run(torque_ref_nmm, theta_rad) must return a dict with 'current_a'") from None
    if current.shape != full_ref.shape:
        raise BmrError(f"compensator returned {current.size} currents for {full_ref.size} reference samples")
    bad = np.flatnonzero(~np.isfinite(current))
    if bad.size:
        raise BmrError(f"compensator returned a non-finite current at sample {int(bad[0])}")
    return _record(actuator, name, "tracking", current, opening.size,
                   {"compensator": type(compensator).__name__}, reference_nmm=full_ref)


# ---------------------------------------------------------------------------------------------------------------
# The experiment set


def _plan(quick: bool, compensator: Any, fs: float, reversals: int | None = None
          ) -> list[tuple[str, Callable[[VirtualActuator], Run]]]:
    if quick:
        nr = 11 if reversals is None else int(reversals)
        o = {"opening_rate_a_per_s": 2.5}
        plan: list[tuple[str, Callable[[VirtualActuator], Run]]] = [
            ("off_state", lambda a: off_state(a, duration_s=8.0, **o)),
            ("multi_step", lambda a: multi_step(a, duration_s=42.0, **o)),
            ("first_order_ascending", lambda a: first_order_ascending(a, reversals=nr, rate_a_per_s=1.0, **o)),
            ("first_order_descending", lambda a: first_order_descending(a, reversals=nr, rate_a_per_s=1.0, **o)),
            ("triangle", lambda a: triangle(a, rate_a_per_s=0.5, duration_s=20.0, **o)),
            ("multipeak", lambda a: multipeak(a, duration_s=20.0, **o)),
        ]
        track = [("tracking_triangle", dict(rate_nmm_per_s=200.0, duration_s=10.0)),
                 ("tracking_multipeak", dict(duration_s=10.0))]
        opening_s = 2.0
    else:
        nf = 21 if reversals is None else int(reversals)
        plan = [
            ("off_state", lambda a: off_state(a)),
            ("multi_step", lambda a: multi_step(a)),
            ("first_order_ascending", lambda a: first_order_ascending(a, reversals=nf)),
            ("first_order_descending", lambda a: first_order_descending(a, reversals=nf)),
            ("triangle", lambda a: triangle(a)),
            ("multipeak", lambda a: multipeak(a)),
        ]
        track = [("tracking_triangle", dict(duration_s=200.0)), ("tracking_multipeak", dict(duration_s=200.0))]
        opening_s = 10.0
    if compensator is not None:
        tri_kw, mp_kw = track[0][1], track[1][1]
        tri = reference_triangle(sample_rate_hz=fs, **tri_kw)
        mp = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, **mp_kw)
        plan.append(("tracking_triangle", lambda a: tracking(a, compensator, tri, name="tracking_triangle",
                                                            opening_duration_s=opening_s)))
        plan.append(("tracking_multipeak", lambda a: tracking(a, compensator, mp, name="tracking_multipeak",
                                                             opening_duration_s=opening_s)))
    return plan


def experiment_count(quick: bool) -> int:
    """The number of runs of the experiment set without a compensator (``quick``: the short set)."""
    return len(_plan(quick, None, BUNDLE_SAMPLE_RATE_HZ))


def simulate_bundle(preset: str = "bmr2013", *, effects: Mapping[str, Any] | Sequence[str] | None = None,
                    seed: int = 0, quick: bool = False, compensator: Any = None,
                    sample_rate_hz: float = BUNDLE_SAMPLE_RATE_HZ,
                    on_run: Callable[[Run], Any] | None = None,
                    overrides: Mapping[str, float] | None = None,
                    extra_runs: Sequence[Callable[[VirtualActuator], Run]] = (),
                    rest_s: float | None = None, forc_reversals: int | None = None) -> Bundle:
    """The paper's experiment set on a fresh virtual actuator, as a :class:`bmr.Bundle`.

    Runs, in order, on one actuator (its thermal state and sensor drift carry over; each run's opening
    excursion resets the steel state): ``off_state``, ``multi_step`` (1 200 s), ``first_order_ascending`` and
    ``first_order_descending`` (21 reversals, 0.25 A/s), ``triangle`` (±1.25 A at 0.125 A/s, 200 s),
    ``multipeak`` (200 s) and — only when a ``compensator`` is given — ``tracking_triangle`` and
    ``tracking_multipeak`` (200 s each). ``quick=True`` gives the same set, shorter (about a second).
    ``seed`` fixes the sensor noise only: every excitation is the same for every seed. The manifest records the
    simulator's preset, seed and active effects under ``"simulator"`` (ground truth for calibration studies).
    ``on_run(run)`` is called after each run (progress reporting). Logged at ``sample_rate_hz`` (500 Hz).
    ``overrides`` changes physical parameters by dotted name (``bmr.ACTUATOR_PARAMETERS``), e.g. the noise level.
    ``extra_runs``: further protocols (callables taking the actuator, returning a run) appended after the set.
    ``rest_s``: the rig rests that long at zero current before each run after the first (the coils cool, creep
    settles; ``VirtualActuator.start_run``); None: back to back. Each run is a new recording either way (per-run
    calibration and the leakage integral start anew). ``forc_reversals``: reversals per first-order family
    (default 21, quick 11).
    """
    actuator = VirtualActuator(preset, seed=seed, sample_rate_hz=sample_rate_hz, effects=effects,
                               overrides=dict(overrides) if overrides else None)
    plan = [fn for _name, fn in _plan(bool(quick), compensator, actuator.sample_rate_hz, forc_reversals)]
    plan += list(extra_runs)
    runs: list[Run] = []
    for i, fn in enumerate(plan):
        if i > 0:
            actuator.start_run(float(rest_s or 0.0))
        calibration = actuator.run_calibration
        runs.append(fn(actuator))
        if "run_gain_offset" in actuator.effects:
            # The recording's hidden calibration (ground truth for calibration studies).
            runs[-1].meta["calibration"] = {"gain": calibration[0], "offset_nmm": calibration[1]}
        if on_run is not None:
            on_run(runs[-1])
    meta = {"simulator": {"preset": preset, "seed": int(seed), "quick": bool(quick),
                          "effects": {k: dict(v) for k, v in actuator.effects.items()},
                          "noise_nmm": actuator.noise_nmm, "rest_s": rest_s,
                          "overrides": {k: float(v) for k, v in (overrides or {}).items()}}}
    # Every run was recorded on this one actuator after the previous: one measurement history.
    return Bundle(actuator=actuator.name, sample_rate_hz=actuator.sample_rate_hz, runs=runs, meta=meta,
                  histories=[[r.name for r in runs]] if len(runs) > 1 else [])
