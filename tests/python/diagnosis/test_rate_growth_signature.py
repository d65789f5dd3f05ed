"""The mechanism signature of the time shifts on the field path (``rate_dependence``, ``coil_lag``): the output
they shift grows with the drive's rate. Tables identified at one drive speed absorb such a shift at that speed as a
wider loop, so the residual without the effect must follow the fitted shift beyond a width change; a residual that
is a width alone (loops sheared or widened the same at every speed) is not a time shift, and runs that all move at
one speed cannot tell a shift from a wider loop."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bmr.diagnosis.effects import RATE_GROWTH_SHARE, input_rate, rate_growth_missing

DT = 0.001
TAU = 0.01
BEFORE = SimpleNamespace(path=None, linear=[])


class _Cache:
    def get(self, key, make):
        return make()


def _triangle(rate: float, n: int = 4000) -> np.ndarray:
    """A triangle wave between ±1 at ``rate`` (units/s): one speed."""
    return np.abs(((np.arange(n) * DT * rate) % 4.0) - 2.0) - 1.0


def _sines() -> list[np.ndarray]:
    t = np.arange(4000) * DT
    return [np.sin(2 * np.pi * f * t) for f in (0.5, 2.0)]


def _slope(u: np.ndarray) -> np.ndarray:
    """A loop's slope, steepest near the middle of the input range (N·mm per input unit)."""
    return 300.0 / np.cosh(3.0 * u) ** 2


def _case(inputs, residual_of):
    """The fitted shift ``d = −tau·slope·du/dt`` of runs driven by ``inputs`` and the residual
    ``residual_of(d, width)`` (``width = d/|du/dt|``, the same shift at one speed) plus noise."""
    runs = [SimpleNamespace(name=f"run{k + 1}", current_a=u, dt_s=DT, start=0, n_eval=u.size)
            for k, u in enumerate(inputs)]
    data = SimpleNamespace(runs=runs, cache=_Cache())
    rate = np.concatenate([input_rate(u, DT) for u in inputs])
    u = np.concatenate(inputs)
    shift = -TAU * _slope(u) * rate
    width = -TAU * _slope(u) * np.sign(rate)
    noise = 0.5 * np.random.default_rng(0).standard_normal(u.size)
    residual = residual_of(shift, width) + noise
    return SimpleNamespace(data=data, model=None, fit=lambda path, linear: (residual, None)), shift


def test_a_shift_the_residual_shows_is_the_signature():
    fitter, shift = _case(_sines(), lambda d, w: d)
    assert rate_growth_missing(fitter, BEFORE, shift, "the lag") == ""


def test_a_shift_the_tables_absorbed_at_one_speed_shows_at_other_speeds():
    # Tables from loops at 2 units/s took the shift there as a wider loop: a run at 0.5 units/s is narrower than
    # they say, one at 4 units/s wider; each run alone moves at one speed.
    fitter, shift = _case([_triangle(0.5), _triangle(4.0)], lambda d, w: d - 2.0 * w)
    assert rate_growth_missing(fitter, BEFORE, shift, "the lag") == ""


def test_a_wider_loop_at_every_speed_is_not_a_shift():
    # The same width change on slow and fast loops (a sheared or non-congruent loop the tables miss): a lag fitted
    # to it gains, but the residual does not grow with the rate.
    fitter, shift = _case(_sines(), lambda d, w: 1.5 * w)
    why = rate_growth_missing(fitter, BEFORE, shift, "the lag")
    assert "grows with the rate by" in why and f"at least {RATE_GROWTH_SHARE:g}" in why, why


def test_a_shift_half_the_size_fitted_is_not_enough():
    fitter, shift = _case(_sines(), lambda d, w: 0.3 * d + 1.0 * w)
    assert "grows with the rate by 0.3" in rate_growth_missing(fitter, BEFORE, shift, "the lag")


def test_one_drive_speed_cannot_show_it():
    fitter, shift = _case([_triangle(1.0), _triangle(1.0)[::-1]], lambda d, w: d)
    assert "one speed" in rate_growth_missing(fitter, BEFORE, shift, "the lag")
