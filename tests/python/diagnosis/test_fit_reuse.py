"""What the diagnosis computes once and reads again: the fold alternation of fit and re-identification stops once
the correction has converged (and only then; before the first pass too), the configuration's regression and field
stay cached while other candidates pass, a candidate's folds stop once it cannot be accepted or is clearly below
the minimum gain, and the learned discrepancy's stacked fold solves equal one solve per fold."""
from __future__ import annotations

import numpy as np
import pytest

from bmr.diagnosis import discrepancy, selection
from bmr.diagnosis.effects import LIBRARY, NonCongruent
from bmr.diagnosis.procedure import nominal_model
from bmr.diagnosis.residuals import prepare
from bmr.diagnosis.selection import Configuration, Fitter, evaluate, heldout
from bmr.simulation.excitation import MEDIUM_EFFECTS, diagnosis_bundle

HARMONIC = {"order": 6.0, "amplitude_nmm": 6.0, "phase_rad": 0.5}


@pytest.fixture(scope="module")
def fitter() -> Fitter:
    # A seal-friction harmonic the nominal friction (3 harmonics) lacks: the tables identified from the protocol
    # runs absorb part of it, so removing it from them changes the tables.
    bundle = diagnosis_bundle("rig_preisach", effects={"friction_harmonics": HARMONIC}, seed=5).decimated(4)
    model = nominal_model(bundle)
    data = prepare(bundle, model.hysteresis.input_range, 3, friction=model.friction)
    protocol = [(r, data.run_start_s[r.name]) for r in bundle.roles().protocol]
    return Fitter(data, model, protocol)


def _effect(name: str):
    return next(e for e in LIBRARY if e.name == name)


def _fold_fit(fitter: Fitter, name: str, value, fold: int) -> tuple[float, int]:
    """Held-out RMS of ``fold`` with the effect added, and the re-identifications it took."""
    config = Configuration(fitter.nominal_path().with_(reidentify=True))
    fitter.solve(config.path, config.linear)  # the configuration's own tables: not the candidate's work
    before = fitter.reidentifier.fits
    ff = selection._fit_with(fitter, config, _effect(name), value, fold)[0]
    return ff.test_rms(fold), fitter.reidentifier.fits - before


def test_the_second_reidentification_runs_only_while_the_correction_moves(fitter, monkeypatch) -> None:
    # The harmonic the data hold: the first correction leaves the tables' share of it, the second pass is needed.
    # A harmonic the data do not hold: its correction is far below the noise, one pass is enough.
    rms_present, passes_present = _fold_fit(fitter, "friction_harmonics", 6, 0)
    rms_absent, passes_absent = _fold_fit(fitter, "friction_harmonics", 11, 1)
    assert passes_present == 2
    assert passes_absent == 1
    assert rms_present < rms_absent
    # The passes skipped (run now: the first one is cached; a harmonic has a cosine and a sine part) change the
    # held-out RMS by far less than any decision resolves.
    monkeypatch.setattr(selection, "CONVERGED_CORRECTION", 0.0)
    rms_forced, extra = _fold_fit(fitter, "friction_harmonics", 11, 1)
    assert extra == selection._correction_passes(2) - 1
    assert abs(rms_forced - rms_absent) <= 1e-3 * rms_forced


def test_a_correction_below_the_noise_keeps_the_configurations_tables(fitter, monkeypatch) -> None:
    # A 4th friction harmonic, which the data do not hold: in this fold its fitted correction changes the protocol
    # runs by less than 1 % of the noise, so the fold is fitted on the configuration's own least-squares tables
    # without re-identifying them.
    rms_kept, passes = _fold_fit(fitter, "friction_harmonics", 4, 2)
    assert passes == 0
    monkeypatch.setattr(selection, "CONVERGED_CORRECTION", 0.0)
    rms_forced, forced = _fold_fit(fitter, "friction_harmonics", 4, 2)
    assert forced >= 1
    assert abs(rms_forced - rms_kept) <= 1e-3 * rms_forced


def test_effects_that_leave_the_tables_alone_are_refitted_without_reidentifying(fitter) -> None:
    # A per-run gain and offset does not bend the protocol runs: its fit on all data re-identifies nothing.
    config = Configuration(fitter.nominal_path().with_(reidentify=True))
    fitter.solve(config.path, config.linear)
    calibration = _effect("run_gain_offset")
    before = fitter.reidentifier.fits
    ff, _, path, _ = selection._fit_with(fitter, config, calibration, calibration.grid(fitter.data)[-1], None)
    assert fitter.reidentifier.fits == before and path == config.path and np.isfinite(ff.sse_train).all()


def _evaluate(fitter: Fitter, name: str):
    """The candidate ``name`` against the configuration with least-squares tables, and the re-identifications
    its folds took."""
    config = Configuration(fitter.nominal_path().with_(reidentify=True))
    before = heldout(fitter, config)
    start = fitter.reidentifier.fits
    cand = evaluate(fitter, config, _effect(name), before)
    return cand, fitter.reidentifier.fits - start


def test_folds_stop_once_most_of_them_cannot_be_positive(fitter, monkeypatch) -> None:
    # Ripple the data do not hold: its first two folds (of three) lose, so it can no longer gain in most folds.
    monkeypatch.setattr(selection, "_clearly_below", lambda *args: False)
    cand, _ = _evaluate(fitter, "torque_ripple")
    assert cand.fold_gains.size == 2 < fitter.data.folds
    assert cand.folds_positive == 0 and not cand.accepted
    assert cand.row()["folds_evaluated"] == 2


def test_folds_stop_once_the_gain_is_clearly_below_the_minimum(fitter, monkeypatch) -> None:
    # Seal friction growing with current, which the data do not hold: tiny positive gains on its first folds.
    stopped, fits_stopped = _evaluate(fitter, "friction_current")
    assert stopped.fold_gains.size == 2 and np.all(stopped.fold_gains > 0)
    monkeypatch.setattr(selection, "_clearly_below", lambda *args: False)
    full, fits_full = _evaluate(fitter, "friction_current")
    assert full.fold_gains.size == fitter.data.folds
    assert fits_stopped >= 1 and fits_full >= 1  # the fold skipped is a re-identification (the others are kept)
    # The same decision, and the folds evaluated gained the same.
    assert not stopped.accepted and not full.accepted and full.mean_gain < selection.MIN_GAIN
    assert set(np.round(stopped.fold_gains, 12)) <= set(np.round(full.fold_gains, 12))


def test_a_present_effect_evaluates_every_fold(fitter) -> None:
    cand, _ = _evaluate(fitter, "friction_harmonics")
    assert cand.fold_gains.size == fitter.data.folds and cand.accepted


def test_the_history_asked_for_again_keeps_its_regression_and_field(fitter) -> None:
    reid = fitter.reidentifier
    base = fitter.nominal_path().with_(reidentify=True, corrections=())
    fitter.field(base)
    fitter.field(base)  # asked for again: kept while other paths pass
    fitter.field(base.with_(curvature=0.1))  # same input history: its regression is asked for again
    regressions, simulations = reid.regressions, fitter.simulations
    for tau in (0.01, 0.02, 0.03, 0.04):  # input-side candidates: new histories fill the other slots
        fitter.field(base.with_(lag_tau_s=tau))
    assert reid.regressions == regressions + 4
    assert len(reid._regressions) + 1 <= reid.max_inputs
    fitter.field(base.with_(curvature=0.2))
    assert reid.regressions == regressions + 4  # the kept history was not prepared again
    fitter.field(base)
    assert fitter.simulations == simulations + 5  # nor the field asked for again simulated again


def test_stacked_fold_solves_equal_one_solve_per_fold() -> None:
    rng = np.random.default_rng(3)
    for trial in range(100):
        p, folds = int(rng.integers(2, 10)), 5
        xs = [rng.standard_normal((40, p)) for _ in range(folds)]
        rs = [x @ rng.standard_normal(p) + rng.standard_normal(40) for x in xs]
        m = discrepancy._Moments(np.stack([x.T @ x for x in xs]), np.stack([x.T @ r for x, r in zip(xs, rs)]),
                                 np.array([r @ r for r in rs]), np.full(folds, 40.0))
        support = rng.random(p) < 0.6
        support[0] = True
        blocks = np.arange(folds) if trial % 2 else np.array([0, 2, 3])
        want = [m.sse(np.array([k]), discrepancy._solve(*m.train(blocks[blocks != k]), support)) for k in blocks]
        np.testing.assert_allclose(discrepancy._heldout_sse(m, blocks, support), want, rtol=1e-12)


def test_a_candidate_stopped_early_is_never_one_its_folds_would_accept() -> None:
    def below(grid_gains: list[float], reidentified: dict[int, float]) -> bool:
        # Gains stand in for the fits: ``grid_gains`` on the configuration's tables, ``reidentified`` the folds
        # re-identified so far.
        def gain(k: int, ff: object) -> float:
            return float(ff)  # type: ignore[arg-type]

        return selection._clearly_below(gain, grid_gains, list(range(len(grid_gains))), dict(reidentified),
                                        len(grid_gains))

    # Re-identification changed nothing and the gains are negative: clearly below the minimum.
    assert below([-0.30, -0.25, -0.20, -0.20, -0.20], {0: -0.30, 1: -0.25})
    # The remaining folds' fits are far below the minimum, but the folds re-identified gain more than it: their
    # mean alone would accept, so the remaining folds run.
    assert not below([0.03, 0.03, -0.5, -0.5, -0.5], {0: 0.03, 1: 0.03})
    # Small gains, but the re-identification raised them by 0.3: the remaining folds could reach the minimum.
    assert not below([-0.30, -0.25, -0.20, -0.20, -0.20], {0: 0.0, 1: 0.01})


@pytest.fixture(scope="module")
def creep_fitter() -> Fitter:
    # Creep and an output map the nominal tables lack: the output map has a best value to find.
    bundle = diagnosis_bundle("rig_preisach", effects={"creep": MEDIUM_EFFECTS["creep"],
                                                       "non_congruent": MEDIUM_EFFECTS["non_congruent"]},
                              seed=6).decimated(4)
    model = nominal_model(bundle)
    data = prepare(bundle, model.hysteresis.input_range, 3, friction=model.friction)
    protocol = [(r, data.run_start_s[r.name]) for r in bundle.roles().protocol]
    return Fitter(data, model, protocol)


def _evaluate_fresh(fitter: Fitter, name: str):
    """As :func:`_evaluate`, with the fits and tables of earlier calls forgotten (each call counts its own)."""
    fitter._fits.clear()
    fitter.reidentifier._tables.clear()
    return _evaluate(fitter, name)


def test_the_output_maps_families_are_searched_coarse_to_fine_with_every_folds_choice_kept(creep_fitter,
                                                                                         monkeypatch) -> None:
    # Each family of the output map (curvature, cubic) coarse to fine: every fold chooses the value the whole grid
    # gives it, for a fraction of the re-identifications. (The mean field's short family is scanned whole either
    # way.)
    fast, fits_fast = _evaluate_fresh(creep_fitter, "non_congruent")
    monkeypatch.setattr(selection, "_scan", lambda *args: None)
    full, fits_full = _evaluate_fresh(creep_fitter, "non_congruent")
    assert fast.values == full.values
    np.testing.assert_array_equal(fast.fold_gains, full.fold_gains)
    assert fast.accepted == full.accepted
    whole = len(NonCongruent.FEEDBACKS)
    assert 3 * (fits_fast - whole) <= 2 * (fits_full - whole), (fits_fast, fits_full)


@pytest.fixture(scope="module")
def lag_fitter() -> Fitter:
    bundle = diagnosis_bundle("rig_preisach", effects={"coil_lag": {"tau_s": 0.02}}, seed=7).decimated(4)
    model = nominal_model(bundle)
    data = prepare(bundle, model.hysteresis.input_range, 3, friction=model.friction)
    protocol = [(r, data.run_start_s[r.name]) for r in bundle.roles().protocol]
    return Fitter(data, model, protocol)


def test_a_candidate_without_its_signature_is_not_searched(fitter) -> None:
    # A friction harmonic (no zero drifting through the session): the configuration's residual lacks the sensor
    # drift's signature, which reads that residual alone. Such a candidate could be neither named nor an
    # alternative, so its grid is not searched at all.
    eff = _effect("sensor_drift")
    config = Configuration(fitter.nominal_path())
    fitter.solve(config.path, config.linear)
    missing = eff.signature_missing(fitter, config, None)
    assert eff.signature_before_only and missing and eff.without_signature() is None
    start = fitter.reidentifier.fits
    sel = selection.forward_selection(fitter, library=[eff], max_effects=1)
    assert fitter.reidentifier.fits == start
    assert not sel["accepted"] and not sel["alternatives"]
    row = next(r for r in sel["rejected"] if r["name"] == "sensor_drift")
    assert row["folds_evaluated"] == 0 and row["fold_gains"] == [] and missing in row["reason"]


def test_without_the_output_maps_signature_only_the_mean_field_is_searched(lag_fitter, monkeypatch) -> None:
    # A coil lag: the residual is no larger after higher-order reversals, so no output map is searched; the mean
    # field acts on every sample (that excess is not its signature) and is searched alone.
    eff = _effect("non_congruent")
    config = Configuration(lag_fitter.nominal_path())
    lag_fitter.solve(config.path, config.linear)
    assert eff.signature_missing(lag_fitter, config, None)
    paths = []
    solve = lag_fitter.solve

    def spy(path, linear):
        paths.append(path)
        return solve(path, linear)

    monkeypatch.setattr(lag_fitter, "solve", spy)
    sel = selection.forward_selection(lag_fitter, library=[eff], max_effects=1)
    searched = [p for p in paths if p.curvature or p.cubic or p.feedback]
    assert searched and all(p.curvature == 0.0 and p.cubic == 0.0 and p.feedback != 0.0 for p in searched)
    row = next(r for r in sel["rejected"] + sel["accepted"] if r["name"] == "non_congruent")
    assert row["folds_evaluated"] > 0


def test_the_measured_torque_is_gathered_on_the_fit_rows_once(fitter, monkeypatch) -> None:
    # Every configuration's fit subtracts its field from the measured torque on the fit rows gathered with the
    # fitter: no fit gathers the measured torque again.
    assert np.array_equal(fitter.measured_rows, fitter.measured[fitter.data.fit_rows])
    gathered = []
    take = np.take

    def spy(a, *args, **kwargs):
        gathered.append(a is fitter.measured)
        return take(a, *args, **kwargs)

    monkeypatch.setattr(selection.np, "take", spy)
    ff = fitter.solve(fitter.nominal_path().with_(curvature=0.0123), [(_effect("run_gain_offset"), "offset")])
    assert gathered and not any(gathered)
    assert np.all(np.isfinite(ff.sse_test))


def test_the_run_calibration_columns_are_the_per_run_products(fitter) -> None:
    # Written into one array, the columns are the per-run indicator times the sensor's reading, the indicator and
    # the friction's angle-dependent part, to the bit.
    data, model = fitter.data, fitter.model
    eff = _effect("run_gain_offset")
    y = fitter.field(fitter.nominal_path())
    ind = eff.columns(data, "offset", y, model)
    for value in ("gain_offset", "gain_offset_friction"):
        cols = eff.columns(data, value, y, model)
        expected = [ind * (y + data.friction_nmm)[:, None], ind]
        if value == "gain_offset_friction":
            expected.append((data.friction_nmm - model.friction.c0)[:, None])
        assert np.array_equal(cols, np.column_stack(expected))



def test_the_next_correction_reaches_an_affine_maps_fixed_point_from_one_pass_per_parameter_and_one() -> None:
    # Fitted parameters as an affine map of the correction the tables were identified with, slowly contracting
    # (a plain alternation would need dozens of passes) and with parameters of unlike scales.
    a = np.array([[0.9, 0.05], [-2.0, 0.8]])
    b = np.array([0.4, 20.0])
    fixed = np.linalg.solve(np.eye(2) - a, b)
    scale = np.array([30.0, 1.0])
    tried: list[np.ndarray] = []
    fitted: list[np.ndarray] = []
    x = np.zeros(2)
    for _ in range(3):
        tried.append(x)
        fitted.append(a @ x + b)
        x = selection._next_correction(tried, fitted, scale)
        if len(tried) == 1:
            assert np.array_equal(x, fitted[0])  # one pass: the fitted parameters themselves
    assert np.allclose(x, fixed, rtol=1e-9, atol=1e-9)


def test_creeps_zero_removals_share_the_configurations_tables(fitter) -> None:
    # The log form's grid removes no fluctuation field at its share 0 for every onset: each is the configuration's
    # own least-squares tables, not a re-identification per onset.
    config = Configuration(fitter.nominal_path().with_(reidentify=True))
    fitter.solve(config.path, config.linear)
    creep = _effect("creep")
    zeros = [v for v in creep.grid(fitter.data) if v[0] == "log" and v[2] == 0.0]
    assert len(zeros) == len(creep.ONSETS_S) > 1
    before = fitter.reidentifier.fits
    for value in zeros:
        path, _ = selection._with(config, creep, value, fitter.data)
        assert path.key() == config.path.key()
        fitter.solve(path, config.linear + [(creep, value)])
    assert fitter.reidentifier.fits == before


class _Chosen:
    """An effect whose folds chose value 1 over its simplest value 0 (for the majority vote alone)."""

    simplest = 0


@pytest.mark.parametrize("chosen_wins, compared", [((True, True, True, False, False), 3),
                                                  ((False, False, False, True, True), 3),
                                                  ((True, False, True, False, True), 5)])
def test_the_simplest_value_stands_or_falls_by_a_majority_decided_as_soon_as_it_is(monkeypatch, chosen_wins,
                                                                                 compared) -> None:
    # Each fold compares the chosen value with the simplest one on its held-out block (two fits); once most folds
    # have spoken either way, the rest are not fitted, and the choice is the one all folds would give.
    calls: list[int] = []

    def fake_fit_with(fitter, config, eff, value, fold):
        calls.append(fold)
        sse = np.zeros(5)
        sse[fold] = 1.0 if (value == 1) == chosen_wins[fold] else 2.0
        return (selection.FoldFit(np.zeros((6, 1)), np.zeros(6), sse, np.ones(5), (0,)), None, None, None)

    monkeypatch.setattr(selection, "_fit_with", fake_fit_with)
    best = selection._simplest_unless_beaten(None, None, _Chosen(), [0, 1], [1] * 5)
    assert best == ([1] * 5 if sum(chosen_wins) > 2 else [0] * 5)
    assert len(calls) == 2 * compared
