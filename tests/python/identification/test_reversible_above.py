"""Cells of the Preisach plane above every input the runs reach by a fall: the runs fix each column's sum there,
not its split, and the table puts that mass on the diagonal (reversible). Outputs along the runs do not change; the
descending major branch above the highest fall does."""
from __future__ import annotations

import numpy as np

from bmr import _core
from bmr.identification.lstsq import descending_top, reversible_above


def _forc_like_inputs(top: float, reversals: np.ndarray) -> list[np.ndarray]:
    # From the top (a calibration point), a jump down to the reversal, then up in steps: no sample falls above it.
    return [np.concatenate([[top], np.linspace(r, top, 40)]) for r in reversals]


def test_mass_above_the_highest_fall_goes_to_the_diagonal_and_the_runs_do_not_see_it() -> None:
    rng = np.random.default_rng(0)
    grid = np.linspace(-1.0, 1.0, 21)
    n = grid.size - 1
    masses = rng.uniform(0.0, 1.0, n * (n + 1) // 2)
    us = _forc_like_inputs(1.0, np.linspace(0.15, -1.0, 12))
    top = descending_top(us, -1.0, 1.0)
    assert top == np.max([u[1] for u in us])  # the highest reversal: the jumps from the top reach nothing higher
    moved = reversible_above(grid, masses, top)
    assert np.isclose(moved.sum(), masses.sum()) and not np.allclose(moved, masses)
    before = _core.EverettModel(grid, masses, 0.0)
    after = _core.EverettModel(grid, moved, 0.0)
    for u in us:
        np.testing.assert_allclose(after.simulate(u, 0.0, [1.0]), before.simulate(u, 0.0, [1.0]), atol=1e-12)
    # The descending major branch between the top and the highest reversal: the moved mass now follows the input
    # back down (reversible) instead of staying up until its down-switching field.
    down = np.linspace(1.0, 0.3, 30)
    assert not np.allclose(after.simulate(down, 0.0, [1.0]), before.simulate(down, 0.0, [1.0]))


def test_a_run_that_falls_through_the_whole_range_leaves_the_table_as_it_is() -> None:
    grid = np.linspace(-1.0, 1.0, 11)
    masses = np.random.default_rng(1).uniform(0.0, 1.0, 55)
    loop = np.concatenate([np.linspace(1.0, -1.0, 50), np.linspace(-1.0, 1.0, 50)])
    top = descending_top([loop], -1.0, 1.0)
    np.testing.assert_array_equal(reversible_above(grid, masses, top), masses)
