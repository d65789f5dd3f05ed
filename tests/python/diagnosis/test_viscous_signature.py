"""The ``viscous`` candidate's mechanism signature: a loss grows with the input's rate in the direction of the
motion in every run that moves (runs of different speed alike); a residual that follows the rate with the opposite
sign in one of them is not a viscous loss, whatever a pooled fit over all runs says."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bmr.diagnosis.effects import Viscous, input_rate


class _Cache:
    def get(self, key, make):
        return make()


def _fitter(residual_of_rate):
    """Two runs (a slow and a fast sine) and a residual made of each run's rate by ``residual_of_rate``."""
    dt = 0.01
    t = np.arange(2000) * dt
    runs = [SimpleNamespace(name=f"run{k}", current_a=np.sin(2 * np.pi * f * t), dt_s=dt, start=0, n_eval=t.size)
            for k, f in ((1, 0.2), (2, 1.0))]
    data = SimpleNamespace(runs=runs, cache=_Cache())
    rng = np.random.default_rng(0)
    residual = np.concatenate([residual_of_rate(k, input_rate(r.current_a, dt)) + 0.05 * rng.standard_normal(t.size)
                               for k, r in enumerate(runs)])
    return SimpleNamespace(data=data, model=None, fit=lambda path, linear: (residual, None))


def test_a_loss_in_every_run_shows_the_signature():
    f = _fitter(lambda k, rate: 3.0 * rate)
    assert Viscous().signature_missing(f, SimpleNamespace(path=None, linear=[])) == ""


def test_a_residual_against_the_motion_in_one_run_does_not():
    # Pooled over both runs the coefficient is positive (the fast run dominates), but the slow run opposes it.
    f = _fitter(lambda k, rate: (-3.0 if k == 0 else 3.0) * rate)
    why = Viscous().signature_missing(f, SimpleNamespace(path=None, linear=[]))
    assert "run1" in why and "run2" not in why, why
