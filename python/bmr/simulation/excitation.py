"""An excitation that shows what the paper's protocol runs hide: nested minor loops (higher-order reversals) at
many levels of the current range. Congruency violations (``non_congruent``) only show after such reversals, so
a bundle meant for diagnosis gains from one ``custom`` run of them.

Units: current A, rate A/s.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from bmr._core import ExcitationError
from bmr.data.bundle import Bundle, Run
from bmr.simulation.experiments import FULL_CURRENT_A, OPENING_RATE_A_PER_S, custom, ramp_path, simulate_bundle

__all__ = ["minor_loop_vertices", "minor_loops", "repeated_loop_vertices", "repeated_loops", "diagnosis_bundle",
           "FAST_LOOP_RATE_A_PER_S", "MEDIUM_EFFECTS"]

# A medium size of every physical effect of the vocabulary on the ``rig_preisach`` actuator: large enough for a
# quick diagnosis bundle to show it, small enough to be realistic. What the calibration and the closed-loop checks
# hide in a bundle (sizes are multiples of these).
MEDIUM_EFFECTS: dict[str, dict[str, float]] = {
    "coil_lag": {"tau_s": 0.02},
    "thermal_drift": {"gain_loss": 0.1, "tau_s": 60.0},
    "friction_current": {"gain_per_a": 0.6},
    "friction_harmonics": {"order": 7.0, "amplitude_nmm": 5.0, "phase_rad": 0.5},
    "torque_ripple": {"eps": 0.05, "phase_rad": 1.0},
    "sensor_drift": {"rate_nmm_per_s": 0.06},
    "time_delay": {"delay_s": 0.02},
    "non_congruent": {"curvature": 2.0},
    "creep": {"fraction": 0.02, "tau_min_s": 0.1, "tau_max_s": 100.0},
    "rate_dependence": {"tau_s": 0.01},
    "run_gain_offset": {"gain_sd": 0.03, "offset_sd": 4.0},
    "leakage": {"rate_per_s": 0.5},
    "accommodation": {"kappa": 0.08, "cycles": 3.0},
    "viscous": {"c": 4.0},
}


def minor_loop_vertices(full_a: float = FULL_CURRENT_A, *, centres: int = 7, depth: int = 3,
                        swing_a: float | None = None) -> list[float]:
    """Reversal currents: for each of ``centres`` levels across ±0.75·full, a nest of ``depth`` shrinking minor
    loops (swing ``swing_a``, default full/4), approached from alternating saturations."""
    if not (isinstance(centres, int) and centres >= 1 and isinstance(depth, int) and depth >= 1):
        raise ExcitationError(f"centres and depth must be positive integers, got {centres!r}, {depth!r}")
    swing = full_a / 4.0 if swing_a is None else float(swing_a)
    if not (0 < swing < full_a):
        raise ExcitationError(f"swing_a must lie in (0, full_a), got {swing_a!r}")
    out: list[float] = []
    for i, c in enumerate(np.linspace(-0.75 * full_a, 0.75 * full_a, centres)):
        out.append(full_a if i % 2 == 0 else -full_a)
        for k in range(depth):
            s = swing * (1.0 - k / (depth + 1.0))
            if i % 2 == 0:
                out += [float(c - s), float(c + s)]
            else:
                out += [float(c + s), float(c - s)]
    out.append(0.0)
    return out


def minor_loops(actuator: Any, *, rate_a_per_s: float = 1.0, name: str = "minor_loops",
                full_a: float = FULL_CURRENT_A, opening_rate_a_per_s: float = OPENING_RATE_A_PER_S,
                **kwargs: Any) -> Run:
    """A ``custom`` run of nested minor loops (:func:`minor_loop_vertices`) at ``rate_a_per_s`` on ``actuator``
    (a ``bmr.VirtualActuator``), opening with the usual excursion to both saturations."""
    if not (np.isfinite(rate_a_per_s) and rate_a_per_s > 0):
        raise ExcitationError(f"rate_a_per_s must be positive, got {rate_a_per_s!r}")
    vertices = minor_loop_vertices(full_a, **kwargs)
    body = ramp_path(0.0, vertices, rate_a_per_s / actuator.sample_rate_hz)
    run = custom(actuator, body, name=name, full_a=full_a, opening_rate_a_per_s=opening_rate_a_per_s)
    run.meta.update({"vertices_a": vertices, "rate_a_per_s": float(rate_a_per_s)})
    return run


def repeated_loop_vertices(full_a: float = FULL_CURRENT_A, *, centres: Sequence[float] = (-0.4, 0.4),
                           swing_a: float | None = None, cycles: int = 6) -> list[float]:
    """Reversal currents of minor loops cycled ``cycles`` times between the same extremes (swing ``swing_a``,
    default full/5) around each of ``centres`` (fractions of full), each approached from the opposite
    saturation: the excitation that shows accommodation (loops drifting from cycle to cycle)."""
    if not (isinstance(cycles, int) and cycles >= 2):
        raise ExcitationError(f"cycles must be an integer >= 2, got {cycles!r}")
    w = full_a / 5.0 if swing_a is None else float(swing_a)
    if not (0 < w < full_a):
        raise ExcitationError(f"swing_a must lie in (0, full_a), got {swing_a!r}")
    out: list[float] = []
    for c in centres:
        c = float(c) * full_a
        from_top = c < 0
        out.append(full_a if from_top else -full_a)
        for _ in range(cycles):
            out += [c - w, c + w] if from_top else [c + w, c - w]
    out.append(0.0)
    return out


def repeated_loops(actuator: Any, *, rate_a_per_s: float = 1.0, name: str = "repeated_loops",
                   full_a: float = FULL_CURRENT_A, opening_rate_a_per_s: float = OPENING_RATE_A_PER_S,
                   **kwargs: Any) -> Run:
    """A ``custom`` run of repeated minor loops (:func:`repeated_loop_vertices`) at ``rate_a_per_s``."""
    if not (np.isfinite(rate_a_per_s) and rate_a_per_s > 0):
        raise ExcitationError(f"rate_a_per_s must be positive, got {rate_a_per_s!r}")
    vertices = repeated_loop_vertices(full_a, **kwargs)
    body = ramp_path(0.0, vertices, rate_a_per_s / actuator.sample_rate_hz)
    run = custom(actuator, body, name=name, full_a=full_a, opening_rate_a_per_s=opening_rate_a_per_s)
    run.meta.update({"vertices_a": vertices, "rate_a_per_s": float(rate_a_per_s)})
    return run


# Drive speed of the second repeated-loop run of the diagnosis bundle (A/s): four times the rate of the
# first-order curves the tables come from, so that a loss in proportion to the rate (``viscous``) shows as loops
# wider than the tables' rather than as a wider table.
FAST_LOOP_RATE_A_PER_S = 4.0


def diagnosis_bundle(preset: str = "rig_preisach", *, effects: Any = None, seed: int = 0, quick: bool = True,
                     sample_rate_hz: float = 500.0, rest_s: float | None = None, overrides: Any = None,
                     forc_reversals: int | None = None) -> Bundle:
    """The paper's experiment set (:func:`bmr.simulation.experiments.simulate_bundle`) plus one
    :func:`minor_loops` run and two :func:`repeated_loops` runs, the second (``repeated_loops_fast``) the same
    loops at :data:`FAST_LOOP_RATE_A_PER_S` (a second drive speed), all on one virtual actuator (``preset`` with
    ``effects``, ``seed``, ``overrides``): the bundle the diagnosis is calibrated on. ``rest_s``: rest between
    runs, ``forc_reversals``: reversals per first-order family (see ``simulate_bundle``)."""
    opening = 2.5 if quick else OPENING_RATE_A_PER_S
    return simulate_bundle(preset, effects=effects, seed=seed, quick=quick, sample_rate_hz=sample_rate_hz,
                           rest_s=rest_s, overrides=overrides, forc_reversals=forc_reversals,
                           extra_runs=[lambda a: minor_loops(a, opening_rate_a_per_s=opening),
                                       lambda a: repeated_loops(a, opening_rate_a_per_s=opening),
                                       lambda a: repeated_loops(a, rate_a_per_s=FAST_LOOP_RATE_A_PER_S,
                                                                name="repeated_loops_fast",
                                                                opening_rate_a_per_s=opening)])
