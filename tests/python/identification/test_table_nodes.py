"""Where the least-squares table's nodes lie (``bmr.identification.lstsq.table_nodes``): evenly spaced, or finer
where the measured branches switch and where the runs reverse."""
import numpy as np
import pytest

from bmr import BmrError
from bmr.identification import lstsq
from bmr.identification.lstsq import table_nodes


def _square_loop(switch: float = 0.5, width: float = 0.03, n: int = 2001) -> tuple[np.ndarray, np.ndarray]:
    """A square major loop over [-1, 1] (input units): ascending switches at +switch, descending at -switch."""
    up = np.linspace(-1.0, 1.0, n)
    down = up[::-1]
    u = np.concatenate([up, down[1:]])
    y = np.concatenate([np.tanh((up - switch) / width), np.tanh((down[1:] + switch) / width)])
    return u, y


def test_uniform_grid_is_evenly_spaced():
    u, y = _square_loop()
    np.testing.assert_array_equal(table_nodes([u], [y], -1.0, 1.0, 40, "uniform"), np.linspace(-1.0, 1.0, 41))


def test_adaptive_grid_is_finer_at_the_switching_fields_and_never_much_coarser():
    u, y = _square_loop()
    n = 40
    nodes = table_nodes([u], [y], -1.0, 1.0, n, "adaptive")
    assert nodes.size == n + 1 and nodes[0] == -1.0 and nodes[-1] == 1.0
    widths = np.diff(nodes)
    assert np.all(widths > 0)
    even = 2.0 / n
    at = (nodes[:-1] + nodes[1:]) / 2
    # The switching fields get cells several times finer than the even spacing; the flat stretches coarser ones,
    # at most 1 / (share left even) times the even spacing.
    for field in (-0.5, 0.5):
        assert widths[np.argmin(np.abs(at - field))] < 0.4 * even
    assert widths[np.argmin(np.abs(at - 0.0))] > even
    assert widths.max() <= even / (1.0 - lstsq.GRID_SLOPE_SHARE - lstsq.GRID_TURN_SHARE) * (1 + 1e-9)


def test_adaptive_grid_follows_the_reversals_of_first_order_curves():
    # Ascending first-order curves of a linear (anhysteretic) output from reversals spread over [-1, 0]: no slope
    # contrast, so the nodes follow where the curves start.
    us, ys = [], []
    for r in np.linspace(-1.0, 0.0, 21):
        u = np.concatenate([[1.0], np.linspace(r, 1.0, 200)])
        us.append(u)
        ys.append(0.5 * u)
    nodes = table_nodes(us, ys, -1.0, 1.0, 40, "adaptive")
    assert np.count_nonzero(nodes < 0.0) > np.count_nonzero(nodes > 0.0) + 10


def test_flat_output_without_reversals_keeps_the_even_grid():
    u = np.linspace(-1.0, 1.0, 500)
    nodes = table_nodes([u], [np.zeros_like(u)], -1.0, 1.0, 24, "adaptive")
    np.testing.assert_allclose(nodes, np.linspace(-1.0, 1.0, 25), atol=1e-12)


def test_unknown_grid_is_a_clear_error():
    u, y = _square_loop()
    with pytest.raises(BmrError, match="grid must be one of"):
        table_nodes([u], [y], -1.0, 1.0, 10, "log")


def test_fit_and_identify_use_the_grid_asked_for():
    import independent_preisach as P

    from bmr.identification.lstsq import fit_tables_lstsq
    from bmr.identification.signals import run_input, run_output

    rng = np.random.default_rng(5)
    plant = P.Plant()
    runs = [P.record(plant, "major", "custom", [0.0, P.HI, P.LO, P.HI, P.LO, P.HI], rng, fs=100.0)]
    u, y = run_input(runs[0]), run_output(runs[0])
    lo, hi = float(u.min()), float(u.max())
    tables = fit_tables_lstsq(runs, n_intervals=24, input_range=(lo, hi), grid="adaptive")
    assert tables.settings["grid"] == "adaptive"
    np.testing.assert_array_equal(np.asarray(tables.everett.grid), table_nodes([u], [y], lo, hi, 24, "adaptive"))
    uniform = fit_tables_lstsq(runs, n_intervals=24, input_range=(lo, hi))
    np.testing.assert_array_equal(np.asarray(uniform.everett.grid), np.linspace(lo, hi, 25))
    with pytest.raises(BmrError, match="grid must be one of"):
        fit_tables_lstsq(runs, n_intervals=24, grid="fine")


def test_auto_grid_is_adaptive_for_a_forc_family_only():
    from bmr.identification.lstsq import resolved_grid

    # Ascending first-order curves, each led by a point at the calibration (high) input: one reversal per run.
    forcs = [np.concatenate([[1.0], np.linspace(r, 1.0, 100)]) for r in np.linspace(-1.0, 0.5, 12)]
    assert resolved_grid("auto", forcs) == "adaptive"
    assert resolved_grid("auto", forcs[:lstsq.FORC_FAMILY_MIN_RUNS - 1]) == "uniform"  # too few curves to tell
    u, _ = _square_loop()
    assert resolved_grid("auto", [u] * 12) == "uniform"  # loops: two reversals each
    assert resolved_grid("uniform", forcs) == "uniform" and resolved_grid("adaptive", [u]) == "adaptive"
    with pytest.raises(BmrError, match="grid must be one of"):
        resolved_grid("log", forcs)
