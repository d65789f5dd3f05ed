"""The independently written plant family (``independent_plant``): every mechanism shows in the recording with
the signature of its physics, and a seed fixes every sample."""
from __future__ import annotations

import math

import numpy as np
import pytest

import bmr
import independent_plant as ip

FS = 500.0


def _drive(mechanisms: dict, current: np.ndarray, seed: int = 3) -> dict[str, np.ndarray]:
    rig = ip.IndependentRig(mechanisms, seed=seed, sample_rate_hz=FS)
    return rig.run(current)


def _excitation() -> np.ndarray:
    """Opening excursion, a minor loop, a dwell, a full-current hold (3 s) and a ramp down."""
    return np.concatenate([np.linspace(0, 1.25, 300), np.linspace(1.25, -1.25, 600), np.linspace(-1.25, 0.4, 400),
                           np.linspace(0.4, -0.2, 150), np.full(500, -0.2), np.linspace(-0.2, 1.25, 350),
                           np.full(1500, 1.25), np.linspace(1.25, 0.0, 300)])


def test_every_effect_of_the_vocabulary_has_a_mechanism():
    covered = {n for m in ip.MECHANISMS.values() for n in m.names}
    assert set(bmr.EFFECTS) <= covered, sorted(set(bmr.EFFECTS) - covered)
    # Effects the issue names two mechanisms for have two.
    for effect in ("rate_dependence", "non_congruent"):
        assert sum(effect in m.names for m in ip.MECHANISMS.values()) >= 2


@pytest.mark.parametrize("mechanism", list(ip.MECHANISMS))
def test_each_mechanism_changes_the_recording_and_a_seed_fixes_it(mechanism):
    u = _excitation()
    clean = _drive({}, u)["torque_nmm"]
    a = _drive({mechanism: {}}, u)["torque_nmm"]
    b = _drive({mechanism: {}}, u)["torque_nmm"]
    assert np.array_equal(a, b)
    assert np.all(np.isfinite(a))
    # The same seed gives the same noise: any difference is the mechanism's (the bridge's warm-up is slow: 8 s of
    # its 600 s time constant move the offset about half a N·mm).
    assert np.sqrt(np.mean((a - clean) ** 2)) > 0.2, mechanism
    # Size 0 of a scaled mechanism is the clean rig.
    zero = _drive({mechanism: ip.at_size(mechanism, 0.0)}, u)["torque_nmm"]
    if mechanism != "cubic_yield":  # its map at size 0 is the identity up to round-off
        assert np.array_equal(zero, clean), mechanism


def test_seeds_differ_only_in_noise_and_draws():
    u = _excitation()
    a = _drive({}, u, seed=1)["torque_nmm"]
    b = _drive({}, u, seed=2)["torque_nmm"]
    assert not np.array_equal(a, b)
    assert np.std(a - b) < 3 * math.sqrt(2) * ip.NOISE_NMM


def test_log_after_effect_keeps_moving_in_a_dwell():
    # A long dwell after a rising ramp: the output keeps rising, about as much from 1 to 4 s as from 4 to 16 s
    # (logarithmic in the time since the reversal, never settling), unlike an exponential relaxation.
    u = np.concatenate([np.linspace(0, 1.25, 300), np.linspace(1.25, -1.25, 600), np.linspace(-1.25, 0.0, 300),
                        np.full(int(20 * FS), 0.0)])
    rig = ip.IndependentRig({"log_after_effect": {}}, seed=0)
    y = rig.run(u)["torque_nmm"]
    clean = ip.IndependentRig({}, seed=0).run(u)["torque_nmm"]
    d = y - clean
    start = 1200

    def at(t: float) -> float:
        k = start + int(t * FS)
        return float(np.mean(d[k - 50:k + 50]))

    early, late = at(4) - at(1), at(16) - at(4)
    assert early > 1.0 and late > 1.0
    assert 0.5 < late / early < 2.0


def test_recalibration_differs_per_recording_and_is_recorded():
    b = ip.independent_bundle({"recalibration": {}}, seed=5, protocol="coarse")
    cal = [r.meta["calibration"] for r in b.runs]
    gains = {round(c["gain"], 12) for c in cal}
    assert len(gains) == len(b.runs)
    span = ip.MECHANISMS["recalibration"].medium["gain_span"]
    assert all(abs(c["gain"] - 1) <= span for c in cal)
    assert b.meta["independent_plant"]["mechanisms"] == {"recalibration": ip.MECHANISMS["recalibration"].medium}


def test_coil_heating_lowers_the_gain_at_full_current():
    u = np.concatenate([np.linspace(0, 1.25, 300), np.full(int(60 * FS), 1.25)])
    y = _drive({"coil_heating": {}}, u)["torque_nmm"]
    clean = _drive({}, u)["torque_nmm"]
    loss = (clean - y)[-500:].mean() / clean[-500:].mean()
    # 60 s at full current is one thermal time constant: about 63 % of rise_k, R(T) adding a little more.
    p = ip.MECHANISMS["coil_heating"].medium
    expected = p["gain_per_k"] * p["rise_k"] * (1 - math.exp(-1))
    assert expected * 0.9 < loss < expected * 1.3


def test_bundle_protocols_and_sample_rate():
    coarse = ip.independent_bundle({}, seed=0, protocol="coarse")
    full = ip.independent_bundle({}, seed=0, protocol="diagnosis")
    assert [r.kind for r in coarse.runs] == ["off_state", "multi_step", "first_order_ascending",
                                             "first_order_descending", "triangle", "multipeak"]
    assert len(full.runs) == len(coarse.runs) + 2
    assert len(coarse.runs[2].meta["reversals_a"]) == 11
    with pytest.raises(ValueError, match="unknown protocol"):
        ip.independent_bundle({}, protocol="long")
    with pytest.raises(ValueError, match="unknown mechanisms"):
        ip.IndependentRig({"creep": {}})
