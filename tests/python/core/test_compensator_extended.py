"""The extended compensator from Python: model file → Compensator.from_model → step/run, the stages it says are
on, allocation-free paths, copies and pickles, errors, and the in-use error of a compensator inside run()."""
from __future__ import annotations

import copy
import math
import pickle
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

import bmr

REPO = Path(__file__).resolve().parents[3]
MODEL = REPO / "tests" / "data" / "extended_model.json"
DT_S = 0.002


def reference(n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * DT_S
    opening = np.concatenate([np.linspace(0, 1500, 300), np.linspace(1500, -1500, 600), np.linspace(-1500, 0, 300)])
    return (np.concatenate([opening, 150 * np.sin(1.3 * t) + 30 * np.sin(3.1 * t)])[:n],
            np.mod(2.0 * t, 2 * np.pi))


def test_a_model_file_gives_the_full_extended_compensator(tmp_path):
    ref, th = reference()
    m = bmr.Model.load(MODEL)
    ext = bmr.Compensator.from_model(MODEL, dt_s=DT_S)
    assert ext.stages == ["time_delay", "coil_lag", "non_congruent", "thermal_drift", "torque_ripple",
                          "friction_harmonics", "friction_current"]
    assert ext.preview_samples == 3 and ext.dt_s == DT_S
    a = ext.run(ref, th)["current_a"]
    # From the Model object, from a saved copy, and by hand from the parts: the same bits.
    b = m.compensator(DT_S).run(ref, th)["current_a"]
    c = bmr.Compensator.from_model(m.save(tmp_path / "m.json"), dt_s=DT_S).run(ref, th)["current_a"]
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)
    # The extensions are not ignored: the nominal compensator commands other currents.
    nominal = m.compensator(stages=[]).run(ref, th)["current_a"]
    assert np.max(np.abs(a - nominal)) > 0.05
    with pytest.raises(bmr.BmrError, match="dt_s"):
        m.compensator()


def test_the_extended_compensator_inverts_the_extended_simulation():
    """Driven through the model's own extended simulation, the extended compensator tracks the reference; the
    nominal one does not."""
    ref, th = reference(6000)
    m = bmr.Model.load(MODEL)
    from bmr.diagnosis.extended_model import ExtendedModel

    sim = ExtendedModel(m)
    errs = {}
    for name, comp in (("extended", m.compensator(DT_S)), ("nominal", m.compensator(stages=[]))):
        cur = comp.run(ref, th)["current_a"]
        torque = sim.simulate(cur, th, dt_s=DT_S, measured=False)
        errs[name] = float(np.sqrt(np.mean((torque[2000:] - ref[2000:]) ** 2)))
    assert errs["extended"] < 0.5 < errs["nominal"] / 10, errs


def test_stage_plan_says_why_and_warns_about_stages_that_hurt():
    m = bmr.Model.load(MODEL)
    content = m.to_dict()
    for e in content["extensions"]:
        if e["name"] == "coil_lag":
            e["tracking"] = {"ratio": 1.22, "plant": "simulator"}
            e["in_loop"] = False
        if e["name"] == "time_delay":
            e["tracking"] = {"ratio": 0.6, "plant": "simulator"}
    hurt = bmr.Model.from_dict(content)
    plan = {r["name"]: r for r in hurt.stage_plan()}
    assert not plan["coil_lag"]["on"] and "worse" in plan["coil_lag"]["reason"] and "1.22" in plan["coil_lag"]["reason"]
    assert plan["time_delay"]["on"] and "0.60" in plan["time_delay"]["reason"]
    with pytest.warns(UserWarning, match="coil_lag.*worse"):
        comp = hurt.compensator(DT_S)
    assert "coil_lag" not in comp.stages and "time_delay" in comp.stages
    with pytest.warns(UserWarning, match="coil_lag is in the loop although"):
        assert "coil_lag" in hurt.compensator(DT_S, stages="all").stages
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert hurt.compensator(DT_S, stages=["time_delay"]).stages == ["time_delay"]
    with pytest.raises(bmr.BmrError, match="not among"):
        hurt.compensator(DT_S, stages=["creep"])


def test_model_files_with_unknown_or_bad_extensions_fail_at_load(tmp_path):
    content = bmr.Model.load(MODEL).to_dict()
    for ext, message in (([{"name": "flux_capacitor", "params": {}}], "flux_capacitor"),
                         ([{"name": "coil_lag", "params": {"tau_s": -1.0}}], "outside"),
                         ([{"name": "coil_lag", "params": {"tau": 0.1}}], "its parameters: tau_s")):
        with pytest.raises(bmr.BmrError, match=message):
            bmr.Model.from_dict({**content, "extensions": ext})


def test_step_into_and_run_columns_write_preallocated_arrays():
    m = bmr.Model.load(MODEL)
    ref, th = reference(3000)
    a, b = m.compensator(DT_S), m.compensator(DT_S)
    full = a.run(ref, th)
    out = {"current_a": np.empty(ref.size), "fault": np.empty(ref.size, dtype=bool)}
    got = b.run(ref, th, columns=["current_a", "fault"], out=out)
    assert got["current_a"] is out["current_a"] and set(got) == {"current_a", "fault"}
    np.testing.assert_array_equal(out["current_a"], full["current_a"])
    np.testing.assert_array_equal(out["fault"], full["fault"])
    with pytest.raises(bmr.BmrError, match="unknown column"):
        a.run(ref, th, columns=["torque"])
    with pytest.raises(bmr.BmrError, match="elements"):
        a.run(ref, th, columns=["current_a"], out={"current_a": np.empty(3)})
    # step_into: the Command fields in a float array, the current returned.
    c1, c2 = m.compensator(DT_S), m.compensator(DT_S)
    buf = np.empty(7)
    for r, t in zip(ref[:500], th[:500]):
        cmd = c1.step(r, t)
        assert c2.step_into(r, t, buf) == cmd.current_a
        assert list(buf) == [cmd.current_a, cmd.coil1_a, cmd.coil2_a, cmd.volt1_v, cmd.volt2_v,
                             float(cmd.saturated), float(cmd.fault)]
    with pytest.raises(bmr.BmrError, match="7 elements"):
        c2.step_into(0.0, 0.0, np.empty(3))


def test_nan_intermediates_and_extreme_parameters():
    h = bmr.Model.load(MODEL).hysteresis
    # The reproducer: a friction series that overflows is refused where it is made.
    with pytest.raises(bmr.BmrError, match="finitely"):
        bmr.Friction(0, [1.7e308, 0, -1.7e308], [1.7e308, 0, 1.7e308])
    with pytest.raises(bmr.BmrError, match="converter gain"):
        bmr.Compensator(h, converter_gain=5e-324)
    c = bmr.Compensator(h, bmr.Friction(-1e300))
    cmd = c.step(1.7976931348623157e308, math.pi / 4)
    assert cmd.fault and cmd.current_a == 0.0
    for bad in (math.nan, math.inf):
        cmd = c.step(bad, 0.0)
        assert cmd.fault and cmd.current_a == 0.0 and cmd.volt1_v == cmd.volt2_v == 0.0
    with pytest.raises(bmr.BmrError, match="friction_current"):
        bmr.Compensator(h, bmr.Friction(1.0, [2.0], [0.0], gain_per_a=0.5))


def test_copies_and_pickles_continue_bit_for_bit():
    m = bmr.Model.load(MODEL)
    ref, th = reference(2000)
    c = m.compensator(DT_S)
    c.run(ref[:1500], th[:1500])
    d = copy.copy(c)
    e = copy.deepcopy(c)
    rest = [c.step(r, t).current_a for r, t in zip(ref[1500:], th[1500:])]
    assert [d.step(r, t).current_a for r, t in zip(ref[1500:], th[1500:])] == rest
    assert [e.step(r, t).current_a for r, t in zip(ref[1500:], th[1500:])] == rest
    # Pickled (to a worker process, say): the parts and the state, every stage included.
    c.run(ref[:1500], th[:1500])
    p = pickle.loads(pickle.dumps(c))
    rest = [c.step(r, t).current_a for r, t in zip(ref[1500:], th[1500:])]
    assert [p.step(r, t).current_a for r, t in zip(ref[1500:], th[1500:])] == rest
    assert p.stages == c.stages and p.dt_s == c.dt_s
    # A pickled snapshot restores into the compensator (or a copy), not into one with other stages.
    s = pickle.loads(pickle.dumps(c.snapshot()))
    a = [c.step(r, t).current_a for r, t in zip(ref[:300], th[:300])]
    c.restore(s)
    assert [c.step(r, t).current_a for r, t in zip(ref[:300], th[:300])] == a
    with pytest.raises(bmr.BmrError):
        m.compensator(DT_S, stages=["coil_lag"]).restore(s)
    f = bmr.Friction(12.0, [25.0, 8.0], [1.0, -2.0], gain_per_a=0.3)
    assert pickle.loads(pickle.dumps(f)) == f and copy.copy(f) == f
    cmd = c.step(100.0, 0.3)
    assert pickle.loads(pickle.dumps(cmd)) == cmd and copy.deepcopy(cmd) == cmd


def test_a_compensator_inside_run_on_another_thread_says_it_is_in_use():
    h = bmr.Model.load(MODEL).hysteresis
    c = bmr.Compensator(h)
    n = 3_000_000
    ref = 200 * np.sin(np.linspace(0, 200, n))
    th = np.linspace(0, 100, n)
    seen = []
    started = threading.Event()

    def other():
        started.wait()
        for _ in range(2000):
            try:
                c.step(1.0, 0.0)
            except bmr.BmrError as exc:
                seen.append(str(exc))
                return

    t = threading.Thread(target=other)
    t.start()
    started.set()
    for _ in range(5):
        c.run(ref, th)
        if seen:
            break
    t.join()
    assert seen and "in use by another thread" in seen[0], seen
