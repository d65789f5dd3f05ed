"""A control loop in Python at 1 kHz: model file → ``bmr.Compensator.from_model`` → ``Compensator.step()`` once a
millisecond. The virtual actuator stands in for the rig (its encoder angle in, the commanded current out, the
measured torque back), so the tracking error says how well the model file's compensator does on it.

    python examples/control_loop.py MODEL.json [--preset bmr2013] [--effect coil_lag:tau_s=0.008]
                                               [--seconds 5] [--rate-hz 1000] [--stages all|none|a,b]

A model file with what the diagnosis found comes from ``bmr diagnose BUNDLE --model-out MODEL.json``. The loop
first brings compensator and actuator to a known state (both coils driven to saturation and back, in one batch),
then runs the multi-peak torque reference one sample per tick, sleeping to the next tick. It prints the tracking
RMS, what one ``step()`` costs in the loop (wall time: median, p99, worst; it is more than in a tight loop, the
caches being cold after each sleep), the CPU time of a whole tick and how many ticks overran their period: a
Python loop on a shared machine is soft real time, and these figures say how soft.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

import bmr
from bmr.simulation.experiments import MULTIPEAK_SEED, ramp_path, reference_multipeak


def control_loop(model_path: str | Path, *, preset: str = "bmr2013", effects: Any = None, seed: int = 0,
                 seconds: float = 5.0, rate_hz: float = 1000.0, stages: Any = None, paced: bool = True
                 ) -> dict[str, Any]:
    """Run the loop (see the module doc); ``stages``: as ``bmr.Model.compensator`` (``[]``: the nominal
    compensator of the same file); ``effects``: the virtual actuator's (as ``bmr.VirtualActuator``). Returns the
    figures and the logged signals."""
    dt = 1.0 / rate_hz
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the stages left off are reported by from_model's stage plan
        comp = bmr.Compensator.from_model(model_path, dt_s=dt, stages=stages)
    plant = bmr.VirtualActuator(preset, seed=seed, sample_rate_hz=rate_hz, effects=effects)
    ref = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=rate_hz, duration_s=seconds)

    # Known state: the reference beyond reach both ways (the current saturates) and back to its first value.
    reach = max(1000.0, 2.5 * float(np.max(np.abs(ref))))
    opening = ramp_path(0.0, [reach, -reach, float(ref[0])], 2.0 * reach / rate_hz)
    plant.run(comp.run(opening, plant.theta_ahead(opening.size), columns=["current_a"])["current_a"])

    n = ref.size
    torque = np.empty(n)
    current = np.empty(n)
    wall_ns = np.empty(n, dtype=np.int64)
    overruns = 0
    cpu0 = time.process_time()
    start = time.perf_counter()
    for k in range(n):
        theta = float(plant.theta_ahead(1)[0])      # the encoder
        w0 = time.perf_counter_ns()
        cmd = comp.step(float(ref[k]), theta)
        wall_ns[k] = time.perf_counter_ns() - w0
        torque[k] = plant.step(cmd.current_a).torque_nmm   # the DACs, then the torque sensor
        current[k] = cmd.current_a
        if paced:
            late = time.perf_counter() - (start + (k + 1) * dt)
            if late > 0.0:
                overruns += 1
            else:
                time.sleep(-late)
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu0
    err = torque - ref
    return {"stages": list(comp.stages), "steps": n, "elapsed_s": elapsed, "overruns": overruns,
            "tracking_rms_nmm": float(np.sqrt(np.mean(err * err))), "max_abs_error_nmm": float(np.max(np.abs(err))),
            "step_us": {"median": statistics.median(wall_ns.tolist()) / 1e3,
                        "p99": float(np.percentile(wall_ns, 99)) / 1e3, "max": float(wall_ns.max()) / 1e3},
            "tick_cpu_us": cpu / n * 1e6,
            "reference_nmm": ref, "torque_nmm": torque, "current_a": current}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model", help="model file (bmr-model/1 JSON)")
    p.add_argument("--preset", default="bmr2013", help="virtual actuator preset (default: bmr2013)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME[:key=value,...]",
                   help="an effect of the virtual actuator (as bmr simulate --effect)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seconds", type=float, default=5.0)
    p.add_argument("--rate-hz", type=float, default=1000.0)
    p.add_argument("--stages", default=None, help="'all', 'none' (the nominal compensator) or a comma-separated "
                   "list (default: those the model file's closed-loop check did not find harmful)")
    args = p.parse_args(argv)
    stages: Any = {None: None, "all": "all", "none": []}.get(args.stages, None)
    if args.stages not in (None, "all", "none"):
        stages = args.stages.split(",")
    try:
        r = control_loop(args.model, preset=args.preset, effects=args.effect or None, seed=args.seed, seconds=args.seconds,
                         rate_hz=args.rate_hz, stages=stages)
    except bmr.BmrError as exc:
        print(f"control_loop: error: {exc}", file=sys.stderr)
        return 2
    print(f"stages: {', '.join(r['stages']) or 'none (nominal)'}")
    print(f"{r['steps']} steps at {args.rate_hz:g} Hz in {r['elapsed_s']:.2f} s, {r['overruns']} ticks overran")
    print(f"tracking RMS {r['tracking_rms_nmm']:.2f} N·mm, max |error| {r['max_abs_error_nmm']:.1f} N·mm")
    st = r["step_us"]
    print(f"step(): median {st['median']:.2f} µs, p99 {st['p99']:.2f} µs, worst {st['max']:.1f} µs (wall); "
          f"CPU per tick (encoder, step, actuator, loop) {r['tick_cpu_us']:.1f} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
