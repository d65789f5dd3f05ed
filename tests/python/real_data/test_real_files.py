"""The instrument readers on the real files of ``../shared/data`` (skipped when absent): what each file holds, as
its folder's README states it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bmr

DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data"


def _file(*parts: str) -> Path:
    p = DATA.joinpath(*parts)
    if not p.is_file():
        pytest.skip(f"needs {p} (see ../shared/data/README.md for its source)")
    return p


@pytest.mark.parametrize("parts,curves,points,units", [
    (("forc-feco-nanowires", "hchb_forc"), 152, 30628, ("Oe", "emu")),
    (("forc-marine-sediment", "MSM33-55-1_d330.forc"), 120, 8514, ("T", "A·m²")),
    (("forc-marine-sediment", "B-9-3-85-87-FORC-1.5T.csv"), 251, 47250, ("T", "A·m²")),
])
def test_forc_files(parts, curves, points, units):
    tables = bmr.read_tables(_file(*parts))
    assert len(tables) == curves
    # Every point of the file is in a table: each curve's and the calibration point before it.
    assert sum(t.n_samples for t in tables) == points
    assert all((t.unit_of("Field"), t.unit_of("Moment")) == units for t in tables)
    cal = np.array([t.meta["calibration_moment"] for t in tables])
    assert all(t.meta["calibration_points"] == 1 for t in tables)
    # The drift check: the moment at the calibration field moves by well under 2 % over the measurement.
    assert 0 < np.ptp(cal) < 0.02 * np.max(np.abs(cal))


def test_feco_calibration_drift_is_the_documented_one():
    tables = bmr.read_tables(_file("forc-feco-nanowires", "hchb_forc"))
    cal = np.array([t.meta["calibration_moment"] for t in tables])
    moment = np.concatenate([t.columns["Moment"] for t in tables])
    # README: about 0.55 % of the saturation moment.
    assert 0.3 < 100 * np.ptp(cal) / np.max(np.abs(moment)) < 0.9


def test_damper_and_bh_files():
    damper = bmr.import_logs([_file("mr-damper-utfpr", "ensaio.A.1.mat")], input="dist:mm", output="forc:N")
    [run] = damper.bundle.runs
    assert damper.rate.hz == pytest.approx(100.0) and run.quantities.output.unit == "N"
    assert damper.runs[0].edges.hold > 0  # the table rests before it starts shaking
    bh = bmr.import_logs([_file("bh-loops-steel-ferrite", "H_MnZn_ferrite.mat"),
                          _file("bh-loops-steel-ferrite", "B_MnZn_ferrite.mat")], input="HmeasT:A/m",
                         output="BmeasT:T")
    assert [r.name for r in bh.bundle.runs] == [f"MnZn_ferrite-{k}" for k in range(1, 5)]
    assert all(r.samples == 129 for r in bh.runs)
