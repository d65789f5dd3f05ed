"""A named effect is physical: no accepted effect has a parameter outside the vocabulary's documented range (a
property over random bundles, and the MR damper's recording, where a negative creep fraction fitted a velocity
force), and a recording-level calibration is named alone."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import bmr
from bmr.diagnosis.selection import Alternative, out_of_range
from bmr.simulation.device import device_bundle

ROOT = Path(__file__).resolve().parents[3]
MR_DAMPER = ROOT.parent / "shared" / "data" / "mr-damper-utfpr"


def _accepted_in_range(d: bmr.Diagnosis) -> None:
    for e in d.effects:
        assert not out_of_range(e["name"], e["params"]), (e["name"], e["params"])


def test_out_of_range_reads_the_vocabulary() -> None:
    assert out_of_range("creep", {"fraction": -13.8, "tau_min_s": 0.05, "tau_max_s": 0.05}) == [
        "fraction=-13.8 (range 0..0.9)"]
    assert out_of_range("creep", {"fraction": 0.02, "tau_min_s": 0.1, "tau_max_s": 100.0}) == []
    assert out_of_range("thermal_drift", {"gain_loss": float("nan"), "tau_s": 10.0})
    # Parameters the vocabulary does not document (reported detail) are not judged.
    assert out_of_range("leakage", {"rate_per_s": 2.0, "carried": 1e9}) == []
    a = Alternative("coil_lag", "time_delay", (0.4, 0.38), (-0.03, 0.07), "input steps")
    assert "coil_lag or time_delay: indistinguishable on this excitation" in a.message
    assert a.to_dict()["excitation"] == "input steps"
    assert "bmr simulate" not in a.message
    b = Alternative("coil_lag", "creep", (0.4, 0.38), (-0.03, 0.07), "a dwell", ("dwell",))
    assert b.message.endswith("(on the virtual actuator: bmr simulate --separate dwell)")
    assert b.to_dict()["separating_runs"] == ["dwell"]


# Quick effects of the piezo device at sizes from barely visible to far beyond the medium calibration size.
EFFECT_SIZES = {
    "creep": lambda s: {"fraction": 0.02 * s, "tau_min_s": 0.1, "tau_max_s": 100.0},
    "leakage": lambda s: {"rate_per_s": 0.002 * s},
    "run_gain_offset": lambda s: {"gain_sd": min(0.02 * s, 0.5), "offset_sd": 0.1 * s},
    "sensor_drift": lambda s: {"rate_nmm_per_s": 0.004 * s},
    "accommodation": lambda s: {"kappa": min(0.05 * s, 0.9), "cycles": 3.0},
}


@pytest.mark.slow
@settings(max_examples=4, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(EFFECT_SIZES)), size=st.sampled_from([0.3, 1.0, 5.0, 20.0]),
       seed=st.integers(0, 50))
def test_no_accepted_effect_lies_outside_its_documented_range(name: str, size: float, seed: int) -> None:
    bundle = device_bundle("piezo", effects={name: EFFECT_SIZES[name](size)}, seed=seed, sample_rate_hz=500.0,
                           reversals=7)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    _accepted_in_range(d)
    for r in d.rejected:
        if r["reason"].startswith("parameters outside"):
            assert r["name"] in r["reason"]


def _mr_damper_bundle() -> bmr.Bundle:
    import pandas as pd
    import scipy.io

    from bmr.data.quantities import Quantities, Quantity

    if not (MR_DAMPER / "ensaio.A.4.mat").is_file():
        pytest.skip(f"needs the MR damper recordings (public repository labcontrol-data/mr-damper, data/) at "
                    f"{MR_DAMPER}")
    q = Quantities(Quantity.declare("mm", "displacement"), Quantity.declare("N", "force"))
    runs = []
    for name, role in (("A.1", "identification"), ("A.2", "identification"), ("A.3", "identification"),
                       ("A.4", "evaluation")):
        m = scipy.io.loadmat(MR_DAMPER / f"ensaio.{name}.mat")
        t = np.ravel(m["Tout"]).astype(float)
        data = pd.DataFrame({"t_s": t - t[0], q.input.column: np.ravel(m["dist"]).astype(float),
                             q.output.column: np.ravel(m["forc"]).astype(float)})
        runs.append(bmr.Run(name, "custom", data, {}, q, role))
    fs = 1.0 / float(np.median(np.diff(runs[0].t)))
    return bmr.Bundle("mr-damper-utfpr", fs, runs, quantities=q)


def test_the_mr_dampers_velocity_force_is_named_viscous_not_creep() -> None:
    # Runs A.1-A.3 identify, A.4 is held out. The structure is the damper's viscous and yield force (N per mm/s of
    # piston speed, N): named viscous with its coefficients in range, far more than half the held-out error gone; creep (a fit
    # with fraction -13.8, outside 0..0.9) is not named.
    d = bmr.diagnose(_mr_damper_bundle(), progress=False, closed_loop=False)
    _accepted_in_range(d)
    names = [e["name"] for e in d.effects]
    assert "creep" not in names
    [viscous] = [e for e in d.effects if e["name"] == "viscous"]
    assert 5.0 < viscous["params"]["c"] < 30.0, viscous
    # The MR fluid's yield force (Bingham form; today f_y 549 N, v0 8.7 mm/s, c 5.8 N·s/mm, gain 0.87).
    assert 300.0 < viscous["params"]["f_y"] < 900.0 and viscous["params"]["v0"] > 0.0, viscous
    assert viscous["gain"] > 0.8, viscous
    assert d.to_dict()["alternatives"] == [a.to_dict() for a in d.alternatives]


@pytest.mark.slow
def test_a_per_recording_calibration_is_named_alone() -> None:
    from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle

    truth = MEDIUM_EFFECTS["run_gain_offset"]
    for seed in (1000, 1001):
        d = bmr.diagnose(diagnosis_bundle("rig_preisach", effects={"run_gain_offset": truth}, seed=seed),
                         progress=False, closed_loop=False)
        physical = [e["name"] for e in d.effects if e["name"] != "table_resolution"]
        assert physical == ["run_gain_offset"], (seed, physical)


@pytest.mark.slow
@pytest.mark.parametrize("size", [0.5, 2.0])
def test_a_viscous_loss_is_named_from_a_second_drive_speed(size: float) -> None:
    # The tables come from first-order curves at 1 A/s and absorb the loss there as a wider loop; the diagnosis
    # bundle's repeated loops at 4 A/s (and the 2.5 A/s openings) are wider than they say, the 0.5 A/s triangle
    # narrower. A time shift would widen them the other way round: named viscous alone. The tables identified
    # again without the fitted loss still keep a little of it: the coefficient falls short, by a third at 2x.
    from bmr.simulation.excitation import diagnosis_bundle

    c = 4.0 * size
    d = bmr.diagnose(diagnosis_bundle("rig_preisach", effects={"viscous": {"c": c}}, seed=1000), progress=False,
                     closed_loop=False)
    physical = [e["name"] for e in d.effects if e["name"] != "table_resolution"]
    assert physical == ["viscous"], [(e["name"], e["params"]) for e in d.effects]
    [viscous] = [e for e in d.effects if e["name"] == "viscous"]
    assert 0.6 * c < viscous["params"]["c"] < 1.2 * c, viscous
