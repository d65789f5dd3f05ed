"""bmr.Controller from Python: built from a model file, stepped, its design, dropouts to a fault, copies and
pickles bit for bit, errors; bmr.simulate_closed_loop against stepping by hand; and (slow tier) the closed loop
on a virtual actuator with a heating the model never saw, against the open-loop extended compensator."""
from __future__ import annotations

import copy
import math
import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest

import bmr

REPO = Path(__file__).resolve().parents[3]
MODEL = REPO / "tests" / "data" / "extended_model.json"
DT_S = 0.002


def reference(n: int) -> np.ndarray:
    t = np.arange(n) * DT_S
    return 150 * np.sin(1.3 * t) + 30 * np.sin(3.1 * t)


def plant() -> bmr.VirtualActuator:
    return bmr.VirtualActuator("rig_preisach", seed=3, sample_rate_hz=1 / DT_S)


def drive(ctl: bmr.Controller, act: bmr.VirtualActuator, n: int, drop: int = 0) -> list[bmr.Command]:
    """Step ``ctl`` on ``act``; every ``drop``-th measurement missing."""
    ref = reference(n)
    out, y = [], math.nan
    for i in range(n):
        c = ctl.step(float(ref[i]), 0.004 * i, math.nan if drop and i % drop == 0 else y)
        out.append(c)
        y = act.step(c.current_a).torque_nmm
    return out


def test_from_model_reports_its_design_and_steps_within_the_limit():
    ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S)
    d = ctl.design
    assert d.dt_s == DT_S and d.delay_samples == 3
    assert d.loop_delay_s == pytest.approx(4.5 * DT_S)
    assert 60.0 <= d.phase_margin_deg < 90.0
    assert d.ki_per_s == pytest.approx(2 * math.pi * d.bandwidth_hz)
    assert d.coil_lag_s == pytest.approx(0.015)
    cmds = drive(ctl, plant(), 3000)
    assert all(abs(c.current_a) <= 1.25 and (c.coil1_a == 0 or c.coil2_a == 0) for c in cmds)
    assert not any(c.fault for c in cmds)
    assert "Controller(" in repr(ctl) and "phase_margin_deg" in repr(d)


def test_a_bandwidth_asked_for_is_given_or_refused():
    ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S, bandwidth_hz=4.0)
    assert ctl.design.bandwidth_hz == pytest.approx(4.0) and ctl.design.asked_hz == 4.0
    assert "asked_hz=4" in repr(ctl.design)
    assert ctl.design.phase_margin_deg == pytest.approx(90 - math.degrees(2 * math.pi * 4.0 * 4.5 * DT_S))
    with pytest.raises(bmr.BmrError, match="phase margin"):
        bmr.Controller.from_model(MODEL, dt_s=DT_S, bandwidth_hz=50.0)
    for bad in ({"fault_after": 0}, {"noise_share": 2.0}, {"adaptation_time_s": 0.0},
                {"correction_limit_nmm": math.inf}, {"bandwidth_hz": math.nan}):
        with pytest.raises(bmr.BmrError):
            bmr.Controller.from_model(MODEL, dt_s=DT_S, **bad)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = bmr.Model.load(MODEL)
    plain = bmr.Compensator(base.compensator(DT_S).hysteresis)
    with pytest.raises(bmr.BmrError, match="dt_s"):
        bmr.Controller(plain)
    with pytest.raises(TypeError):
        bmr.Controller("not a compensator")  # type: ignore[arg-type]


def test_missing_measurements_fault_after_the_count_and_the_loop_resumes():
    ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S, fault_after=3)
    for _ in range(2):
        assert not ctl.step(50.0, 0.0, math.nan).fault
    assert ctl.missing_samples == 2
    c = ctl.step(50.0, 0.0, math.inf)
    assert c.fault and c.current_a == 0.0
    assert ctl.step(50.0, 0.0, 40.0).fault is False and ctl.missing_samples == 0


def test_adaptation_finds_a_hidden_sensor_gain_freezes_and_resets():
    # The plant is the model's own hysteresis, read through a sensor 20 % weak: the adapted gain must find 0.8.
    h = bmr.Compensator.from_model(MODEL, dt_s=DT_S).hysteresis
    ctl = bmr.Controller(bmr.Compensator(h), dt_s=DT_S)
    core = copy.copy(h)
    ref = reference(8000)
    y = math.nan
    for i in range(ref.size):
        c = ctl.step(float(ref[i]), 0.0, y)
        y = 0.8 * core.step(c.current_a) + 2.0
    assert ctl.gain == pytest.approx(0.8, abs=0.005)
    assert ctl.offset_nmm == pytest.approx(2.0, abs=0.5)
    ctl.freeze_adaptation()
    g = ctl.gain
    drive(ctl, plant(), 500)
    assert ctl.adaptation_frozen and ctl.gain == g
    ctl.reset_adaptation()
    assert (ctl.gain, ctl.offset_nmm) == (1.0, 0.0)


def test_copies_pickles_and_snapshots_continue_bit_for_bit():
    ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S, fault_after=4)
    act = plant()
    drive(ctl, act, 700, drop=9)
    snap, at = ctl.snapshot(), copy.copy(act)
    twins = [copy.copy(ctl), copy.deepcopy(ctl), pickle.loads(pickle.dumps(ctl))]
    first = drive(ctl, act, 600, drop=7)
    for t in twins:
        assert drive(t, copy.copy(at), 600, drop=7) == first
    ctl.restore(snap)
    assert drive(ctl, copy.copy(at), 600, drop=7) == first
    # Another controller's snapshot is refused.
    other = bmr.Controller(bmr.Compensator(ctl.compensator.hysteresis), dt_s=DT_S)
    with pytest.raises(bmr.TableError):
        other.restore(snap)


def fields(c: bmr.Command) -> tuple:
    return (c.current_a, c.coil1_a, c.coil2_a, c.volt1_v, c.volt2_v, c.saturated, c.fault)


@pytest.mark.parametrize("make", ["controller", "compensator"])
def test_commands_handed_out_again_never_change_under_a_holder(make):
    """A step writes its command into an object only this loop still holds: commands kept (the last one, or all of
    them) keep their values, and whatever the caller keeps, every step gives the same values."""
    comp = bmr.Compensator.from_model(MODEL, dt_s=DT_S)
    ref = reference(400)
    if make == "controller":
        ctls = [bmr.Controller(copy.copy(comp), dt_s=DT_S) for _ in range(3)]
        steps = [lambda i, c=c: c.step(float(ref[i]), 0.004 * i, 0.9 * float(ref[i - 1]) if i else math.nan)
                 for c in ctls]
    else:
        comps = [copy.copy(comp) for _ in range(3)]
        steps = [lambda i, c=c: (c.step if i % 2 else c.step_ahead)(float(ref[i]), 0.004 * i) for c in comps]
    kept_all, values_all = [], []
    prev, prev_values, values_last = None, None, []
    values_dropped = []
    for i in range(ref.size):
        c = steps[0](i)
        kept_all.append(c)
        values_all.append(fields(c))
        if prev is not None:
            assert fields(prev) == prev_values  # the previous command, still held, is untouched
        prev = steps[1](i)
        prev_values = fields(prev)
        values_last.append(prev_values)
        values_dropped.append(fields(steps[2](i)))  # dropped at once: its object is written again
    assert [fields(c) for c in kept_all] == values_all
    assert len({id(c) for c in kept_all}) == ref.size
    assert values_all == values_last == values_dropped
    assert len({v[0] for v in values_all}) > 100  # the commands do vary


def test_simulate_closed_loop_is_stepping_by_hand():
    ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S)
    act = plant()
    ref = reference(1500)
    ctl2, plant2 = copy.copy(ctl), copy.copy(act)
    run = bmr.simulate_closed_loop(ctl, act, ref)
    assert isinstance(run, bmr.ClosedLoopRun)
    theta = plant2.theta_ahead(ref.size)
    y, torque, current = math.nan, [], []
    for i in range(ref.size):
        c = ctl2.step(float(ref[i]), float(theta[i]), y)
        y = plant2.step(c.current_a).torque_nmm
        torque.append(y)
        current.append(c.current_a)
    np.testing.assert_array_equal(run.torque_nmm, torque)
    np.testing.assert_array_equal(run.current_a, current)
    np.testing.assert_array_equal(run.reference_nmm, ref)
    assert run.gain[-1] == ctl.gain and run.saturated.dtype == bool
    assert run.tracking_rms_nmm() == pytest.approx(float(np.sqrt(np.mean((np.array(torque) - ref) ** 2))))
    with pytest.raises(bmr.BmrError, match="theta_rad"):
        bmr.simulate_closed_loop(ctl, act, ref, theta[:10])


def test_simulate_closed_loop_writes_every_column_of_every_sample():
    """Every column, of a reference given as a contiguous array, a strided view and a list, equals stepping by
    hand (the columns are written into arrays that start uninitialised)."""
    base = reference(1201)
    for ref in (base, np.repeat(base, 2)[::2], base.tolist()):
        ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S)
        act = plant()
        ctl2, plant2 = copy.copy(ctl), copy.copy(act)
        run = bmr.simulate_closed_loop(ctl, act, ref)
        theta = plant2.theta_ahead(len(ref))
        y = math.nan
        want: dict[str, list] = {k: [] for k in ("t_s", "torque_nmm", "torque_true_nmm", "current_a",
                                                  "correction_nmm", "gain", "offset_nmm", "saturated", "fault")}
        for i in range(len(ref)):
            c = ctl2.step(float(base[i]), float(theta[i]), y)
            s = plant2.step(c.current_a)
            y = s.torque_nmm
            for k, v in (("t_s", s.t_s), ("torque_nmm", y), ("torque_true_nmm", s.torque_true_nmm),
                         ("current_a", c.current_a), ("correction_nmm", ctl2.correction_nmm), ("gain", ctl2.gain),
                         ("offset_nmm", ctl2.offset_nmm), ("saturated", c.saturated), ("fault", c.fault)):
                want[k].append(v)
        for k, v in want.items():
            np.testing.assert_array_equal(getattr(run, k), np.array(v), err_msg=k)
        np.testing.assert_array_equal(run.reference_nmm, base)
        assert run.reference_nmm.dtype == np.float64 and run.reference_nmm.flags.c_contiguous


@pytest.mark.slow
def test_closed_loop_beats_the_open_loop_extended_compensator_on_a_heating_plant(tmp_path):
    from bmr.diagnosis.procedure import diagnose
    from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle
    from bmr.simulation.experiments import MULTIPEAK_SEED, ramp_path, reference_multipeak

    lag = {"coil_lag": dict(MEDIUM_EFFECTS["coil_lag"])}
    bundle = diagnosis_bundle("rig_preisach", effects=lag, seed=0)
    fs = bundle.sample_rate_hz
    d = diagnose(bundle, progress=False)
    path = d.extended_model.save(tmp_path / "extended.json")
    body = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, duration_s=40.0)
    opening = ramp_path(0.0, [1000.0, -1000.0, body[0]], 400.0 / fs)
    ref = np.concatenate([opening, body])

    def heating_plant() -> bmr.VirtualActuator:
        return bmr.VirtualActuator("rig_preisach", seed=1, sample_rate_hz=fs,
                                   effects={**lag, "thermal_drift": {"gain_loss": 0.1, "tau_s": 60.0}})

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        comp = bmr.Compensator.from_model(path, dt_s=1 / fs)
        act = heating_plant()
        e = act.run(comp.run(ref, act.theta_ahead(ref.size))["current_a"])["torque_nmm"] - ref
        open_rms = float(np.sqrt(np.mean(e[opening.size:] ** 2)))
        ctl = bmr.Controller.from_model(path, dt_s=1 / fs)
    run = bmr.simulate_closed_loop(ctl, heating_plant(), ref)
    closed_rms = run.tracking_rms_nmm(opening.size)
    assert np.all(np.abs(run.current_a) <= comp.current_limit)
    assert closed_rms < 2.0 and closed_rms < 0.8 * open_rms, (closed_rms, open_rms)
