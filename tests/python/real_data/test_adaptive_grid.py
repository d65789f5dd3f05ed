"""The least-squares table on an adaptive grid (``bmr identify --grid adaptive``, what ``auto`` takes for a FORC
family) on a real FORC file: the marine sediment MicroMag export, every other curve held out, through the command
line. Skipped when the data are absent."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import bmr
from bmr.cli import main
from bmr.data.signals import sample_noise

DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "forc-marine-sediment"
FILE = DATA / "MSM33-55-1_d330.forc"


def test_adaptive_grid_predicts_held_out_sediment_forcs_within_the_noise_floor(tmp_path):
    if not FILE.is_file():
        pytest.skip(f"needs {FILE} (see ../shared/data/README.md for its source)")
    names = [t.name for t in bmr.read_tables(FILE)]
    held = ",".join(names[1::2])
    bundle, model, pred = tmp_path / "bundle", tmp_path / "model.json", tmp_path / "prediction.json"
    assert main(["import", str(FILE), "--input", "Field", "--output", "Moment", "--holdout", held,
                 "-o", str(bundle)]) == 0
    assert main(["identify", str(bundle), "--grid", "adaptive", "-o", str(model)]) == 0
    assert main(["predict", str(model), str(bundle), "--json", str(pred)]) == 0
    assert json.loads(model.read_text())["meta"]["identification"]["lstsq_fit"]["settings"]["grid"] == "adaptive"
    rms = json.loads(pred.read_text())["total"]["rms"]
    floor = sample_noise([np.asarray(r.output, dtype=float) for r in bmr.read_bundle(bundle).runs])
    # 0.82x the moment's own noise floor (4.94e-10 A·m²); the evenly spaced grid (--grid uniform) 1.18x.
    assert rms < 1.0 * floor, (rms, floor)
