"""The Python API of bmr.VirtualActuator: outputs, determinism, state, errors."""
from __future__ import annotations

import threading

import numpy as np
import pytest

import bmr

LOGGED = ("t_s", "current_a", "coil1_a", "coil2_a", "theta_rad", "speed_rad_s", "torque_nmm")
HIDDEN = ("b1_t", "b2_t", "field_torque_nmm", "friction_nmm", "torque_true_nmm")


def _cmd(n=3000):
    return 1.2 * np.sin(np.arange(n) * 2e-3) * np.cos(np.arange(n) * 7e-4)


def test_run_returns_every_column_at_the_sample_rate():
    act = bmr.VirtualActuator("bmr2013", seed=3, sample_rate_hz=250.0)
    out = act.run(_cmd())
    assert set(LOGGED + HIDDEN) <= set(out)
    for v in out.values():
        assert v.shape == (3000,) and v.dtype == np.float64 and np.all(np.isfinite(v))
    np.testing.assert_allclose(out["t_s"], np.arange(3000) / 250.0)
    np.testing.assert_array_equal(out["current_a"], _cmd())
    assert np.all((out["theta_rad"] >= 0) & (out["theta_rad"] < 2 * np.pi))
    assert act.time_s == pytest.approx(12.0)
    # Lists and ints are accepted.
    assert act.run([0, 1, 0])["torque_nmm"].shape == (3,)


def test_same_seed_is_bit_identical_and_reset_replays():
    a = bmr.VirtualActuator("bmr2013", seed=11)
    b = bmr.VirtualActuator("bmr2013", seed=11)
    ra, rb = a.run(_cmd()), b.run(_cmd())
    for k in ra:
        assert ra[k].tobytes() == rb[k].tobytes(), k
    a.reset()
    again = a.run(_cmd())
    for k in ra:
        assert again[k].tobytes() == ra[k].tobytes(), k


def test_run_continues_from_the_current_state():
    whole = bmr.VirtualActuator("bmr2013", seed=5).run(_cmd())
    split = bmr.VirtualActuator("bmr2013", seed=5)
    first, second = split.run(_cmd()[:1234]), split.run(_cmd()[1234:])
    for k in whole:
        np.testing.assert_array_equal(whole[k], np.concatenate([first[k], second[k]]), err_msg=k)


def test_different_seeds_differ_only_in_noise():
    a = bmr.VirtualActuator("bmr2013", seed=1).run(_cmd(20000))
    b = bmr.VirtualActuator("bmr2013", seed=2).run(_cmd(20000))
    for k in LOGGED + HIDDEN:
        if k != "torque_nmm":
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    d = a["torque_nmm"] - b["torque_nmm"]
    noise = bmr.VirtualActuator("bmr2013").noise_nmm
    assert abs(d.mean()) < 0.1
    assert d.std() == pytest.approx(np.sqrt(2) * noise, rel=0.05)


def test_measurement_is_truth_plus_sensor_noise():
    act = bmr.VirtualActuator("bmr2013", seed=4)
    out = act.run(_cmd(50000))
    e = out["torque_nmm"] - out["torque_true_nmm"]
    assert e.std() == pytest.approx(act.noise_nmm, rel=0.05)
    q = act.resolution_nmm
    np.testing.assert_allclose(out["torque_nmm"] / q, np.round(out["torque_nmm"] / q), atol=1e-6)
    np.testing.assert_allclose(out["torque_true_nmm"], out["field_torque_nmm"] + out["friction_nmm"], atol=1e-9)


def test_true_friction_and_theta_ahead():
    act = bmr.VirtualActuator("bmr2013", seed=0)
    act.run(np.zeros(777))
    ahead = act.theta_ahead(500)
    out = act.run(np.zeros(500))
    np.testing.assert_array_equal(ahead, out["theta_rad"])
    np.testing.assert_allclose(act.true_friction(out["theta_rad"]), out["friction_nmm"], atol=1e-12)
    assert bmr.VirtualActuator("ideal").true_friction([0.0, 1.0]).tolist() == [0.0, 0.0]


def test_properties_and_repr():
    act = bmr.VirtualActuator("bmr2013", seed=9, sample_rate_hz=500.0, effects=["sensor_drift"])
    assert act.preset == "bmr2013" and act.seed == 9 and act.sample_rate_hz == 500.0
    assert "bmr2013" in act.name
    assert act.noise_nmm == pytest.approx(1.5)
    assert "sensor_drift:rate_nmm_per_s=0.02" in repr(act)
    assert bmr.PRESETS == ("bmr2013", "ideal", "rig_preisach")


@pytest.mark.parametrize("kwargs, message", [
    (dict(preset="bmr2099"), "unknown virtual actuator preset"),
    (dict(sample_rate_hz=0.0), "sample_rate_hz"),
    (dict(sample_rate_hz=float("nan")), "sample_rate_hz"),
    (dict(seed=-1), "seed must be an integer"),

])
def test_bad_construction_is_a_clear_error(kwargs, message):
    with pytest.raises(bmr.BmrError, match=message):
        bmr.VirtualActuator(**kwargs)


def test_wrong_argument_types_are_type_errors_naming_the_argument():
    with pytest.raises(TypeError, match="seed must be an integer"):
        bmr.VirtualActuator(seed="x")
    with pytest.raises(TypeError, match="effects"):
        bmr.VirtualActuator(effects=3)
    with pytest.raises(TypeError, match="current_a: complex values"):
        bmr.VirtualActuator().run(np.array([1 + 1j]))
    with pytest.raises(TypeError, match="current_a: boolean values"):
        bmr.VirtualActuator().run(np.array([True, False]))


def test_bad_commands_are_clear_errors_and_leave_the_state_untouched():
    act = bmr.VirtualActuator("bmr2013", seed=0)
    act.run([0.1, 0.2])
    with pytest.raises(bmr.BmrError, match=r"current_a\[2\] = NaN"):
        act.run([0.0, 0.3, float("nan")])
    with pytest.raises(bmr.BmrError, match="current_a"):
        act.run([[1.0, 2.0]])
    with pytest.raises(TypeError, match="current_a"):
        act.run("abc")
    assert act.time_s == pytest.approx(2e-3)


def test_run_releases_the_gil():
    act = bmr.VirtualActuator("bmr2013", seed=0)
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)

    t = threading.Thread(target=count)
    t.start()
    try:
        while not ticks:
            pass
        before = len(ticks)
        act.run(np.zeros(3_000_000))
        during = len(ticks) - before
    finally:
        stop.set()
        t.join()
    # Holding the GIL for the ~0.5 s run would let the other thread count only around the call's edges.
    assert during > 20_000


def test_step_matches_run_and_flags_non_finite_commands():
    cmd = _cmd(50)
    whole = bmr.VirtualActuator("bmr2013", seed=8).run(cmd)
    act = bmr.VirtualActuator("bmr2013", seed=8)
    steps = [act.step(float(c)) for c in cmd]
    assert list(whole) == bmr.ActuatorSample.keys()[:-1]
    for k in whole:
        np.testing.assert_array_equal(whole[k], [getattr(s, k) for s in steps], err_msg=k)
        np.testing.assert_array_equal(whole[k], [s[k] for s in steps], err_msg=k)
    assert all(s.command_valid for s in steps)
    s = act.step(float("nan"))
    assert s.command_valid is False and s.current_a == 0.0 and s.coil1_a == s.coil2_a == 0.0
    assert np.isfinite(s.torque_nmm)
    with pytest.raises(KeyError, match="torque_true_nmm"):
        s["torque"]
    assert "torque_nmm=" in repr(s) and s == s and s != steps[0]


def test_overrides_change_physical_parameters_by_name():
    quiet = bmr.VirtualActuator("bmr2013", seed=1, overrides={"sensor.noise_n": 0.0, "sensor.resolution_n": 0.0})
    out = quiet.run(_cmd(2000))
    np.testing.assert_allclose(out["torque_nmm"], out["torque_true_nmm"], atol=1e-9)
    half = bmr.VirtualActuator("bmr2013", overrides={"friction.scale": 0.5, "friction.offset_nmm": 0.0})
    th = np.linspace(0, 2 * np.pi, 40)
    np.testing.assert_allclose(half.true_friction(th), 0.5 * (bmr.VirtualActuator("bmr2013").true_friction(th) - 20.0),
                               atol=1e-9)
    assert half.parameters["friction"]["offset_nmm"] == 0.0
    assert "sensor.noise_n" in bmr.ACTUATOR_PARAMETERS
    with pytest.raises(bmr.BmrError, match='unknown actuator parameter "sensor.noize_n"'):
        bmr.VirtualActuator(overrides={"sensor.noize_n": 0.0})
    with pytest.raises(bmr.BmrError, match="sensor.lever_mm"):
        bmr.VirtualActuator(overrides={"sensor.lever_mm": -1.0})
    with pytest.raises(TypeError, match="overrides must be a dict"):
        bmr.VirtualActuator(overrides=[("sensor.noise_n", 0.0)])
