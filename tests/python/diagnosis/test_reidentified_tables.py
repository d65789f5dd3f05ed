"""The least-squares tables a diagnosis identifies again: where a hard steel's density is a ridge along the
diagonal of the Preisach plane (narrow coercivity spread, broad interaction field), whole sweeps held out from the
protocol runs prefer a share of the smoothness penalty along the diagonal, and those tables predict the held-out
evaluation runs better than the isotropic ones, with the same names."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
import bmr.diagnosis.field as field
from bmr import _core
from bmr.diagnosis.effects import PHYSICAL
from bmr.simulation.excitation import diagnosis_bundle

# The calibration's `rig_soft` steel: harder, narrower switching fields, less reversible flux.
HARD_STEEL = {f"steel{k}.{p}": v for k in (1, 2) for p, v in
              (("coercivity_a", 0.12), ("coercivity_width_a", 0.05), ("interaction_width_a", 0.6),
               ("reversible_fraction", 0.15))}


def _diagnose(monkeypatch: pytest.MonkeyPatch, shares: tuple[float, ...]) -> bmr.Diagnosis:
    monkeypatch.setattr(field, "DIAGONAL_SHARES", shares)
    bundle = diagnosis_bundle("rig_preisach", seed=1000, sample_rate_hz=250.0, forc_reversals=7,
                              overrides=HARD_STEEL)
    return bmr.diagnose(bundle, progress=False, closed_loop=False)


def test_a_coercivity_ridge_between_few_curves_is_carried_along_the_diagonal(monkeypatch: pytest.MonkeyPatch) -> None:
    shares = field.DIAGONAL_SHARES
    isotropic = _diagnose(monkeypatch, (0.0,))
    chosen = _diagnose(monkeypatch, shares)
    doc = chosen.to_dict()["reidentified_tables"]
    assert doc["diagonal_smoothing"] > 0.0
    sweeps = {row["diagonal_smoothing"]: row["rms"] for row in doc["sweep_rms"]}
    assert sweeps[doc["diagonal_smoothing"]] <= (1.0 - field.DIAGONAL_GAIN) * sweeps[0.0]
    # Seven curves per family: the isotropic tables left 2.43 N·mm held out (noise 1.48), the chosen ones 2.06.
    assert chosen.residual_rms < isotropic.residual_rms - 0.2, (chosen.residual_rms, isotropic.residual_rms)
    # A clean bundle: no physical name either way.
    assert not [e["name"] for e in chosen.effects if e["name"] in PHYSICAL]
    assert isotropic.to_dict()["reidentified_tables"]["diagonal_smoothing"] == 0.0


def test_the_diagonal_share_is_checked() -> None:
    grid = np.linspace(-1.0, 1.0, 9)
    u = np.r_[np.linspace(-1, 1, 50), np.linspace(1, -1, 50)]
    run = (u, np.tanh(2 * u), np.ones(u.size), 0)
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(bmr.BmrError, match="diagonal_smoothing"):
            _core.fit_everett(grid, [run], diagonal_smoothing=bad)
    assert _core.fit_everett(grid, [run], diagonal_smoothing=0.0).rms == _core.fit_everett(grid, [run]).rms
