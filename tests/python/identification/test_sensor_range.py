"""A torque sensor at the end of its range reads one value whatever the device does: those samples are found
(the output's extreme held while the input moves, where the output elsewhere resolves its noise), left out of the
identification and of the scores, and said; a recording that only saturates, or repeats values everywhere, has no
range end."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.data.signals import MIN_RAIL_SAMPLES, output_rails
from bmr.identification.prediction import AT_RANGE_END
from bmr.simulation.excitation import diagnosis_bundle

# The rig's sensor range cut to 9.5 N on the 60 mm lever: ±570 N·mm, below the field torque's ±600-650 N·mm.
CLIPPED = {"sensor.range_n": 9.5}
NOISE_NMM = 1.46  # the rig's sensor noise


def _noisy_clipped(rng: np.random.Generator, limit: float) -> tuple[np.ndarray, np.ndarray]:
    u = np.sin(np.linspace(0.0, 6 * np.pi, 3000))
    y = np.round((100.0 * np.tanh(2 * u) + rng.normal(0.0, 1.5, u.size)) / 0.19) * 0.19
    return u, np.clip(y, -limit, limit)


def test_a_held_extreme_of_a_noisy_output_is_a_range_end() -> None:
    u, y = _noisy_clipped(np.random.default_rng(1), 90.0)
    rails = output_rails([(u, y)])
    assert rails.low == -90.0 and rails.high == 90.0
    assert rails.samples == int(np.count_nonzero(np.abs(y) >= 90.0)) > 100
    assert "range end" in rails.describe()


def test_an_unclipped_noisy_output_has_no_range_end() -> None:
    u, y = _noisy_clipped(np.random.default_rng(2), 1e9)
    assert not output_rails([(u, y)]).any


def test_a_coarse_flat_saturation_is_not_claimed() -> None:
    # Noise-free and logged with few digits: values repeat everywhere, a flat top is not told from a range end.
    u = np.linspace(-1.0, 1.0, 2000)
    y = np.round(1.5 * np.tanh(4 * u), 2)
    assert not output_rails([(u, y)]).any


def test_a_held_extreme_while_the_input_dwells_is_not_a_range_end() -> None:
    u, y = _noisy_clipped(np.random.default_rng(3), 1e9)
    k = int(np.argmax(y))
    u = np.r_[u[:k + 1], np.full(MIN_RAIL_SAMPLES + 3, u[k]), u[k + 1:]]
    y = np.r_[y[:k + 1], np.full(MIN_RAIL_SAMPLES + 3, y[k]), y[k + 1:]]
    assert output_rails([(u, y)]).high is None


def test_a_clipped_recording_is_identified_and_scored_on_what_the_sensor_measured() -> None:
    bundle = diagnosis_bundle("rig_preisach", seed=1000, overrides=CLIPPED)
    rails = output_rails([(r.input, r.output) for r in bundle.runs])
    assert rails.high == pytest.approx(570.0) and rails.low == pytest.approx(-570.0)
    model = bmr.identify(bundle)
    pred = bmr.predict(model, bundle)
    # Without leaving the held samples out the tables carry the flat tops: 3.45 N·mm held out, 6.5 scored on all.
    assert pred.rms < 1.2 * NOISE_NMM
    assert any(r.dropped.get(AT_RANGE_END, 0) > 0 for r in pred.runs)
    assert AT_RANGE_END in pred.table()


@pytest.mark.slow
def test_the_diagnosis_of_a_clipped_clean_rig_names_nothing_and_says_why() -> None:
    d = bmr.diagnose(diagnosis_bundle("rig_preisach", seed=1000, overrides=CLIPPED), progress=False,
                     closed_loop=False)
    assert [e["name"] for e in d.effects if e["name"] != "table_resolution"] == []
    assert d.residual_rms < 1.2 * d.noise_floor
    assert d.to_dict()["output_rails"]["samples"] > 1000
