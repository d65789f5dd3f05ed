"""A transport delay next to a coil lag: both shift ramps by their time, so the one fitted first takes the other's
shift of ramps too; only steps tell them apart. The newcomer keeps the sum of the two (``CoilLag.apply``,
``TimeDelay.apply``) and the two are then searched together (``selection._retune_timing``): the paper's actuator,
whose coils lag by themselves, with a delay hidden in it gets both named at their own values, not the delay
stretched and the lag's approach after steps named creep."""
from __future__ import annotations

import pytest

import bmr
from bmr.diagnosis.effects import PHYSICAL
from bmr.simulation.excitation import separating_run
from bmr.simulation.experiments import simulate_bundle


def _named(d) -> dict[str, dict[str, float]]:
    return {e["name"]: e["params"] for e in d.effects if e["name"] in PHYSICAL}


@pytest.fixture(scope="module")
def own_lag_s() -> float:
    """The coil lag the clean quick set of the paper's actuator is diagnosed with (its coils' own)."""
    d = bmr.diagnose(simulate_bundle("bmr2013", seed=1, quick=True), progress=False, closed_loop=False)
    named = _named(d)
    assert list(named) == ["coil_lag"], named
    return named["coil_lag"]["tau_s"]


@pytest.mark.slow
@pytest.mark.parametrize(("delay_s", "separate"), [(0.02, ()), (0.02, ("dwell",)), (0.05, ())])
def test_a_delay_is_named_next_to_the_actuators_own_coil_lag(own_lag_s, delay_s, separate):
    bundle = simulate_bundle("bmr2013", effects={"time_delay": {"delay_s": delay_s}}, seed=1, quick=True,
                             extra_runs=[separating_run(k, quick=True) for k in separate])
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    named = _named(d)
    assert sorted(named) == ["coil_lag", "time_delay"], named
    dt = 1.0 / bundle.sample_rate_hz
    assert abs(named["time_delay"]["delay_s"] - delay_s) <= dt + 1e-9, named
    assert abs(named["coil_lag"]["tau_s"] - own_lag_s) <= 0.2 * own_lag_s, (named, own_lag_s)
