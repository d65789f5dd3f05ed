"""The ``thermal_drift`` stage undoes the virtual actuator's coil heating: with the plant's own heating parameters, the
extended compensator on a heating actuator produces the torque the nominal compensator produces on the same
actuator with cold coils, while the nominal compensator's torque sags with the heating."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.diagnosis.extended_model import with_extensions
from bmr.simulation.experiments import MULTIPEAK_SEED, reference_multipeak, simulate_bundle, tracking

PRESET = "rig_preisach"
FS = 500.0
# Strong and fast enough that a 40 s run heats the coils to a few tenths of the steady full-current state.
HEATING = {"gain_loss": 0.2, "tau_s": 10.0}


@pytest.fixture(scope="module")
def model() -> bmr.Model:
    """Least-squares tables of the cold plant, so what remains of the tracking error is the heating."""
    return bmr.identify(simulate_bundle(PRESET, seed=0, quick=True), method="lstsq", max_order=3)


def _torque(comp, effects: dict) -> tuple[np.ndarray, np.ndarray]:
    """Measured and reference torque (N·mm) after the opening of a 40 s multi-peak run from cold coils."""
    act = bmr.VirtualActuator(PRESET, seed=1, sample_rate_hz=FS, effects=effects)
    ref = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=FS, duration_s=40.0)
    run = tracking(act, comp, ref, opening_duration_s=2.0)
    k = int(run.meta["opening_end_s"] * FS)
    return run.torque[k:], run.column("reference_nmm")[k:]


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


def test_the_heating_stage_inverts_the_plants_thermal_drift(model: bmr.Model) -> None:
    ext = with_extensions(model, [{"name": "thermal_drift", "params": HEATING}]).compensator(1.0 / FS, stages="all")
    assert ext.stages == ["thermal_drift"]
    heated = {"thermal_drift": HEATING}
    cold, ref = _torque(model.compensator(), {})
    nominal, _ = _torque(model.compensator(), heated)
    extended, _ = _torque(ext, heated)
    # Same noise stream on every run: the differences are the heating and what the stage does about it.
    drift_nominal = _rms(nominal - cold)
    drift_extended = _rms(extended - cold)
    assert drift_nominal > 2.0, drift_nominal  # the run does heat the coils
    assert drift_extended < 0.1 * drift_nominal, (drift_extended, drift_nominal)
    # Tracking: as good as on cold coils, and far better than the nominal compensator on the heating plant.
    assert _rms(extended - ref) < 1.1 * _rms(cold - ref), (_rms(extended - ref), _rms(cold - ref))
    assert _rms(extended - ref) < 0.6 * _rms(nominal - ref), (_rms(extended - ref), _rms(nominal - ref))
