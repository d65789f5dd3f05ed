"""Bundles from the virtual hysteretic device (``bmr.VirtualDevice``: a piezo stack, a ferroelectric capacitor —
one input, one output, no angle): the second plant structure the diagnosis is calibrated on.

Every run opens with an excursion to both saturations (centre → +end → −end → centre), so the core's state is
known from its first saturation on. The set (:func:`device_bundle`):

* identification: ``first_order_ascending`` and ``first_order_descending`` (``reversals`` curves each, at
  ``forc_rate``, a fraction of the span per second);
* evaluation: ``steps`` (levels held for ``dwell_s``: creep shows after every step), ``sweep`` (triangles at three
  rates: rate dependence shows as loops that widen with rate), ``repeated_loops`` (minor loops cycled between the
  same extremes: accommodation) and ``random`` (random reversals at random rates).

Runs are recorded one after the other on one device; ``rest_s`` (None: back to back) lets the device rest
between them (creep settles, self-heating cools) and starts each as a new recording (the leakage integral
restarts, the per-run calibration of ``run_gain_offset`` is drawn anew). Units: the device's (e.g. V → µm).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from bmr._core import BmrError, VirtualDevice
from bmr.data.bundle import Bundle, Run
from bmr.data.quantities import Quantities, Quantity
from bmr.simulation.experiments import _SplitMix64, ramp_path

__all__ = ["device_bundle", "device_quantities", "DEVICE_SAMPLE_RATE_HZ"]

DEVICE_SAMPLE_RATE_HZ = 2000.0
"""Sample rate of simulated device bundles."""


def device_quantities(device: Any) -> Quantities:
    """The bundle quantities of a ``bmr.VirtualDevice`` (input and output named and in its units)."""
    (iname, iunit), (oname, ounit) = device.quantities
    return Quantities(Quantity.declare(iunit, iname), Quantity.declare(ounit, oname))


def _record(device: Any, q: Quantities, name: str, kind: str, role: str, u: np.ndarray, opening: int,
            meta: Mapping[str, Any] | None = None) -> Run:
    start_s = device.time_s
    out = device.run(np.ascontiguousarray(u, dtype=float))
    fs = device.sample_rate_hz
    data = pd.DataFrame({"t_s": np.arange(u.size, dtype=float) / fs, q.input.column: out["input"],
                         q.output.column: out["output"]})
    run_meta = {"start_s": float(start_s), "opening_end_s": float(opening / fs)}
    run_meta.update(meta or {})
    return Run(name, kind, data, run_meta, q, role)


def _opening(lo: float, hi: float, step: float) -> np.ndarray:
    c = 0.5 * (lo + hi)
    return ramp_path(c, [hi, lo, c], step)


def device_bundle(preset: str = "piezo", *, effects: Mapping[str, Any] | Sequence[str] | None = None,
                  seed: int = 0, sample_rate_hz: float = DEVICE_SAMPLE_RATE_HZ, reversals: int = 11,
                  forc_rate: float = 0.5, sweep_rates: Sequence[float] = (0.5, 2.0, 8.0), dwell_s: float = 4.0,
                  rest_s: float | None = None, overrides: Mapping[str, float] | None = None,
                  random_seed: int = 2013, imported: bool = False) -> Bundle:
    """The device's experiment set (module doc) as a ``bmr-bundle/2`` :class:`bmr.Bundle`. Rates are in spans per
    second (a span: from one saturation end to the other). ``seed`` fixes the noise and the per-run
    calibration; the excitations are the same for every seed (``random_seed`` fixes the random run).
    ``imported``: as an import of the recordings makes them (:meth:`bmr.Bundle.as_imported`)."""
    dev = VirtualDevice(preset, seed=seed, sample_rate_hz=sample_rate_hz, effects=effects,
                        overrides=dict(overrides) if overrides else None)
    q = device_quantities(dev)
    lo, hi = dev.input_range
    span = hi - lo
    fs = dev.sample_rate_hz
    if not (isinstance(reversals, int) and 3 <= reversals <= 201):
        raise BmrError(f"reversals must be an integer in [3, 201], got {reversals!r}")
    for name, rate in [("forc_rate", forc_rate), *[("sweep_rates", r) for r in sweep_rates]]:
        if not (np.isfinite(rate) and rate > 0):
            raise BmrError(f"{name} must be positive spans per second, got {rate!r}")
    open_step = 2.0 * span / fs
    step = forc_rate * span / fs
    grid = np.linspace(lo, hi, reversals)
    plans: list[tuple[str, str, str, np.ndarray, dict[str, Any]]] = []
    asc = [hi]
    for m in grid[:-1]:
        asc += [float(m), hi]
    desc = [lo]
    for m in grid[::-1][:-1]:
        desc += [float(m), lo]
    plans.append(("first_order_ascending", "first_order_ascending", "identification",
                  ramp_path(hi, asc, step), {"reversals": reversals}))
    plans.append(("first_order_descending", "first_order_descending", "identification",
                  ramp_path(lo, desc, step), {"reversals": reversals}))
    levels = [lo + span * f for f in (0.5, 0.7, 0.9, 0.6, 0.3, 0.1, 0.4, 0.55)]
    hold = max(2, int(round(dwell_s * fs)))
    steps = np.concatenate([np.full(hold, v) for v in levels])
    plans.append(("steps", "multi_step", "evaluation", steps, {"levels": levels, "hold_s": hold / fs}))
    sweep = []
    for rate in sweep_rates:
        sweep.append(ramp_path(0.5 * (lo + hi), [hi, lo, hi, lo, 0.5 * (lo + hi)], rate * span / fs))
    plans.append(("sweep", "triangle", "evaluation", np.concatenate(sweep),
                  {"rates_spans_per_s": [float(r) for r in sweep_rates]}))
    loops: list[float] = []
    for centre, from_top in ((0.3, True), (0.65, False)):
        c = lo + centre * span
        w = 0.12 * span
        loops.append(hi if from_top else lo)
        for _ in range(6):
            loops += [c - w, c + w] if from_top else [c + w, c - w]
    plans.append(("repeated_loops", "custom", "evaluation", ramp_path(0.5 * (lo + hi), loops, step),
                  {"vertices": loops}))
    rng = _SplitMix64(random_seed)
    verts, value = [], 0.5 * (lo + hi)
    path = []
    for _ in range(24):
        target = lo + span * rng.uniform()
        if abs(target - value) < 0.05 * span:
            continue
        rate = forc_rate * (0.5 + 4.0 * rng.uniform())
        path.append(ramp_path(value, [target], rate * span / fs))
        verts.append(target)
        value = target
    plans.append(("random", "custom", "evaluation", np.concatenate(path), {"vertices": verts}))

    runs = []
    for i, (name, kind, role, body, meta) in enumerate(plans):
        if i > 0 or rest_s:
            dev.start_run(float(rest_s or 0.0))
        opening = _opening(lo, hi, open_step)
        meta = dict(meta)
        if "run_gain_offset" in dev.effects:
            gain, offset = dev.run_calibration
            meta["calibration"] = {"gain": gain, "offset": offset}
        runs.append(_record(dev, q, name, kind, role, np.concatenate([opening, body]), opening.size, meta))
    sim = {"device": preset, "seed": int(seed), "effects": {k: dict(v) for k, v in dev.effects.items()},
           "noise": dev.noise, "rest_s": rest_s, "overrides": {k: float(v) for k, v in (overrides or {}).items()}}
    # Every run was recorded on this one device after the previous: one measurement history.
    bundle = Bundle(dev.name, fs, runs, {"simulator": sim}, q, [[r.name for r in runs]] if len(runs) > 1 else [])
    return bundle.as_imported() if imported else bundle
