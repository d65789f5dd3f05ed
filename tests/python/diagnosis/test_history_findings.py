"""What a memory model cannot explain across a measurement history: the level at each run's start and repeated
loops that do not retrace, measured against the noise and handed to the effects that explain them. A virtual
actuator's runs are one history; accommodation hidden in it must be found as loops that drift, and named; the clean
actuator is the negative control. The SLAC quadrupole's runs 3-8 show both findings in real data."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bmr.cli import main
from bmr.diagnosis.history import EXPLAINED_BY, history_findings
from bmr.diagnosis.procedure import diagnose, nominal_model
from bmr.simulation.excitation import diagnosis_bundle

PRESET = "rig_preisach"
ACCOMMODATION = {"accommodation": {"kappa": 0.1, "cycles": 3.0}}


def _findings(effects, seed=204):
    bundle = diagnosis_bundle(PRESET, effects=effects, seed=seed)
    [h] = history_findings(nominal_model(bundle), bundle, bundle.meta["simulator"]["noise_nmm"])
    return bundle, h


def _repeated(h):
    return [lp for lp in h.loops if lp.first == lp.second == "repeated_loops"]


def test_accommodation_shows_as_repeated_loops_drifting_to_the_middle_and_clean_loops_retrace():
    bundle, h = _findings(ACCOMMODATION)
    assert h.runs == [r.name for r in bundle.runs]
    loops = _repeated(h)
    assert len(loops) >= 10
    drifting = [lp for lp in loops if lp.significant]
    assert len(drifting) >= len(loops) // 2, [(lp.input_from, lp.mean_shift) for lp in loops]
    # Loops below the middle of the output range move up, loops above it move down.
    for lp in drifting:
        below = max(lp.input_from, lp.input_to) <= 0.0
        assert (lp.mean_shift > 0) == below, lp
    assert "accommodation" in h.candidates and h.to_dict()["loops_not_retracing"] >= len(drifting)

    _, clean = _findings(None)
    assert not any(lp.significant for lp in _repeated(clean)), [lp.mean_shift for lp in _repeated(clean)]
    assert not clean.start_level_changes, clean.start_levels
    assert max(abs(lp.mean_shift) for lp in _repeated(clean)) < 0.1 * max(abs(lp.mean_shift) for lp in loops)


def test_per_run_offsets_show_as_start_levels_the_history_does_not_explain():
    bundle, h = _findings({"run_gain_offset": {"gain_sd": 0.0, "offset_sd": 5.0}}, seed=7)
    assert h.start_level_changes and "run_gain_offset" in h.candidates
    assert h.start_level_sd > 2.0 * h.sigma
    # The levels follow the hidden calibrations (up to a common offset), run by run.
    offsets = np.array([r.meta["calibration"]["offset_nmm"] for r in bundle.runs if r.name in h.start_levels])
    levels = np.array([h.start_levels[r.name] for r in bundle.runs if r.name in h.start_levels])
    assert np.corrcoef(offsets, levels)[0, 1] > 0.9, (offsets, levels)


@pytest.mark.slow
def test_diagnosis_reports_the_history_findings_and_names_accommodation(tmp_path):
    bundle = diagnosis_bundle(PRESET, effects=ACCOMMODATION, seed=204)
    d = diagnose(bundle, progress=False, closed_loop=False)
    [h] = d.history
    assert h.loops_not_retracing and "accommodation" in h.named, (h.named, [e["name"] for e in d.effects])
    doc = d.to_dict()["history"][0]
    assert doc["named"] == h.named and doc["loops_not_retracing"] == len(h.loops_not_retracing)
    assert set(EXPLAINED_BY["loop_within_run"]) <= set(doc["candidates"])
    json.dumps(d.to_dict())
    assert "Across the measurement history" in d.html_section()


def test_slac_history_remanence_changes_and_the_major_loop_does_not_retrace(slac_data, tmp_path, capsys):
    files = [str(slac_data / f"strplt.ru{k}") for k in range(3, 9)]
    assert main(["import", *files, "--input", "MAIN:A", "--output", "BL:T", "--output-name", "integrated gradient",
                 "--output-sigma", "sigBL", "--holdout", "run7,run8", "-o", str(tmp_path / "b")]) == 0
    from bmr.data.bundle import read_bundle

    bundle = read_bundle(tmp_path / "b")
    [h] = history_findings(nominal_model(bundle), bundle, 1.2e-5)
    # The field at 0 A at the runs' starts spreads by about 7.5e-4 T (0.03407-0.03482 T).
    assert h.start_level_changes and 6e-4 < h.start_level_range < 9e-4, h.start_levels
    # Run 3's second major ascent lies above its first: about 3.3e-4 T at 0 A to 8.8e-4 T at 165 A.
    [ascent] = [lp for lp in h.loops if lp.first == lp.second == "run3" and lp.direction == "ascending"]
    assert ascent.significant and 2e-4 < ascent.shift_at_start < 5e-4 and 6e-4 < ascent.shift_at_end < 1.1e-3
    # The diagnosis reports them (never refuses), in its JSON, its text and its HTML report.
    capsys.readouterr()
    assert main(["diagnose", str(tmp_path / "b"), "--json", str(tmp_path / "d.json"), "--report",
                 str(tmp_path / "d.html")]) == 0
    out = capsys.readouterr().out
    assert "history run3..run8 (6 runs): level at each run's start" in out and "do not retrace" in out
    doc = json.loads((tmp_path / "d.json").read_text())["history"][0]
    assert doc["start_level_changes"] and doc["loops_not_retracing"] >= 1
    assert set(doc["candidates"]) >= {"accommodation", "run_gain_offset"}
    assert "Across the measurement history" in (tmp_path / "d.html").read_text()
