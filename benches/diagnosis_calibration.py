"""Calibration of ``bmr.diagnose`` on the virtual actuator: detection, wrong-name and false-alarm rates and
parameter error per effect and size, plus held-out gains and wall time per bundle.

For each effect of the vocabulary and each size (a multiple of the effect's "medium" size), many seeds: a
diagnosis bundle (``bmr.diagnosis.excitation.diagnosis_bundle``: the quick experiment set plus a minor-loop run)
from the ``rig_preisach`` virtual actuator with that effect is diagnosed blind.

* detection: the effect is among the accepted ones;
* wrong name: another *physical* effect is accepted (``table_resolution`` is not physics and not counted);
* false alarm (clean bundles, no effect): any physical effect accepted;
* parameter error: relative error of the effect's main parameter.

Usage: ``python benches/diagnosis_calibration.py [--seeds 10] [--sizes 0.5,1,2] [--effects a,b] [--closed-loop]``
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

import numpy as np

from bmr.diagnosis.procedure import diagnose
from bmr.diagnosis.effects import PHYSICAL
from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle

# The parameters scaled with the size (the first is the one whose relative error is reported).
SCALED = {"coil_lag": ["tau_s"], "thermal_drift": ["gain_loss"], "friction_current": ["gain_per_a"],
          "friction_harmonics": ["amplitude_nmm"], "torque_ripple": ["eps"], "sensor_drift": ["rate_nmm_per_s"],
          "time_delay": ["delay_s"], "non_congruent": ["curvature"]}


def effect_at(name: str, size: float) -> dict[str, float]:
    params = MEDIUM_EFFECTS[name]
    out = dict(params)
    for k in SCALED[name]:
        out[k] = params[k] * size
    if name == "time_delay":
        out["delay_s"] = max(0.002, round(out["delay_s"] / 0.002) * 0.002)
    return out


def one(name: str | None, size: float, seed: int, closed_loop: bool = False) -> dict[str, Any]:
    effects = {name: effect_at(name, size)} if name else None
    bundle = diagnosis_bundle("rig_preisach", effects=effects, seed=seed)
    t0 = time.perf_counter()
    d = diagnose(bundle, progress=False, closed_loop=closed_loop)
    wall = time.perf_counter() - t0
    names = [e["name"] for e in d.effects]
    physical = [n for n in names if n in PHYSICAL]
    row: dict[str, Any] = {"effect": name or "clean", "size": size, "seed": seed, "found": names,
                           "wall_s": wall, "nominal": d.nominal_heldout_rms_nmm, "final": d.residual_rms_nmm,
                           "noise": d.noise_floor_nmm,
                           "loop_ratio": (d.closed_loop or {}).get("ratio", math.nan)}
    if name:
        row["detected"] = name in physical
        row["wrong"] = any(n != name for n in physical)
        key = SCALED[name][0]
        truth = effects[name][key]
        got = next((e["params"].get(key) for e in d.effects if e["name"] == name), None)
        row["param_err"] = abs(got - truth) / abs(truth) if got is not None else math.nan
    else:
        row["false_alarm"] = bool(physical)
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--sizes", default="0.5,1,2")
    p.add_argument("--effects", default=",".join(MEDIUM_EFFECTS))
    p.add_argument("--closed-loop", action="store_true",
                   help="also measure extended vs nominal compensator tracking on each bundle's plant")
    args = p.parse_args(argv)
    sizes = [float(s) for s in args.sizes.split(",")]
    effects = [e for e in args.effects.split(",") if e]
    rows = []
    t0 = time.perf_counter()
    for seed in range(args.seeds):
        rows.append(one(None, 0.0, 1000 + seed))
        print(f"clean seed {seed}: {rows[-1]['found']}", file=sys.stderr)
    for name in effects:
        for size in sizes:
            for seed in range(args.seeds):
                rows.append(one(name, size, 1000 + seed, args.closed_loop))
                r = rows[-1]
                print(f"{name} ×{size:g} seed {seed}: {r['found']} param err {r['param_err']:.3f} "
                      f"({r['wall_s']:.1f} s)", file=sys.stderr)
    clean = [r for r in rows if r["effect"] == "clean"]
    walls = np.array([r["wall_s"] for r in rows])
    print(f"\n{len(rows)} bundles in {time.perf_counter() - t0:.0f} s; diagnosis wall time per bundle: median "
          f"{np.median(walls):.1f} s, max {walls.max():.1f} s (2-core machine)\n")
    fa = np.mean([r["false_alarm"] for r in clean]) if clean else math.nan
    print(f"Clean bundles (rig_preisach, no effect): false-alarm rate {fa:.2f} over {len(clean)} seeds; found: "
          f"{sorted({tuple(r['found']) for r in clean})}\n")
    loop = " median tracking ratio extended/nominal |" if args.closed_loop else ""
    print("| effect | size | medium parameters | detection | wrong name | median param. error | held-out RMS "
          "nominal → extended (N·mm) |" + loop)
    print("|---|---|---|---|---|---|---|" + ("---|" if args.closed_loop else ""))
    for name in effects:
        for size in sizes:
            sel = [r for r in rows if r["effect"] == name and r["size"] == size]
            if not sel:
                continue
            det = np.mean([r["detected"] for r in sel])
            wrong = np.mean([r["wrong"] for r in sel])
            err = np.nanmedian([r["param_err"] for r in sel]) if any(
                math.isfinite(r["param_err"]) for r in sel) else math.nan
            nom = np.median([r["nominal"] for r in sel])
            fin = np.median([r["final"] for r in sel])
            params = ", ".join(f"{k}={v:g}" for k, v in effect_at(name, size).items())
            extra = f" {np.nanmedian([r['loop_ratio'] for r in sel]):.2f} |" if args.closed_loop else ""
            print(f"| {name} | ×{size:g} | {params} | {det:.2f} | {wrong:.2f} | {err:.3f} | {nom:.2f} → {fin:.2f} |"
                  + extra)
    return 0


if __name__ == "__main__":
    sys.exit(main())
