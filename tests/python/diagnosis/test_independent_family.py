"""Blind diagnosis of effects made by mechanisms bmr's vocabulary did not write (``independent_plant``): each
cell hides one mechanism at medium size and requires a name that is right for it; a clean bundle gets no physical
name. A report that names an effect together with the effects it cannot tell it from on this excitation ("coil_lag
or rate_dependence") is right when one of its names is, and wrong when none is; no report may be wrong. Cells the
diagnosis does not name yet are expected failures with the measured reason
(``benches/diagnosis_calibration.py --family independent`` measures every cell)."""
from __future__ import annotations

import pytest

import bmr
import independent_plant as ip
from bmr.diagnosis.effects import PHYSICAL
from bmr.diagnosis.selection import out_of_range

SEED = 1000

# Mechanism → why the diagnosis misses it today (measured on this seed), or None when it is named.
CELLS: dict[str, str | None] = {
    "coil_eddy_circuit": None,
    "fractional_delay": None,
    "seal_lobes": None,
    "eccentric_gap": None,
    "recalibration": None,
    "reptation": None,
    # Reported as "coil_lag or rate_dependence": one time constant fits most of a dynamic field on one drive speed.
    "eddy_field": None,
    # Heating through I²R(T): no sensor drift next to it (the trend left vanishes where the field does).
    "coil_heating": None,
    "rate_loss": None,
    # Named creep with a thermal fluctuation field on the core's input (the unbounded log-time form).
    "log_after_effect": None,
    # Named with the output map's cubic term, judged on the higher-order reversal curves where the map shows.
    "cubic_yield": None,
    # Named with the mean field (a moving Preisach core): the tables identified again on the fed-back input.
    "moving_preisach": None,
}


def _physical(d) -> list[str]:
    return [e["name"] for e in d.effects if e["name"] in PHYSICAL]


def _reports(d) -> list[set[str]]:
    """Each accepted physical effect with the effects the diagnosis says it cannot tell it from."""
    return [{n} | {a.other for a in d.alternatives if a.chosen == n} for n in _physical(d)]


def _assert_named(d, mechanisms: list[str]) -> None:
    reports = _reports(d)
    right = {n for m in mechanisms for n in ip.MECHANISMS[m].names}
    for m in mechanisms:
        names = ip.MECHANISMS[m].names
        assert any(n in r for r in reports for n in names), f"{m}: expected one of {names}, reported {reports}"
    wrong = [r for r in reports if not r & right]
    assert not wrong, f"{mechanisms}: wrong names {wrong} (reported {reports})"


def _cell(mechanism: str):
    reason = CELLS[mechanism]
    marks = [pytest.mark.slow]
    if reason is not None:
        # Only a missed name is expected: a crash still fails.
        marks.append(pytest.mark.xfail(strict=True, raises=AssertionError, reason=reason))
    return pytest.param(mechanism, marks=marks, id=mechanism)


@pytest.mark.parametrize("mechanism", [_cell(m) for m in CELLS])
def test_hidden_mechanism_is_named(mechanism):
    bundle = ip.independent_bundle({mechanism: ip.at_size(mechanism, 1.0)}, seed=SEED)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    _assert_named(d, [mechanism])


def test_a_coil_with_a_slow_eddy_loop_is_named_coil_lag():
    # 80 % of every current change arrives in 4 ms, 20 % in 100 ms: one lag of 24 ms fits best (13.5 -> 4.8 N·mm
    # held out), and the residual without it grows with the rate by 0.50 of what that lag predicts (a single time
    # constant overstates the growth at the fastest drive). Against the 0.5 asked before, the lag was refused and
    # the dynamic field named instead (13.5 -> 5.5).
    d = bmr.diagnose(ip.independent_bundle({"coil_eddy_circuit": {"tau_coil_s": 0.004, "eddy_share": 0.2,
                                                                  "tau_eddy_s": 0.1}}, seed=SEED),
                     progress=False, closed_loop=False)
    _assert_named(d, ["coil_eddy_circuit"])


def test_an_extended_model_never_predicts_worse_than_the_model_it_extends():
    # A saturating yield map (cubic -0.3) on the diagnosis protocol: tables identified again by least squares
    # without the map predict worse (2.40 N·mm held out) than the measured curves' own (1.96). Judged against those
    # tables, the map gained 7 % and was named, and the extended model predicted 2.07 N·mm, worse than the model it
    # extended.
    d = bmr.diagnose(ip.independent_bundle({"cubic_yield": {"cubic": -0.3}}, seed=SEED), progress=False,
                     closed_loop=False)
    assert d.residual_rms <= d.nominal_heldout_rms, (d.residual_rms, d.nominal_heldout_rms, _physical(d))


@pytest.mark.slow
@pytest.mark.parametrize("mechanism", ["eddy_field", "coil_heating"])
def test_the_papers_protocol_names_no_second_effect(mechanism):
    # Three evaluation runs at one drive speed. A dynamic field sampled at the end of each sample trails a ramp by
    # half a sample more than bmr's lag with the input held over the sample: that 1 ms is no coil lag of 0.74 ms
    # next to the rate dependence. A heating scales the field torque about its zero, the middle of the loop (the
    # tables count from the off-state's remanence): scaled about the tables' zero it left a trend at zero field
    # torque that was named a sensor drift.
    bundle = ip.independent_bundle({mechanism: ip.at_size(mechanism, 1.0)}, seed=SEED, protocol="coarse")
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    _assert_named(d, [mechanism])


@pytest.mark.slow
def test_log_after_effect_is_creep_with_its_fluctuation_field():
    # A thermal fluctuation field along the input's last direction, logarithmic in the time since it turned and
    # never settling within a run: named creep in its unbounded form, the field within 30 % of the plant's.
    truth = ip.at_size("log_after_effect", 1.0)
    bundle = ip.independent_bundle({"log_after_effect": truth}, seed=SEED)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["creep"], d.to_dict()["effects"]
    got = next(e["params"] for e in d.effects if e["name"] == "creep")
    assert got["fraction"] == 0.0
    assert abs(got["fluctuation"] - truth["viscosity_a"]) <= 0.3 * truth["viscosity_a"], got
    spec = bmr.effect_parameters()["creep"]["params"]
    assert spec["tau0_s"]["min"] <= got["tau0_s"] <= spec["tau0_s"]["max"]


PAIR = ["coil_heating", "bridge_warmup"]


@pytest.fixture(scope="module")
def heating_and_warming_sensor():
    bundle = ip.independent_bundle({m: ip.at_size(m, 1.0) for m in PAIR}, seed=SEED)
    return bmr.diagnose(bundle, progress=False, closed_loop=False)


@pytest.mark.slow
def test_heating_and_a_warming_sensor_are_not_named_a_per_run_calibration(heating_and_warming_sensor):
    # The bridge's offset warms up along the session and the coils heat: the runs' offsets and gains follow the
    # session's time, and every run moves along that trend from its first half to its second, which a calibration
    # drawn per recording does not.
    d = heating_and_warming_sensor
    assert "run_gain_offset" not in _physical(d)
    right = {n for m in PAIR for n in ip.MECHANISMS[m].names}
    assert all(r & right for r in _reports(d)), _reports(d)


@pytest.mark.slow
def test_heating_and_a_warming_sensor_are_both_named(heating_and_warming_sensor):
    # Alone, neither is named (5.83 N·mm held out, noise 1.48): the heating gains 19 % but the share of heat it
    # would carry over between runs reads the bridge's warm-up (-3, outside [0, 1]), the drift gains 14 % in 4 folds
    # of 5; each is accepted with its signature once the other is in, so both are named together.
    d = heating_and_warming_sensor
    _assert_named(d, PAIR)
    assert {e.get("paired_with") for e in d.effects} == set(ip.MECHANISMS[m].names[0] for m in PAIR)
    assert d.residual_rms_nmm < 1.5 * d.noise_floor_nmm, (d.residual_rms_nmm, d.noise_floor_nmm)
    # The heating's gain loss at steady full current: 40 K × 0.25 %/K = 10 %.
    heat = next(e["params"] for e in d.effects if e["name"] == "thermal_drift")
    truth = ip.at_size("coil_heating", 1.0)
    assert abs(heat["gain_loss"] - truth["rise_k"] * truth["gain_per_k"]) <= 0.25 * truth["rise_k"] * truth["gain_per_k"], heat


@pytest.mark.slow
@pytest.mark.parametrize("protocol", ["diagnosis", "coarse"])
def test_a_moving_preisach_is_non_congruent_with_its_mean_field(protocol):
    # The core sees h + feedback_a·y/S (S = 600 N·mm): named non_congruent by its mean field alone, the feedback per
    # unit output (what the tables' own full scale leaves comparable) within 30 % of the plant's, and physical: the
    # loop stays single-valued. On the paper's protocol (few higher-order reversals) the residual is no larger after
    # higher-order reversals than on the first-order-like curves: the output map's signature is missing, and the
    # mean field, which acts on every sample, is searched alone.
    truth = ip.at_size("moving_preisach", 1.0)
    bundle = ip.independent_bundle({"moving_preisach": truth}, seed=SEED, protocol=protocol)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["non_congruent"], d.to_dict()["effects"]
    got = next(e["params"] for e in d.effects if e["name"] == "non_congruent")
    assert got["curvature"] == 0.0 and got["cubic"] == 0.0, got
    per_output, true_per_output = got["feedback"] / got["scale_nmm"], truth["feedback_a"] / ip.FULL_SCALE_NMM
    assert abs(per_output - true_per_output) <= 0.3 * true_per_output, (got, per_output, true_per_output)


@pytest.mark.parametrize("protocol, feedback_a", [("coarse", 0.3), ("diagnosis", -0.2)])
def test_a_strong_or_demagnetizing_moving_preisach_is_its_mean_field_alone(protocol, feedback_a):
    # Twice the medium feedback (0.3 A per 600 N·mm of core output), and a demagnetizing one. Over the full scale
    # of the nominal tables (1050 and 736 N·mm: they count from the off-state's remanence) they are 0.42 and -0.2 of
    # the 1.25 A full current; the mean fields searched ended at 0.24 and -0.12 of it, so the strong one was named
    # at the end of that range with a 2.3 ms coil_lag for what it left (wrong; 2.51 N·mm, noise 1.47), and the
    # demagnetizing one at -0.15 A (9.7 N·mm left against 1.56 with its own feedback).
    bundle = ip.independent_bundle({"moving_preisach": {"feedback_a": feedback_a}}, seed=SEED, protocol=protocol)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["non_congruent"], d.to_dict()["effects"]
    got = next(e["params"] for e in d.effects if e["name"] == "non_congruent")
    per_output, true_per_output = got["feedback"] / got["scale_nmm"], feedback_a / ip.FULL_SCALE_NMM
    assert abs(per_output - true_per_output) <= 0.15 * abs(true_per_output), (got, per_output, true_per_output)
    # Within the tables' own floor: a clean bundle leaves 1.24 (paper's protocol) and 1.1 (diagnosis) x the noise.
    assert d.residual_rms < 1.35 * d.noise_floor_nmm, (d.residual_rms, d.noise_floor_nmm)


def test_a_cubic_yield_map_is_named_on_the_papers_protocol():
    # 11 first-order curves per family and no nested loops: the map shows in the multi-peak run only. One fold
    # chose the cubic 0.9 by every training sample (held-out gain -2.7 %), and the block of the run's last, small
    # loops, where the map is nearly linear, gained nothing on the higher-order curves, so the interval there
    # reached below zero: not named, 2.05 N·mm left (noise 1.49). Each fold now chooses the map by the samples
    # where it acts, and a gain whose interval over all samples excludes zero counts: named, 1.65 N·mm left.
    d = bmr.diagnose(ip.independent_bundle({"cubic_yield": ip.at_size("cubic_yield", 1.0)}, seed=SEED,
                                           protocol="coarse"), progress=False, closed_loop=False)
    _assert_named(d, ["cubic_yield"])
    got = next(e["params"] for e in d.effects if e["name"] == "non_congruent")
    assert got["curvature"] == 0.0 and got["feedback"] == 0.0 and 0.3 <= got["cubic"] <= 0.7, got


def _protocol_gain_ratio(bundle) -> float:
    gains = [r.meta["calibration"]["gain"] for r in bundle.roles().protocol]
    return gains[1] / gains[0]


@pytest.mark.slow
def test_a_calibration_per_recording_is_divided_out_of_the_tables_too():
    # The ascending and the descending family are recordings with their own sensor gains (here 1.049 and 0.982):
    # per-run terms on the evaluation runs alone left 5.36 N·mm held out (noise 1.47), the tables agreeing with
    # neither family. Their gains are estimated from the protocol runs and divided out before the tables are
    # identified again: the residual reaches the noise.
    from bmr.diagnosis.effects import LIBRARY
    from bmr.diagnosis.procedure import nominal_model
    from bmr.diagnosis.residuals import prepare
    from bmr.diagnosis.selection import Fitter

    bundle = ip.independent_bundle({"recalibration": ip.at_size("recalibration", 1.0)}, seed=SEED)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert _physical(d) == ["run_gain_offset"], d.to_dict()["effects"]
    assert d.residual_rms_nmm < 1.2 * d.noise_floor_nmm, (d.residual_rms_nmm, d.noise_floor_nmm)
    # The protocol runs' gain ratio, from the protocol runs alone: within 0.1 % of the plant's.
    model = nominal_model(bundle)
    data = prepare(bundle, model.hysteresis.input_range, 5, friction=model.friction)
    fitter = Fitter(data, model, [(r, data.run_start_s[r.name]) for r in bundle.roles().protocol])
    calibration = next(e for e in LIBRARY if e.name == "run_gain_offset")
    gains = calibration.protocol_gains(fitter.nominal_path().with_(reidentify=True))
    assert abs(gains[1] / gains[0] - _protocol_gain_ratio(bundle)) < 1e-3, (gains, _protocol_gain_ratio(bundle))


@pytest.mark.slow
def test_an_after_effect_is_named_next_to_a_calibration_per_recording():
    # The calibrations between recordings (22.4 N·mm held out) hid the log-time after-effect while the tables
    # still carried the protocol runs' gains (6.5 N·mm left after run_gain_offset); with the tables corrected
    # the after-effect is creep's fluctuation field, within 30 % of the plant's.
    truth = ip.at_size("log_after_effect", 1.0)
    bundle = ip.independent_bundle({"log_after_effect": truth,
                                    "recalibration": ip.at_size("recalibration", 1.0)}, seed=SEED)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    _assert_named(d, ["log_after_effect", "recalibration"])
    creep = next(e["params"] for e in d.effects if e["name"] == "creep")
    assert abs(creep["fluctuation"] - truth["viscosity_a"]) <= 0.3 * truth["viscosity_a"], creep
    assert d.residual_rms_nmm < 1.5 * d.noise_floor_nmm, (d.residual_rms_nmm, d.noise_floor_nmm)


@pytest.mark.slow
def test_a_transport_delay_is_named_next_to_reptation():
    # Reptation moves every minor loop towards the middle, reversal by reversal; the delay shifts every branch in
    # time. Alone each is named; together both are (20.3 N·mm held out, each fold gaining once both are in).
    mechanisms = ["fractional_delay", "reptation"]
    bundle = ip.independent_bundle({m: ip.at_size(m, 1.0) for m in mechanisms}, seed=SEED)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    _assert_named(d, mechanisms)
    delay = next(e["params"] for e in d.effects if e["name"] == "time_delay")
    truth = ip.at_size("fractional_delay", 1.0)["delay_s"]
    assert abs(delay["delay_s"] - truth) <= 0.25 * truth, delay


# A 6 ms delay next to a reptation reaching 60 % of its shift per reversal (constants the calibration does not use).
SHORT_DELAY_FAST_REPTATION = {"fractional_delay": {"delay_s": 0.006},
                              "reptation": {"share": 0.08, "per_reversal": 0.6}}


def test_a_short_delay_next_to_a_faster_reptation_is_named_on_the_papers_protocol():
    # A 6 ms delay and a reptation reaching 60 % of its shift per reversal: in the time block of the multi-peak
    # run the delay's correction cancels the reptation's shifts (-18 %), so the delay alone was refused (gains 78,
    # -18, 71, 6, 13 %), and the reptation, which gains in that block only, was never tried next to it: nothing was
    # named and 11.6 N·mm (noise 1.48) left.
    d = bmr.diagnose(ip.independent_bundle(SHORT_DELAY_FAST_REPTATION, seed=SEED, protocol="coarse"),
                     progress=False, closed_loop=False)
    _assert_named(d, list(SHORT_DELAY_FAST_REPTATION))
    assert d.residual_rms < 0.5 * d.nominal_heldout_rms, (d.residual_rms, d.nominal_heldout_rms)


def test_a_delay_that_explains_more_than_the_coil_lag_in_every_fold_is_not_passed_over():
    # The same pair on the diagnosis protocol, seed 2000: after the reptation, the delay gains 38 % held out with
    # every fold at least as much as the coil lag's 27 %, but spread wider (its 95 % interval reached -0.002), so the
    # lag alone was accepted and named (wrong; 4.93 N·mm left, 4.09 with the delay).
    d = bmr.diagnose(ip.independent_bundle(SHORT_DELAY_FAST_REPTATION, seed=2000), progress=False,
                     closed_loop=False)
    _assert_named(d, list(SHORT_DELAY_FAST_REPTATION))


def test_a_charge_amplifier_that_discharges_in_seconds_is_leakage_not_creep():
    # The conductance's charge decays with the amplifier's 10 s feedback time within every 20-44 s run: an ideal
    # integrator could not follow it, and creep over 1-100 s was named instead (wrong, 1.77 N·mm left); with the
    # discharge searched, leakage (decay 0.064/s against 0.1) leaves 1.64 (noise 1.47).
    d = bmr.diagnose(ip.independent_bundle({"parallel_conductance": {"conductance": 0.5, "tau_amp_s": 10.0}},
                                           seed=SEED), progress=False, closed_loop=False)
    _assert_named(d, ["parallel_conductance"])
    leak = next(e["params"] for e in d.effects if e["name"] == "leakage")
    assert 0.03 <= leak["decay_per_s"] <= 0.3, leak


def test_a_bridge_warming_within_the_session_is_a_settling_sensor_drift():
    # The bridge's offset warms up towards 40 N·mm with 100 s, within the paper's protocol: a line in time left
    # 2.3 N·mm (noise 1.46) and `thermal_drift` took the bend (a wrong name). The drift's warm-up searched: it
    # alone, 9.79 → 1.71 N·mm, settling at about 1/100 s.
    d = bmr.diagnose(ip.independent_bundle({"bridge_warmup": {"drift_nmm": 40.0, "tau_s": 100.0}}, seed=3000,
                                           protocol="coarse"), progress=False, closed_loop=False)
    _assert_named(d, ["bridge_warmup"])
    drift = next(e["params"] for e in d.effects if e["name"] == "sensor_drift")
    assert 1 / 300 <= drift["settle_per_s"] <= 1 / 30, drift
    assert drift["rate_nmm_per_s"] / drift["settle_per_s"] == pytest.approx(40.0, rel=0.25), drift


def test_an_after_effects_leftover_in_one_recording_is_not_named_leakage():
    # A log-time after-effect with t0 = 10 ms next to per-recording calibrations, paper's protocol, seed 2000: both
    # named, and then leakage too (5 % of a residual 1.17 x the noise): its coefficient on the input's integral came
    # from the multi-step run alone (the other runs, without it, fitted -3.7 times that coefficient).
    mechanisms = {"log_after_effect": {"viscosity_a": 0.003, "t0_s": 0.01},
                  "recalibration": {"gain_span": 0.03, "offset_span_nmm": 3.0}}
    d = bmr.diagnose(ip.independent_bundle(mechanisms, seed=2000, protocol="coarse"), progress=False,
                     closed_loop=False)
    _assert_named(d, list(mechanisms))


@pytest.mark.slow
def test_a_session_trend_is_not_a_calibration_per_recording_with_few_evaluation_runs():
    # The paper's protocol alone has three evaluation runs, too few to tell a session's trend from calibrations
    # drawn per recording; the two first-order recordings of the same session carry the trend too. With them, a
    # heating next to a warming bridge is named as both (it was named run_gain_offset).
    bundle = ip.independent_bundle({m: ip.at_size(m, 1.0) for m in PAIR}, seed=SEED, protocol="coarse")
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert "run_gain_offset" not in _physical(d), d.to_dict()["effects"]
    _assert_named(d, PAIR)


@pytest.mark.slow
def test_a_rate_loss_is_named_viscous_on_the_papers_protocol_alone():
    # The loss saturates above 10 A/s: the multi-step run's one-sample steps (125 A/s) leave it near 56 N·mm,
    # where the first-order curves (1 A/s) and the triangle (0.5 A/s) move in its proportional part. The yield
    # part bounds it at the steps; the tables, identified at one speed, keep no share of it as a wider loop.
    bundle = ip.independent_bundle({"rate_loss": ip.at_size("rate_loss", 1.0)}, seed=SEED, protocol="coarse")
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    _assert_named(d, ["rate_loss"])
    named = next(e for e in d.effects if e["name"] in ip.MECHANISMS["rate_loss"].names)
    assert not out_of_range(named["name"], named["params"]), named["params"]
    assert d.residual_rms_nmm <= 1.4 * d.noise_floor_nmm, (d.residual_rms_nmm, d.noise_floor_nmm)


@pytest.mark.slow
@pytest.mark.parametrize("protocol", ["standard", "coarse"])
def test_a_strong_dynamic_field_is_named_rate_dependence(protocol):
    # The eddy field at twice its medium size (k = 0.02 s). The rate dependence's lag follows the core's slopes,
    # taken from the nominal core, which was identified from runs the field itself distorted: its best fit (31.6
    # -> 14.8 N·mm on all data) fell behind one coil lag's (7.3) and coil_lag alone was named, 7.3 N·mm left at a
    # noise of 1.5. With the tables identified again on the slopes of the tables just identified (four passes,
    # 14.8 -> 5.8 -> 3.6 -> 2.6), the rate dependence explains it.
    kw = {"protocol": "coarse"} if protocol == "coarse" else {}
    bundle = ip.independent_bundle({"eddy_field": ip.at_size("eddy_field", 2.0)}, seed=SEED, **kw)
    d = bmr.diagnose(bundle, progress=False, closed_loop=False)
    assert "rate_dependence" in _physical(d), d.to_dict()["effects"]
    _assert_named(d, ["eddy_field"])
    assert d.residual_rms_nmm < 2.5 * d.noise_floor_nmm, (d.residual_rms_nmm, d.noise_floor_nmm)
