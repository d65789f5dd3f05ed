"""Closed-loop tracking of the multi-peak torque reference with ``bmr.Controller`` against the open-loop
compensators, on a virtual actuator the model does not fully know.

The plant: the ``rig_preisach`` virtual actuator with a coil lag (``coil_lag``, which the diagnosis is given a
bundle to find) and a heating it never sees (``thermal_drift``: the field gain falls with coil temperature, 60 s
thermal constant), 1.5 N·mm sensor noise. The model: the diagnosis of a bundle recorded with the coil lag only
(nominal = the identified model, extended = the diagnosed one). Every row drives a fresh plant (same seed) along
the same opening excursion (beyond reach both ways, so plant and model start from known states) and then the
120 s multi-peak reference; RMS of measured − reference after the opening. Closed-loop rows run in Rust
(``bmr.simulate_closed_loop``); each controller gets the torque measured at the sample before.

Throughput (closed-loop samples per CPU-second): the steady loop of ``bmr.simulate_closed_loop`` alone, on runs of
at least ``--throughput-samples`` samples (the reference repeated), ``--throughput-runs`` of them per controller in
this process, each with a fresh controller and plant built before the clocks start; the median over the runs is the
figure, printed with the runs' spread and the wall-clock rate next to it (CPU time counts only this process, wall
time also what other processes take from it). Building them (the plant integrates its steel's Everett table) is
timed apart and printed.

``--plant independent``: the same rows on the independently written rig of ``tests/python/independent_plant.py``
(its own coil circuit with an eddy-current loop, and coil heating through the copper's resistance), diagnosed from
its own bundle; every row steps it sample by sample from Python (``Controller.step``), as a user's loop would.

    python benches/closed_loop_controller.py [--plant virtual|independent] [--seed 0] [--duration 120]
                                             [--throughput-samples 1000000] [--throughput-runs 5]
                                             [--json out.json] [--record]

``--record`` stores the rows of that plant in ``docs/measurements.json`` (section ``closed_loop_controller``, one
entry per plant), from which ``benches/readme_figures.py render`` writes the table of docs/results.md.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

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


def independent_rows(seed: int, duration_s: float) -> tuple[list[str], list[tuple[str, float, float]], object]:
    """The rows on the independent rig (coil circuit diagnosed, heating never seen), stepped sample by sample."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
    import independent_plant as ip

    bundle = ip.independent_bundle({"coil_eddy_circuit": {}}, seed=seed)
    fs = bundle.sample_rate_hz
    d = diagnose(bundle, progress=False)
    named = [e["name"] for e in d.effects]
    ref, start = reference(fs, duration_s)
    mechanisms = {"coil_eddy_circuit": {}, "coil_heating": {}}

    def track(step: object) -> tuple[float, float]:
        rig = ip.IndependentRig(mechanisms, seed=seed + 1, sample_rate_hz=fs)
        theta = 2 * np.pi * np.arange(ref.size) / fs % (2 * np.pi)  # the rig turns at 1 rev/s from angle 0
        torque = np.empty(ref.size)
        y = float("nan")
        t0 = time.process_time()
        for k in range(ref.size):
            c = step(float(ref[k]), float(theta[k]), y)  # type: ignore[operator]
            if abs(c.current_a) > 1.25:
                raise SystemExit("a command beyond the current limit")
            y = float(rig.run(np.array([c.current_a]))["torque_nmm"][0])
            torque[k] = y
        e = torque[start:] - ref[start:]
        return float(np.sqrt(np.mean(e * e))), time.process_time() - t0

    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = d.extended_model.save(Path(tmp) / "extended.json")
        ext = lambda: bmr.Compensator.from_model(path, dt_s=1.0 / fs)  # noqa: E731
        rows: list[tuple[str, float, float]] = []
        for name, comp in [("nominal model, open loop", d.model.compensator()), ("extended model, open loop", ext())]:
            rows.append((name, track(lambda r, th, y, c=comp: c.step(r, th))[0], 0.0))
        ctl = None
        for name, make, settings in [
            ("Controller around the nominal compensator", d.model.compensator, {}),
            ("Controller (feedback + adaptation)", ext, {}),
            ("Controller, adaptation off", ext, {"adaptation": False}),
            ("Controller, feedback off (adaptation only)", ext, {"feedback": False}),
        ]:
            c = bmr.Controller(make(), dt_s=1.0 / fs, **settings)
            rows.append((name, track(c.step)[0], 0.0))
            ctl = c if name.startswith("Controller (") else ctl
    return named, rows, ctl


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=120.0, help="multi-peak reference length (s)")
    ap.add_argument("--json", type=Path, help="write the rows here")
    ap.add_argument("--plant", choices=("virtual", "independent"), default="virtual")
    ap.add_argument("--throughput-samples", type=int, default=1_000_000,
                    help="length of the run the closed-loop throughput is timed on (virtual plant)")
    ap.add_argument("--throughput-runs", type=int, default=5,
                    help="timed runs per controller; the median is the figure (virtual plant)")
    ap.add_argument("--record", action="store_true", help="record the rows in docs/measurements.json")
    args = ap.parse_args()
    if args.throughput_runs < 1 or args.throughput_samples < 1:
        ap.error("--throughput-runs and --throughput-samples must be at least 1")
    if args.plant == "independent":
        named, rows, ctl = independent_rows(args.seed, args.duration)
        print(f"diagnosis named {named}; independent rig + coil_eddy_circuit, coil_heating; {args.duration:g} s "
              f"multi-peak, 1.5 N·mm noise, seed {args.seed}; stepped sample by sample from Python")
        print(f"design: {ctl.design!r}")  # type: ignore[union-attr]
        print("| controller | RMS (N·mm) |")
        print("|---|---|")
        for name, rms, _ in rows:
            print(f"| {name} | {rms:.2f} |")
        if args.record:
            _record(args, named, ctl, rows)
        return 0

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
        # Per closed-loop row: the runs' rates (samples per CPU-second, per wall-clock second).
        rates: dict[str, tuple[list[float], list[float]]] = {}

        long_ref = np.tile(ref, -(-args.throughput_samples // ref.size))
        built: list[tuple[float, float]] = []  # CPU seconds to build (controller, plant)

        def closed(name: str, make: Callable[[], bmr.Compensator], **settings: Any) -> bmr.Controller:
            ctl = bmr.Controller(make(), dt_s=1.0 / fs, **settings)
            run = bmr.simulate_closed_loop(ctl, plant(seed, fs), ref)
            if np.any(np.abs(run.current_a) > ctl.compensator.current_limit):
                raise SystemExit(f"{name}: a command beyond the current limit")
            # The steady loop's throughput: each run's controller and plant built before the clocks start.
            cpu_rates, wall_rates = [], []
            for _ in range(args.throughput_runs):
                t0 = time.process_time()
                timed_ctl = bmr.Controller(make(), dt_s=1.0 / fs, **settings)
                t1 = time.process_time()
                act = plant(seed, fs)
                t2 = time.process_time()
                w2 = time.perf_counter()
                bmr.simulate_closed_loop(timed_ctl, act, long_ref)
                wall = time.perf_counter() - w2
                cpu = time.process_time() - t2
                built.append((t1 - t0, t2 - t1))
                cpu_rates.append(long_ref.size / cpu)
                wall_rates.append(long_ref.size / wall)
            rates[name] = (cpu_rates, wall_rates)
            rows.append((name, run.tracking_rms_nmm(start), float(np.median(cpu_rates))))
            return ctl

        rows.append(("nominal model, open loop", open_loop_rms(nominal(), plant(seed, fs), ref, start), 0.0))
        rows.append(("extended model, open loop", open_loop_rms(extended(), plant(seed, fs), ref, start), 0.0))
        closed("Controller around the nominal compensator", nominal)
        ctl = closed("Controller (feedback + adaptation)", extended)
        closed("Controller, adaptation off", extended, adaptation=False)
        closed("Controller, feedback off (adaptation only)", extended, feedback=False)

    print(f"diagnosis named {named}; {PRESET} + {sorted(PLANT)}; {args.duration:g} s multi-peak, "
          f"{NOISE_NMM} N·mm noise, seed {args.seed}")
    print(f"design: {ctl.design!r}")
    print(f"adapted at the end: gain {ctl.gain:.4f}, offset {ctl.offset_nmm:.3f} N·mm")
    ctl_ms, plant_ms = (1e3 * float(np.median(x)) for x in zip(*built))
    print(f"throughput: {args.throughput_runs} runs of {long_ref.size} samples per controller, median (min-max) "
          f"in M samples per second; load average at the end {', '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"built apart (median CPU): controller {ctl_ms:.2f} ms, plant {plant_ms:.2f} ms")
    print("| controller | RMS (N·mm) | closed-loop samples per CPU-second | per wall-clock second |")
    print("|---|---|---|---|")
    for name, rms, _ in rows:
        if name in rates:
            cpu_rates, wall_rates = rates[name]
            print(f"| {name} | {rms:.2f} | {_spread(cpu_rates)} | {_spread(wall_rates)} |")
        else:
            print(f"| {name} | {rms:.2f} | | |")
    if args.json:
        out = {"named": named, "design": repr(ctl.design), "throughput_samples": int(long_ref.size),
               "throughput_runs": args.throughput_runs,
               "construction_cpu_ms": {"controller": ctl_ms, "plant": plant_ms},
               "rows": [{"controller": n, "rms_nmm": r, "samples_per_cpu_s": s,
                         **({"runs_samples_per_cpu_s": rates[n][0], "runs_samples_per_wall_s": rates[n][1]}
                            if n in rates else {})} for n, r, s in rows]}
        args.json.write_text(json.dumps(out, indent=1))
    if args.record:
        _record(args, named, ctl, rows)
    return 0


def _spread(rates: list[float]) -> str:
    """Median (min-max) of rates, in millions."""
    return f"{np.median(rates) / 1e6:.2f} M ({min(rates) / 1e6:.2f}-{max(rates) / 1e6:.2f})"


def _record(args: argparse.Namespace, named: list[str], ctl: object, rows: list[tuple[str, float, float]]) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from measurements import load, record

    values = dict((load().get("closed_loop_controller") or {}).get("values", {}))
    design = ctl.design  # type: ignore[attr-defined]
    values[args.plant] = {"named": named, "duration_s": args.duration, "seed": args.seed,
                          "design": {"bandwidth_hz": design.bandwidth_hz, "ki_per_s": design.ki_per_s,
                                     "phase_margin_deg": design.phase_margin_deg,
                                     "loop_delay_s": design.loop_delay_s},
                          "rows": [{"controller": n, "rms_nmm": r, "samples_per_cpu_s": s} for n, r, s in rows]}
    record("closed_loop_controller", "python benches/closed_loop_controller.py --plant virtual --record && "
           "python benches/closed_loop_controller.py --plant independent --record", values)


if __name__ == "__main__":
    sys.exit(main())
