"""An effect that acts on part of the samples only (an output map after a congruent core: the higher-order
reversal curves) is judged on those samples: consistent there, and still a gain over all samples; each fold chooses
its value by its training fit there."""
from __future__ import annotations

import numpy as np

from bmr.diagnosis.effects import LIBRARY
from bmr.diagnosis.selection import Candidate, _chosen_where_it_acts

EFFECT = next(e for e in LIBRARY if e.name == "non_congruent")
NOISE = 1.5


def _candidate(gains, before=2.0, after=1.7, local=None):
    c = Candidate(EFFECT, np.asarray(gains, dtype=float), before, after, [None] * len(gains), NOISE)
    c.local = local
    return c


# Folds whose blocks hold few higher-order curves gain little: positive everywhere, not consistent overall.
UNEVEN = [0.04, 0.035, 0.19, 0.2, 0.02]


def test_uneven_gains_over_all_samples_are_not_enough():
    assert not _candidate(UNEVEN).accepted


def test_a_consistent_gain_where_the_effect_acts_is_accepted():
    local = _candidate([0.18, 0.12, 0.25, 0.3, 0.1], before=2.5, after=1.9)
    assert _candidate(UNEVEN, local=local).accepted


def test_where_it_acts_the_gain_must_be_consistent_and_explain_the_excess():
    assert not _candidate(UNEVEN, local=_candidate([0.3, -0.05, 0.25, -0.02, 0.01], 2.5, 2.2)).accepted
    # Consistent but a sliver of the excess over the noise floor.
    assert not _candidate(UNEVEN, local=_candidate([0.011, 0.012, 0.01, 0.011, 0.012], 2.5, 2.47)).accepted


def test_it_must_still_gain_over_all_samples():
    local = _candidate([0.18, 0.12, 0.25, 0.3, 0.1], before=2.5, after=1.9)
    assert not _candidate([0.01, -0.02, 0.03, -0.01, 0.0], after=1.99, local=local).accepted
    assert not _candidate([0.01, 0.01, 0.01, 0.01, 0.01], after=1.98, local=local).accepted  # below MIN_GAIN


def test_a_gain_consistent_over_all_samples_is_enough_where_the_loops_are_small():
    # The paper's protocol with a cubic yield map (seed 1000): the block of the multi-peak run's last, small loops
    # holds as many higher-order samples as the others but the map is nearly linear there (local gain -0.1 %), so
    # the interval over those samples reaches below zero while the gain over all samples is positive in every fold
    # and its interval excludes zero.
    local = _candidate([0.30, 0.07, 0.065, 0.187, -0.001], before=2.12, after=1.86)
    everywhere = [0.061, 0.024, 0.038, 0.080, 0.002]
    assert local.interval[0] < 0 < _candidate(everywhere).interval[0]
    assert _candidate(everywhere, before=1.74, after=1.67, local=local).accepted
    # Where the effect acts it must still be positive in most folds and explain enough of the excess.
    assert not _candidate(everywhere, 1.74, 1.67, local=_candidate([0.3, -0.05, 0.25, -0.02, -0.01], 2.5, 2.2)).accepted
    assert not _candidate(everywhere, 1.74, 1.67,
                          local=_candidate([0.011, 0.012, 0.01, 0.011, 0.012], 2.5, 2.47)).accepted


def test_each_fold_chooses_an_output_map_by_the_samples_where_it_acts():
    # Grid values 2 and 3 are output maps (training sums of squares of two folds on the higher-order curves);
    # value 7, a mean field, acts on every sample and keeps its fold.
    acting = {2: np.array([10.0, 5.0]), 3: np.array([8.0, 9.0])}
    assert _chosen_where_it_acts(acting, [2, 7]) == [3, 7]
    assert _chosen_where_it_acts(acting, [3, 2]) == [3, 2]
