"""The coarse-to-fine scan of input-side effects' grids: the grid's best value with fewer evaluations."""
from __future__ import annotations

import numpy as np
import pytest

from bmr.diagnosis.selection import coarse_to_fine


@pytest.mark.parametrize("n", [2, 9, 22, 49])
def test_finds_the_minimum_of_every_unimodal_criterion(n):
    rng = np.random.default_rng(n)
    for _ in range(50):
        centres = rng.uniform(-3, n + 3, size=3)  # minima inside the grid or beyond either end
        calls = []

        def score(i: int) -> np.ndarray:
            calls.append(i)
            return (i - centres) ** 2 + 0.1 * np.abs(i - centres)

        done = coarse_to_fine(n, score)
        full = np.array([score(i) for i in range(n)])
        for k in range(3):
            assert min(done, key=lambda i: done[i][k]) == int(np.argmin(full[:, k]))
        assert len(set(calls[:len(done)])) == len(calls[:len(done)])  # nothing evaluated twice


@pytest.mark.parametrize("n", [22, 49])
def test_one_criterion_needs_well_under_half_the_grid(n):
    for centre in np.linspace(-2, n + 2, 25):
        done = coarse_to_fine(n, lambda i: np.array([abs(i - centre) ** 1.5]))
        assert min(done, key=lambda i: done[i][0]) == int(np.clip(round(centre), 0, n - 1))
        assert len(done) <= n // 4 + 2 + 6


def test_nan_scores_count_as_worst():
    done = coarse_to_fine(20, lambda i: np.array([np.nan if i < 10 else (i - 14.0) ** 2]))
    assert min(done, key=lambda i: np.nan_to_num(done[i][0], nan=np.inf)) == 14


def test_product_grid_is_searched_one_axis_at_a_time():
    # Separable bowls on a 12 × 6 product grid (index outer·6 + inner), three criteria with their own minima.
    from bmr.diagnosis.selection import coordinate_scan

    rng = np.random.default_rng(7)
    for _ in range(50):
        centres = rng.uniform(-1, [12, 6], size=(3, 2))
        calls = []

        def score(i: int) -> np.ndarray:
            calls.append(i)
            o, j = divmod(i, 6)
            return (o - centres[:, 0]) ** 2 + 2.0 * (j - centres[:, 1]) ** 2

        done = coordinate_scan((12, 6), score)
        full = np.array([score(i) for i in range(72)])
        for k in range(3):
            assert min(done, key=lambda i: done[i][k]) == int(np.argmin(full[:, k]))
        assert len(done) < 72 and len(set(calls[:len(done)])) == len(done)


def test_a_long_grid_starts_eight_values_apart():
    # The delay grid (50 values): a first pass every eighth value, then three halvings around the best.
    from bmr.diagnosis.selection import coarse_stride

    assert coarse_stride(50) == 8 and coarse_stride(16) == 4 and coarse_stride(8) is None
    for centre in np.linspace(-2, 51, 40):
        done = coarse_to_fine(50, lambda i: np.array([abs(i - centre) ** 1.5]))
        assert min(done, key=lambda i: done[i][0]) == int(np.clip(round(centre), 0, 49))
        assert len(done) <= 50 // 8 + 2 + 6
