"""Physics sanity and calibration of the virtual actuator presets."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.simulation import experiments as ex

FULL = 1.25


def _ramp(start, vertices, rate_a_per_s, fs):
    return ex.ramp_path(start, vertices, rate_a_per_s / fs)


def _major_loop(preset="bmr2013", fs=500.0, rate=0.05, effects=None):
    """Opening, then one slow major loop −F → +F → −F; returns (current, field torque) of the loop."""
    act = bmr.VirtualActuator(preset, seed=1, sample_rate_hz=fs, effects=effects)
    act.run(np.concatenate([ex.opening_path(fs), _ramp(0.0, [-FULL], 0.5, fs)]))
    loop = _ramp(-FULL, [FULL, -FULL], rate, fs)
    out = act.run(loop)
    return loop, out


def test_bmr2013_torque_range_matches_the_paper():
    loop, out = _major_loop()
    t = out["field_torque_nmm"]
    t_pos, t_neg = t[np.argmax(loop)], t[np.argmin(loop)]
    # Paper: ±1.25 A → about ±600 N·mm.
    assert 540.0 < t_pos < 660.0, t_pos
    assert -660.0 < t_neg < -540.0, t_neg
    # The measured torque includes seal friction and noise but stays in the sensor range.
    assert np.max(np.abs(out["torque_nmm"])) < 720.0


def test_bmr2013_off_state_friction_band():
    act = bmr.VirtualActuator("bmr2013", seed=2, sample_rate_hz=500.0)
    theta = np.linspace(0.0, 2 * np.pi, 721)
    f = act.true_friction(theta)
    # Figs 11-12: about −20…50 N·mm over a revolution.
    assert -25.0 < f.min() < -15.0 and 45.0 < f.max() < 55.0, (f.min(), f.max())
    run = ex.off_state(act, duration_s=10.0)
    body = run.data[run.data.t_s >= run.meta["opening_end_s"]]
    measured = body.torque_nmm.to_numpy()
    expected = act.true_friction(body.theta_rad.to_numpy())
    # Measured off-state torque = friction + remanence torque (tiny) + sensor noise (1.5 N·mm).
    resid = measured - expected
    assert abs(resid.mean()) < 2.0
    assert 1.0 < resid.std() < 2.5


def test_bmr2013_loop_width_like_figs_14_15():
    loop, out = _major_loop()
    t = out["field_torque_nmm"]
    top = int(np.argmax(loop))
    up_i, up_t = loop[: top + 1], t[: top + 1]
    dn_i, dn_t = loop[top:][::-1], t[top:][::-1]
    grid = np.linspace(-1.0, 1.0, 41)
    width = np.interp(grid, dn_i, dn_t) - np.interp(grid, up_i, up_t)
    assert np.all(width[np.abs(grid) > 0.1] > 0.0), "descending branch must lie above the ascending one"
    # A clear loop, ~10 % of the range: 40…100 N·mm at its widest.
    assert 40.0 < width.max() < 100.0, width.max()


def test_first_ascent_is_monotone_in_abs_current():
    fs = 500.0
    for sign in (+1.0, -1.0):
        act = bmr.VirtualActuator("bmr2013", seed=0, sample_rate_hz=fs, effects={"coil_lag": None})
        cur = sign * _ramp(0.0, [FULL], 0.1, fs)
        t = act.run(cur)["field_torque_nmm"]
        assert np.all(np.diff(sign * t) >= -1e-9)
        assert sign * t[-1] > 500.0


def test_remanence_survives_a_zero_crossing():
    fs = 500.0
    act = bmr.VirtualActuator("bmr2013", seed=0, sample_rate_hz=fs)
    act.run(_ramp(0.0, [FULL, 0.0], 0.5, fs))
    out = act.run(_ramp(0.0, [-0.6, 0.0, 0.4], 0.5, fs))
    neg = out["current_a"] < -0.05
    pos = out["current_a"] > 0.05
    # The idle coil keeps its remanence while the other one works (memory is not reset at zero current).
    assert np.all(out["b2_t"][neg] > 0.01)
    assert np.all(out["b1_t"][pos] > 0.01)
    assert np.all(out["coil2_a"][neg] == 0.0) and np.all(out["coil1_a"][pos] == 0.0)
    # Coil 2's remanence opposes coil 1's torque: the negative torque is smaller than from a virgin coil 2.
    virgin = bmr.VirtualActuator("bmr2013", seed=0, sample_rate_hz=fs)
    v = virgin.run(_ramp(0.0, [-0.6], 0.5, fs))["field_torque_nmm"][-1]
    k = int(np.argmin(out["current_a"]))
    assert out["field_torque_nmm"][k] > v + 5.0


def test_torque_sign_convention_and_coil_split():
    act = bmr.VirtualActuator("bmr2013", seed=0, sample_rate_hz=500.0)
    out = act.run(np.r_[np.full(200, 0.8), np.full(200, -0.8)])
    assert out["coil2_a"][199] == pytest.approx(0.8) and out["coil1_a"][199] == 0.0
    assert out["coil1_a"][-1] == pytest.approx(0.8) and out["coil2_a"][-1] == 0.0
    assert out["field_torque_nmm"][199] > 300.0 and out["field_torque_nmm"][-1] < -300.0


def test_converter_limits_current():
    act = bmr.VirtualActuator("bmr2013", seed=0, sample_rate_hz=500.0)
    out = act.run(np.r_[np.full(50, 5.0), np.full(50, -5.0)])
    assert out["coil2_a"].max() == pytest.approx(1.5)
    assert out["coil1_a"].max() == pytest.approx(1.5)
    assert act.converter_gain_a_per_v == 0.125


def _curves(run: bmr.Run, rising: bool) -> list[tuple[np.ndarray, np.ndarray]]:
    """Split a first-order run into its curves: from each reversal to the following saturation."""
    data = run.data[run.data.t_s >= run.meta["opening_end_s"]]
    u = data.current_a.to_numpy()
    y = data.torque_nmm.to_numpy()
    full = np.max(np.abs(u))
    target = full if rising else -full
    curves = []
    i = 0
    n = len(u)
    while i < n - 1:
        # A curve starts at a reversal (direction changes to rising/falling) and ends at saturation.
        moving = (u[i + 1] > u[i]) if rising else (u[i + 1] < u[i])
        reversed_here = i > 0 and ((u[i - 1] > u[i]) if rising else (u[i - 1] < u[i]))
        if moving and reversed_here:
            j = i
            while j + 1 < n and u[j + 1] != target and ((u[j + 1] > u[j]) if rising else (u[j + 1] < u[j])):
                j += 1
            j = min(j + 1, n - 1)
            curves.append((u[i: j + 1].copy(), y[i: j + 1].copy()))
            i = j
        else:
            i += 1
    return curves


def _forc_model(preset: str, effects=None, fs: float = 500.0) -> tuple[bmr.Hysteresis, float]:
    act = bmr.VirtualActuator(preset, seed=0, sample_rate_hz=fs, effects=effects)
    asc = ex.first_order_ascending(act, reversals=21, rate_a_per_s=1.0)
    desc = ex.first_order_descending(act, reversals=21, rate_a_per_s=1.0)
    a, d = _curves(asc, True), _curves(desc, False)
    assert len(a) == 20 and len(d) == 20
    step = ex._forc_step(21, FULL, 1.0, fs)
    return bmr.Hysteresis.from_curves(a, d, max_nodes=4096), step


def _compare(preset, vertices, effects=None, fs=500.0):
    model, step = _forc_model(preset, effects, fs)
    act = bmr.VirtualActuator(preset, seed=0, sample_rate_hz=fs, effects=effects)
    # Known start: opening, then negative saturation (the model's default initial state).
    act.run(np.concatenate([ex.opening_path(fs), ex.ramp_path(0.0, [-FULL], step)]))
    u = ex.ramp_path(-FULL, vertices, step)
    plant = act.run(u)["torque_nmm"]
    cbh = model.run(u)
    return u, plant, cbh


def test_ideal_preset_is_preisach_cbh_reproduces_it_to_round_off():
    # Higher-order reversals, all on the first-order reversal grid (0.125 A).
    vertices = [1.0, -0.5, 0.75, 0.0, 0.5, 0.25, 1.25, -1.0, -0.25, -0.75, 0.125, -1.25, 0.625]
    u, plant, cbh = _compare("ideal", vertices)
    assert np.max(np.abs(plant)) > 400.0
    assert np.max(np.abs(plant - cbh)) < 1e-9 * 600.0


def test_non_congruent_breaks_only_higher_order_reversals():
    fx = {"non_congruent": {"curvature": 2.0}}
    # First-order path: +sat → reversal → +sat is reproduced exactly…
    u1, p1, c1 = _compare("ideal", [FULL, 0.0, FULL], effects=fx)
    assert np.max(np.abs(p1 - c1)) < 1e-9 * 600.0
    # …a second-order minor loop is not (minor loops scale with the local slope of g). Its reversal minimum is
    # above 0 A: for coil 2, zero current is its own negative saturation, so a minimum at 0 A is first-order.
    u2, p2, c2 = _compare("ideal", [FULL, 0.5, 0.75, 0.625, FULL], effects=fx)
    second = np.flatnonzero(np.isclose(u2, 0.75))[0]
    err = np.abs(p2 - c2)
    assert err[: second + 1].max() < 1e-9 * 600.0
    # Small in absolute terms (the steel's narrow switching-field spread limits how far histories diverge) but
    # orders of magnitude above round-off.
    assert err[second:].max() > 0.01


def test_the_per_rotor_output_map_is_one_odd_map_of_the_field_torque() -> None:
    """``non_congruent`` bends each rotor's yield torque, ``T = M(τ2) − M(τ1)``. The idle coil's steel sits at
    the same flux after any excursion (its hysterons all fall back at zero current), so the idle rotor's torque
    ``r`` is a constant and the field torque is ``sign(y)·(M(r + |y|) − M(r))`` of the unbent ``y = τ2 − τ1``:
    for the curvature map, the same map with curvature ``c / (1 + 2cρ)`` (``ρ = r/S``) and a gain — one output
    map after one core, which the diagnosis searches. On the harder ``rig_soft`` steel the idle flux is
    0.072 T."""
    soft = {f"steel{k}.{p}": v for k in (1, 2) for p, v in
            (("coercivity_a", 0.12), ("coercivity_width_a", 0.05), ("interaction_width_a", 0.6),
             ("reversible_fraction", 0.15))}
    rng = np.random.default_rng(5)
    turns = np.r_[1.25, -1.25, rng.uniform(-1.2, 1.2, 40)]
    current = np.concatenate([np.linspace(a, b, 60) for a, b in zip(np.r_[0.0, turns[:-1]], turns)])
    runs = {}
    for c in (0.0, 2.0):
        act = bmr.VirtualActuator("rig_preisach", seed=3, sample_rate_hz=250.0, overrides=soft,
                                  effects={"non_congruent": {"curvature": c}} if c else None)
        runs[c] = act.run(current)
    r0 = runs[0.0]
    idle = np.r_[r0["b1_t"][r0["coil1_a"] == 0][200:], r0["b2_t"][r0["coil2_a"] == 0][200:]]
    assert np.ptp(idle) < 1e-9
    y, bent = runs[0.0]["field_torque_nmm"][120:], runs[2.0]["field_torque_nmm"][120:]  # after the virgin curve
    s = 600.0  # the preset's full-scale torque
    best = np.inf
    for c_eff in np.linspace(0.8, 1.6, 161):
        g = y * (1 + c_eff * np.abs(y) / s)
        k = float(g @ bent / (g @ g))
        best = min(best, float(np.sqrt(np.mean((bent - k * g) ** 2))))
    assert best < 0.2  # N·mm, against a bend of more than 50 N·mm RMS
    assert np.sqrt(np.mean((bent - y) ** 2)) > 50.0
