"""Excitations that show what the paper's protocol runs hide, and ``bmr simulate``.

Nested minor loops (higher-order reversals) at many levels of the current range: congruency violations
(``non_congruent``) only show after such reversals, so a bundle meant for diagnosis gains from one ``custom`` run of
them. The runs that separate two effects one bundle's excitation cannot tell apart (:data:`SEPARATING_RUNS`: a
dwell after reversals, a second drive speed, a repeat of a run, ...): the diagnosis names the one it needs
(``bmr.Diagnosis.alternatives``) and ``bmr simulate --separate KIND`` appends it to the virtual actuator's bundle.

Units: current A, rate A/s, time s.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from bmr._core import BmrError, ExcitationError, VirtualActuator
from bmr.data.bundle import Bundle, Run, write_bundle
from bmr.data.files import check_output_folder
from bmr.simulation.experiments import (FULL_CURRENT_A, OPENING_RATE_A_PER_S, custom, experiment_count, multipeak,
                                        ramp_path, simulate_bundle, triangle)

__all__ = ["minor_loop_vertices", "minor_loops", "repeated_loop_vertices", "repeated_loops", "diagnosis_bundle",
           "FAST_LOOP_RATE_A_PER_S", "MEDIUM_EFFECTS", "SEPARATING_RUNS", "separating_run", "run_cli"]

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


# ---------------------------------------------------------------------------------------------------------------
# Runs that separate effects


def _held_run(actuator: VirtualActuator, name: str, levels: Sequence[float], hold_s: float, opening: float) -> Run:
    """A ``custom`` run stepping through ``levels`` (A), each held for ``hold_s``."""
    if not (np.isfinite(hold_s) and hold_s > 0):
        raise ExcitationError(f"hold time must be positive, got {hold_s!r}")
    body = np.repeat(np.asarray(levels, dtype=float), max(2, int(round(hold_s * actuator.sample_rate_hz))))
    run = custom(actuator, body, name=name, opening_rate_a_per_s=opening)
    run.meta.update({"levels_a": list(levels), "hold_s": hold_s})
    return run


def _dwell(actuator: VirtualActuator, quick: bool, opening: float) -> Run:
    # Steps after reversals at both signs and at zero, each held: creep relaxes logarithmically in the time since
    # the reversal, a coil lag relaxes over its time constant, a delay only shifts the step, a leakage keeps moving
    # at a nonzero input, a sensor's zero moves from one zero hold to the next.
    levels = [f * FULL_CURRENT_A for f in (1.0, 0.4, 0.8, 0.0, -0.2, -1.0, -0.4, -0.8, 0.0, 0.2, 0.0)]
    return _held_run(actuator, "separate_dwell", levels, 2.0 if quick else 10.0, opening)


def _heat_rest(actuator: VirtualActuator, quick: bool, opening: float) -> Run:
    # Near-full input held, then zero for as long: the coils heat (the gain falls) and cool (it recovers).
    return _held_run(actuator, "separate_heat_rest", [0.9 * FULL_CURRENT_A, 0.0], 20.0 if quick else 120.0, opening)


def _constant_currents(actuator: VirtualActuator, quick: bool, opening: float) -> Run:
    # The rotor turns through several revolutions at each of several constant currents: the seal friction's
    # growth with the current, its harmonics and the torque ripple each show as lines in the angle.
    levels = [f * FULL_CURRENT_A for f in (0.0, 0.3, 0.6, 0.9, -0.3, -0.6, -0.9, 0.0)]
    return _held_run(actuator, "separate_constant_currents", levels, 3.0 if quick else 8.0, opening)


def _minor_loops(actuator: VirtualActuator, quick: bool, opening: float) -> Run:
    # Minor loops between the same extremes, first approached from positive saturation, then from negative, each
    # cycled three times: a non-congruent loop changes its size with the history, accommodation drifts it.
    a, b = -0.2 * FULL_CURRENT_A, 0.4 * FULL_CURRENT_A
    vertices = [FULL_CURRENT_A] + [a, b] * 3 + [-FULL_CURRENT_A] + [b, a] * 3 + [0.0]
    rate = 1.0 if quick else 0.25
    body = ramp_path(0.0, vertices, rate / actuator.sample_rate_hz)
    run = custom(actuator, body, name="separate_minor_loops", opening_rate_a_per_s=opening)
    run.meta.update({"vertices_a": vertices, "rate_a_per_s": rate})
    return run


def _second_speed(actuator: VirtualActuator, quick: bool, opening: float) -> Run:
    # The set's triangle at eight times its speed: a dynamic field widens the loop where the branch is steep, a
    # loss everywhere and leaves the tips in place, a time shift moves the tips.
    rate, duration = (4.0, 20.0) if quick else (1.0, 200.0)
    return triangle(actuator, rate_a_per_s=rate, duration_s=duration, name="separate_second_speed",
                    opening_rate_a_per_s=opening)


def _repeat(actuator: VirtualActuator, quick: bool, opening: float) -> Run:
    # The set's multi-peak run recorded again: the same input history, so what differs is the recording's.
    return multipeak(actuator, duration_s=20.0 if quick else 200.0, name="separate_repeat",
                     opening_rate_a_per_s=opening)


# Kind → (what the run is, its protocol ``(actuator, quick, opening rate) → Run``).
SEPARATING_RUNS: dict[str, tuple[str, Callable[[VirtualActuator, bool, float], Run]]] = {
    "dwell": ("input steps after reversals, each held (at both signs and at zero)", _dwell),
    "second_speed": ("the triangle at eight times its speed", _second_speed),
    "repeat": ("the multi-peak run recorded again", _repeat),
    "minor_loops": ("minor loops between the same extremes approached from both saturations, each cycled three "
                    "times", _minor_loops),
    "heat_rest": ("near-full input held, then a rest at zero as long", _heat_rest),
    "constant_currents": ("several revolutions at each of several constant currents", _constant_currents),
}


def separating_run(kind: str, *, quick: bool = False) -> Callable[[VirtualActuator], Run]:
    """The protocol of the separating run ``kind`` (a key of :data:`SEPARATING_RUNS`) for
    ``simulate_bundle(extra_runs=...)``; ``quick`` as the bundle's."""
    if kind not in SEPARATING_RUNS:
        raise BmrError(f"unknown separating run {kind!r}; use one of {', '.join(SEPARATING_RUNS)}")
    make = SEPARATING_RUNS[kind][1]
    opening = 2.5 if quick else OPENING_RATE_A_PER_S
    return lambda actuator: make(actuator, quick, opening)


def _parse_overrides(items: Sequence[str]) -> dict[str, float]:
    """``["sensor.noise_n=0", ...]`` → ``{"sensor.noise_n": 0.0}``, with a clear error for malformed items."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep or not name.strip():
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise BmrError(f"--override {item!r}: expected GROUP.PARAM=NUMBER, e.g. sensor.noise_n=0") from None
    return out


def run_cli(args: Any) -> int:
    """``bmr simulate``: write the experiment set, then the separating runs asked for (``--separate``), as a
    bundle, with a progress bar on stderr (simulation and writing of each run)."""
    from tqdm import tqdm

    t0 = time.perf_counter()
    effects = list(args.effect or [])
    overrides = _parse_overrides(getattr(args, "override", None) or [])
    separate = list(dict.fromkeys(getattr(args, "separate", None) or []))
    reversals = getattr(args, "forc_reversals", None)
    # Everything that can be wrong is found before the progress bar starts: the output folder, the effects, the
    # parameters (an actuator built once with them) and the runs asked for.
    check_output_folder(args.out, "bundle folder")
    VirtualActuator(args.preset, effects=effects or None, overrides=overrides or None)
    extra = [separating_run(kind, quick=bool(args.quick)) for kind in separate]
    if reversals is not None and not 2 <= int(reversals) <= 201:
        raise BmrError(f"--forc-reversals {reversals}: expected 2 to 201 reversals per first-order family")
    n_runs = experiment_count(bool(args.quick)) + len(extra)
    with tqdm(total=2 * n_runs, file=sys.stderr, unit="step", desc="bmr simulate") as bar:
        bundle = simulate_bundle(args.preset, effects=effects, seed=args.seed, quick=args.quick,
                                 overrides=overrides or None, extra_runs=extra, forc_reversals=reversals,
                                 on_run=lambda run: (bar.set_postfix_str(f"simulated {run.name}"), bar.update(1)))
        out = write_bundle(bundle, Path(args.out), fmt=args.format,
                           on_run_written=lambda run: (bar.set_postfix_str(f"wrote {run.name}"), bar.update(1)))
    rows = sum(len(r.data) for r in bundle.runs)
    print(f"bmr simulate: wrote {len(bundle.runs)} runs, {rows} samples at {bundle.sample_rate_hz:g} Hz to {out} "
          f"in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0
