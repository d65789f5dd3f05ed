"""Closed-loop gain of the extended compensator per effect of the vocabulary, on the virtual actuator.

For each effect: a diagnosis bundle from the ``rig_preisach`` virtual actuator with that effect hidden (its medium
size, ``bmr.simulation.excitation.MEDIUM_EFFECTS``), diagnosed blind; the diagnosed model is saved to a file,
loaded, and ``bmr.Compensator.from_model`` builds the compensator from it. Both it and the nominal compensator
(the paper's model) track the multi-peak torque reference on the very plant that made the bundle (same preset,
effect and seed); the ratio is the extended tracking RMS over the nominal one (below 1: the extended compensator
tracks better). The reference is as long as the diagnosis's closed-loop check makes it
(``bmr.diagnosis.procedure.check_duration_s``: 20 s, longer for a slow stage such as the heating). Each row also keeps what the diagnosis's closed-loop check stored in the model file for every
stage (tracking with / without it, judged with the other stages in).

    python benches/closed_loop_ratios.py [--effects a,b] [--seed 0] [--json out.json] [--record]

``--record`` stores the rows in ``docs/measurements.json`` (section ``closed_loop``, rendered into the README by
``benches/readme_figures.py``).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

import bmr
from bmr.diagnosis.effects import PHYSICAL
from bmr.diagnosis.procedure import CHECK_MIN_S, check_duration_s, diagnose
from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle
from bmr.simulation.experiments import MULTIPEAK_SEED, reference_multipeak, tracking

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measurements import record  # noqa: E402

PRESET = "rig_preisach"


def tracking_rms(effects: dict, seed: int, comp: Any, fs: float, duration_s: float = CHECK_MIN_S) -> float:
    """RMS (N·mm) of measured − reference torque after the opening, ``comp`` driving a fresh virtual actuator."""
    ref = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, duration_s=duration_s)
    act = bmr.VirtualActuator(PRESET, seed=seed, sample_rate_hz=fs, effects=effects)
    run = tracking(act, comp, ref, opening_duration_s=2.0)
    k = int(run.meta["opening_end_s"] * fs)
    e = run.torque[k:] - run.column("reference_nmm")[k:]
    return float(np.sqrt(np.mean(e * e)))


def one(name: str, seed: int, model_dir: Path) -> dict[str, Any]:
    """The closed-loop row of one hidden effect (the diagnosed model file is written into ``model_dir``)."""
    effects = {name: MEDIUM_EFFECTS[name]}
    bundle = diagnosis_bundle(PRESET, effects=effects, seed=seed)
    t0 = time.perf_counter()
    d = diagnose(bundle, progress=False)
    wall = time.perf_counter() - t0
    fs = bundle.sample_rate_hz
    path = d.extended_model.save(Path(model_dir) / f"{name}.json")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        comp = bmr.Compensator.from_model(path, dt_s=1.0 / fs)
    duration = check_duration_s(d.extended_model)
    nominal = tracking_rms(effects, seed, d.model.compensator(), fs, duration)
    extended = tracking_rms(effects, seed, comp, fs, duration)
    check = d.closed_loop or {}
    on = [s["name"] for s in bmr.Model.load(path).stage_plan() if s["on"]]
    return {"effect": name, "params": dict(effects[name]), "named": [e["name"] for e in d.effects],
            "stages_on": on, "duration_s": duration, "nominal_rms_nmm": nominal, "extended_rms_nmm": extended,
            "ratio": extended / nominal,
            "stages": {k: {"ratio": float(v["ratio"]), "in_loop": bool(v["in_loop"])}
                       for k, v in (check.get("stages") or {}).items()},
            "model_file": str(path), "diagnosis_s": wall}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--effects", default=",".join(PHYSICAL))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default=None)
    p.add_argument("--record", action="store_true", help="store the rows in docs/measurements.json")
    args = p.parse_args(argv)
    rows = []
    print(f"{'effect':20s} {'named':40s} {'stages on':40s} {'nominal':>8s} {'extended':>8s} {'ratio':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.effects.split(","):
            r = one(name, args.seed, Path(tmp))
            r.pop("model_file")
            rows.append(r)
            print(f"{name:20s} {','.join(r['named']):40s} {','.join(r['stages_on']) or '-':40s} "
                  f"{r['nominal_rms_nmm']:8.3f} {r['extended_rms_nmm']:8.3f} {r['ratio']:6.2f}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float) + "\n")
    if args.record:
        record("closed_loop", "python benches/closed_loop_ratios.py --record",
               {"preset": PRESET, "seed": args.seed, "duration_s": CHECK_MIN_S, "rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
