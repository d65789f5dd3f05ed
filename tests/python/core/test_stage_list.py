"""The vocabulary drives every stage list: pickles, copies and snapshots of a compensator with any stage continue
bit for bit, the ``stages`` getter names every stage that is on, and a stage that keeps time needs ``dt_s``."""
from __future__ import annotations

import copy
import functools
import pickle
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import bmr
from bmr import _core

# Sizes that make each stage act visibly on the 2 ms loop below (parameters documented in bmr.effect_parameters()).
SIZES: dict[str, dict[str, float]] = {
    "coil_lag": {"tau_s": 0.02},
    "time_delay": {"delay_s": 0.01},
    "thermal_drift": {"gain_loss": 0.1, "tau_s": 5.0},
    "torque_ripple": {"eps": 0.05},
    "non_congruent": {"curvature": 1.0},
    "friction_current": {"gain_per_a": 0.6},
    "friction_harmonics": {"order": 5.0, "amplitude_nmm": 6.0},
    "creep": {"fraction": 0.1, "tau_min_s": 0.01, "tau_max_s": 10.0},
    "rate_dependence": {"tau_s": 0.01},
    "accommodation": {"kappa": 0.2, "cycles": 2.0},
    "viscous": {"c": 2.0},
}
DT_S = 0.002
MODEL = Path(__file__).resolve().parents[2] / "data" / "extended_model.json"


@functools.cache
def _hysteresis() -> bmr.Hysteresis:
    return bmr.Model.load(MODEL).hysteresis


@pytest.fixture(scope="module")
def hysteresis() -> bmr.Hysteresis:
    return _hysteresis()


def _reference(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT_S
    r = 200.0 * np.sin(2 * np.pi * 3.0 * t) * np.exp(-t) + 20.0 * rng.standard_normal(n)
    return r, (5.0 * t) % (2 * np.pi)


def _compensator(h: bmr.Hysteresis, names: list[str]) -> bmr.Compensator:
    return bmr.Compensator(h, extensions=[(n, SIZES[n]) for n in names], dt_s=DT_S)


def test_every_in_loop_effect_has_a_size_here() -> None:
    effects = {n for n in _core.LOOP_STAGES if n in bmr.EFFECTS}
    assert effects == set(SIZES), "a new stage: give it a size here so the pickle checks cover it"


@pytest.mark.parametrize("name", ["creep", "rate_dependence", "accommodation", "viscous"])
def test_pickled_mid_run_continues_bit_for_bit(hysteresis: bmr.Hysteresis, name: str) -> None:
    c = _compensator(hysteresis, [name])
    r, th = _reference(1500, 3)
    c.run(r[:1000], th[:1000])
    back = pickle.loads(pickle.dumps(c))
    a = c.run(r[1000:], th[1000:])["current_a"]
    b = back.run(r[1000:], th[1000:])["current_a"]
    assert a.tobytes() == b.tobytes(), f"{name}: up to {np.abs(a - b).max():.3g} A apart"


@settings(max_examples=25, deadline=None)
@given(which=st.sets(st.sampled_from(sorted(SIZES)), min_size=1), split=st.integers(1, 700),
       seed=st.integers(0, 2**16), how=st.sampled_from(["pickle", "copy", "snapshot", "state_pickle"]))
def test_any_stages_continue_bit_for_bit(which: set[str], split: int, seed: int, how: str) -> None:
    h = _hysteresis()
    c = _compensator(h, sorted(which))
    r, th = _reference(split + 300, seed)
    c.run(r[:split], th[:split])
    if how == "pickle":
        other = pickle.loads(pickle.dumps(c))
    elif how == "copy":
        other = copy.deepcopy(c)
    else:
        snap = c.snapshot()
        other = _compensator(h, sorted(which))
        other.restore(pickle.loads(pickle.dumps(snap)) if how == "state_pickle" else snap)
    a = c.run(r[split:], th[split:])
    b = other.run(r[split:], th[split:])
    for col in ("current_a", "model_torque_nmm"):
        assert a[col].tobytes() == b[col].tobytes(), (sorted(which), how, col)


def test_stages_getter_names_every_stage_in_loop_order(hysteresis: bmr.Hysteresis) -> None:
    c = _compensator(hysteresis, sorted(SIZES))
    assert c.stages == [n for n in _core.LOOP_STAGES if n in SIZES]
    for name in SIZES:
        assert _compensator(hysteresis, [name]).stages == [name]


@pytest.mark.parametrize("name", sorted(SIZES))
def test_a_stage_that_keeps_time_refuses_to_be_built_without_dt(hysteresis: bmr.Hysteresis, name: str) -> None:
    needs = bmr.effect_parameters()[name]["needs_period"]
    assert needs == (name in _core.PERIOD_EFFECTS)
    if needs:
        with pytest.raises(bmr.BmrError, match=f"{name}.*need dt_s"):
            bmr.Compensator(hysteresis, extensions=[(name, SIZES[name])])
    else:
        assert bmr.Compensator(hysteresis, extensions=[(name, SIZES[name])]).stages == [name]


def test_creep_without_dt_is_an_error_not_a_one_second_period(hysteresis: bmr.Hysteresis) -> None:
    with pytest.raises(bmr.BmrError, match="dt_s"):
        bmr.Compensator(hysteresis, extensions=[("creep", {"fraction": 0.05})])


def test_python_lists_come_from_the_vocabulary() -> None:
    from bmr.diagnosis.effects import ANGLE_EFFECTS, LIBRARY, PHYSICAL
    from bmr.identification.model import LOOP_STAGES

    params = bmr.effect_parameters(model_entries=True)
    ordered = sorted((v["loop_order"], k) for k, v in params.items() if v["loop_order"] is not None)
    assert LOOP_STAGES == tuple(k for _, k in ordered)
    assert set(ANGLE_EFFECTS) == {k for k, v in params.items() if v["on_angle"]}
    assert set(PHYSICAL) == {e.name for e in LIBRARY} & set(bmr.EFFECTS)
    assert all(e.needs_angle == (e.name in ANGLE_EFFECTS) for e in LIBRARY)
