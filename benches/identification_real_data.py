"""Identification on data bmr was not tuned on, measured for the README (section ``identification``).

    python benches/identification_real_data.py [--slac DIR]

* An independently written Preisach plant (``tests/python/independent_preisach.py``: its own density, memory and
  protocols, no bmr plant code): 21 first-order curves per family at 0.5 A/s, 500 Hz, exact currents, 1.5 N·mm
  noise; a held-out multi-peak run predicted by ``--method forc``, ``lstsq``, ``auto`` and by the raw curves
  (every sample handed to ``Hysteresis.from_curves``).
* The same plant as a bench: continued switching after reversals (30 ms lag), every recording from the state the
  previous excitation left; one family of curves only, and a run that reaches saturation only at its end.
* Node selection: dense measured curves (20 per family, 2 500 samples each, noise-free) rebuilt and replayed at
  their own reversals, at the default bound (0) and compressed with a stated bound.
* The SLAC quadrupole 4194 (when ``--slac`` or ``BMR_SLAC_DATA`` points at it): runs 3-6 train, 7 and 8 held out.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(ROOT / "tests" / "python"))
import independent_preisach as P  # noqa: E402
from measurements import record  # noqa: E402

import bmr  # noqa: E402
from bmr.identification.prediction import predict  # noqa: E402

ASC, DESC = "first_order_ascending", "first_order_descending"
BEFORE_SLAC_RMS_T = 1.37e-3  # examples/slac_magnet.py before: Everett table, offset from the first sample


def _pre(plant: P.Plant, seed: int) -> None:
    plant.reset()
    plant.drive(P.ramps(P.multipeak_vertices(seed, 6), 0.5, 500.0)[1], 0.002)


def forc_protocol() -> dict:
    rng = np.random.default_rng(0)
    plant = P.Plant()
    runs = [P.record(plant, ASC, ASC, P.forc_vertices("ascending"), rng),
            P.record(plant, DESC, DESC, P.forc_vertices("descending"), rng)]
    held = P.record(plant, "multipeak", "multipeak", P.multipeak_vertices(100), rng)
    bundle = bmr.Bundle("independent", 500.0, runs)
    out = {"noise_nmm": 1.5}
    for method in ("forc", "lstsq", "auto"):
        m = bmr.identify(bundle, method=method)
        out[method] = predict(m, held).rms
        if method == "forc":
            out["family_mismatch_nmm"] = m.identification.table["mismatch"]["max_abs"]
        if method == "auto":
            out["auto_chose"] = m.identification.chosen
            out["cv_rms"] = m.identification.cv
    # Raw curves: each curve's samples (its first full pass) straight into the table builder, no binning.
    asc: dict[float, tuple] = {}
    desc: dict[float, tuple] = {}
    tol = 0.01
    for r in runs:
        u, y = r.current, r.torque
        bounds = [0, *bmr._core.find_reversals(u, 0.02).tolist(), u.size - 1]
        segs = list(zip(bounds[:-1], bounds[1:]))
        for k in range(1, len(segs)):
            a, c = segs[k]
            prev = segs[k - 1][0]
            if u[c] > u[a] and u[c] > P.HI - tol and (u[prev] > P.HI - tol or u[a] < P.LO + tol):
                asc.setdefault(round(float(u[a]), 2), (u[a:c + 1], y[a:c + 1]))
            if u[c] < u[a] and u[c] < P.LO + tol and (u[prev] < P.LO + tol or u[a] > P.HI - tol):
                desc.setdefault(round(float(u[a]), 2), (u[a:c + 1], y[a:c + 1]))
    h = bmr.Hysteresis.from_curves(list(asc.values()), list(desc.values()))
    out["raw_curves"] = predict(bmr.Model(h), held).rms
    return out


def bench_plant() -> dict:
    rng = np.random.default_rng(1)
    plant = P.Plant(lag_s=0.03)
    runs = {}
    for seed, (name, fam) in enumerate(((ASC, "ascending"), (DESC, "descending"))):
        _pre(plant, seed)
        runs[name] = P.record(plant, name, name, P.forc_vertices(fam), rng, fresh=False)
    _pre(plant, 5)
    held = P.record(plant, "multipeak", "multipeak", P.multipeak_vertices(100), rng, fresh=False)
    out = {}
    for label, sel in (("ascending_only", [ASC]), ("descending_only", [DESC]), ("both", [ASC, DESC])):
        b = bmr.Bundle("bench", 500.0, [runs[k] for k in sel])
        out[label] = {m: predict(bmr.identify(b, method=m), held).rms for m in ("forc", "lstsq")}
    # A run from an unknown state that reaches saturation only at its end.
    train, held2 = P.unknown_start_runs(plant, rng)
    b = bmr.Bundle("drift", 500.0, [train])
    out["unknown_start"] = {}
    for state in ("estimate", "saturation"):
        m = bmr.identify(b, method="lstsq", initial_state=state)
        out["unknown_start"][state] = {"rms": predict(m, held2).rms, "used": m.identification.samples.used,
                                       "total": m.identification.samples.total}
    return out


def node_bound() -> dict:
    """Dense noise-free curves (20 per family, 2 500 samples each): replay each measured curve from its reversal
    and report the largest error, relative to the output span, at the default bound and compressed."""
    plant = P.Plant()
    asc, desc = [], []
    for m in np.linspace(P.LO, P.HI, 21)[:-1]:
        plant.reset()
        plant.drive(np.array([P.HI, m]), 0.002)
        u = np.linspace(m, P.HI, 2500)
        asc.append((u, plant.drive(u, 0.002)))
        plant.reset()
        plant.drive(np.array([-m]), 0.002)
        u = np.linspace(-m, P.LO, 2500)
        desc.append((u, plant.drive(u, 0.002)))
    h = bmr.Hysteresis.from_curves(asc, desc)
    span = float(np.ptp(h.output_range))

    def worst(op: bmr.Hysteresis) -> float:
        err = 0.0
        for u, y in asc:
            op.reset("positive")
            op.run(np.array([u[0]]))
            err = max(err, float(np.max(np.abs(op.run(u) - y))))
        return err / span

    out = {"default": {"nodes": h.build_report.nodes[0], "inputs": h.build_report.inputs[0],
                       "bound": h.build_report.node_tolerance[0] / span, "error": worst(h)}}
    for tol in (1e-4, 1e-3):
        small, bound = h.compressed(tol)
        out[f"compressed_{tol:g}"] = {"nodes": bound["ascending"]["nodes"], "bound": tol,
                                      "reached": bound["ascending"]["error"] / span, "error": worst(small)}
    return out


def slac(data: Path) -> dict | None:
    if not (data / "strplt.ru3").is_file():
        return None
    imported = bmr.import_logs([data / f"strplt.ru{k}" for k in range(3, 9)], input="MAIN:A", output="BL:T",
                               output_name="integrated gradient", output_sigma="sigBL", holdout=["run7", "run8"])
    b = imported.bundle
    train = bmr.Bundle("slac", b.sample_rate_hz, b.identification_runs(), quantities=b.quantities)
    held = b.evaluation_runs()
    sigma = float(np.sqrt(np.mean(np.concatenate([r.output_sigma[1:] for r in held]) ** 2)))
    out = {"sigma_t": sigma, "before_rms_t": BEFORE_SLAC_RMS_T}
    for label, kw in (("default", {}), ("smoothing_0.1", {"smoothing": 0.1})):
        m = bmr.identify(train, **kw)
        for off in ("shrunk", "first"):
            p = predict(m, held, offset=off, calibration=1, evaluate="all")
            out[f"{label}_{off}"] = {"rms_t": p.rms, "max_t": p.max_abs}
    u = np.concatenate([r.input for r in train.runs])
    y = np.concatenate([r.output for r in train.runs])
    poly = np.polyfit(u / u.max(), y, 7)
    e = np.concatenate([(r.output - np.polyval(poly, r.input / u.max()))[1:]
                        - (r.output[0] - np.polyval(poly, r.input[0] / u.max())) for r in held])
    out["single_valued"] = {"rms_t": float(np.sqrt(np.mean(e ** 2))), "max_t": float(np.max(np.abs(e)))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slac", type=Path, default=Path(os.environ.get("BMR_SLAC_DATA", ROOT.parent / "shared" /
                                                                    "data" / "slac-quad-4194")))
    args = ap.parse_args(argv)
    values = {"forc_protocol": forc_protocol(), "bench": bench_plant(), "nodes": node_bound(),
              "slac": slac(args.slac)}
    record("identification", "python benches/identification_real_data.py --slac DIR", values)
    print(values)
    return 0


if __name__ == "__main__":
    sys.exit(main())
