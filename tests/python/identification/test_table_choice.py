"""The least-squares table's resolution and smoothing chosen by cross-validation over whole sweeps of the training
runs, on the independently written Preisach plant (``independent_preisach``): the choice predicts a held-out run
at least as well as the fixed default, one major loop (which says nothing about the loops inside it) keeps the
default, it does not hinge on where exactly the input range ends, and ``identify`` reports it."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.identification.lstsq import fit_tables_lstsq
from bmr.identification.prediction import predict
from bmr.identification.signals import run_input, run_output
from bmr.identification.spans import SATURATION_TOL, evaluation_start, input_range_of
from bmr.identification.table_choice import (DEFAULT_INTERVALS, DEFAULT_SMOOTHING, block_folds,
                                             choose_table_settings, distinct_reversals, sweep_folds, sweeps)

import independent_preisach as P

FS = 100.0  # Hz: 0.5 A/s ramps sampled every 5 mA


@pytest.fixture(scope="module")
def loops():
    """A major loop and scattered minor loops on a plant with continued switching (30 ms), each recording from the
    state the previous one left; a held-out run of nested loops."""
    rng = np.random.default_rng(3)
    plant = P.Plant(lag_s=0.03)
    plant.reset()
    plant.drive(P.ramps(P.multipeak_vertices(11, 6), 0.5, 500.0)[1], 0.002)
    train = [P.record(plant, "major", "custom", [0.0, P.HI, P.LO, P.HI, P.LO, P.HI], rng, fs=FS, fresh=False)]
    for k in range(3):
        v = [float(x) for x in np.random.default_rng(10 + k).uniform(-1.1, 1.1, 8)]
        train.append(P.record(plant, f"minor{k}", "custom", [0.0] + v, rng, fs=FS, fresh=False))
    nested = [0.9, -0.1, 0.8, -0.2, 0.7, -0.3, 0.6, -0.4, 0.5]
    held = P.record(plant, "nested", "custom", [0.0, P.HI, P.LO] + [x * 1.25 for x in nested], rng, fs=FS,
                    fresh=False)
    return train, held


def _held_rms(tables, held: bmr.Run) -> float:
    """RMS of the tables on the held-out run from where its state is known (both saturation ends visited)."""
    u, y = run_input(held), run_output(held)
    lo, hi = tables.input_range
    s = evaluation_start(u, lo, hi, SATURATION_TOL * (hi - lo))
    e = (y - tables.everett.simulate(u, tables.offset, []))[s:]
    return float(np.sqrt(np.mean(e * e)))


def test_folds_hold_out_every_sample_once_in_contiguous_blocks():
    masks = block_folds([100, 37, 5], folds=3, blocks_per_fold=2)
    for k, n in enumerate((100, 37, 5)):
        held = np.array([fold[k] for fold in masks])
        assert held.shape == (3, n)
        np.testing.assert_array_equal(held.sum(axis=0), np.ones(n))
    # Run 0: six blocks of 16-17 samples, fold 0 holds the first and the fourth.
    assert np.flatnonzero(np.diff(masks[0][0].astype(int))).tolist() == [16, 49, 66]
    # A run too short to keep samples for its own offset is never held out (a FORC file's first curve).
    assert not any(fold[0].any() for fold in block_folds([2, 50]))
    with pytest.raises(bmr.BmrError):
        block_folds([10], folds=1)


def test_sweep_folds_hold_out_whole_branches():
    # Two runs: a loop of two sweeps and a first-order curve (one sweep, from its reversal up).
    loop = np.concatenate([np.linspace(1.0, -1.0, 50), np.linspace(-1.0, 1.0, 50)[1:]])
    curve = np.linspace(-0.3, 1.0, 30)
    assert [(s.start, s.stop) for s in sweeps(loop, 0.02)] == [(0, 50), (50, 99)]
    masks = sweep_folds([loop, curve], [np.ones(99), np.ones(30)], 0.02)
    assert len(masks) == 3
    # The loop's branches go to folds 0 and 1, the curve to fold 2 less its first two samples (its offset).
    assert masks[0][0][:50].all() and not masks[0][0][50:].any() and masks[1][0][50:].all()
    assert not masks[2][1][:2].any() and masks[2][1][2:].all() and not masks[0][1].any()
    # One loop alone: two folds, one branch each.
    assert len(sweep_folds([loop], [np.ones(99)], 0.02)) == 2


@pytest.fixture(scope="module")
def major_loop():
    """One major loop recorded from positive saturation down and back (a hysteresisgraph's B(H) loop, 313
    samples), and three smaller symmetric loops, each entered from positive saturation, held out."""
    rng = np.random.default_rng(0)
    fs = 25.0
    plant = P.Plant(coercivity_width=0.1, interaction_width=0.05)
    plant.reset()
    major = P.record(plant, "major", "custom", [0.0, P.HI, P.LO, P.HI], rng, fs=fs, fresh=False)
    smaller = []
    for a in (0.4, 0.7, 0.9):
        plant.reset()
        plant.drive(P.ramps([P.LO, P.HI, a], 0.5, fs)[1], 1.0 / fs)
        smaller.append(P.record(plant, f"loop{a}", "custom", [a, -a, a, -a, a], rng, fs=fs, fresh=False))
    return major, smaller


def test_one_major_loop_keeps_the_default_table_for_the_loops_inside_it(major_loop):
    # The loops inside a major loop lie in cells of the Preisach plane the major loop never reaches: time blocks
    # along it rank first a table that predicts the smaller loops 8 % worse; holding out a whole branch shows that
    # the rest does not determine it, so the default is kept and the result says why.
    major, smaller = major_loop
    lo, hi = input_range_of([run_input(major)])
    choice = choose_table_settings([major], input_range=(lo, hi))

    def smaller_rms(n: int, s: float) -> float:
        tables = fit_tables_lstsq([major], n_intervals=n, smoothing=s, input_range=(lo, hi))
        e = [(d := run_output(r) - tables.everett.simulate(run_input(r), 0.0, [P.HI])) - d.mean() for r in smaller]
        return float(np.sqrt(np.mean(np.concatenate(e) ** 2)))

    chosen, default = smaller_rms(choice.n_intervals, choice.smoothing), smaller_rms(DEFAULT_INTERVALS,
                                                                                      DEFAULT_SMOOTHING)
    print(choice, "smaller loops:", round(chosen, 2), "default:", round(default, 2))
    assert choice.undecided is not None and choice.ranked is not None and choice.sweep_folds >= 2
    assert choice.sweep_rms > 0.2 * choice.sweep_spread
    assert chosen <= 1.02 * default
    ranked = smaller_rms(*choice.ranked)
    print("ranked first by the blocks:", choice.ranked, round(ranked, 2))
    assert ranked > 1.05 * default  # the plant exposes what the blocks alone get wrong


def test_one_monotone_sweep_offers_no_check_and_the_blocks_ranking_stands(major_loop):
    # The major loop's descending branch alone: one sweep, nothing to hold out whole.
    major, _ = major_loop
    u = run_input(major)
    top = int(np.argmax(u[: u.size // 2]))
    bottom = top + int(np.argmin(u[top:]))
    branch = bmr.Run("branch", "custom", major.data.iloc[top:bottom + 1].reset_index(drop=True))
    lo, hi = input_range_of([run_input(branch)])
    choice = choose_table_settings([branch], input_range=(lo, hi))
    assert choice.skipped is None and choice.undecided is None and choice.ranked is None
    assert choice.sweeps == 1 and np.isnan(choice.sweep_rms)
    best = min(choice.candidates, key=lambda c: c.cv_rms)
    assert choice.cv_rms <= best.cv_rms * 1.01  # the blocks' ranking (within its tie band)
    print(choice)


def test_the_chosen_setting_predicts_held_out_loops_at_least_as_well_as_the_default(loops):
    train, held = loops
    chosen = bmr.identify(bmr.Bundle("loops", FS, train), method="lstsq")
    default = bmr.identify(bmr.Bundle("loops", FS, train), method="lstsq", n_intervals=DEFAULT_INTERVALS,
                           smoothing=DEFAULT_SMOOTHING)
    choice = chosen.identification.table_choice
    assert default.identification.table_choice is None  # both given: nothing chosen
    assert choice is not None and choice.fixed == ()
    assert chosen.identification.lstsq.n_intervals == choice.n_intervals
    assert chosen.identification.lstsq.settings["smoothing"] == choice.smoothing
    # The default is among the settings scored, and the choice scores no worse on the held-out blocks.
    assert choice.cv_rms <= choice.default_cv_rms
    # Minor loops inside the major one: the rest predicts whole held-out sweeps, so the ranking is trusted.
    assert choice.undecided is None and choice.sweep_rms < 0.2 * choice.sweep_spread
    assert len(choice.candidates) >= 4  # the default and its neighbours in smoothing and resolution
    # Loops and minor loops, not a family of first-order reversal curves: no signed density is tried.
    assert choice.density is None and not np.isfinite(choice.nonnegative_cv_rms)
    assert not chosen.identification.lstsq.signed
    rms_chosen, rms_default = predict(chosen, held).rms, predict(default, held).rms
    print(choice, "held out:", round(rms_chosen, 3), "default:", round(rms_default, 3))
    assert rms_chosen <= 1.05 * rms_default
    # Reported in the model file's identification record and in the summary.
    record = chosen.meta["identification"]["table_choice"]
    assert record["n_intervals"] == choice.n_intervals and record["folds"] == 3 and record["undecided"] is None
    assert "TableChoice(" in repr(chosen.identification)


def test_distinct_reversals_count_each_curve_start_and_merge_close_inputs():
    # Five first-order reversal curves (each starts at its reversal), two of them 1e-4 of the range apart, and one
    # run that reverses twice inside: 4 + 2 distinct reversal inputs.
    curves = [np.linspace(r, 1.0, 50) for r in (-0.9, -0.5, -0.1, -0.1 + 2e-4, 0.3)]
    loop = np.concatenate([np.linspace(0.0, 0.8, 40), np.linspace(0.8, -0.6, 60), np.linspace(-0.6, 0.2, 30)])
    assert distinct_reversals(curves + [loop], -1.0, 1.0) == 4 + 3  # the loop's start (0.0) counts as well
    assert distinct_reversals([], -1.0, 1.0) == 0


def test_a_given_setting_is_kept_and_only_the_other_is_searched(loops):
    train, _ = loops
    model = bmr.identify(bmr.Bundle("loops", FS, train), method="lstsq", n_intervals=32)
    choice = model.identification.table_choice
    assert choice.fixed == ("n_intervals",) and choice.n_intervals == 32
    assert {c.n_intervals for c in choice.candidates} == {32}
    assert model.identification.lstsq.n_intervals == 32


@pytest.mark.slow
def test_the_choice_is_stable_to_a_tiny_move_of_the_range_end(loops):
    # Moving the range's lower end by a thousandth of the span must not change the held-out figure much (a
    # barely-regularised fine table can jump by a factor of 4 under such a move).
    train, held = loops
    lo, hi = input_range_of([run_input(r) for r in train])
    figures = []
    for shift in (0.0, 1e-3 * (hi - lo)):
        rng = (lo - shift, hi)
        choice = choose_table_settings(train, input_range=rng)
        tables = fit_tables_lstsq(train, n_intervals=choice.n_intervals, smoothing=choice.smoothing,
                                  input_range=rng)
        figures.append(_held_rms(tables, held))
    print("held-out RMS at the two range ends:", [round(f, 3) for f in figures])
    assert abs(figures[1] - figures[0]) < 0.15 * min(figures)


def test_recordings_too_short_to_cut_into_blocks_keep_the_default_and_say_so(loops):
    train, _ = loops
    # Two runs of 20 samples each over their whole loops (a log taken at a few points per branch).
    short = [bmr.Run(r.name, r.kind, r.data.iloc[::len(r.data) // 20].iloc[:20].reset_index(drop=True),
                     quantities=r.quantities) for r in train[:2]]
    model = bmr.identify(bmr.Bundle("short", FS, short), method="lstsq")
    choice = model.identification.table_choice
    assert (choice.n_intervals, choice.smoothing) == (DEFAULT_INTERVALS, DEFAULT_SMOOTHING)
    assert choice.skipped is not None and "40 regression rows" in choice.skipped and not choice.candidates
    assert "not cross-validated" in repr(model.identification)
    assert model.meta["identification"]["table_choice"]["skipped"] == choice.skipped
    # Tables finer than the default are tried only with two rows per cell (the loops have ~6700 rows: 80
    # intervals, 3240 cells, is out).
    full = choose_table_settings(train, input_range=input_range_of([run_input(r) for r in train]))
    assert full.skipped is None and 80 not in {c.n_intervals for c in full.candidates}
