"""Discovery: the effects real devices show (creep, rate dependence, per-run calibration, leakage, accommodation),
runs whose history is unknown (coils cold after a rest), generic devices without an angle, and what no library
names (a sparse regression of the residual). Each hidden effect must be named and its parameter recovered; clean
bundles and an effect outside every library are the negative controls.

The blind diagnoses take tens of seconds each and run in the ``slow`` tier; the sparse regression, the noise
floor and the learned term of the extended model have fast tests here."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import bmr
from bmr.diagnosis.discrepancy import candidate_library, learn
from bmr.diagnosis.effects import PHYSICAL
from bmr.diagnosis.extended_model import learned_term
from bmr.diagnosis.noise import from_data, from_residual
from bmr.diagnosis.procedure import diagnose
from bmr.simulation.device import device_bundle
from bmr.simulation.excitation import diagnosis_bundle

PRESET = "rig_preisach"


# ------------------------------------------------------------------------------------------------- fast tier
def _synthetic_runs(n_runs: int = 3, n: int = 12_000, dt: float = 0.002) -> list[SimpleNamespace]:
    runs = []
    for k in range(n_runs):
        t = np.arange(n) * dt
        u = 1.2 * np.sin(2 * np.pi * 0.3 * t * (1 + 0.3 * k)) * np.sin(2 * np.pi * 0.05 * t + k)
        runs.append(SimpleNamespace(t_s=t, u=u, y=500.0 * np.tanh(u), theta=np.mod(2 * np.pi * t, 2 * np.pi),
                                    start=500))
    return runs


def _blocks(runs: list[SimpleNamespace], folds: int) -> np.ndarray:
    sizes = [r.t_s.size - r.start for r in runs]
    return np.concatenate([np.minimum(np.arange(m) * folds // m, folds - 1) for m in sizes])


def test_sparse_regression_finds_a_hidden_term_with_its_units_and_drops_the_rest():
    rng = np.random.default_rng(4)
    runs = _synthetic_runs()
    lib = candidate_library(runs, deadband=0.02)
    i = lib.names.index("int(u^2 dt)")
    j = lib.names.index("dir*ln(1+t_rev/dt)")
    truth = 0.8 * lib.matrix[:, i] - 1.5 * lib.matrix[:, j]
    r = truth + 1.5 * rng.standard_normal(truth.size)
    res = learn(lib, r, _blocks(runs, 5), 5, 1.5, input_unit="A", output_unit="N·mm")
    names = [t["name"] for t in res.terms]
    assert set(names) == {"int(u^2 dt)", "dir*ln(1+t_rev/dt)"}, res.equation()
    got = {t["name"]: t for t in res.terms}
    assert abs(got["int(u^2 dt)"]["coefficient"] - 0.8) < 0.05
    assert got["int(u^2 dt)"]["coefficient_unit"] == "N·mm/(A²·s)"
    assert abs(got["dir*ln(1+t_rev/dt)"]["coefficient"] + 1.5) < 0.15
    assert res.folds_positive == 5 and res.rms_after < 1.05 * 1.5
    assert "N·mm/(A²·s) · int(u^2 dt)" in res.equation()
    # Pure noise: nothing is kept.
    quiet = learn(lib, 1.5 * rng.standard_normal(truth.size), _blocks(runs, 5), 5, 1.5, input_unit="A",
                  output_unit="N·mm")
    assert quiet.mean_gain < 0.01


def test_learned_term_of_the_extended_model_is_the_library_signal():
    runs = _synthetic_runs(1, 4000)
    r = runs[0]
    lib = candidate_library([SimpleNamespace(**{**vars(r), "start": 0})], deadband=0.02)
    entry = {"name": "learned_discrepancy", "intercept": 0.5, "deadband": 0.02,
             "terms": [{"name": "int(u dt)", "coefficient": 2.0}, {"name": "cos(2θ)", "coefficient": -1.0}]}
    want = 0.5 + 2.0 * lib.matrix[:, lib.names.index("int(u dt)")] - lib.matrix[:, lib.names.index("cos(2θ)")]
    np.testing.assert_allclose(learned_term(entry, r.u, r.y, r.theta, 0.002), want, atol=1e-9)
    with pytest.raises(bmr.BmrError, match="unknown signal"):
        learned_term({**entry, "terms": [{"name": "nope", "coefficient": 1.0}]}, r.u, r.y, r.theta, 0.002)


def test_noise_floor_names_the_estimate_it_used():
    rng = np.random.default_rng(0)

    def run(u, y, kind="custom", sigma=None):
        return SimpleNamespace(input=np.asarray(u, float), output=np.asarray(y, float), kind=kind,
                               output_sigma=sigma)

    # Dwells: a step input held, output creeping slowly plus noise 0.3.
    u = np.repeat([0.0, 1.0, 2.0, 1.0], 500)
    y = 10 * u + np.cumsum(np.full(u.size, 1e-3)) + 0.3 * rng.standard_normal(u.size)
    est = from_data([run(u, y)], [run(u, y)])
    assert est.method == "dwell" and abs(est.sigma - 0.3) < 0.03
    # Declared uncertainties win.
    sig = np.full(u.size, 0.05)
    est = from_data([run(u, y, sigma=sig)], [run(u, y, sigma=sig)])
    assert est.method == "declared_sigma" and est.sigma == pytest.approx(0.05)
    # A ramp without dwells or repeats: no estimate from the data; the residual's high-frequency part then.
    ramp = np.linspace(0, 1, 800)
    assert from_data([run(ramp, ramp)], [run(ramp, ramp)]) is None
    hf = from_residual([np.sin(np.linspace(0, 3, 5000)) + 0.2 * rng.standard_normal(5000)])
    assert hf.method == "residual_high_frequency" and abs(hf.sigma - 0.2) < 0.02


# ------------------------------------------------------------------------------------------------- slow tier
def _draw(name: str, rng: np.random.Generator) -> dict[str, float]:
    """A realistic size of each effect for the quick diagnosis bundle."""
    u = rng.uniform
    return {
        "creep": lambda: {"fraction": u(0.02, 0.04), "tau_min_s": 0.1, "tau_max_s": float(rng.choice([10.0, 100.0]))},
        "rate_dependence": lambda: {"tau_s": u(0.008, 0.02)},
        "run_gain_offset": lambda: {"gain_sd": u(0.02, 0.04), "offset_sd": u(3.0, 6.0)},
        "leakage": lambda: {"rate_per_s": u(0.3, 0.8) * rng.choice([-1.0, 1.0])},
        "accommodation": lambda: {"kappa": u(0.06, 0.12), "cycles": 3.0},
    }[name]()


# Parameter tolerances (relative) of the main parameter of each effect.
TOLERANCE = {"creep": ("fraction", 0.5), "rate_dependence": ("tau_s", 0.35), "leakage": ("rate_per_s", 0.15),
             "accommodation": ("kappa", 0.35)}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["creep", "rate_dependence", "run_gain_offset", "leakage", "accommodation"])
def test_hidden_material_effect_is_named_fitted_and_removed(name: str) -> None:
    seed = 200 + ["creep", "rate_dependence", "run_gain_offset", "leakage", "accommodation"].index(name)
    truth = _draw(name, np.random.default_rng(seed))
    bundle = diagnosis_bundle(PRESET, effects={name: truth}, seed=seed)
    d = diagnose(bundle, progress=False, closed_loop=False)
    physical = [e["name"] for e in d.effects if e["name"] in PHYSICAL]
    assert physical == [name], (truth, d.to_dict()["effects"])
    got = next(e["params"] for e in d.effects if e["name"] == name)
    if name == "run_gain_offset":
        # Against the spread of the calibrations the evaluation runs actually drew.
        cal = [r.meta["calibration"] for r in bundle.evaluation_runs()]
        offsets = np.array([c["offset_nmm"] for c in cal])
        assert abs(got["offset_sd"] - np.std(offsets, ddof=1)) < 0.35 * np.std(offsets, ddof=1) + 0.5, (got, cal)
    else:
        key, tol = TOLERANCE[name]
        assert abs(got[key] - truth[key]) <= tol * abs(truth[key]), (name, truth, got)
    excess = d.nominal_heldout_rms - d.noise_floor
    assert d.nominal_heldout_rms - d.residual_rms >= 0.5 * excess
    assert d.noise["method"] == "off_state"


@pytest.mark.slow
def test_runs_that_start_with_cold_coils_are_diagnosed_as_heating() -> None:
    # Every run starts after an hour's rest: the heating state does not carry over, and the diagnosis must
    # estimate that instead of assuming the runs followed back to back.
    truth = {"gain_loss": 0.1, "tau_s": 60.0}
    bundle = diagnosis_bundle(PRESET, effects={"thermal_drift": truth}, seed=31, rest_s=3600.0)
    d = diagnose(bundle, progress=False, closed_loop=False)
    assert d.cause == "thermal_drift", d.to_dict()["effects"]
    assert [e["name"] for e in d.effects if e["name"] in PHYSICAL] == ["thermal_drift"]
    assert d.residual_rms < 1.15 * d.noise_floor


@pytest.mark.slow
def test_an_effect_outside_every_library_is_not_named_but_learned() -> None:
    # An offset that grows with the heat the sensor's neighbourhood takes in: k ∫u² dt from each run's start
    # (no cooling, not a gain, not the vocabulary's), added to every run of a clean bundle.
    k = 0.6  # N·mm/(A²·s)
    bundle = diagnosis_bundle(PRESET, seed=41)
    for r in bundle.runs:
        u, t = r.input, r.time
        heat = np.concatenate([[0.0], np.cumsum(0.5 * np.diff(t) * (u[1:] ** 2 + u[:-1] ** 2))])
        r.data[r.quantities.output.column] = r.output + k * heat
    d = diagnose(bundle, progress=False, closed_loop=False)
    assert not [e["name"] for e in d.effects if e["name"] in PHYSICAL], d.to_dict()["effects"]
    assert d.learned and d.learned["accepted"], d.learned
    terms = {t["name"]: t for t in d.learned["terms"]}
    assert "int(u^2 dt)" in terms, d.learned["equation"]
    assert abs(terms["int(u^2 dt)"]["coefficient"] - k) < 0.3 * k
    assert terms["int(u^2 dt)"]["coefficient_unit"] == "N·mm/(A²·s)"
    assert any(e["name"] == "learned_discrepancy" for e in d.extended_model.extensions)


PIEZO_TRUTH = {"creep": {"fraction": 0.03, "tau_min_s": 0.1, "tau_max_s": 100.0},
               "rate_dependence": {"tau_s": 0.004}}


@pytest.fixture(scope="module")
def piezo_diagnosis(tmp_path_factory):
    """A piezo-like device (voltage → displacement, no angle) with creep and rate dependence, written as a bundle
    folder and diagnosed from it."""
    path = tmp_path_factory.mktemp("piezo") / "bundle"
    bmr.write_bundle(device_bundle("piezo", effects=PIEZO_TRUTH, seed=3), path)
    return path, diagnose(path, progress=False, closed_loop=False)


@pytest.mark.slow
def test_piezo_without_angle_is_diagnosed_end_to_end(piezo_diagnosis, tmp_path, capsys) -> None:
    path, d = piezo_diagnosis
    names = [e["name"] for e in d.effects if e["name"] in PHYSICAL]
    assert "creep" in names, d.to_dict()["effects"]
    assert not set(names) & {"friction_current", "friction_harmonics", "torque_ripple"}
    creep = next(e["params"] for e in d.effects if e["name"] == "creep")
    key, tol = TOLERANCE["creep"]
    assert abs(creep[key] - PIEZO_TRUTH["creep"][key]) <= tol * PIEZO_TRUTH["creep"][key], creep
    excess = d.nominal_heldout_rms - d.noise_floor
    assert d.nominal_heldout_rms - d.residual_rms >= 0.5 * excess
    doc = d.to_dict()
    assert doc["units"] == {"input": "V", "output": "µm"}
    assert doc["noise"]["method"] in ("dwell", "residual_high_frequency")
    assert "µm" in repr(d) and "voltage" in d.html_section()
    from bmr.cli import main

    assert main(["diagnose", str(path), "--json", str(tmp_path / "d.json")]) == 0
    out = capsys.readouterr().out
    assert "voltage (V) → displacement (µm)" in out and "µm" in out
    assert "N·mm" not in out


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="with creep in the same runs, a constant input lag (coil_lag) wins the first "
                                       "round by a hair over the slope-following one (held-out gains 0.57 and "
                                       "0.56) and rate_dependence adds too little after it")
def test_piezo_rate_dependence_is_told_apart_from_an_input_lag_under_creep(piezo_diagnosis) -> None:
    _, d = piezo_diagnosis
    names = [e["name"] for e in d.effects if e["name"] in PHYSICAL]
    assert set(names) == {"creep", "rate_dependence"}, d.to_dict()["effects"]
    got = next(e["params"] for e in d.effects if e["name"] == "rate_dependence")
    key, tol = TOLERANCE["rate_dependence"]
    assert abs(got[key] - PIEZO_TRUTH["rate_dependence"][key]) <= tol * PIEZO_TRUTH["rate_dependence"][key]


@pytest.mark.slow
@pytest.mark.parametrize("device", ["piezo", "ferroelectric"])
def test_clean_device_bundles_raise_no_alarm(device: str) -> None:
    # Negative control without an angle: nothing physical named, no learned term kept.
    d = diagnose(device_bundle(device, seed=11), progress=False, closed_loop=False)
    assert not [e["name"] for e in d.effects if e["name"] in PHYSICAL], d.to_dict()["effects"]
    assert not (d.learned and d.learned["accepted"]), d.learned


@pytest.mark.slow
def test_slac_quadrupole_diagnosis_reports_in_tesla(slac_data) -> None:
    from bmr.data.importing import import_logs

    res = import_logs([slac_data / f"strplt.ru{k}" for k in range(3, 9)], input="MAIN:A", output="BL:T",
                      output_sigma="sigBL", output_name="integrated gradient", holdout=["run7", "run8"])
    d = diagnose(res.bundle, progress=False, closed_loop=False)
    doc = d.to_dict()
    assert doc["units"]["output"] == "T" and doc["noise"]["method"] == "declared_sigma"
    assert 3e-5 < d.noise_floor < 2e-4  # the declared sigmas, ~6e-5 T RMS
    assert 1e-4 < d.nominal_heldout_rms < 1e-2
    assert d.residual_rms <= d.nominal_heldout_rms * (1 + 1e-9)
    if not d.effects and not (d.learned and d.learned["accepted"]):
        # What stays unexplained is named by the signal it depends on.
        assert d.unexplained and d.unexplained[0]["signal"]
