"""Each effect of the virtual actuator changes the data with its documented signature and nothing else.

Every test compares the same excitation, seed and preset with and without the effect: the sensor noise stream is
identical, so the difference is the effect alone.
"""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.simulation import experiments as ex

FS = 500.0
FULL = 1.25
UNCHANGED = ("t_s", "current_a", "theta_rad", "speed_rad_s")


def _pair(current, effects, preset="bmr2013", base_effects=None):
    base = bmr.VirtualActuator(preset, seed=7, sample_rate_hz=FS, effects=base_effects)
    fx = dict(base_effects or {})
    fx.update(effects)
    with_fx = bmr.VirtualActuator(preset, seed=7, sample_rate_hz=FS, effects=fx)
    cur = np.concatenate([ex.opening_path(FS), np.asarray(current, dtype=float)])
    a, b = base.run(cur), with_fx.run(cur)
    k = len(cur) - len(current)
    return {n: v[k:] for n, v in a.items()}, {n: v[k:] for n, v in b.items()}, with_fx


def _assert_same(a, b, names):
    for n in names:
        np.testing.assert_array_equal(a[n], b[n], err_msg=n)


def test_vocabulary_and_parameter_listing():
    assert bmr.EFFECTS == ("coil_lag", "thermal_drift", "friction_current", "friction_harmonics",
                           "torque_ripple", "sensor_drift", "time_delay", "non_congruent", "creep",
                           "rate_dependence", "run_gain_offset", "leakage", "accommodation", "viscous")
    params = bmr.effect_parameters()
    assert set(params) == set(bmr.EFFECTS)
    expected = {"coil_lag": {"tau_s"}, "thermal_drift": {"gain_loss", "tau_s"}, "friction_current": {"gain_per_a"},
                "friction_harmonics": {"order", "amplitude_nmm", "phase_rad"},
                "torque_ripple": {"eps", "phase_rad"}, "sensor_drift": {"rate_nmm_per_s", "settle_per_s"},
                "time_delay": {"delay_s"}, "non_congruent": {"curvature", "scale_nmm", "cubic", "feedback"},
                "creep": {"fraction", "tau_min_s", "tau_max_s", "fluctuation", "tau0_s"}, "rate_dependence": {"tau_s"},
                "run_gain_offset": {"gain_sd", "offset_sd"}, "leakage": {"rate_per_s", "decay_per_s"},
                "accommodation": {"kappa", "cycles"}, "viscous": {"c", "f_y", "v0"}}
    for name, keys in expected.items():
        assert set(params[name]["params"]) == keys
        assert "Signature" in params[name]["doc"]
        for p in params[name]["params"].values():
            assert {"unit", "default", "min", "max", "doc"} <= set(p)


def test_effects_are_off_by_default_except_the_preset_ones():
    assert bmr.VirtualActuator("ideal").effects == {}
    assert bmr.VirtualActuator("bmr2013").effects == {"coil_lag": {"tau_s": 0.008}}
    act = bmr.VirtualActuator("bmr2013", effects=["coil_lag:off", "time_delay:delay_s=0.004"])
    assert act.effects == {"time_delay": {"delay_s": 0.004}}
    act = bmr.VirtualActuator("bmr2013", effects={"coil_lag": None, "torque_ripple": {}})
    assert act.effects == {"torque_ripple": {"eps": 0.05, "phase_rad": 0.0}}


@pytest.mark.parametrize("spec, message", [
    (["magic"], "unknown effect"),
    (["coil_lag:tau=1"], "has no parameter"),
    (["coil_lag:tau_s=x"], "not a number"),
    (["time_delay:delay_s=5"], "outside"),
])
def test_bad_effect_specs_are_clear_errors(spec, message):
    with pytest.raises(bmr.BmrError, match=message):
        bmr.VirtualActuator("bmr2013", effects=spec)


@pytest.mark.parametrize("spec, message", [
    ({"coil_lag": {"tau_s": "slow"}}, "not a number"),
    ({"coil_lag": 3}, "dict"),
    (42, "effects"),
])
def test_effect_specs_of_the_wrong_type_are_type_errors(spec, message):
    with pytest.raises(TypeError, match=message):
        bmr.VirtualActuator("bmr2013", effects=spec)


def _loop_area(current, torque):
    """|∮ T dI| over the samples (N·mm·A)."""
    return abs(np.sum(0.5 * (torque[1:] + torque[:-1]) * np.diff(current)))


def test_coil_lag_widens_loops_with_rate():
    areas = {}
    for tau in (0.0, 0.02):
        for rate in (0.25, 5.0):
            cycle = ex.ramp_path(0.0, [FULL, -FULL, 0.0], rate / FS)
            act = bmr.VirtualActuator("bmr2013", seed=1, sample_rate_hz=FS, effects={"coil_lag": {"tau_s": tau}})
            act.run(ex.opening_path(FS))
            out = act.run(np.tile(cycle, 2))
            n = len(cycle)
            areas[tau, rate] = _loop_area(out["current_a"][n:], out["field_torque_nmm"][n:])
    # Without lag the steel loop is rate independent; the lag widens it in proportion to the rate.
    assert areas[0.0, 5.0] == pytest.approx(areas[0.0, 0.25], rel=0.01)
    slow = areas[0.02, 0.25] - areas[0.0, 0.25]
    fast = areas[0.02, 5.0] - areas[0.0, 5.0]
    assert slow > 0.0 and fast > 5.0 * slow
    assert areas[0.02, 5.0] > 1.5 * areas[0.0, 5.0]
    # Nothing else changes: converter currents, angle and friction are those without lag.
    cur = ex.ramp_path(0.0, [FULL, -FULL], 2.0 / FS)
    a, b, _ = _pair(cur, {"coil_lag": {"tau_s": 0.05}}, base_effects={"coil_lag": None})
    _assert_same(a, b, UNCHANGED + ("coil1_a", "coil2_a"))


def test_thermal_drift_is_a_slow_multiplicative_gain_loss():
    hold = np.full(int(300 * FS), 1.0)
    a, b, _ = _pair(np.r_[hold, np.zeros(int(10 * FS))], {"thermal_drift": {"gain_loss": 0.1, "tau_s": 100.0}})
    ratio = b["field_torque_nmm"][: hold.size] / a["field_torque_nmm"][: hold.size]
    # Heating by (I/I_full)^2 = 0.64 with tau = 100 s: loss 0.1 * 0.64 * (1 - exp(-t/100)) (plus opening heat).
    t = np.arange(hold.size) / FS
    expected = 1.0 - 0.1 * 0.64 * (1.0 - np.exp(-t / 100.0))
    assert np.all(np.diff(ratio) <= 1e-12), "the gain falls monotonically under constant current"
    assert np.max(np.abs(ratio[100:] - expected[100:])) < 0.01
    # Multiplicative: no change where there is no field torque; friction untouched.
    _assert_same(a, b, UNCHANGED + ("coil1_a", "coil2_a", "friction_nmm", "b1_t", "b2_t"))


def test_friction_current_grows_the_angle_ripple_with_current():
    levels = np.repeat([0.0, 0.5, 1.0, -1.0], int(4 * FS))
    a, b, act = _pair(levels, {"friction_current": {"gain_per_a": 0.5}}, base_effects={"coil_lag": None})
    ripple = a["friction_nmm"] - 20.0  # the preset's mean friction c0 = 20 N·mm
    extra = b["friction_nmm"] - a["friction_nmm"]
    field_a = np.abs(a["current_a"])
    np.testing.assert_allclose(extra, 0.5 * field_a * ripple, atol=1e-9)
    assert np.all(extra[: int(4 * FS)] == 0.0), "no change at zero current"
    _assert_same(a, b, UNCHANGED + ("field_torque_nmm", "coil1_a", "coil2_a"))


def _periodogram_lines(theta, torque, kmax=14):
    """Amplitude of sin/cos(kθ) in torque by least squares, k = 1..kmax (N·mm)."""
    cols = [np.ones_like(theta)]
    for k in range(1, kmax + 1):
        cols += [np.sin(k * theta), np.cos(k * theta)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), torque, rcond=None)
    return np.hypot(coef[1::2], coef[2::2])


def test_friction_harmonics_adds_one_periodogram_line_above_the_third():
    zeros = np.zeros(int(20 * FS))
    a, b, act = _pair(zeros, {"friction_harmonics": {"order": 7, "amplitude_nmm": 4.0, "phase_rad": 0.5}})
    diff = b["torque_true_nmm"] - a["torque_true_nmm"]
    np.testing.assert_allclose(diff, 4.0 * np.sin(7 * a["theta_rad"] + 0.5), atol=1e-9)
    lines_a = _periodogram_lines(a["theta_rad"], a["torque_nmm"])
    lines_b = _periodogram_lines(b["theta_rad"], b["torque_nmm"])
    assert lines_a[3:].max() < 0.3, "the preset's friction has 3 harmonics only"
    assert lines_b[6] == pytest.approx(4.0, abs=0.2)
    others = np.delete(lines_b - lines_a, 6)
    assert np.max(np.abs(others)) < 0.2
    # The ground-truth friction includes it.
    th = np.linspace(0, 2 * np.pi, 50)
    base = bmr.VirtualActuator("bmr2013")
    np.testing.assert_allclose(act.true_friction(th) - base.true_friction(th), 4.0 * np.sin(7 * th + 0.5), atol=1e-9)
    _assert_same(a, b, UNCHANGED + ("field_torque_nmm", "coil1_a", "coil2_a"))


def test_torque_ripple_is_angle_ripple_proportional_to_field_torque():
    levels = np.repeat([0.0, 0.6, -1.1], int(5 * FS))
    a, b, _ = _pair(levels, {"torque_ripple": {"eps": 0.08, "phase_rad": 1.0}})
    extra = b["field_torque_nmm"] - a["field_torque_nmm"]
    np.testing.assert_allclose(extra, 0.08 * np.cos(a["theta_rad"] + 1.0) * a["field_torque_nmm"], atol=1e-9)
    _assert_same(a, b, UNCHANGED + ("friction_nmm", "coil1_a", "coil2_a", "b1_t", "b2_t"))


def test_sensor_drift_is_a_trend_in_the_measurement_only():
    zeros = np.zeros(int(100 * FS))
    a, b, _ = _pair(zeros, {"sensor_drift": {"rate_nmm_per_s": 0.1}})
    _assert_same(a, b, UNCHANGED + ("torque_true_nmm", "field_torque_nmm", "friction_nmm"))
    diff = b["torque_nmm"] - a["torque_nmm"]
    t_abs = a["t_s"]  # actuator time: the drift runs from the actuator's start
    q = bmr.VirtualActuator("bmr2013").resolution_nmm
    assert np.max(np.abs(diff - 0.1 * t_abs)) <= q + 1e-9  # two roundings to the sensor's step
    slope = np.polyfit(t_abs, diff, 1)[0]
    assert slope == pytest.approx(0.1, rel=0.01)


def test_a_warming_bridge_drifts_at_its_rate_and_settles():
    # A strain bridge warming up with a 20 s time constant: 0.1 N·mm/s at the start, 2 N·mm in all.
    zeros = np.zeros(int(100 * FS))
    a, b, _ = _pair(zeros, {"sensor_drift": {"rate_nmm_per_s": 0.1, "settle_per_s": 0.05}})
    _assert_same(a, b, UNCHANGED + ("torque_true_nmm", "field_torque_nmm", "friction_nmm"))
    diff = b["torque_nmm"] - a["torque_nmm"]
    want = 0.1 * -np.expm1(-0.05 * a["t_s"]) / 0.05
    q = bmr.VirtualActuator("bmr2013").resolution_nmm
    assert np.max(np.abs(diff - want)) <= q + 1e-9
    np.testing.assert_allclose(bmr._core.drift_offset(a["t_s"], 0.05), -np.expm1(-0.05 * a["t_s"]) / 0.05, rtol=1e-13)
    np.testing.assert_array_equal(bmr._core.drift_offset(a["t_s"]), a["t_s"])
    with pytest.raises(bmr.BmrError, match="settle_per_s"):
        bmr._core.drift_offset(a["t_s"], -1.0)
    with pytest.raises(bmr.BmrError):
        bmr.VirtualActuator("bmr2013", effects={"sensor_drift": {"rate_nmm_per_s": 0.1, "settle_per_s": 2.0}})


def test_time_delay_shifts_the_command_without_widening_loops():
    cur = np.concatenate([ex.ramp_path(0.0, [FULL, -FULL, FULL], 1.0 / FS), np.full(100, FULL)])
    a, b, _ = _pair(cur, {"time_delay": {"delay_s": 0.02}}, base_effects={"coil_lag": None})
    n = 10  # 20 ms at 500 Hz
    # Same field torque and coil currents, n samples later; the angle (and friction) are not delayed.
    np.testing.assert_array_equal(b["coil2_a"][n:], a["coil2_a"][:-n])
    np.testing.assert_allclose(b["field_torque_nmm"][n:], a["field_torque_nmm"][:-n], atol=1e-9)
    _assert_same(a, b, UNCHANGED + ("friction_nmm",))
    # Residual ∝ rate: zero where the current is held.
    hold = slice(-80, None)
    assert np.max(np.abs(b["field_torque_nmm"][hold] - a["field_torque_nmm"][hold])) < 1e-9


def test_non_congruent_keeps_the_range_and_changes_only_the_output_map():
    cur = ex.ramp_path(0.0, [FULL, -FULL, 0.5, -0.2, 0.3], 0.5 / FS)
    a, b, _ = _pair(cur, {"non_congruent": {"curvature": 1.0}}, preset="ideal")
    _assert_same(a, b, UNCHANGED + ("coil1_a", "coil2_a", "b1_t", "b2_t", "friction_nmm"))
    # Same flux, different torque — but the torque range stays about the same (g(T_full) = T_full per rotor).
    assert np.max(np.abs(b["field_torque_nmm"] - a["field_torque_nmm"])) > 20.0
    assert np.max(b["field_torque_nmm"]) == pytest.approx(np.max(a["field_torque_nmm"]), rel=0.1)
    # The output map is a single-valued monotone function of each rotor's torque: same B → same T.
    i = np.argsort(a["field_torque_nmm"])
    assert np.all(np.diff(b["field_torque_nmm"][i]) >= -1e-9)


def test_non_congruent_cubic_term_is_an_odd_stiffening_map_of_each_rotor_torque():
    # The yield stress of an MR fluid cubic in the steel's flux: T = S (n + k n^3)/(1 + k), n = T_core/S.
    cur = ex.ramp_path(0.0, [FULL, -FULL, 0.5, -0.2, 0.3], 0.5 / FS)
    a, b, _ = _pair(cur, {"non_congruent": {"curvature": 0.0, "cubic": 1.0}}, preset="ideal")
    _assert_same(a, b, UNCHANGED + ("coil1_a", "coil2_a", "b1_t", "b2_t", "friction_nmm"))
    ta, tb = a["field_torque_nmm"], b["field_torque_nmm"]
    assert np.max(np.abs(tb - ta)) > 20.0
    i = np.argsort(ta)
    assert np.all(np.diff(tb[i]) >= -1e-9)
    # Stiffening: small torques shrink (to half at k = 1), the full scale stays.
    small = (np.abs(ta) > 5.0) & (np.abs(ta) < 0.1 * np.max(np.abs(ta)))
    assert np.any(small)
    assert np.all(np.abs(tb[small]) < 0.6 * np.abs(ta[small]))
    assert np.max(tb) == pytest.approx(np.max(ta), rel=0.15)


def test_non_congruent_map_is_inverted_exactly_by_the_core_table():
    core = np.linspace(-900.0, 900.0, 1001)
    for curvature, cubic in [(0.0, 0.5), (0.3, 1.0), (0.0, -0.3), (-0.45, 0.0)]:
        field = bmr._core.output_map(core, curvature, 600.0, cubic)
        assert np.all(np.diff(field) > 0), (curvature, cubic)
        back = bmr._core.output_map_inverse(field, curvature, 600.0, cubic)
        np.testing.assert_allclose(back, core, atol=1e-9)
    with pytest.raises(bmr.BmrError, match="cubic"):
        bmr._core.output_map(core, 0.0, 600.0, -2.0)
