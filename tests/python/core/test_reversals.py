"""Reversal finding in the core: dead-band extrema and the reversal order of every sample."""
import numpy as np
import pytest

import bmr
from bmr import _core


def test_extrema_of_a_noisy_triangle_train():
    rng = np.random.default_rng(0)
    vertices = [0.0, 1.0, -0.6, 0.4, -1.0, 0.9]
    u = np.concatenate([np.linspace(a, b, 400, endpoint=False) for a, b in zip(vertices[:-1], vertices[1:])])
    noisy = u + rng.normal(0, 0.004, u.size)
    rev = _core.find_reversals(noisy, 0.05)
    assert rev.dtype == np.int64
    # One reversal per inner vertex, each within a few samples of the true apex (noise moves the extreme sample).
    np.testing.assert_allclose(rev, [400, 800, 1200, 1600], atol=12)
    assert np.all(np.diff(rev) > 0)
    # A dead-band wider than every swing finds nothing; the run's start is never a reversal.
    assert _core.find_reversals(noisy, 5.0).size == 0
    assert _core.find_reversals(np.zeros(3), 0.1).size == 0


def test_reversal_order_counts_from_the_last_saturation():
    path = np.array([0.0, 1.0, 0.2, 0.6, 0.3, -1.0, 0.5, 0.45, 0.52])
    order = _core.reversal_order(path, -1.0, 1.0, 0.05)
    # Up to saturation (0), down (1st reversal), up (2nd), down (3rd), saturation resets, up (1st), a slip below
    # the dead-band is no reversal.
    assert order.tolist() == [0, 0, 1, 2, 3, 0, 1, 1, 1]


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_deadband_is_a_clear_error(bad):
    with pytest.raises(bmr.BmrError, match="dead-band"):
        _core.find_reversals(np.linspace(0, 1, 10), bad)


def test_non_finite_input_names_the_sample():
    u = np.linspace(0, 1, 10)
    u[4] = np.nan
    with pytest.raises(bmr.BmrError, match="sample 4"):
        _core.find_reversals(u, 0.1)
    with pytest.raises(bmr.BmrError, match="sample 4"):
        _core.reversal_order(u, 0.0, 1.0)
    with pytest.raises(bmr.BmrError, match="lo < hi"):
        _core.reversal_order(np.zeros(3), 1.0, 1.0)
