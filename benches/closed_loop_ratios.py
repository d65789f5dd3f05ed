"""Closed-loop gain of the extended compensator per effect of the vocabulary, on the virtual actuator.

For each effect: a diagnosis bundle from the ``rig_preisach`` virtual actuator with that effect hidden (a medium
size), diagnosed blind; the diagnosed model is saved to a file, loaded, and ``bmr.Compensator.from_model`` builds
the compensator from it. Both it and the nominal compensator (the paper's model) track the multi-peak torque
reference on the very plant that made the bundle (same preset, effect and seed); the ratio is the extended
tracking RMS over the nominal one (below 1: the extended compensator tracks better).

    python benches/closed_loop_ratios.py [--effects a,b] [--seed 0] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import bmr
from bmr.diagnosis.effects import PHYSICAL
from bmr.diagnosis.procedure import diagnose
from bmr.simulation.excitation import diagnosis_bundle
from bmr.simulation.experiments import MULTIPEAK_SEED, reference_multipeak, tracking

PRESET = "rig_preisach"
MEDIUM = {
    "coil_lag": {"tau_s": 0.02},
    "thermal_drift": {"gain_loss": 0.1, "tau_s": 60.0},
    "friction_current": {"gain_per_a": 0.6},
    "friction_harmonics": {"order": 7.0, "amplitude_nmm": 5.0, "phase_rad": 0.5},
    "torque_ripple": {"eps": 0.05, "phase_rad": 1.0},
    "sensor_drift": {"rate_nmm_per_s": 0.06},
    "time_delay": {"delay_s": 0.02},
    "non_congruent": {"curvature": 2.0},
}


def tracking_rms(effects: dict, seed: int, comp, fs: float, duration_s: float = 20.0) -> float:
    ref = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, duration_s=duration_s)
    act = bmr.VirtualActuator(PRESET, seed=seed, sample_rate_hz=fs, effects=effects)
    run = tracking(act, comp, ref, opening_duration_s=2.0)
    k = int(run.meta["opening_end_s"] * fs)
    e = run.torque[k:] - run.column("reference_nmm")[k:]
    return float(np.sqrt(np.mean(e * e)))


def one(name: str, seed: int) -> dict:
    effects = {name: MEDIUM[name]}
    bundle = diagnosis_bundle(PRESET, effects=effects, seed=seed)
    t0 = time.perf_counter()
    d = diagnose(bundle, progress=False)
    wall = time.perf_counter() - t0
    fs = bundle.sample_rate_hz
    with tempfile.TemporaryDirectory() as tmp:
        path = d.extended_model.save(Path(tmp) / "model.json")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            comp = bmr.Compensator.from_model(path, dt_s=1.0 / fs)
    nominal = tracking_rms(effects, seed, d.model.compensator(), fs)
    extended = tracking_rms(effects, seed, comp, fs)
    return {"effect": name, "named": [e["name"] for e in d.effects], "stages_on": comp.stages,
            "nominal_rms_nmm": nominal, "extended_rms_nmm": extended, "ratio": extended / nominal,
            "closed_loop_check": d.closed_loop, "diagnosis_s": wall}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--effects", default=",".join(PHYSICAL))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    rows = []
    print(f"{'effect':20s} {'named':40s} {'stages on':40s} {'nominal':>8s} {'extended':>8s} {'ratio':>6s}")
    for name in args.effects.split(","):
        r = one(name, args.seed)
        rows.append(r)
        print(f"{name:20s} {','.join(r['named']):40s} {','.join(r['stages_on']) or '-':40s} "
              f"{r['nominal_rms_nmm']:8.3f} {r['extended_rms_nmm']:8.3f} {r['ratio']:6.2f}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
