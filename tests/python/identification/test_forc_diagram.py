"""The FORC diagram of an identified model: a Preisach model's density is nonnegative and holds half its output
span (each hysteron switches by its weight once up and once down), and the figure is written."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.report.forc_diagram import forc_density, forc_diagram


def test_density_of_a_preisach_model(small_curves, tmp_path):
    asc, desc = small_curves
    model = bmr.Model.from_curves(asc, desc)
    d = forc_density(model, 61)
    step = float(d.hr[1] - d.hr[0])
    rho = d.rho[np.isfinite(d.rho)]
    lo, hi = model.hysteresis.output_range
    assert rho.sum() * step ** 2 == pytest.approx(0.5 * (hi - lo), rel=0.05)
    assert rho.min() > -0.02 * rho.max()
    # Below the diagonal (h < hr) there is no curve.
    assert np.all(np.isnan(d.rho[np.tril_indices(d.rho.shape[0], -1)]))
    path = forc_diagram(model, tmp_path / "forc.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(bmr.BmrError, match="points must be an integer >= 5"):
        forc_density(model, 3)
