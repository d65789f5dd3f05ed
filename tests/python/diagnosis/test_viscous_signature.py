"""The ``viscous`` candidate's mechanism signature: loop width that grows with the input's rate across speeds.
Tables identified at one drive speed absorb the loss at that speed as a wider loop, so what is left is a width
change the same in every run plus the growth with the rate beyond it; a residual that follows the rate with the
opposite sign (a time shift) in a run that moves at two speeds is not a viscous loss, and runs that all move at one
speed cannot tell a loss from a wider loop."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bmr.diagnosis.effects import Viscous, input_rate

DT = 0.01
BEFORE = SimpleNamespace(path=None, linear=[])


class _Cache:
    def get(self, key, make):
        return make()


def _triangle(rate: float, n: int = 2000) -> np.ndarray:
    """A triangle wave between ±1 at ``rate`` (units/s): one speed."""
    return np.abs(((np.arange(n) * DT * rate) % 4.0) - 2.0) - 1.0


def _fitter(inputs, residual_of_rate):
    """Runs driven by ``inputs`` and a residual made of each run's rate by ``residual_of_rate(k, rate)``."""
    runs = [SimpleNamespace(name=f"run{k + 1}", current_a=u, dt_s=DT, start=0, n_eval=u.size)
            for k, u in enumerate(inputs)]
    data = SimpleNamespace(runs=runs, cache=_Cache())
    rng = np.random.default_rng(0)
    residual = np.concatenate([residual_of_rate(k, input_rate(r.current_a, DT)) + 0.05 * rng.standard_normal(r.n_eval)
                               for k, r in enumerate(runs)])
    return SimpleNamespace(data=data, model=None, fit=lambda path, linear: (residual, None))


def _sines():
    t = np.arange(2000) * DT
    return [np.sin(2 * np.pi * f * t) for f in (0.2, 1.0)]


def test_a_loss_in_every_run_shows_the_signature():
    f = _fitter(_sines(), lambda k, rate: 3.0 * rate)
    assert Viscous().signature_missing(f, BEFORE, None) == ""


def test_a_loss_the_tables_absorbed_at_one_speed_shows_in_runs_at_other_speeds():
    # Tables from loops at 1 unit/s took the loss there as a wider loop: a run at 0.5 units/s is narrower than
    # they say, one at 4 units/s wider. Each run alone moves at one speed; across them the width grows with rate.
    c, identified_at = 3.0, 1.0
    f = _fitter([_triangle(0.5), _triangle(4.0)], lambda k, rate: c * (rate - identified_at * np.sign(rate)))
    assert Viscous().signature_missing(f, BEFORE, None) == ""


def test_a_time_shift_does_not_show_it():
    # A lag lowers the output where it rises, more the faster it moves: the width grows against the motion.
    f = _fitter([_triangle(0.5), _triangle(4.0)], lambda k, rate: -3.0 * (rate - np.sign(rate)))
    assert "does not grow with the rate" in Viscous().signature_missing(f, BEFORE, None)


def test_one_drive_speed_cannot_show_it():
    f = _fitter([_triangle(1.0), _triangle(1.0)[::-1]], lambda k, rate: 3.0 * rate)
    assert "one speed" in Viscous().signature_missing(f, BEFORE, None)


def test_a_residual_against_the_motion_in_one_run_does_not():
    # Pooled over both runs the coefficient is positive (the fast run dominates), but the slow run, which moves at
    # many speeds itself, opposes it.
    f = _fitter(_sines(), lambda k, rate: (-3.0 if k == 0 else 3.0) * rate)
    why = Viscous().signature_missing(f, BEFORE, None)
    assert "run1" in why and "run2" not in why, why
