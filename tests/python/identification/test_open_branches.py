"""Identification never refuses on the nominal model's assumptions: the nonnegative solve terminates and reports
its conditioning, and first-order families whose branches do not close because the output integrates a leakage
are identified jointly with that leakage (the virtual ferroelectric capacitor recorded as first-order curves)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from lab_files import write_aixacct

import bmr
from bmr.cli import main
from bmr.identification.lstsq import OPEN_BRANCH_SHARE, fit_tables_lstsq, saturation_closure
from bmr.identification.signals import running_integral
from bmr.simulation.device import device_bundle

# The virtual ferroelectric capacitor at a low logging rate (the first-order families are unchanged).
FS = 500.0


def _forc_problem() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 16-interval Everett table driven through first-order reversals and a drifting minor-loop train."""
    g = np.linspace(-1.0, 1.0, 17)
    rng = np.random.default_rng(4)
    truth = bmr.EverettModel(g, rng.uniform(0.0, 0.02, g.size * (g.size - 1) // 2), 0.1)
    parts = []
    for turn in np.linspace(-0.9, 0.9, 10):
        parts += [np.linspace(-1, turn, 30), np.linspace(turn, -1, 30)]
    t = np.linspace(0, 1, 600)
    parts.append(-0.6 + 1.2 * t + 0.15 * np.sin(2 * np.pi * 9 * t))
    u = np.concatenate(parts)
    return g, u, truth.simulate(u)


def test_the_nonnegative_solve_terminates_when_pivoting_is_cut_short_and_reports_its_conditioning() -> None:
    g, u, y = _forc_problem()
    full = bmr.fit_everett(g, [(u, y, np.ones(u.size), 0)])
    cut = bmr.fit_everett(g, [(u, y, np.ones(u.size), 0)], max_iter=1)
    assert full.converged and cut.converged
    assert full.kkt_violation <= 1e-9 and cut.kkt_violation <= 1e-9
    assert np.isfinite(full.condition) and full.condition >= 1.0
    # The same minimiser either way (unique: the quadratic is strictly convex).
    assert cut.rss == pytest.approx(full.rss, rel=1e-6, abs=1e-12)
    np.testing.assert_allclose(cut.model.masses, full.model.masses, atol=1e-6 * np.max(full.model.masses))
    tables = fit_tables_lstsq([_run(u, y)], n_intervals=16)
    cond = tables.conditioning
    assert cond is not None and cond.converged and cond.to_dict()["converged"] is True
    assert "solve converged" in repr(tables)


def _run(u: np.ndarray, y: np.ndarray, t: np.ndarray | None = None) -> bmr.Run:
    import pandas as pd

    from bmr.data.quantities import Quantities, Quantity

    q = Quantities(Quantity.declare("V", "voltage"), Quantity.declare("V", "charge", column="charge_v"))
    t = np.arange(u.size) * 1e-3 if t is None else t
    return bmr.Run("forc", "custom", pd.DataFrame({"t_s": t, q.input.column: u, q.output.column: y}), {}, q,
                   "identification")


def test_saturation_closure_measures_open_branches() -> None:
    _, u, y = _forc_problem()
    t = np.arange(u.size) * 1e-3
    assert saturation_closure([u], [y], -1.0, 1.0, 1e-3) < 1e-9
    leaky = y + 0.5 * running_integral(u, t)
    assert saturation_closure([u], [leaky], -1.0, 1.0, 1e-3) > OPEN_BRANCH_SHARE
    # Leakage only in "leakage" mode or when the branches are open.
    tables = fit_tables_lstsq([_run(u, leaky, t)], n_intervals=16, drift="auto")
    assert tables.leakage_rate == pytest.approx(0.5, rel=0.02)
    assert fit_tables_lstsq([_run(u, y, t)], n_intervals=16, drift="auto").leakage_rate is None
    assert fit_tables_lstsq([_run(u, leaky, t)], n_intervals=16).leakage_rate is None
    with pytest.raises(bmr.BmrError, match="drift must be one of"):
        fit_tables_lstsq([_run(u, y, t)], drift="linear")


@pytest.fixture(scope="module")
def leaky_capacitor() -> bmr.Bundle:
    return device_bundle("ferroelectric", effects={"leakage": {"rate_per_s": 1.0}}, seed=1, sample_rate_hz=FS)


def test_leaky_first_order_families_are_identified_with_their_leakage(leaky_capacitor: bmr.Bundle) -> None:
    # The curves' branches do not meet at saturation: the first-order tables are refused, the least-squares
    # tables are identified jointly with the leakage rate, which is reported.
    m = bmr.identify(leaky_capacitor)
    rep = m.identification
    assert rep.chosen == "lstsq" and "do not meet" in rep.selection
    lst = rep.lstsq
    assert lst.closure > OPEN_BRANCH_SHARE
    assert lst.leakage_rate == pytest.approx(1.0, rel=0.02)
    assert lst.to_dict()["leakage_rate"] == lst.leakage_rate and "leakage 1" in repr(lst)
    # The hysteretic part is identified: the training runs are fitted to well under 1 % of the span.
    span = float(np.diff(m.hysteresis.output_range)[0])
    assert lst.rms < 0.01 * span
    # Without a leakage the same protocol's branches close and no leakage is fitted.
    clean = bmr.identify(device_bundle("ferroelectric", seed=1, sample_rate_hz=FS), method="lstsq")
    assert clean.identification.lstsq.leakage_rate is None


@pytest.mark.slow
def test_the_diagnosis_of_a_leaky_capacitor_names_leakage_first(leaky_capacitor: bmr.Bundle) -> None:
    d = bmr.diagnose(leaky_capacitor, progress=False, closed_loop=False)
    assert d.effects and d.effects[0]["name"] == "leakage" and d.cause == "leakage"
    assert d.effects[0]["params"]["rate_per_s"] == pytest.approx(1.0, rel=0.05)
    assert d.identification_drift is not None
    assert d.identification_drift["leakage_rate"] == pytest.approx(1.0, rel=0.02)
    assert d.to_dict()["identification_drift"]["closure"] > OPEN_BRANCH_SHARE


def test_a_leaky_analyzer_export_goes_through_import_identify_and_diagnose(tmp_path, capsys) -> None:
    # The virtual ferroelectric capacitor measured as an analyzer writes it: one table per first-order curve
    # (each a new measurement: the charge integration restarts), a repeat with random reversals held out. No
    # step refuses; identify reports the leakage, diagnose names it with its rate.
    fs = 1000.0
    dev = bmr.VirtualDevice("ferroelectric", seed=2, sample_rate_hz=fs, effects={"leakage": {"rate_per_s": 1.0}})
    step = 20.0 / fs

    def ramp(a: float, b: float) -> np.ndarray:
        return np.linspace(a, b, max(2, int(abs(b - a) / step) + 1))

    def table(v: np.ndarray) -> tuple[dict[str, str], list[str], np.ndarray]:
        dev.start_run(0.0)
        out = dev.run(np.ascontiguousarray(v))
        return {}, ["Time s", "Vplus V", "P1 uC_per_cm2"], np.column_stack([np.arange(v.size) / fs, out["input"],
                                                                            out["output"]])

    tables = [table(np.r_[ramp(0, 10), ramp(10, -10), ramp(-10, 10)[1:], ramp(10, r)[1:], ramp(r, 10)[1:],
                          ramp(10, 0)[1:]]) for r in np.linspace(-10, 10, 11)[:-1]]
    pts = np.r_[0, 10, -10, np.random.default_rng(3).uniform(-10, 10, 12), 0]
    check = table(np.concatenate([ramp(a, b)[1:] for a, b in zip(pts[:-1], pts[1:])]))
    forc, held = write_aixacct(tmp_path / "forc.dat", tables), write_aixacct(tmp_path / "check.dat", [check])
    bundle, model = tmp_path / "bundle", tmp_path / "m.json"
    assert main(["import", str(forc), str(held), "--input", "Vplus:V", "--output", "P1:uC/cm2", "--holdout",
                 "check", "-o", str(bundle)]) == 0
    assert main(["identify", str(bundle), "-o", str(model)]) == 0
    out = capsys.readouterr().out
    assert "leakage 1.00" in out and "solve converged" in out
    # Prediction with the nominal model adds the leakage fitted with its tables.
    assert main(["predict", str(model), str(bundle)]) == 0
    assert "ran: core tables, leakage identified with the tables" in capsys.readouterr().out
    assert main(["diagnose", str(bundle), "--json", str(tmp_path / "d.json")]) == 0
    out = capsys.readouterr().out
    assert "cause leakage" in out and "accepted leakage" in out
    doc = json.loads((tmp_path / "d.json").read_text())
    assert doc["effects"][0]["name"] == "leakage"
    assert doc["effects"][0]["params"]["rate_per_s"] == pytest.approx(1.0, rel=0.02)
    assert doc["identification_drift"]["leakage_rate"] == pytest.approx(1.0, rel=0.02)
