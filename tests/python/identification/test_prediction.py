"""``predict`` / ``bmr predict``: held-out errors in the declared units against the single-valued baseline, on an
actuator bundle (``bmr-bundle/1``, unchanged) and on generic runs with known answers."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.cli import main
from bmr.data.quantities import ACTUATOR, Quantities, Quantity
from bmr.identification.prediction import BEFORE_KNOWN_STATE, CALIBRATION, predict, single_valued_baseline
from bmr.simulation.experiments import simulate_bundle
from preisach_plant import PreisachPlant

PIEZO = Quantities(Quantity.declare("V"), Quantity.declare("um"),
                   output_sigma=Quantity("displacement sigma", "um", "displacement_um_sigma"))


@pytest.fixture(scope="module")
def actuator(tmp_path_factory):
    folder = tmp_path_factory.mktemp("act")
    b = simulate_bundle("ideal", quick=True, seed=5)
    bmr.write_bundle(b, folder / "bundle")
    model = bmr.identify(bmr.read_bundle(folder / "bundle"), method="both")
    model.save(folder / "model.json")
    return folder


def test_actuator_bundle_v1_end_to_end(actuator, capsys):
    manifest = json.loads((actuator / "bundle" / "manifest.json").read_text())
    assert manifest["format"] == "bmr-bundle/1" and "quantities" not in manifest
    model = bmr.Model.load(actuator / "model.json")
    assert model.quantities == ACTUATOR
    p = predict(model, actuator / "bundle")  # a bundle folder: its evaluation runs
    assert [r.name for r in p.runs] == ["multi_step", "triangle", "multipeak"]
    assert p.quantities.output.unit == "N·mm" and 1100 < p.span < 1300
    total = p.total()
    # The identified CBH model tracks the plant to a few N·mm; the single-valued curve is off by the loop width.
    assert total["rms"] < 3.0 and total["baseline_rms"] > 10 * total["rms"], total
    assert all(r.state_known and r.out_of_range == 0 for r in p.runs)
    # The same figures as identify's own held-out report.
    info = model.meta["identification"]
    assert p.run("multi_step").rms == pytest.approx(info["heldout_rms"][info["chosen"]]["multi_step"], rel=1e-9)
    assert main(["predict", str(actuator / "model.json"), str(actuator / "bundle")]) == 0
    out = capsys.readouterr().out
    assert "current (A) → torque (N·mm)" in out and "RMS (N·mm)" in out and "all" in out
    assert "before the run's state is known" in out


def test_model_file_version_1_still_predicts(actuator, tmp_path):
    content = json.loads((actuator / "model.json").read_text())
    assert content["format"] == "bmr-model/2" and content["quantities"]["output"]["unit"] == "N·mm"
    old = {k: v for k, v in content.items() if k not in ("quantities", "sha256")}
    old["format"] = "bmr-model/1"
    (tmp_path / "v1.json").write_text(json.dumps(old))
    v1 = bmr.Model.load(tmp_path / "v1.json")
    assert v1.quantities == ACTUATOR
    a = predict(v1, actuator / "bundle").total()
    b = predict(actuator / "model.json", actuator / "bundle").total()
    assert a["rms"] == b["rms"]


# --------------------------------------------------------------------------------------------- generic, known
@pytest.fixture(scope="module")
def piezo_model(small_curves):
    """The 60-threshold reference plant's curves on 0..100 V, in µm (output 0..about 30 µm)."""
    asc, desc = small_curves

    def scale(curves):
        return [(50.0 * (u + 1.0), 15.0 + y / 20.0) for u, y in curves]

    return bmr.Model.from_curves(scale(asc), scale(desc), quantities=PIEZO)


def _run(name: str, volts: np.ndarray, *, sigma: float = 0.01, role: str = "evaluation") -> bmr.Run:
    plant = PreisachPlant(60)
    y = 15.0 + plant.run(volts / 50.0 - 1.0) / 20.0
    df = pd.DataFrame({"t_s": np.arange(volts.size) * 1e-3, "voltage_v": volts, "displacement_um": y,
                       "displacement_um_sigma": sigma})
    return bmr.Run(name, "custom", df, quantities=PIEZO, role=role)


def _bundle(*runs: bmr.Run) -> bmr.Bundle:
    return bmr.Bundle("stack", 1000.0, list(runs), quantities=PIEZO)


def test_baseline_is_the_middle_of_the_major_loop(piezo_model):
    asc, desc = piezo_model.hysteresis.curves()
    (ua, ya) = min(asc, key=lambda c: c[0][0])
    (ud, yd) = max(desc, key=lambda c: c[0][0])
    assert ua[0] == pytest.approx(0.0) and ud[0] == pytest.approx(100.0)
    u = np.linspace(0.0, 100.0, 37)
    expected = 0.5 * (np.interp(u, ua, ya) + np.interp(u, np.asarray(ud)[::-1], np.asarray(yd)[::-1]))
    np.testing.assert_allclose(single_valued_baseline(piezo_model, u), expected, rtol=1e-12)


def test_offsets_unknown_states_ranges_and_sigmas(piezo_model):
    up_down = np.concatenate([np.linspace(0, 100, 201), np.linspace(100, 30, 141), np.linspace(30, 80, 101)])
    inside = np.concatenate([np.linspace(40, 70, 61), np.linspace(70, 45, 51)])
    beyond = np.concatenate([np.linspace(0, 110, 221), np.linspace(110, 20, 181)])
    a = _run("a", up_down, sigma=0.02)
    shifted = a.data.assign(displacement_um=a.data["displacement_um"] + 0.7)
    b = bmr.Run("b", "custom", shifted, quantities=PIEZO, role="evaluation")
    p = predict(piezo_model, _bundle(a, b, _run("inside", inside), _run("beyond", beyond)))
    ra, rb, rin, rbe = p.runs
    # Scored from where the input has been to both ends (the top, 200 samples in), to the table's resolution.
    assert ra.state_known and ra.dropped == {BEFORE_KNOWN_STATE: 200}
    sa = ra.stats()
    # (the 60-threshold plant's own staircase between its thresholds is most of the error)
    assert sa["rms"] < 0.01 * p.span and sa["baseline_rms"] > 10 * sa["rms"]
    assert sa["rms_sigmas"] == pytest.approx(sa["rms"] / 0.02) and sa["evaluated"] == up_down.size - 200
    # An output offset shows in full with the model's offset...
    np.testing.assert_allclose(rb.residual, ra.residual + 0.7, atol=1e-12)
    # ...a run whose input never reaches both ends nor starts at one is flagged: its state is assumed.
    assert not rin.state_known and "assumed" in rin.initial
    text = p.table()
    assert "inside *" in text and "* inside: from negative saturation (assumed" in text
    assert "a: 200 sample(s) before the run's state is known (not scored)" in text
    # Beyond the range: counted, with the largest excess.
    assert rbe.out_of_range == int(np.sum(beyond > 100.0)) and rbe.max_excess == pytest.approx(10.0)
    assert "beyond: 40 sample(s) outside the model's input range (largest excess 10 V; clamped)" in text
    # An offset from the first sample removes the run's offset; that sample is not scored.
    q = predict(piezo_model, _bundle(a, b), offset="first", calibration=1, evaluate="all")
    np.testing.assert_allclose(q.run("b").residual, q.run("a").residual, atol=1e-12)
    assert q.run("b").offset - q.run("a").offset == pytest.approx(0.7)
    assert np.isnan(q.run("b").residual[0]) and q.run("b").dropped == {CALIBRATION: 1}
    assert q.run("b").evaluated == up_down.size - 1
    d = q.to_dict()
    assert d["format"] == "bmr-prediction/1" and d["output_unit"] == "µm"
    assert d["runs"]["b"]["offset_source"] == "from 1 leading sample" and d["runs"]["b"]["role"] == "evaluation"
    assert d["total"]["evaluated"] == 2 * (up_down.size - 1)
    # The baseline is calibrated the same way: its residual starts at zero too.
    assert (q.run("b").measured - q.run("b").baseline)[0] == pytest.approx(0.0, abs=1e-12)


def test_prediction_errors(piezo_model, tmp_path):
    t = np.arange(10) * 1e-3
    df = pd.DataFrame({"t_s": t, "current_a": t, "theta_rad": t, "torque_nmm": t})
    act = bmr.Bundle("rig", 1000.0, [bmr.Run("tri", "triangle", df)])
    with pytest.raises(bmr.BmrError, match=r"run 'tri': the model's input is voltage \(V\) but the run's is current "
                                           r"\(A\): they do not convert"):
        predict(piezo_model, act)
    b = _bundle(_run("a", np.linspace(0, 100, 50), role="identification"))
    assert [r.name for r in predict(piezo_model, b).runs] == ["a"]  # nothing held out: every run
    with pytest.raises(bmr.BmrError, match="offset must be 'model', 'run', 'first', 'shrunk', a number"):
        predict(piezo_model, b, offset="fit")
    with pytest.raises(bmr.BmrError, match="offset='first' needs calibration >= 1"):
        predict(piezo_model, b, offset="first")


@pytest.mark.parametrize("offset", ["first", "shrunk"])
def test_offset_options_with_a_model_identified_from_one_run(tmp_path, capsys, offset):
    # One training run gives no spread of offsets: the prior is unknown (NaN, null in the model file) and
    # "shrunk" falls back to "first" instead of failing on it.
    volts = np.concatenate([np.linspace(0, 100, 201), np.linspace(100, 20, 161), np.linspace(20, 90, 141),
                            np.linspace(90, 0, 181)])
    train = _run("train", volts, role="identification")
    held = _run("held", volts[::-1].copy())
    shifted = held.data.assign(displacement_um=held.data["displacement_um"] + 0.5)
    bundle = _bundle(train, bmr.Run("held", "custom", shifted, quantities=PIEZO, role="evaluation"))
    bmr.write_bundle(bundle, tmp_path / "b")
    model = bmr.identify(bmr.read_bundle(tmp_path / "b"), method="lstsq")
    model.save(tmp_path / "m.json")
    assert main(["predict", str(tmp_path / "m.json"), str(tmp_path / "b"), "--offset", offset]) == 0
    out = capsys.readouterr().out
    assert "from 1 leading sample" in out
    p = predict(tmp_path / "m.json", tmp_path / "b", offset=offset, calibration=1)
    assert p.run("held").offset - predict(model, bundle).run("held").offset == pytest.approx(0.5, abs=0.05)


def test_a_model_with_extensions_predicts_with_them(piezo_model, tmp_path, capsys):
    # A drive-to-output delay of 25 ms in the data: the model extended with that delay (as `bmr diagnose
    # --model-out` writes it) runs it through the Rust forward chain and predicts the run; its core alone cannot.
    from bmr.diagnosis.extended_model import with_extensions

    volts = np.concatenate([np.linspace(0, 100, 301), np.linspace(100, 25, 226), np.linspace(25, 85, 181)])
    run = _run("late", volts)
    delay = 25
    late = run.data.assign(displacement_um=np.concatenate([np.full(delay, run.output[0]), run.output[:-delay]]))
    bundle = _bundle(bmr.Run("late", "custom", late, quantities=PIEZO, role="evaluation"))
    extended = with_extensions(piezo_model, [{"name": "time_delay", "params": {"delay_s": delay * 1e-3}}])
    whole = predict(extended, bundle)
    core = predict(extended, bundle, whole_model=False)
    assert whole.ran == ["core tables", "time_delay"] and core.ran == ["core tables"]
    assert whole.total()["rms"] < 0.3 * core.total()["rms"], (whole.total(), core.total())
    # The core alone is what the model without extensions predicts.
    np.testing.assert_allclose(core.runs[0].predicted, predict(piezo_model, bundle).runs[0].predicted)
    extended.save(tmp_path / "extended.json")
    bmr.write_bundle(bundle, tmp_path / "b")
    assert main(["predict", str(tmp_path / "extended.json"), str(tmp_path / "b")]) == 0
    assert "ran: core tables, time_delay" in capsys.readouterr().out
    # The extended chain starts from a saturation: other initial states are one clear error.
    with pytest.raises(bmr.BmrError, match="extended model runs from a saturation"):
        predict(extended, bundle, initial="estimate")


def test_offset_of_the_run_itself_is_the_cli_default(piezo_model, tmp_path, capsys):
    # A held-out recording whose sensor offset moved by 0.7 µm: its own offset, fitted on its scored samples,
    # removes it (the model's leaves it in full); the result says how the offset was found.
    volts = np.concatenate([np.linspace(0, 100, 201), np.linspace(100, 30, 141), np.linspace(30, 80, 101)])
    a = _run("a", volts)
    b = bmr.Run("b", "custom", a.data.assign(displacement_um=a.data["displacement_um"] + 0.7), quantities=PIEZO,
                role="evaluation")
    own = predict(piezo_model, _bundle(a, b), offset="run")
    fixed = predict(piezo_model, _bundle(a, b))
    assert own.run("b").offset - own.run("a").offset == pytest.approx(0.7, abs=1e-9)
    assert own.run("b").rms == pytest.approx(own.run("a").rms, rel=1e-9)
    assert own.run("b").rms < 0.5 * fixed.run("b").rms
    assert own.run("b").offset_source == f"the run's own, fitted on its {own.run('b').evaluated} scored samples"
    assert own.run("b").dropped == fixed.run("b").dropped  # nothing more left unscored
    bmr.write_bundle(_bundle(a, b), tmp_path / "b")
    piezo_model.save(tmp_path / "m.json")
    assert main(["predict", str(tmp_path / "m.json"), str(tmp_path / "b")]) == 0
    assert "(the run's own, fitted on its" in capsys.readouterr().out
    # With a model identified by least squares from several runs, the run's own offset is shrunk towards the
    # model's by the training runs' spread, and stated.
    train = [_run(f"t{k}", volts, role="identification") for k in range(3)]
    train = [bmr.Run(r.name, "custom", r.data.assign(displacement_um=r.data["displacement_um"] + 0.2 * k),
                     quantities=PIEZO, role="identification") for k, r in enumerate(train)]
    fitted = bmr.identify(_bundle(*train, b), method="lstsq")
    q = predict(fitted, _bundle(b), offset="run")
    assert "× the model's (spread" in q.run("b").offset_source, q.run("b").offset_source
