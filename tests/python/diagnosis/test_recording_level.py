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


# Another Preisach density (harder, narrower steel, less reversible flux) and a coarser protocol: 7 first-order
# curves per family at 250 Hz, where a per-run calibration was named with a heating next to it.
SOFT_STEEL = {f"steel{k}.{p}": v for k in (1, 2) for p, v in
              (("coercivity_a", 0.12), ("coercivity_width_a", 0.05), ("interaction_width_a", 0.6),
               ("reversible_fraction", 0.15))}


@pytest.mark.parametrize("hidden", ["run_gain_offset", "creep + run_gain_offset"])
def test_a_calibration_per_recording_is_not_named_a_heating(hidden: str) -> None:
    # The runs' gains differ from recording to recording, not along the coils' I² history: a heating fitted to them
    # would carry about twice the heat the runs before leave into each run.
    effects = {name: MEDIUM_EFFECTS[name] for name in hidden.split(" + ")}
    bundle = diagnosis_bundle("rig_preisach", effects=effects, seed=1000, sample_rate_hz=250.0, forc_reversals=7,
                              overrides=SOFT_STEEL)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    names = _physical(d)
    assert "run_gain_offset" in names and "thermal_drift" not in names, d.to_dict()["effects"]


def test_a_heating_is_named_with_the_heat_carried_between_runs() -> None:
    # The same soft rig heated by its current (back to back: each run starts with the heat the runs before left).
    bundle = diagnosis_bundle("rig_preisach", effects={"thermal_drift": MEDIUM_EFFECTS["thermal_drift"]}, seed=1000,
                              sample_rate_hz=250.0, forc_reversals=7, overrides=SOFT_STEEL)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert "thermal_drift" in _physical(d), d.to_dict()["effects"]


def test_a_creep_after_a_recalibration_is_named_on_tables_with_the_protocol_calibrations_divided_out() -> None:
    # The independent plant's unbounded log-time after-effect and a sensor recalibrated for every recording, on the
    # coarse 11-curve protocol. The calibration is named first, on the tables as measured (on all data they fit
    # better than tables with the protocol runs' gains divided out, while the creep is still unmodelled); the creep
    # re-identifies the tables, and with the protocol runs' gains kept in them its folds disagreed (one lost 14 %,
    # held-out RMS 4.35 N·mm left at noise 1.53): judged on tables with those gains divided out it is named.
    bundle = ip.independent_bundle({m: ip.at_size(m, 1.0) for m in ("log_after_effect", "recalibration")},
                                   seed=2000, protocol="coarse")
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert sorted(_physical(d)) == ["creep", "run_gain_offset"], d.to_dict()["effects"]
    assert d.residual_rms < 1.5 * d.noise_floor, (d.residual_rms, d.noise_floor)


@pytest.mark.parametrize("protocol", ["standard", "coarse"])
def test_a_heating_and_a_warming_sensor_are_named_not_a_calibration_per_recording(protocol: str) -> None:
    # The independent plant's coils heated by their current and its strain bridge's offset warming up over the
    # session (seed 3000). Per-run offsets and gains fit the pair's effect on each run (held-out 5.8 -> 2.4 N·mm);
    # together they follow the session's time loosely (a line leaves 12 % of their spread, each run's halves
    # line up with it to 19 % only: the heating's gain follows the drive, not the clock), but the offsets alone
    # follow a line to 0.5 % and each run moves along it (71 % of its change between the halves): a drifting
    # sensor, not a calibration per recording. On the coarse protocol neither drift is accepted alone (the
    # sensor's rise reads as heat carried over between runs 2.5 times what the current left) and the pair is the
    # round's fourth most promising: pairs are tried among four.
    kw = {"protocol": "coarse"} if protocol == "coarse" else {}
    bundle = ip.independent_bundle({m: ip.at_size(m, 1.0) for m in ("coil_heating", "bridge_warmup")}, seed=3000,
                                   **kw)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert sorted(_physical(d)) == ["sensor_drift", "thermal_drift"], d.to_dict()["effects"]
    assert d.residual_rms < 1.3 * d.noise_floor, (d.residual_rms, d.noise_floor)

