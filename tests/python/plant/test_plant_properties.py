"""Property tests of the virtual actuator on random command sequences."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import bmr

commands = st.lists(st.floats(min_value=-3.0, max_value=3.0, allow_nan=False), min_size=2, max_size=300)


@settings(max_examples=40, deadline=None)
@given(cmd=commands, seed=st.integers(min_value=0, max_value=2**64 - 1), split=st.integers(min_value=0, max_value=300))
def test_any_command_sequence_is_safe_deterministic_and_splittable(cmd, seed, split):
    fx = {"time_delay": {"delay_s": 0.004}, "thermal_drift": {}, "friction_current": {}}
    whole = bmr.VirtualActuator("bmr2013", seed=seed, sample_rate_hz=500.0, effects=fx).run(cmd)
    act = bmr.VirtualActuator("bmr2013", seed=seed, sample_rate_hz=500.0, effects=fx)
    k = min(split, len(cmd))
    parts = [act.run(cmd[:k]) if k else None, act.run(cmd[k:]) if k < len(cmd) else None]
    for name, v in whole.items():
        assert np.all(np.isfinite(v)), name
        joined = np.concatenate([p[name] for p in parts if p is not None])
        assert joined.tobytes() == v.tobytes(), name
    # Converters clamp to [0, 1.5 A] and only one coil carries current; the sensor clips at its ±12 N range.
    assert np.all((whole["coil1_a"] >= 0) & (whole["coil1_a"] <= 1.5))
    assert np.all((whole["coil2_a"] >= 0) & (whole["coil2_a"] <= 1.5))
    assert np.all(np.minimum(whole["coil1_a"], whole["coil2_a"]) == 0.0)
    assert np.all(np.abs(whole["torque_nmm"]) <= 12.0 * 60.0 + 1e-9)
    assert np.all(np.abs(whole["field_torque_nmm"]) < 800.0)
