"""Closed-loop tracking of the multi-peak torque reference with ``bmr.Controller`` against the open-loop
compensators, on a virtual actuator the model does not fully know.

The plant: the ``rig_preisach`` virtual actuator with a coil lag (``coil_lag``, which the diagnosis is given a
bundle to find) and a heating it never sees (``thermal_drift``: the field gain falls with coil temperature, 60 s
thermal constant), 1.5 N·mm sensor noise. The model: the diagnosis of a bundle recorded with the coil lag only
(nominal = the identified model, extended = the diagnosed one). Every row drives a fresh plant (same seed) along
the same opening excursion (beyond reach both ways, so plant and model start from known states) and then the
120 s multi-peak reference; RMS of measured − reference after the opening. Closed-loop rows run in Rust
(``bmr.simulate_closed_loop``); each controller gets the torque measured at the sample before.

    python benches/closed_loop_controller.py [--seed 0] [--duration 120] [--json out.json]
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
from bmr.diagnosis.procedure import diagnose
from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle
from bmr.simulation.experiments import MULTIPEAK_SEED, ramp_path, reference_multipeak

PRESET = "rig_preisach"
LAG = {"coil_lag": dict(MEDIUM_EFFECTS["coil_lag"])}
PLANT = {**LAG, "thermal_drift": {"gain_loss": 0.1, "tau_s": 60.0}}
NOISE_NMM = 1.5


def plant(seed: int, fs: float) -> bmr.VirtualActuator:
    act = bmr.VirtualActuator(PRESET, seed=seed, sample_rate_hz=fs, effects=PLANT)
    if act.noise_nmm != NOISE_NMM:
        raise SystemExit(f"the {PRESET} preset's sensor noise is {act.noise_nmm} N·mm, not {NOISE_NMM}")
    return act


def reference(fs: float, duration_s: float) -> tuple[np.ndarray, int]:
    """Opening excursion then the multi-peak reference; the index where the multi-peak part starts."""
    body = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, duration_s=duration_s)
    reach = max(1000.0, 2.5 * float(np.max(np.abs(body))))
    opening = ramp_path(0.0, [reach, -reach, body[0]], 4.0 * reach / 10.0 / fs)
    return np.concatenate([opening, body]), opening.size


def open_loop_rms(comp: bmr.Compensator, act: bmr.VirtualActuator, ref: np.ndarray, start: int) -> float:
    theta = act.theta_ahead(ref.size)
    torque = act.run(comp.run(ref, theta)["current_a"])["torque_nmm"]
    e = torque[start:] - ref[start:]
    return float(np.sqrt(np.mean(e * e)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=120.0, help="multi-peak reference length (s)")
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args()

    bundle = diagnosis_bundle(PRESET, effects=LAG, seed=args.seed)
    fs = bundle.sample_rate_hz
    d = diagnose(bundle, progress=False)
    named = [e["name"] for e in d.effects]
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = d.extended_model.save(Path(tmp) / "extended.json")
        extended = lambda: bmr.Compensator.from_model(path, dt_s=1.0 / fs)  # noqa: E731
        nominal = d.model.compensator
        ref, start = reference(fs, args.duration)
        seed = args.seed + 1
        rows: list[tuple[str, float, float]] = []

        def closed(name: str, comp: bmr.Compensator, **settings: object) -> bmr.Controller:
            ctl = bmr.Controller(comp, dt_s=1.0 / fs, **settings)
            t0 = time.process_time()
            run = bmr.simulate_closed_loop(ctl, plant(seed, fs), ref)
            cpu = time.process_time() - t0
            if np.any(np.abs(run.current_a) > comp.current_limit):
                raise SystemExit(f"{name}: a command beyond the current limit")
            rows.append((name, run.tracking_rms_nmm(start), ref.size / cpu))
            return ctl

        rows.append(("nominal model, open loop", open_loop_rms(nominal(), plant(seed, fs), ref, start), 0.0))
        rows.append(("extended model, open loop", open_loop_rms(extended(), plant(seed, fs), ref, start), 0.0))
        closed("Controller around the nominal compensator", nominal())
        ctl = closed("Controller (feedback + adaptation)", extended())
        closed("Controller, adaptation off", extended(), adaptation=False)
        closed("Controller, feedback off (adaptation only)", extended(), feedback=False)

    print(f"diagnosis named {named}; {PRESET} + {sorted(PLANT)}; {args.duration:g} s multi-peak, "
          f"{NOISE_NMM} N·mm noise, seed {args.seed}")
    print(f"design: {ctl.design!r}")
    print(f"adapted at the end: gain {ctl.gain:.4f}, offset {ctl.offset_nmm:.3f} N·mm")
    print("| controller | RMS (N·mm) | closed-loop samples per CPU-second |")
    print("|---|---|---|")
    for name, rms, rate in rows:
        print(f"| {name} | {rms:.2f} | {rate / 1e6:.2f} M |" if rate else f"| {name} | {rms:.2f} | |")
    if args.json:
        out = {"named": named, "design": repr(ctl.design),
               "rows": [{"controller": n, "rms_nmm": r, "samples_per_cpu_s": s} for n, r, s in rows]}
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
