"""Compensator through the Python API: exact inverse tracking, paper inverse measured, safety, friction."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import bmr
from preisach_plant import first_order_curves


@pytest.fixture(scope="module")
def hyst():
    asc, desc = first_order_curves(60, 13)
    scale = lambda fam: [(1.25 * u, y) for u, y in fam]  # noqa: E731  ±1.25 A, ±300 N·mm
    return bmr.Hysteresis.from_curves(scale(asc), scale(desc))


@pytest.fixture(scope="module")
def friction():
    return bmr.Friction.from_amplitude_phase(12.0, [25.0, 8.0, 4.0], [0.3, 1.1, -0.7])


def multipeak(n, seed=0):
    rng = np.random.default_rng(seed)
    knots = rng.uniform(-250, 250, n // 200 + 2)
    return np.interp(np.arange(n), np.linspace(0, n, len(knots)), knots)


def test_exact_inverse_reproduces_reference_through_the_model(hyst, friction):
    c = bmr.Compensator(hyst, friction)
    ref = multipeak(20000)
    theta = np.linspace(0, 40 * np.pi, ref.size)
    out = c.run(ref, theta)
    assert np.max(np.abs(out["model_torque_nmm"] - ref)) < 1e-9 * 600
    assert not out["saturated"].any() and not out["fault"].any()


def test_paper_inverse_is_measured_against_exact(hyst, friction):
    ref = multipeak(20000, seed=1)
    theta = np.linspace(0, 40 * np.pi, ref.size)
    plant = bmr.Hysteresis.from_curves(*hyst.curves())
    errs = {}
    for inv in ("exact", "paper"):
        c = bmr.Compensator(hyst, friction, inverse=inv)
        cur = c.run(ref, theta)["current_a"]
        plant.reset()
        torque = plant.run(cur) + friction(theta)
        errs[inv] = float(np.sqrt(np.mean((torque - ref) ** 2)))
    assert errs["exact"] < 1e-6
    assert math.isfinite(errs["paper"]) and errs["paper"] > errs["exact"]


def test_step_matches_run_and_snapshot_replays(hyst, friction):
    a = bmr.Compensator(hyst, friction)
    b = bmr.Compensator(hyst, friction)
    ref = multipeak(2000, 3)
    th = np.linspace(0, 6, 2000)
    run = a.run(ref, th)
    steps = [b.step(r, t) for r, t in zip(ref, th)]
    assert np.array_equal(run["current_a"], [s.current_a for s in steps])
    s = b.snapshot()
    first = [b.step(r, 0.1).current_a for r in ref[:300]]
    b.restore(s)
    assert first == [b.step(r, 0.1).current_a for r in ref[:300]]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-700, 700)),
                          st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-10, 10))),
                min_size=1, max_size=40),
       st.sampled_from(["exact", "paper"]), st.floats(0.1, 2.0))
def test_safety_invariants(hyst, friction, seq, inverse, limit):
    c = bmr.Compensator(hyst, friction, inverse=inverse, current_limit=limit)
    for r, th in seq:
        cmd = c.step(r, th)
        assert cmd.coil1_a == 0.0 or cmd.coil2_a == 0.0
        assert abs(cmd.current_a) <= limit
        assert math.isclose(cmd.volt1_v * 0.125, cmd.coil1_a) and math.isclose(cmd.volt2_v * 0.125, cmd.coil2_a)
        if not (math.isfinite(r) and math.isfinite(th)):
            assert cmd.fault and cmd.current_a == 0.0
        assert c.hysteresis.input == cmd.current_a


def test_bad_arguments(hyst):
    with pytest.raises(bmr.BmrError, match="inverse"):
        bmr.Compensator(hyst, inverse="magic")
    with pytest.raises(bmr.BmrError, match="converter gain"):
        bmr.Compensator(hyst, converter_gain=0)
    with pytest.raises(bmr.BmrError, match="current limit"):
        bmr.Compensator(hyst, current_limit=-1)
    with pytest.raises(bmr.BmrError, match="samples"):
        bmr.Compensator(hyst).run([1.0, 2.0], [0.0])


def test_friction_vectorised_and_amplitude_phase_round_trip(friction):
    th = np.linspace(-10, 10, 1001)
    closed = 12 + 25 * np.sin(th + 0.3) + 8 * np.sin(2 * th + 1.1) + 4 * np.sin(3 * th - 0.7)
    assert np.allclose(friction(th), closed, atol=1e-9)
    assert friction(0.7) == friction(np.array([0.7]))[0]
    amp, ph = friction.amplitude_phase()
    assert np.allclose(amp, [25, 8, 4]) and np.allclose(ph, [0.3, 1.1, -0.7])
    f2 = bmr.Friction(friction.c0, friction.a, friction.b)
    assert np.array_equal(f2(th), friction(th))
    with pytest.raises(bmr.BmrError, match=f"at most {bmr._core.FRICTION_MAX_ORDER}"):
        bmr.Friction(0, [1.0] * (bmr._core.FRICTION_MAX_ORDER + 1), [])
    with pytest.raises(bmr.BmrError):
        bmr.Friction.from_amplitude_phase(0, [1.0], [])
