"""For every effect the diagnosis names: the compensator built in the core from the diagnosed model file
(`Compensator.from_model`) tracks the multi-peak torque reference better than the nominal one on the very plant
that made the bundle, the effect's own stage is kept, and every stage it keeps helps. Each case is a whole blind
diagnosis (slow tier; the fast representatives are the coil-lag case in test_diagnosis.py and the heating stage in
test_thermal_stage.py). The measurement is the README's
(``benches/closed_loop_ratios.py``), so the figures it prints are the ones checked here."""
from __future__ import annotations

from pathlib import Path

import pytest

import bmr
from bmr.identification.model import LOOP_STAGES

from repo_scripts import load_script


def _bench():
    return load_script("benches/closed_loop_ratios.py")


# The creep stage (the exact inverse of the relaxation) makes tracking worse on this plant at medium size: the
# closed-loop check leaves it off and the refined tables alone give ratio 0.70. Strict: reported the day it helps.
_EXPECTED_MISSES = {
    "creep": "creep: the stage does not help on rig_preisach; ratio from the refined tables alone",
}
_CASES = [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=_EXPECTED_MISSES[n]))
          if n in _EXPECTED_MISSES else n for n in _bench().CLOSED_LOOP_EFFECTS]


@pytest.mark.slow
@pytest.mark.parametrize("name", _CASES)
def test_the_compensator_from_the_diagnosed_model_file_tracks_better(name: str, tmp_path: Path) -> None:
    row = _bench().one(name, 0, tmp_path)
    assert name in row["named"]
    assert row["ratio"] < 0.6, row
    # The effect's own stage is in the loop and helps (a slow one, the heating, over a reference long enough for
    # its state to build up).
    if name in LOOP_STAGES:
        own = row["stages"][name]
        assert own["in_loop"] and own["ratio"] < 1.0, (name, own)
        assert name in row["stages_on"]
    # Every stage left in helps (with it / without it < 1) and the file says so.
    model = bmr.Model.load(row["model_file"])
    for stage, verdict in row["stages"].items():
        assert model.extension(stage)["in_loop"] == verdict["in_loop"]
        if verdict["in_loop"]:
            assert verdict["ratio"] < 1.0, (stage, verdict)
            assert stage in row["stages_on"]
        else:
            assert stage not in row["stages_on"]
