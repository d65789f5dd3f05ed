"""The batch filters the diagnosis uses are the plant's and the compensator's own per-sample filters."""
import math

import numpy as np
import pytest

import bmr
from bmr import _core


def test_lag_is_the_exact_zero_order_hold_lag_and_lead_inverts_it():
    dt, tau = 1e-3, 0.02
    y = _core.lag(np.ones(300), tau, dt, initial=0.0)
    n = np.arange(1, 301)
    np.testing.assert_allclose(y, 1.0 - np.exp(-n * dt / tau), rtol=0, atol=1e-12)
    x = np.sin(np.linspace(0, 20, 2000)) + 0.1 * np.random.default_rng(0).standard_normal(2000)
    np.testing.assert_allclose(_core.lag(_core.lead(x, tau, dt), tau, dt), x, rtol=0, atol=1e-11)
    # No lag: a copy; starting at rest at x[0] by default.
    np.testing.assert_array_equal(_core.lag(x, 0.0, dt), x)
    assert _core.lag([2.0, 2.0], tau, dt)[0] == 2.0


def test_delay_holds_the_fill_value_before_the_start():
    x = np.arange(6.0)
    np.testing.assert_array_equal(_core.delay(x, 0.002, 1e-3), [0, 0, 0, 1, 2, 3])
    np.testing.assert_array_equal(_core.delay(x, 0.002, 1e-3, fill=-1.0), [-1, -1, 0, 1, 2, 3])
    np.testing.assert_array_equal(_core.delay(x, 10.0, 1e-3, fill=7.0), np.full(6, 7.0))
    np.testing.assert_array_equal(_core.delay(x, 0.0, 1e-3), x)


def test_heating_state_matches_the_plants_thermal_drift():
    """The plant's thermal gain is ``1 - gain_loss * heating_state(coil currents)``: recover it exactly."""
    rate, loss, tau = 1000.0, 0.3, 0.5
    over = {"sensor.noise_n": 0.0, "full_current_a": 1.1}
    act = bmr.VirtualActuator("ideal", sample_rate_hz=rate, overrides=over,
                              effects={"thermal_drift": {"gain_loss": loss, "tau_s": tau}})
    ref = bmr.VirtualActuator("ideal", sample_rate_hz=rate, overrides=over)
    cur = 1.2 * np.sin(np.linspace(0, 12, 3000))
    a, b = act.run(cur), ref.run(cur)
    x = b["field_torque_nmm"]
    ok = np.abs(x) > 10.0
    gain = a["field_torque_nmm"][ok] / x[ok]
    heat = _core.heating_state(np.hypot(a["coil1_a"], a["coil2_a"]), tau, 1.0 / rate, 1.1)
    np.testing.assert_allclose(gain, 1.0 - loss * heat[ok], rtol=1e-9)


@pytest.mark.parametrize("call", [
    lambda: _core.lag([1.0], -1.0, 1e-3),
    lambda: _core.lead([1.0], 0.1, 0.0),
    lambda: _core.delay([1.0], math.nan, 1e-3),
    lambda: _core.heating_state([1.0], 1.0, 1e-3, 0.0),
    lambda: _core.leak_integral([1.0], 1e-3, -0.1),
    lambda: _core.leak_integral([1.0], 0.0),
])
def test_bad_parameters_are_bmr_errors(call):
    with pytest.raises(bmr.BmrError):
        call()
