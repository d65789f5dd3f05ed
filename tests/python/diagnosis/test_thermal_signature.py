"""The ``thermal_drift`` candidate's mechanism signature: one heating state driven by the coils' current through the
whole session, so each run starts with at most the heat the runs before it left (a share in [0, 1] of it). A fit
that needs a share far outside is fitting gains that change from recording to recording."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bmr.diagnosis.effects import ThermalDrift


def _after(cold: float, gain: float, carried: float) -> SimpleNamespace:
    # A configuration's coefficients: the constant, an earlier effect's column, then the heating's three
    # (``-cold·y``, ``y``, ``-carried·y``) last.
    return SimpleNamespace(beta=np.array([0.3, 1.7, cold, gain, carried]))


@pytest.mark.parametrize("share", [0.0, 0.9, 1.0, 1.3])
def test_heat_carried_over_within_the_history_shows_the_signature(share: float) -> None:
    assert ThermalDrift().signature_missing(None, None, _after(0.05, 0.1, share * 0.05)) == ""


@pytest.mark.parametrize("share", [2.1, -0.8])
def test_heat_carried_over_beyond_the_history_does_not(share: float) -> None:
    why = ThermalDrift().signature_missing(None, None, _after(-0.12, -0.06, share * -0.12))
    assert f"{share:.2f} times" in why and "between recordings" in why, why
