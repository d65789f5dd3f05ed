"""Recording-level effects are recording-level: a sensor calibration that differs from recording to recording is
named ``run_gain_offset`` alone (not seal friction growing with the drive, not heating or drift), and seal friction
that does grow with the drive is named ``friction_current`` without a per-run calibration next to it. The evidence
is what differs between recordings: a per-run gain and offset explains the first wholly, and the second only
where the friction ripple follows the drive within a run."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
import independent_plant as ip
from bmr.diagnosis.effects import PHYSICAL
from bmr.simulation.device import device_bundle
from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle

pytestmark = pytest.mark.slow


def _physical(d: bmr.Diagnosis) -> list[str]:
    return [e["name"] for e in d.effects if e["name"] in PHYSICAL]


@pytest.mark.parametrize("seed", [1000, 1001])
def test_a_sensor_recalibrated_per_recording_is_named_run_gain_offset_alone(seed: int) -> None:
    # Gain within ±4 % and offset within ±5 N·mm, drawn anew for every recording by the independent plant.
    bundle = ip.independent_bundle({"recalibration": {"gain_span": 0.04, "offset_span_nmm": 5.0}}, seed=seed)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["run_gain_offset"], d.to_dict()["effects"]
    # The reported offset spread is that of the calibrations the evaluation runs drew (uniform ±5: sd ≈ 2.9).
    drawn = [r.meta["calibration"]["offset_nmm"] for r in bundle.runs if r.name in d.per_run_rms]
    got = next(e["params"] for e in d.effects if e["name"] == "run_gain_offset")
    assert abs(got["offset_sd"] - np.std(drawn, ddof=1)) < 0.35 * np.std(drawn, ddof=1) + 0.5, (got, drawn)


@pytest.mark.parametrize("plant", ["independent", "virtual"])
def test_drive_scaled_seal_friction_is_named_without_a_per_run_calibration(plant: str) -> None:
    if plant == "independent":
        # Magnetic pull on the seals: friction × (1 + growth·(field/S)²), no recalibration between recordings.
        bundle = ip.independent_bundle({"field_normal_force": {}}, seed=1000)
    else:
        bundle = diagnosis_bundle("rig_preisach", effects={"friction_current": MEDIUM_EFFECTS["friction_current"]},
                                  seed=1000)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    names = _physical(d)
    assert "friction_current" in names and "run_gain_offset" not in names, d.to_dict()["effects"]


def test_leakage_on_the_piezo_device_is_named_without_a_per_run_calibration() -> None:
    # The charge amplifier integrates a leakage through the stack from the start of every recording; the
    # calibration does not change between recordings. What per-run terms fit after the leakage is smaller than one
    # reading's noise and changes along each recording.
    bundle = device_bundle("piezo", effects={"leakage": {"rate_per_s": 0.002}}, seed=1000)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["leakage"], d.to_dict()["effects"]


def test_a_piezo_recalibrated_per_recording_is_named_without_a_sensor_drift() -> None:
    # Four evaluation recordings, each with its own gain and offset: what the calibration leaves is no trend that
    # every recording shares (left alone, one recording carries it).
    bundle = device_bundle("piezo", effects={"run_gain_offset": {"gain_sd": 0.02, "offset_sd": 0.1}}, seed=1001)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["run_gain_offset"], d.to_dict()["effects"]
