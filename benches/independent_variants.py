"""The independently written plant (``tests/python/independent_plant.py``) with constants other than the ones its
calibration cells use: each mechanism with another time constant, order, phase, share or sign, at about its medium
strength. The diagnosis was never tuned on these. One line per bundle: the names given, whether one is right for
the mechanism and which are wrong, the held-out RMS nominal → extended and the noise floor (N·mm).

``--pairs``: two variants of different mechanisms in one bundle instead (:data:`PAIRS`), both to be named.

Usage: ``python benches/independent_variants.py [--protocol coarse] [--seed N] [--pairs] [MECHANISM ...]``
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "python"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

VARIANTS: dict[str, list[dict[str, float]]] = {
    "coil_eddy_circuit": [{"tau_coil_s": 0.004, "eddy_share": 0.2, "tau_eddy_s": 0.1},
                          {"tau_coil_s": 0.03, "eddy_share": 0.0, "tau_eddy_s": 0.03}],
    "fractional_delay": [{"delay_s": 0.006}, {"delay_s": 0.04}],
    "log_after_effect": [{"viscosity_a": 0.003, "t0_s": 0.01}, {"viscosity_a": 0.003, "t0_s": 0.5}],
    "coil_heating": [{"rise_k": 40.0, "tau_s": 20.0, "gain_per_k": 0.0025},
                     {"rise_k": 20.0, "tau_s": 200.0, "gain_per_k": 0.005}],
    "cubic_yield": [{"cubic": -0.3}],
    "moving_preisach": [{"feedback_a": -0.1}],
    "seal_lobes": [{"order": 4.0, "amplitude_nmm": 5.0, "phase_rad": 2.0},
                   {"order": 9.0, "amplitude_nmm": 5.0, "phase_rad": 0.3}],
    "eccentric_gap": [{"eccentricity": 0.025, "phase_rad": 2.5}],
    "bridge_warmup": [{"drift_nmm": 40.0, "tau_s": 100.0}, {"drift_nmm": 40.0, "tau_s": 3000.0}],
    "recalibration": [{"gain_span": 0.03, "offset_span_nmm": 3.0}],
    "parallel_conductance": [{"conductance": 0.5, "tau_amp_s": 50.0}],
    "reptation": [{"share": 0.08, "per_reversal": 0.6}],
    "field_normal_force": [{"growth": 0.4}],
    "rate_loss": [{"c_nmm_s_per_a": 3.0}],
    "eddy_field": [{"k_s": 0.02}],
}

# Pairs of the variants above (each mechanism's first variant).
PAIRS: list[tuple[str, str]] = [("coil_eddy_circuit", "seal_lobes"), ("coil_heating", "bridge_warmup"),
                                ("log_after_effect", "recalibration"), ("fractional_delay", "reptation"),
                                ("rate_loss", "eccentric_gap"), ("moving_preisach", "parallel_conductance"),
                                ("eddy_field", "field_normal_force")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mechanisms", nargs="*", help=f"any of {', '.join(VARIANTS)} (default: all)")
    ap.add_argument("--protocol", default="diagnosis", choices=("diagnosis", "coarse"))
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--pairs", action="store_true", help="two mechanisms per bundle (PAIRS) instead of one")
    args = ap.parse_args(argv)
    unknown = [m for m in args.mechanisms if m not in VARIANTS]
    if unknown:
        ap.error(f"unknown mechanism(s) {', '.join(unknown)}")
    import bmr
    import independent_plant as ip
    from diagnosis_calibration import _row  # the calibration's scoring: a name, or "a or b", right or wrong

    if args.pairs:
        cases = [{a: VARIANTS[a][0], b: VARIANTS[b][0]} for a, b in PAIRS
                 if not args.mechanisms or a in args.mechanisms or b in args.mechanisms]
    else:
        cases = [{m: p} for m in args.mechanisms or list(VARIANTS) for p in VARIANTS[m]]
    right = wrong = total = 0
    for mechanisms in cases:
        c0 = time.process_time()
        bundle = ip.independent_bundle(mechanisms, seed=args.seed, protocol=args.protocol)
        d = bmr.diagnose(bundle, progress=False, closed_loop=False).to_dict()
        row = _row({"effects": mechanisms, "expect": [list(ip.MECHANISMS[m].names) for m in mechanisms]}, d,
                   time.process_time() - c0, None)
        total += 1
        right += row["detected"]
        wrong += row["wrong"]
        bad = f" (wrong: {', '.join(row['wrong_names'])})" if row["wrong"] else ""
        print(f"{mechanisms}: {', '.join(row['reports']) or 'nothing'}{'' if row['detected'] else ' (missed)'}{bad}; "
              f"held out {row['nominal']:.3g} -> {row['final']:.3g} N·mm (noise {row['noise']:.3g}); "
              f"{row['cpu_s']:.1f} CPU-s", flush=True)
    print(f"{right} of {total} named right, {wrong} with a wrong name ({args.protocol} protocol, seed {args.seed})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
