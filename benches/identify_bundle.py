"""Identification figures on full simulated bundles: recovered-vs-true friction, held-out RMS of both table paths,
identification time.

Usage: python benches/identify_bundle.py [--preset ideal|bmr2013] [--seed N] [--repeat N] [--json OUT]
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

import bmr
from bmr.simulation.experiments import simulate_bundle

HIDDEN = {"order": 9, "amplitude_nmm": 4.0, "phase_rad": 0.5}
# Seal friction of the presets (amplitude N·mm, phase rad per harmonic) and offset, for the comparison table.
TRUE_FRICTION = {"bmr2013": (20.0, [(30.0, 0.4), (9.3, 1.9), (4.6, -0.7)]), "ideal": (0.0, [])}


def true_coefficients(preset: str, effects: dict) -> tuple[float, np.ndarray, np.ndarray]:
    c0, harmonics = TRUE_FRICTION[preset]
    order = max([len(harmonics)] + [int(e["order"]) for n, e in effects.items() if n == "friction_harmonics"])
    a, b = np.zeros(order), np.zeros(order)
    for k, (amp, ph) in enumerate(harmonics):
        a[k], b[k] = amp * math.cos(ph), amp * math.sin(ph)
    if "friction_harmonics" in effects:
        e = effects["friction_harmonics"]
        k = int(e["order"]) - 1
        a[k] += e["amplitude_nmm"] * math.cos(e["phase_rad"])
        b[k] += e["amplitude_nmm"] * math.sin(e["phase_rad"])
    return c0, a, b


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="bmr2013", choices=("ideal", "bmr2013"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeat", type=int, default=3, help="identification timings (best of)")
    p.add_argument("--json", help="write the figures here")
    args = p.parse_args()
    effects = {"friction_harmonics": HIDDEN}
    bundle = simulate_bundle(args.preset, effects=effects, seed=args.seed)
    n = sum(len(r.data) for r in bundle)
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        model = bmr.identify(bundle, method="both")
        times.append(time.perf_counter() - t)
    info = model.meta["identification"]
    fit = model.friction
    c0, a, b = true_coefficients(args.preset, effects)
    print(f"{bundle.actuator}: {len(bundle)} runs, {n} samples; identify(method='both') best of {args.repeat}: "
          f"{min(times):.2f} s ({', '.join(f'{k} {v:.2f}' for k, v in info['time_s'].items())} s)")
    print(f"friction: order {fit.order} (hidden line at {HIDDEN['order']}), residual {fit.residual_rms_nmm:.3f} N·mm")
    print(f"  {'coef':>5} {'true':>9} {'fitted':>9} {'stderr':>8} {'z':>6}")
    rows = []
    for row in fit.table():
        name = row["name"]
        k = int(name[1:]) - 1 if name != "c0" else -1
        true = c0 if k < 0 else (a if name[0] == "a" else b)[k] if k < a.size else 0.0
        z = (row["value"] - true) / row["stderr"] if row["stderr"] > 0 else float("nan")
        rows.append({**row, "true": true, "z": z})
        if name == "c0" or abs(true) > 0 or abs(z) > 2:
            print(f"  {name:>5} {true:9.3f} {row['value']:9.3f} {row['stderr']:8.4f} {z:6.2f}")
    for method, per_run in info["heldout_rms"].items():
        print(f"held-out RMS [{method}] " + ", ".join(f"{k} {v:.2f}" for k, v in per_run.items()) + " N·mm")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"preset": args.preset, "samples": n, "identify_s": min(times), "friction": rows,
                       "heldout_rms": info["heldout_rms"], "noise_nmm": bundle.meta["simulator"]["noise_nmm"]},
                      fh, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
