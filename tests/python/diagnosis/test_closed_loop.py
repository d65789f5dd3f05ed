"""For every effect the diagnosis names: the compensator built in the core from the diagnosed model file
(`Compensator.from_model`) tracks the multi-peak torque reference better than the nominal one on the very plant
that made the bundle, and every stage it keeps helps. Each case is a whole blind diagnosis (slow tier; the fast
representative is the coil-lag case in test_diagnosis.py)."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

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


def _tracking_rms(effects: dict, comp, fs: float) -> float:
    ref = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, duration_s=20.0)
    run = tracking(bmr.VirtualActuator(PRESET, seed=0, sample_rate_hz=fs, effects=effects), comp, ref,
                   opening_duration_s=2.0)
    k = int(run.meta["opening_end_s"] * fs)
    e = run.torque[k:] - run.column("reference_nmm")[k:]
    return float(np.sqrt(np.mean(e * e)))


@pytest.mark.slow
@pytest.mark.parametrize("name", PHYSICAL)
def test_the_compensator_from_the_diagnosed_model_file_tracks_better(name: str, tmp_path: Path) -> None:
    effects = {name: MEDIUM[name]}
    bundle = diagnosis_bundle(PRESET, effects=effects, seed=0)
    d = diagnose(bundle, progress=False)
    assert name in [e["name"] for e in d.effects]
    fs = bundle.sample_rate_hz
    path = d.extended_model.save(tmp_path / "model.json")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        comp = bmr.Compensator.from_model(path, dt_s=1.0 / fs)
    ratio = _tracking_rms(effects, comp, fs) / _tracking_rms(effects, d.model.compensator(), fs)
    assert ratio < 0.6, (name, ratio, d.closed_loop)
    # Every stage left in helps (with it / without it < 1) and the file says so.
    for stage, verdict in d.closed_loop["stages"].items():
        entry = bmr.Model.load(path).extension(stage)
        assert entry["in_loop"] == verdict["in_loop"]
        if verdict["in_loop"]:
            assert verdict["ratio"] < 1.0, (stage, verdict)
