"""Identification: friction least squares and order selection, reversal finding, first-order curves, the FORC
and least-squares table paths on a synthetic Preisach plant, and the ``bmr identify`` command."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.data.bundle import Run, write_bundle
from bmr.identification.forc import find_reversals

from identify_synthetic import FRICTION, friction_nmm, plant_everett, synthetic_bundle


def _off_state_run(c0, a, b, noise=1.0, n=30000, seed=0):
    rng = np.random.default_rng(seed)
    theta = np.linspace(0.0, 60.0, n)
    torque = friction_nmm(theta, c0, a, b) + rng.normal(0.0, noise, n)
    return Run("off", "off_state", pd.DataFrame({"t_s": np.arange(n) * 1e-3, "current_a": np.zeros(n),
                                                   "theta_rad": theta, "torque_nmm": torque}))


def test_friction_coefficients_within_their_uncertainty():
    c0, a, b = FRICTION
    fit = bmr.fit_friction(_off_state_run(c0, a, b))
    assert fit.order == 3
    true = [c0] + [v for pair in zip(a, b) for v in pair]
    for row, t in zip(fit.table(), true):
        assert abs(row["value"] - t) < 4.0 * row["stderr"], (row, t)
    # The standard errors are honest: about noise / sqrt(n/2) for the harmonics.
    assert 0.5 < fit.a_stderr[0] / (1.0 / np.sqrt(30000 / 2)) < 2.0
    assert fit.residual_rms_nmm == pytest.approx(1.0, rel=0.05)


@pytest.mark.parametrize("hidden", [5, 8, 12])
@pytest.mark.parametrize("criterion", ["bic", "holdout"])
def test_hidden_harmonic_order_is_found(hidden, criterion):
    a = np.zeros(hidden)
    b = np.zeros(hidden)
    a[0], b[1] = 5.0, -2.0
    a[hidden - 1] = 1.2  # gear-mesh-like line well above the paper's 3rd harmonic
    fit = bmr.fit_friction(_off_state_run(10.0, a, b, seed=hidden), criterion=criterion)
    assert fit.order == hidden, fit.scores
    assert abs(fit.a[hidden - 1] - 1.2) < 4 * fit.a_stderr[hidden - 1]
    assert set(fit.scores) == set(range(13))


def test_friction_errors_are_clear():
    run = _off_state_run(1.0, [0.0], [0.0], n=3)
    fit = bmr.fit_friction(run)  # three samples determine the constant only
    assert fit.order == 0
    with pytest.raises(bmr.BmrError, match="off_state"):
        bmr.fit_friction(bmr.Bundle("x", 1000.0, [synthetic_bundle().run("triangle")]))
    with pytest.raises(bmr.BmrError, match="max_order"):
        bmr.fit_friction(run, max_order=-1)


def test_reversals_ignore_noise_and_small_slips():
    u = np.concatenate([np.linspace(0, 1, 200), np.linspace(1, -0.5, 300), np.linspace(-0.5, 0.8, 260)])
    rng = np.random.default_rng(3)
    noisy = u + rng.normal(0, 0.003, u.size)
    noisy[100:105] -= 0.02  # a small backward slip on the way up
    rev = find_reversals(noisy, 0.05)
    assert len(rev) == 2
    assert abs(rev[0] - 199) < 15 and abs(rev[1] - 499) < 15
    with pytest.raises(bmr.BmrError):
        find_reversals(u, 0.0)


def test_first_order_curves_are_monotone_and_start_at_their_reversals():
    b = synthetic_bundle(noise_nmm=2.0)
    fr = bmr.fit_friction(b)
    curves = bmr.extract_first_order_curves(b.by_kind("first_order_ascending", "first_order_descending"), fr)
    assert len(curves.ascending) == 11 and len(curves.descending) == 11
    for u, y in curves.ascending:
        assert np.all(np.diff(u) > 0) and np.all(np.diff(y) >= 0)
    for u, y in curves.descending:
        assert np.all(np.diff(u) < 0) and np.all(np.diff(y) <= 0)
    # Reversal outputs sit on the plant's major branches (noise 2 N·mm, averaged).
    plant = plant_everett()
    for u, y in curves.ascending[1:]:
        m = u[0]
        on_major = plant.simulate(np.array([-1.25, 1.25, m]))[-1]
        assert abs(y[0] - on_major) < 6.0
    cur_a, cur_d = bmr.Hysteresis.from_curves(curves.ascending, curves.descending).current_curves()
    for t, i in cur_a:
        assert np.all(np.diff(t) > 0)
    for t, i in cur_d:
        assert np.all(np.diff(t) < 0)


def test_forc_and_lstsq_reproduce_held_out_runs():
    b = synthetic_bundle(noise_nmm=1.0)
    model = bmr.identify(b, method="both")
    info = model.meta["identification"]
    forc = info["heldout_rms"]["forc"]
    lstsq = info["heldout_rms"]["lstsq"]
    assert set(forc) == {"triangle", "multipeak"}
    # FORC: 10 measured reversals per family over ±1.25 A (table resolution ~ 10 N·mm on a 1000 N·mm loop).
    assert max(forc.values()) < 15.0
    # Least squares on the same runs: at least as good, near the 1 N·mm noise floor.
    for name in forc:
        assert lstsq[name] <= forc[name]
        assert lstsq[name] < 5.0
    assert info["chosen"] == "lstsq"
    # How long identification takes is measured by benches/identify_bundle.py, not asserted here.
    assert info["time_s"]["total"] > 0


def test_identify_rejects_unknown_method_and_missing_protocol():
    b = synthetic_bundle()
    with pytest.raises(bmr.BmrError, match="method"):
        bmr.identify(b, method="magic")
    only_eval = bmr.Bundle("x", 1000.0, [r for r in b.runs if not r.kind.startswith("first_order")])
    with pytest.raises(bmr.BmrError, match="first_order"):
        bmr.identify(only_eval, method="forc")
    # The least-squares path works from any excitation.
    model = bmr.identify(only_eval, method="lstsq")
    assert [r["name"] for r in model.meta["identification"]["lstsq_fit"]["runs"]] == ["triangle", "multipeak"]


def test_everett_fit_errors_are_bmr_errors():
    g = np.linspace(0, 1, 5)
    u = np.linspace(0, 1, 50)
    with pytest.raises(bmr.BmrError, match="no samples"):
        bmr.fit_everett(g, [(u, u, np.zeros(50), 0)])
    with pytest.raises(bmr.BmrError, match="offset column"):
        bmr.fit_everett(g, [(u, u, np.ones(50), 3)], 1)
    with pytest.raises(bmr.BmrError, match="strictly increase"):
        bmr.fit_everett(np.array([0.0, 1.0, 0.5]), [(u, u, np.ones(50), 0)])
    bad = u.copy()
    bad[7] = np.nan
    with pytest.raises(bmr.BmrError, match="sample 7"):
        bmr.fit_everett(g, [(bad, u, np.ones(50), 0)])
    with pytest.raises(bmr.BmrError, match="nonnegative"):
        bmr.EverettModel(g, -np.ones(10), 0.0)


def test_cli_identify_writes_model_and_summary(tmp_path, capsys):
    from bmr.cli import main

    write_bundle(synthetic_bundle(), tmp_path / "b")
    out = tmp_path / "model.json"
    assert main(["identify", str(tmp_path / "b"), "-o", str(out), "--method", "both"]) == 0
    text = capsys.readouterr().out
    assert "friction: order 3" in text and "held-out RMS" in text
    content = json.loads(out.read_text())
    assert content["format"] == "bmr-model/2"
    assert main(["identify", str(tmp_path / "missing"), "-o", str(out)]) == 2


def test_least_squares_results_are_typed() -> None:
    # The identification bindings return result classes (attributes with units in their docs), not dicts.
    g = np.linspace(-1.0, 1.0, 9)
    u = np.r_[np.linspace(-1, 1, 80), np.linspace(1, -0.2, 60), np.linspace(-0.2, 1, 60)]
    truth = bmr.EverettModel(g, np.full(36, 0.05), -0.4)
    y = truth.simulate(u)
    fit = bmr.fit_everett(g, [(u, y, np.ones(u.size), 0)])
    assert isinstance(fit, bmr.EverettFit) and isinstance(fit.model, bmr.EverettModel)
    assert fit.n_rows == u.size and fit.offsets.shape == (1,) and fit.passive.dtype == bool
    assert fit.rms < 1e-3 and repr(fit).startswith("EverettFit(rms=")
    theta = np.linspace(0, 4 * np.pi, 400)
    f = bmr._core.fit_friction_order(theta, 3.0 + 0.5 * np.sin(theta) - 0.2 * np.cos(2 * theta), 2)
    assert isinstance(f, bmr.FrictionOrderFit) and f.order == 2 and f.covariance.shape == (5, 5)
    np.testing.assert_allclose([f.c0, *f.a, *f.b], [3.0, 0.5, 0.0, 0.0, -0.2], atol=1e-9)
    with pytest.raises(TypeError):
        fit["model"]  # type: ignore[index]
