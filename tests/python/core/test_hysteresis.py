"""The CBH operator through the Python API: accuracy against a Preisach plant, state handling, bad tables."""
import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import bmr
from preisach_plant import PreisachPlant, edge_grid, first_order_curves


def span(h):
    lo, hi = h.output_range
    return hi - lo


def test_reproduces_preisach_plant_on_measured_reversals(preisach_curves):
    asc, desc = preisach_curves
    h = bmr.Hysteresis.from_curves(asc, desc)
    grid = edge_grid(200)
    rng = np.random.default_rng(1)
    # Legs between measured reversal nodes, sampled on the measurement grid.
    nodes = np.arange(0, 201, 10)
    idx, inputs = 0, []
    for target in rng.choice(nodes, 60):
        path = range(idx, target, 1 if target > idx else -1)
        inputs.extend(grid[i] for i in path)
        idx = target
    inputs = np.array(inputs[1:] + [grid[idx]])
    plant = PreisachPlant(200)
    err = np.abs(h.run(inputs) - plant.run(inputs)).max() / span(h)
    assert err < 1e-9


@pytest.mark.parametrize("count", [21, 41])
def test_off_grid_history_rms_below_one_percent(count):
    asc, desc = first_order_curves(200, count)
    h = bmr.Hysteresis.from_curves(asc, desc)
    rng = np.random.default_rng(count)
    u, cur, lo, hi = [], -1.0, -1.0, 1.0
    for r in range(120):
        tgt = cur + (hi - cur) * rng.uniform(0.2, 1) if r % 2 == 0 else cur - (cur - lo) * rng.uniform(0.2, 1)
        if r % 2 == 0:
            lo = cur
        else:
            hi = cur
        if rng.uniform() < 0.3:
            lo, hi = -1.0, 1.0
        u.extend(np.linspace(cur, tgt, 12)[1:])
        cur = tgt
    u = np.array(u)
    rms = np.sqrt(np.mean((h.run(u) - PreisachPlant(200).run(u)) ** 2)) / span(h)
    assert rms < 0.01, f"{count} curves: RMS {100 * rms:.3f} % of span"


def test_initial_states_and_reset(small_curves):
    asc, desc = small_curves
    h = bmr.Hysteresis.from_curves(asc, desc, initial="positive")
    lo, hi = h.output_range
    assert h.output == hi and h.input == 1.0
    h.reset()
    assert h.output == lo and h.memory == [(-1.0, lo)]
    h.reset(("ascending", 0.2))
    y_up = h.output
    h.reset(("descending", 0.2))
    assert h.output > y_up  # the descending major branch lies above the ascending one
    with pytest.raises(bmr.BmrError, match="initial"):
        h.reset("sideways")


def test_run_continues_state_and_matches_step(small_curves):
    asc, desc = small_curves
    a = bmr.Hysteresis.from_curves(asc, desc)
    b = copy.copy(a)
    u = np.sin(np.linspace(0, 20, 5000)) * np.linspace(1, 0.1, 5000)
    first = a.run(u[:2500])
    second = a.run(u[2500:])
    stepped = np.array([b.step(x) for x in u])
    assert np.array_equal(np.r_[first, second], stepped)
    assert a.run([0, 1]).dtype == np.float64  # lists and ints are accepted


def test_nan_input_is_a_documented_safe_output(small_curves):
    h = bmr.Hysteresis.from_curves(*small_curves)
    h.step(0.4)
    mem = h.memory
    assert np.isnan(h.step(float("nan")))
    assert h.memory == mem
    assert h.step(float("inf")) == h.output_range[1]


def test_snapshot_restore_replays_bit_for_bit(small_curves):
    h = bmr.Hysteresis.from_curves(*small_curves)
    h.run(np.array([0.5, -0.3, 0.2]))
    s = h.snapshot()
    u = np.random.default_rng(0).uniform(-1, 1, 300)
    y1 = h.run(u)
    h.restore(s)
    assert np.array_equal(h.run(u), y1)
    other = bmr.Hysteresis.from_curves(*first_order_curves(40, 5))
    with pytest.raises(bmr.BmrError, match="snapshot"):
        other.restore(s)


def test_consistency_zero_for_preisach_and_large_for_nonlinear_output(small_curves):
    c = bmr.Hysteresis.from_curves(*small_curves).consistency()
    assert c["max_abs"] < 1e-9 and c["pairs"] > 50
    bent = first_order_curves(60, 13, output_map=lambda y: y + 0.002 * y * abs(y))
    c2 = bmr.Hysteresis.from_curves(*bent).consistency()
    assert c2["rms"] > 1.0  # N·mm-scale mismatch: not congruent


def test_curves_round_trip(small_curves):
    h = bmr.Hysteresis.from_curves(*small_curves)
    a, d = h.curves()
    h2 = bmr.Hysteresis.from_curves(a, d)
    u = np.random.default_rng(5).uniform(-1.1, 1.1, 500)
    assert np.allclose(h.run(u), h2.run(u), atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1.5, 1.5), min_size=1, max_size=80))
def test_memory_bounded_and_nested(inputs):
    h = bmr.Hysteresis.from_curves(*first_order_curves(40, 5))
    for u in inputs:
        h.step(u)
        mem = h.memory
        assert len(mem) <= h.capacity
        maxima = [m[0] for m in mem[1::2]]
        minima = [m[0] for m in mem[0::2]]
        assert all(np.diff(maxima) < 0) and all(np.diff(minima) > 0)


# ---- bad tables: each case names the family, curve and sample -------------------------------------------------

def _good():
    return first_order_curves(40, 5)


def _with(family, i, u=None, y=None):
    asc, desc = _good()
    fam = list(asc if family == "asc" else desc)
    cu, cy = fam[i]
    fam[i] = (cu if u is None else u(cu.copy()), cy if y is None else y(cy.copy()))
    return (fam, desc) if family == "asc" else (asc, fam)


def _set(a, i, v):
    a[i] = v
    return a


@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda: (_good()[0][:1], _good()[1][:1]), r"1 ascending and 1 descending curve"),
        (lambda: _with("asc", 1, y=lambda y: y[:-1]), r"ascending curve 1: .*as many inputs as outputs"),
        (lambda: _with("desc", 2, y=lambda y: _set(y, 3, np.nan)), r"descending curve 2, sample 3: .*NaN"),
        (lambda: _with("asc", 1, u=lambda u: _set(u, 4, u[3] - 0.8)), r"ascending curve 1, sample 4: input falls back by"),
        (lambda: _with("desc", 1, u=lambda u: _set(u, 2, u[1] + 0.8)), r"descending curve 1, sample 2: input rises back by"),
        (lambda: _with("asc", 2, y=lambda y: _set(y, 5, y[5] - 400)), r"ascending curve 2, sample 5: output falls by .* \(limit"),
        (lambda: _with("desc", 2, y=lambda y: _set(y, 5, y[5] + 400)), r"descending curve 2, sample 5: output rises by .* \(limit"),
        (lambda: _with("asc", 2, u=lambda u: u[:-10], y=lambda y: y[:-10]), r"ascending curve 2 stops at input .* must reach saturation"),
        (lambda: (_good()[0] + [_good()[0][1]], _good()[1]), r"ascending curves 1 and 4 start at the same reversal"),
        (lambda: _with("asc", 0, y=lambda y: y + np.linspace(0, 60, len(y))), r"major branches do not meet at saturation input 1"),
    ],
    ids=["too-few", "length", "nan", "asc-input", "desc-input", "asc-output", "desc-output", "short", "duplicate",
         "open-loop"],
)
def test_bad_tables_raise_clear_errors(make, pattern):
    asc, desc = make()
    with pytest.raises(bmr.BmrError, match=pattern):
        bmr.Hysteresis.from_curves(asc, desc)
    assert issubclass(bmr.BmrError, ValueError)


def test_real_curves_are_accepted_measured_and_fitted_monotonically():
    # Continued switching after the reversal (the output keeps falling), noise, an input that steps back a little.
    asc, desc = _good()
    asc = list(asc)
    u, y = asc[2]
    y = y.copy()
    y[1:4] -= [3.0, 5.0, 4.0]
    asc[2] = (u, y)
    u3 = asc[3][0].copy()
    u3[6] = u3[5] - 0.002  # the input steps back where the output is flat enough not to matter
    asc[3] = (u3, asc[3][1])
    h = bmr.Hysteresis.from_curves(asc, desc)
    r = h.build_report
    worst = r.worst_violation
    assert (worst.family, worst.curve, worst.violation_sample) == ("ascending", 2, 2)
    assert worst.violation == pytest.approx(y[0] - y[2], abs=1e-9)
    assert worst.reshaped_rms > 0
    assert r.curves[3].input_backtrack == pytest.approx(0.002, rel=1e-6)
    assert [c.violation for c in r.curves if c.family == "descending"] == [0.0] * len(desc)
    d = r.to_dict()
    assert d["curves"][2]["violation_sample"] == 2 and "CurveReport" not in repr(d)
    assert f"largest move against a curve's direction {y[0] - y[2]:.4g}" in repr(r)


def test_one_family_builds_the_other_and_says_so():
    asc, desc = first_order_curves(40, 11)
    full = bmr.Hysteresis.from_curves(asc, desc, subdivisions=4)
    assert full.build_report.derived is None and full.build_report.mismatch["max_abs"] < 1e-6
    assert full.build_report.densified == (30, 30)
    for a, d, which in ((asc, desc[:1], "descending"), (asc[:1], desc, "ascending"), (asc, [], "descending")):
        h = bmr.Hysteresis.from_curves(a, d, subdivisions=4)
        r = h.build_report
        assert r.derived == which and r.mismatch is None
        assert r.derived_major == ("reversal points" if not d else "measured")
        np.testing.assert_allclose(h.output_range, full.output_range, atol=1e-9)
        # Without the opposite major branch, its reversal points trace it (linear in between): coarser.
        tol = (0.005 if d else 0.03) * np.ptp(full.output_range)
        for u in (np.linspace(-1, 1, 9), np.linspace(1, -0.6, 7), np.linspace(-0.6, 0.4, 6)):
            np.testing.assert_allclose(h.run(u), full.run(u), atol=tol)
    with pytest.raises(bmr.BmrError, match="must be its major branch"):
        bmr.Hysteresis.from_curves(asc, desc[2:3])


def test_nodes_follow_an_error_bound_and_compress_with_their_own():
    asc, desc = _good()
    h = bmr.Hysteresis.from_curves(asc, desc)
    r = h.build_report
    assert r.node_tolerance == (0.0, 0.0) and r.node_error == (0.0, 0.0)
    coarse = bmr.Hysteresis.from_curves(asc, desc, node_tolerance=1e-3).build_report
    assert coarse.nodes[0] < r.nodes[0] and 0 < coarse.node_error[0] <= coarse.node_tolerance[0]
    small, bound = h.compressed(1e-3)
    span = np.ptp(h.output_range)
    assert bound["ascending"]["error"] <= 1e-3 * span * (1 + 1e-9)
    assert small.build_report is None
    u = np.concatenate([np.linspace(-1, 0.7, 50), np.linspace(0.7, -0.2, 40), np.linspace(-0.2, 1, 50)])
    h.reset()
    assert np.max(np.abs(small.run(u) - h.run(u))) <= 2e-3 * span


def test_reversal_outside_major_range_is_rejected():
    asc, desc = _good()
    asc = list(asc) + [(np.array([1.2, 1.3]), np.array([0.0, 1.0]))]
    with pytest.raises(bmr.BmrError, match=r"ascending curve 4 starts at 1.2, outside the major-loop input range"):
        bmr.Hysteresis.from_curves(asc, desc)


def test_non_sequence_arguments_are_clear_errors():
    # Wrong types are TypeErrors that name the argument.
    with pytest.raises(TypeError, match="ascending"):
        bmr.Hysteresis.from_curves(3, [])
    with pytest.raises(TypeError, match="ascending curve 0"):
        bmr.Hysteresis.from_curves([("a", "b")], [])
