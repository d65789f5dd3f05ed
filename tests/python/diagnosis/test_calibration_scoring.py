"""How the calibration bench scores a diagnosis (``benches/diagnosis_calibration.py``): a report that names an
effect together with the effects the excitation could not tell it from ("coil_lag or rate_dependence") detects the
hidden effect when one of its names is the hidden one, is a wrong name only when none is, and is counted as
ambiguous; a plain wrong name stays wrong."""
from __future__ import annotations

from repo_scripts import load_script


def _bench():
    return load_script("benches/diagnosis_calibration.py")


def _diagnosis(names: list[str], alternatives: list[tuple[str, str]]) -> dict:
    return {"effects": [{"name": n, "params": {}} for n in names],
            "alternatives": [{"chosen": a, "other": b} for a, b in alternatives],
            "nominal_heldout_rms": 10.0, "residual_rms": 2.0, "noise_floor": 1.5, "wall_time_s": 1.0}


def _case(expect: list[list[str]]) -> dict:
    return {"plant": "independent", "label": "x", "size": 1.0, "seed": 1000, "effects": {"m": {}}, "expect": expect}


def test_an_ambiguous_report_that_holds_the_hidden_effect_detects_it_and_is_not_wrong() -> None:
    row = _bench()._row(_case([["rate_dependence"]]),
                        _diagnosis(["coil_lag"], [("coil_lag", "rate_dependence")]), 1.0, None)
    assert row["detected"] and not row["wrong"] and row["ambiguous"]
    assert row["reports"] == ["coil_lag or rate_dependence"]


def test_an_ambiguous_report_without_the_hidden_effect_is_a_wrong_name() -> None:
    row = _bench()._row(_case([["rate_dependence"]]),
                        _diagnosis(["coil_lag"], [("coil_lag", "time_delay")]), 1.0, None)
    assert not row["detected"] and row["wrong"] and row["ambiguous"]
    assert row["wrong_names"] == ["coil_lag or time_delay"]


def test_a_plain_name_is_scored_as_before() -> None:
    bench = _bench()
    right = bench._row(_case([["thermal_drift"]]), _diagnosis(["thermal_drift"], []), 1.0, None)
    assert right["detected"] and not right["wrong"] and not right["ambiguous"]
    extra = bench._row(_case([["thermal_drift"]]), _diagnosis(["thermal_drift", "sensor_drift"], []), 1.0, None)
    assert extra["detected"] and extra["wrong"] and extra["wrong_names"] == ["sensor_drift"]
    # A pair: each hidden effect needs a report holding one of its names.
    pair = bench._row(_case([["thermal_drift"], ["sensor_drift"]]), _diagnosis(["thermal_drift"], []), 1.0, None)
    assert not pair["detected"] and not pair["wrong"]
