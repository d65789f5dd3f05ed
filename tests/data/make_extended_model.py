"""Writes tests/data/extended_model.json: a small model (first-order curves of a discretised Preisach plant,
±1.25 A, ±300 N·mm, the paper's 3-harmonic friction) with every extension the compensator has, for the firmware
export tests (the C program, nostd-check/src/model.rs). Deterministic: run it again to get the same file.

    python tests/data/make_extended_model.py
"""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "python"))

import bmr  # noqa: E402
from preisach_plant import first_order_curves  # noqa: E402

EXTENSIONS = [
    {"name": "time_delay", "params": {"delay_s": 0.006}},
    {"name": "coil_lag", "params": {"tau_s": 0.015}},
    {"name": "non_congruent", "params": {"curvature": 1.2, "scale_nmm": 300.0, "cubic": 0.3}},
    {"name": "thermal_drift", "params": {"gain_loss": 0.08, "tau_s": 20.0}},
    {"name": "torque_ripple", "params": {"eps": 0.04, "phase_rad": 0.6}},
    {"name": "friction_harmonics", "params": {"order": 6.0, "amplitude_nmm": 4.0, "phase_rad": -0.3}},
    {"name": "friction_current", "params": {"gain_per_a": 0.3}},
    {"name": "sensor_drift", "params": {"rate_nmm_per_s": 0.02}},
    {"name": "offset", "params": {"offset_nmm": 0.5}},
]


def build() -> bmr.Model:
    asc, desc = first_order_curves(40, 7)
    scale = lambda fam: [(1.25 * u, y) for u, y in fam]  # noqa: E731
    friction = bmr.FrictionFit.from_coefficients(12.0, [23.9, 3.6, -3.0], [7.4, 7.1, -2.6])
    return bmr.Model.from_curves(scale(asc), scale(desc), friction, extensions=EXTENSIONS,
                                 meta={"source": "tests/data/make_extended_model.py"})


if __name__ == "__main__":
    print(build().save(HERE / "extended_model.json"))
