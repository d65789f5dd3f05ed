"""One measurement history: runs recorded one after the other on one device. The bundle says so (readers that know
the recording order, the simulators, the manifest's ``histories``), and ``initial="continue"`` predicts each run from
the state the model holds after every earlier run's input."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.cli import main
from bmr.data.bundle import read_bundle, write_bundle
from bmr.identification.prediction import predict
from bmr.identification.signals import run_input
from bmr.simulation.device import device_bundle


@pytest.fixture(scope="module")
def piezo():
    bundle = device_bundle("piezo", seed=2, reversals=5, sweep_rates=(1.0,), dwell_s=0.5)
    return bundle, bmr.identify(bundle)


def test_simulated_runs_are_one_history_in_recording_order(piezo):
    bundle, _ = piezo
    assert bundle.histories == [[r.name for r in bundle.runs]]
    last = bundle.runs[-1].name
    assert [r.name for r in bundle.history_of(last)] == [r.name for r in bundle.runs]


def test_continue_is_one_long_simulation_cut_into_runs_bit_for_bit(piezo):
    bundle, model = piezo
    runs = bundle.runs
    p = predict(model, runs, initial="continue", offset="model", evaluate="all", bundle=bundle)
    whole = model.simulate(np.concatenate([run_input(r) for r in runs]))
    y_lo = model.hysteresis.output_range[0]
    start = 0
    for r in runs:
        n = len(r.time)
        cut = whole[start:start + n]
        start += n
        got = p.run(r.name)
        # Gain 1 and the model's offset: the prediction is the cut, through the same arithmetic.
        assert np.array_equal(got.predicted, y_lo + 1.0 * (cut - y_lo)), r.name
        assert got.evaluated == n and "continuing the history" in got.initial
    # A run that starts away from a saturation starts elsewhere than the default assumes: continuing differs.
    reset = predict(model, runs, initial="negative", offset="model", evaluate="all")
    moved = [r.name for r in runs if not np.array_equal(reset.run(r.name).predicted, p.run(r.name).predicted)]
    assert moved, "no run's start state depends on the runs before it"


def test_continue_scores_from_where_the_history_state_is_known(piezo):
    bundle, model = piezo
    p = predict(model, bundle, initial="continue")
    first = p.runs[0]
    # Held-out runs come after the identification runs, which went to both ends: every sample is scored.
    assert all(r.evaluated == r.samples for r in p.runs), [(r.name, r.dropped) for r in p.runs]
    assert first.state_known


def test_continue_without_a_history_is_one_clear_error(piezo, tmp_path, capsys):
    bundle, model = piezo
    bundle.histories = []
    try:
        with pytest.raises(bmr.BmrError, match="records no measurement history.*'negative', 'positive' or "
                                               "'estimate'"):
            predict(model, bundle, initial="continue")
        with pytest.raises(bmr.BmrError, match="needs the bundle"):
            predict(model, bundle.runs[-1], initial="continue")
        write_bundle(bundle, tmp_path / "b")
        model.save(tmp_path / "m.json")
        assert main(["predict", str(tmp_path / "m.json"), str(tmp_path / "b"), "--initial", "continue"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "no measurement history" in err[0] and "Traceback" not in err[0]
    finally:
        bundle.histories = [[r.name for r in bundle.runs]]


def test_manifest_histories_round_trip_and_old_manifests_read_as_before(piezo, tmp_path):
    bundle, _ = piezo
    write_bundle(bundle, tmp_path / "b")
    manifest = json.loads((tmp_path / "b" / "manifest.json").read_text())
    assert manifest["histories"] == bundle.histories
    assert read_bundle(tmp_path / "b").histories == bundle.histories
    del manifest["histories"]
    (tmp_path / "b" / "manifest.json").write_text(json.dumps(manifest))
    old = read_bundle(tmp_path / "b")
    assert old.histories == [] and old.history_of(bundle.runs[0].name) == []
    assert "histories" not in old.meta
    for bad, why in (([["nope"]], "does not hold"), ([[bundle.runs[0].name], [bundle.runs[0].name]], "twice"),
                     ("run1", "list of non-empty lists")):
        manifest["histories"] = bad
        (tmp_path / "b" / "manifest.json").write_text(json.dumps(manifest))
        with pytest.raises(bmr.BundleError, match=why):
            read_bundle(tmp_path / "b")


def test_slac_runs_are_one_history_and_predict_continues_it(slac_data, tmp_path, capsys):
    files = [str(slac_data / f"strplt.ru{k}") for k in (5, 3, 4, 6, 8, 7)]  # any order on the command line
    assert main(["import", *files, "--input", "MAIN:A", "--output", "BL:T", "--output-name", "integrated gradient",
                 "--output-sigma", "sigBL", "--holdout", "run7,run8", "-o", str(tmp_path / "b")]) == 0
    bundle = read_bundle(tmp_path / "b")
    assert bundle.histories == [[f"run{k}" for k in range(3, 9)]]
    assert "one measurement history of 6 runs" in capsys.readouterr().out
    assert main(["identify", str(tmp_path / "b"), "-o", str(tmp_path / "m.json")]) == 0
    capsys.readouterr()
    assert main(["predict", str(tmp_path / "m.json"), str(tmp_path / "b"), "--initial", "continue", "--json",
                 str(tmp_path / "p.json")]) == 0
    out = capsys.readouterr()
    assert "Traceback" not in out.err and "continuing the history from run3" in out.out
    result = json.loads((tmp_path / "p.json").read_text())
    assert set(result["runs"]) == {"run7", "run8"} and result["total"]["rms"] < 2e-3


def test_continue_runs_the_extended_model_over_the_history_once(piezo):
    # A model with a stage that holds state (a drive-to-output delay): continuing carries the delay line and the
    # core's memory from one run into the next, as one run of the whole chain over the concatenated inputs.
    from bmr.diagnosis.extended_model import with_extensions
    from bmr.identification.extended import simulate_extended

    bundle, model = piezo
    extended = with_extensions(model, [{"name": "time_delay", "params": {"delay_s": 0.02}}])
    runs = bundle.runs
    p = predict(extended, runs, initial="continue", offset="model", evaluate="all", bundle=bundle)
    assert p.ran == ["core tables", "time_delay"]
    u = np.concatenate([run_input(r) for r in runs])
    dt = float(np.median(np.diff(runs[0].time)))
    whole = simulate_extended(extended, u, np.zeros(u.size), dt_s=dt, t0_s=float(runs[0].time[0]))
    y_lo = extended.hysteresis.output_range[0]
    bounds = np.cumsum([0] + [len(r.time) for r in runs])
    for r, a, b in zip(runs, bounds[:-1], bounds[1:]):
        assert np.array_equal(p.run(r.name).predicted, y_lo + 1.0 * (whole[a:b] - y_lo)), r.name
    # Each run alone starts its delay line empty: the first samples after a run boundary differ.
    alone = predict(extended, runs, initial="negative", offset="model", evaluate="all")
    assert not np.array_equal(alone.runs[-1].predicted, p.runs[-1].predicted)


def test_a_history_that_starts_at_an_end_is_known_from_its_first_sample(piezo):
    # First-order curves as a magnetometer records them: each from the top down to its reversal and back, the
    # lowest reversal in the last curve only. The state is known from the first sample on, as for one run.
    bundle, model = piezo
    lo, hi = model.hysteresis.input_range
    q = bundle.quantities
    runs = []
    for k, rev in enumerate(np.linspace(lo + 0.6 * (hi - lo), lo, 4)):
        u = np.concatenate([np.linspace(hi, rev, 40), np.linspace(rev, hi, 40)[1:]])
        data = {"t_s": 100.0 * k + 0.01 * np.arange(u.size), q.input.column: u, q.output.column: np.zeros(u.size)}
        runs.append(bmr.Run(f"forc{k + 1}", "custom", pd.DataFrame(data), quantities=q, role="evaluation"))
    history = bmr.Bundle("magnetometer", 100.0, runs, quantities=q, histories=[[r.name for r in runs]])
    p = predict(model, history, initial="continue")
    assert all(r.evaluated == r.samples and r.state_known for r in p.runs), [(r.name, r.dropped) for r in p.runs]
