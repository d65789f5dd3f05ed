"""The effects real devices show beyond the paper's model (creep, rate dependence, accommodation, leakage, per-run
calibration), recordings after a rest, and the virtual hysteretic device: each effect leaves its documented
signature and nothing else."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.simulation.experiments import ramp_path
from bmr.simulation.device import device_bundle

FS = 500.0


def _pair(effects, u, preset="ideal", **kw):
    a = bmr.VirtualActuator(preset, sample_rate_hz=FS, **kw).run(u)
    b = bmr.VirtualActuator(preset, sample_rate_hz=FS, effects=effects, **kw).run(u)
    return a, b


def test_creep_relaxes_logarithmically_after_a_step_and_settles():
    # Saturate, step to +0.3 A and hold 200 s: the output keeps creeping towards its equilibrium.
    u = np.concatenate([ramp_path(0.0, [1.25, -1.25, 0.3], 1.0 / FS), np.full(int(210 * FS), 0.3)])
    a, b = _pair({"creep": {"fraction": 0.05, "tau_min_s": 0.01, "tau_max_s": 1e4}}, u)
    d = b["torque_nmm"] - a["torque_nmm"]
    hold0 = u.size - int(210 * FS)
    at = lambda s: d[hold0 + int(s * FS)]  # noqa: E731
    # Behind the equilibrium after the rise, by less and less; equal steps per decade of time in the middle.
    assert at(2) < at(20) < at(200) < 0
    assert abs((at(20) - at(2)) / (at(200) - at(20)) - 1.0) < 0.3
    # The noise-free seal friction and current are untouched.
    np.testing.assert_array_equal(a["current_a"], b["current_a"])


def test_creeps_fluctuation_field_keeps_the_output_moving_with_log_time_and_restarts_at_a_turn():
    # Saturate, rise to +0.3 A and hold 200 s: the fluctuation field keeps pushing the field the way it last moved,
    # by equal steps per e-fold of time, never settling; a small turn back starts it again the other way.
    hold = int(210 * FS)
    u = np.concatenate([ramp_path(0.0, [1.25, -1.25, 0.3], 1.0 / FS), np.full(hold, 0.3),
                        np.linspace(0.3, 0.28, 11)[1:], np.full(int(10 * FS), 0.28)])
    a, b = _pair({"creep": {"fraction": 0.0, "fluctuation": 0.004, "tau0_s": 0.05}}, u)
    d = b["torque_nmm"] - a["torque_nmm"]
    hold0 = u.size - hold - 10 - int(10 * FS)
    at = lambda s: d[hold0 + int(s * FS)]  # noqa: E731
    assert 0 < at(2) < at(20) < at(200)
    # ln(1 + t/τ₀) for t ≫ τ₀: the same step per decade of time.
    assert abs((at(20) - at(2)) / (at(200) - at(20)) - 1.0) < 0.2
    # After the turn back the output creeps down: the field along the new direction.
    after = hold0 + hold + 10
    assert d[after + int(9 * FS)] < d[after + int(1 * FS)]


def test_rate_dependence_widens_loops_with_rate_most_where_the_loop_is_steep():
    widths = []
    for rate in (0.5, 2.0):
        u = ramp_path(0.0, [1.25, -1.25, 1.25, -1.25], rate / FS)
        a, b = _pair({"rate_dependence": {"tau_s": 0.01}}, u)
        d = np.abs(b["torque_nmm"] - a["torque_nmm"])[u.size // 2:]
        uu = u[u.size // 2:]
        steep = d[np.abs(uu) < 0.3].max()
        flat = d[np.abs(uu) > 1.15].max()
        widths.append(steep)
        assert flat < 0.2 * steep
    assert widths[1] > 2.5 * widths[0]


def test_viscous_loss_follows_the_rate_alike_on_steep_and_saturated_branches():
    # c·du/dt with u the field current the steel sees: on a ramp it is c times the ramp rate wherever the loop is
    # (steep middle or saturated end), changes sign with the ramp, and a faster ramp scales it by the rate.
    c = 4.0
    for rate in (0.5, 2.0):
        u = ramp_path(0.0, [1.25, -1.25, 1.25, -1.25], rate / FS)
        a, b = _pair({"viscous": {"c": c}}, u)
        d = (b["torque_nmm"] - a["torque_nmm"])[u.size // 2:]
        du = np.gradient(u)[u.size // 2:]
        uu = u[u.size // 2:]
        # Away from the turning points (where the converter and the coil still follow the command's kink).
        ramp = np.abs(np.convolve(np.sign(du), np.ones(41) / 41, mode="same")) > 0.999
        for part in (np.abs(uu) < 0.3, (np.abs(uu) > 1.0) & (np.abs(uu) < 1.2)):
            sel = part & ramp
            assert sel.sum() > 20
            np.testing.assert_allclose(d[sel], c * rate * np.sign(du[sel]), rtol=0.02)
    # A hold: no rate, no loss.
    u = np.concatenate([ramp_path(0.0, [1.25, 0.3], 1.0 / FS), np.full(int(2 * FS), 0.3)])
    a, b = _pair({"viscous": {"c": c}}, u)
    assert np.abs((b["torque_nmm"] - a["torque_nmm"])[-int(FS):]).max() < 1e-9


def test_an_actuator_with_a_viscous_loss_pickled_mid_run_continues_bit_for_bit():
    import pickle

    u = ramp_path(0.0, [1.25, -1.25, 0.7], 1.0 / FS)
    act = bmr.VirtualActuator("ideal", sample_rate_hz=FS, effects={"viscous": {"c": 3.0}}, seed=4)
    act.run(u[:700])
    back = pickle.loads(pickle.dumps(act))
    a, b = act.run(u[700:])["torque_nmm"], back.run(u[700:])["torque_nmm"]
    assert a.tobytes() == b.tobytes()
    # The loss's last input is part of the state: one without it would jump at the first sample.
    fresh = bmr.VirtualActuator("ideal", sample_rate_hz=FS, effects={"viscous": {"c": 3.0}}, seed=4)
    assert np.abs(fresh.run(u)["torque_nmm"][700:] - a).max() < 1e-9


def test_leakage_integrates_the_input_and_restarts_with_each_recording():
    u = np.full(int(10 * FS), 0.5)
    act = bmr.VirtualActuator("ideal", sample_rate_hz=FS, effects={"leakage": {"rate_per_s": 2.0}})
    ref = bmr.VirtualActuator("ideal", sample_rate_hz=FS)
    d = act.run(u)["torque_nmm"] - ref.run(u)["torque_nmm"]
    t = np.arange(u.size) / FS
    # 2 N·mm/(A·s) × 0.5 A × t (the first sample's trapezoid starts from the 0 A before it).
    np.testing.assert_allclose(d[1:], 1.0 * t[1:] + 0.25 / FS * 2.0, atol=1e-9)
    act.start_run()
    ref.start_run()
    d2 = act.run(u)["torque_nmm"] - ref.run(u)["torque_nmm"]
    assert abs(d2[0]) < 0.01


def test_a_charge_amplifier_discharges_the_leakage_integral_towards_its_steady_charge():
    # q' = u - decay q: held at 0.5 A with decay 0.5/s, the added output 2 N·mm/(A·s) × q settles at 2 × 0.5/0.5.
    u = np.full(int(30 * FS), 0.5)
    act = bmr.VirtualActuator("ideal", sample_rate_hz=FS,
                              effects={"leakage": {"rate_per_s": 2.0, "decay_per_s": 0.5}})
    ref = bmr.VirtualActuator("ideal", sample_rate_hz=FS)
    d = act.run(u)["torque_nmm"] - ref.run(u)["torque_nmm"]
    t = np.arange(u.size) / FS
    np.testing.assert_allclose(d, 2.0 * (1.0 - np.exp(-0.5 * t)), atol=2e-3)
    # The diagnosis's column is the same integral (of the input from the 0 A before the first sample).
    q = bmr._core.leak_integral(np.concatenate([[0.0], u]), 1.0 / FS, 0.5)[1:]
    np.testing.assert_allclose(d, 2.0 * q, rtol=0, atol=1e-9)


def test_accommodation_drifts_repeated_minor_loops_and_saturation_wipes_it():
    verts = [1.25]
    for _ in range(8):
        verts += [-0.55, -0.25]
    verts += [1.25]
    u = ramp_path(0.0, verts, 1.0 / FS)
    a, b = _pair({"accommodation": {"kappa": 0.2, "cycles": 2.0}}, u)
    d = b["torque_nmm"] - a["torque_nmm"]
    # At the top of each cycle (u = -0.25) the shift grows towards its limit, then saturation wipes it.
    tops = np.flatnonzero(np.isclose(u, -0.25) & (np.diff(u, append=u[-1]) > -1e-12))
    shifts = d[tops]
    assert np.all(np.diff(np.abs(shifts[1:])) > -1e-9)
    assert abs(shifts[-1]) > 2.0
    assert d[-1] == 0.0


def test_run_gain_offset_is_drawn_per_recording_and_leaves_the_noise_alone():
    u = np.full(2000, 1.0)
    act = bmr.VirtualActuator("rig_preisach", sample_rate_hz=FS, seed=3,
                              effects={"run_gain_offset": {"gain_sd": 0.05, "offset_sd": 5.0}})
    ref = bmr.VirtualActuator("rig_preisach", sample_rate_hz=FS, seed=3)
    ratios = []
    for _ in range(4):
        act.start_run()
        ref.start_run()
        a, r = act.run(u), ref.run(u)
        ratios.append(np.median(a["torque_nmm"] - r["torque_nmm"]))
    assert np.std(ratios) > 1.0
    # Same seed, effect off: bit for bit what a bundle without start_run gives.
    one = bmr.VirtualActuator("rig_preisach", sample_rate_hz=FS, seed=3).run(np.tile(u, 2))["torque_nmm"]
    two = bmr.VirtualActuator("rig_preisach", sample_rate_hz=FS, seed=3)
    first = two.run(u)["torque_nmm"]
    two.start_run()
    np.testing.assert_array_equal(one, np.concatenate([first, two.run(u)["torque_nmm"]]))


def test_rest_between_recordings_cools_the_coils():
    u = np.full(int(60 * FS), 1.25)
    fx = {"thermal_drift": {"gain_loss": 0.1, "tau_s": 20.0}}
    hot = bmr.VirtualActuator("ideal", sample_rate_hz=FS, effects=fx)
    hot.run(u)
    cold = bmr.VirtualActuator("ideal", sample_rate_hz=FS, effects=fx)
    cold.run(u)
    cold.start_run(float("inf"))
    hot.start_run(0.0)
    y_hot = hot.run(u[:10])["torque_nmm"]
    y_cold = cold.run(u[:10])["torque_nmm"]
    # Hot coils lost ~10 % of the gain; after a long rest the gain is back.
    assert y_cold[-1] > y_hot[-1] * 1.08
    with pytest.raises(bmr.BmrError, match="rest_s"):
        hot.start_run(-1.0)


def test_virtual_device_bundle_declares_its_quantities_and_has_no_angle():
    b = device_bundle("piezo", seed=2, reversals=5, sweep_rates=(1.0,), dwell_s=0.5)
    assert b.quantities.input.unit == "V" and b.quantities.output.unit == "µm"
    assert b.quantities.angle is None
    assert [r.role for r in b.runs][:2] == ["identification", "identification"]
    assert all(r.angle is None for r in b.runs)
    again = device_bundle("piezo", seed=2, reversals=5, sweep_rates=(1.0,), dwell_s=0.5)
    for r, s in zip(b.runs, again.runs):
        np.testing.assert_array_equal(r.output, s.output)
    with pytest.raises(bmr.BmrError, match="rotor angle"):
        bmr.VirtualDevice("piezo", effects={"torque_ripple": {"eps": 0.1}})
    with pytest.raises(bmr.BmrError, match="unknown virtual device preset"):
        bmr.VirtualDevice("nope")


def test_virtual_device_viscous_loss_is_c_times_the_input_rate():
    # Piezo stack (V → µm): c = 0.01 µm per V/s; a ramp at 50 and 200 V/s adds 0.5 and 2 µm wherever it is.
    for rate in (50.0, 200.0):
        dev = bmr.VirtualDevice("piezo", effects={"viscous": {"c": 0.01}})
        ref = bmr.VirtualDevice("piezo")
        fs = dev.sample_rate_hz
        u = np.concatenate([np.full(50, -90.0), np.arange(-90.0, 90.0, rate / fs)])
        d = dev.run(u)["output_true"] - ref.run(u)["output_true"]
        np.testing.assert_allclose(d[60:], 0.01 * rate, rtol=1e-9)
        assert np.all(d[1:50] == 0.0)


def test_a_mean_field_steepens_or_shears_the_loop_and_is_nothing_when_off():
    # non_congruent's mean field (a moving Preisach core): the core sees u + feedback·y/S. Off (0), the very bits
    # of the plant without it; magnetizing (> 0), the core sees more than u where the output is positive, so the
    # loop reaches higher and rises faster through zero; demagnetizing (< 0), the other way.
    u = ramp_path(0.0, [90.0, -90.0, 90.0, -90.0], 100.0 / FS)
    half = u.size // 2
    rising = np.flatnonzero(np.diff(u[half:]) > 0) + half

    def loop(feedback):
        fx = None if feedback is None else {"non_congruent": {"curvature": 0.0, "feedback": feedback}}
        return bmr.VirtualDevice("piezo", sample_rate_hz=FS, effects=fx).run(u)["output_true"]

    def steepest_rise(y):
        return float(np.max(np.diff(y)[rising[:-1]]))

    plain = loop(None)
    np.testing.assert_array_equal(loop(0.0), plain)
    up, down = loop(9.0), loop(-9.0)
    assert up.max() > plain.max() + 0.3 > down.max() + 0.6
    assert steepest_rise(up) > steepest_rise(plain) > steepest_rise(down)
    # The actuator: each steel circuit fed back its own flux; off, the same bits.
    i = ramp_path(0.0, [1.25, -1.25, 1.25, -1.25], 1.0 / FS)
    a, b = _pair({"non_congruent": {"curvature": 0.0, "feedback": 0.0}}, i)
    np.testing.assert_array_equal(a["torque_nmm"], b["torque_nmm"])
    a, c = _pair({"non_congruent": {"curvature": 0.0, "feedback": 0.1}}, i)
    assert np.max(np.abs(c["b1_t"] - a["b1_t"])) > 0.01
