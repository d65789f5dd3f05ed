"""Raw logs → bundle → model → held-out prediction, on a piezo-like device (voltage V → displacement µm, no
angle) logged by a dSPACE rig, and the clear errors of every bad input on the way."""
from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.cli import main
from bmr.data.importing import import_logs
from bmr.identification.prediction import predict
from lab_files import Piezo, descending_forc_drive, multi_reversal_drive, write_aixacct, write_controldesk

RATE_HZ = 1000.0


@pytest.fixture(scope="module")
def piezo_logs(tmp_path_factory):
    """A FORC capture and a later held-out capture of the same stack (the held-out run starts wherever the FORC
    protocol left the stack, mid-range: an unknown state for the model)."""
    folder = tmp_path_factory.mktemp("rig")
    stack = Piezo(seed=1)
    paths = {}
    for name, drive in (("forc_01", descending_forc_drive()), ("check_02", 40.0 + multi_reversal_drive()[1:] * 0.6)):
        x = stack.run(drive)
        t = np.arange(drive.size) / RATE_HZ
        paths[name] = write_controldesk(folder / f"{name}.mat", name, [t], [
            ("Model Root/Amp/Vout", "Model Root/Amp", drive, "V", 1),
            ("x", "Model Root/Sensor", x, "", 1)])  # the sensor channel states no unit
    return paths


def _import(paths, **kw):
    args = dict(input="Vout", output="x:um", protocol="forc-descending", holdout=["check_02"], device="stack P1")
    args.update(kw)
    return import_logs([paths["forc_01"], paths["check_02"]], **args)


def test_import_finds_the_protocol_and_labels_runs(piezo_logs):
    res = _import(piezo_logs)
    b = res.bundle
    assert b.quantities.describe() == "voltage (V) → displacement (µm)" and b.quantities.angle is None
    assert b.sample_rate_hz == RATE_HZ and not res.rate.irregular
    forc, check = res.runs
    assert (forc.name, forc.role, forc.kind, forc.curves) == ("forc_01", "identification",
                                                              "first_order_descending", 12)
    assert forc.reversals == 23  # 12 maxima and the 11 returns to 0 V between them
    assert (check.role, check.kind) == ("evaluation", "custom")  # held out: any excitation
    assert forc.input_range == (0.0, 100.0)
    text = res.summary()
    assert "voltage (V) → displacement (µm)" in text and "dead-band 1 V" in text and "1000 Hz" in text
    assert re.search(r"forc_01\s+identification\s+first_order_descending\s+2593\s+23\s+12\s+0\.\.100", text), text
    assert b.run("forc_01").meta["first_order_curves"] == 12


def test_piezo_import_identify_predict(piezo_logs, tmp_path):
    b = _import(piezo_logs).bundle
    model = bmr.identify(b, method="lstsq")
    assert model.quantities == b.quantities and model.friction is None
    assert model.meta["identification"]["units"] == {"input": "V", "output": "µm"}
    saved = json.loads(model.save(tmp_path / "m.json").read_text())
    assert saved["format"] == "bmr-model/2" and saved["quantities"]["output"]["unit"] == "µm"
    assert set(saved["limits"]) == {"voltage_v", "displacement_um"}
    back = bmr.Model.load(tmp_path / "m.json")
    p = predict(back, b)  # the bundle's evaluation runs
    [r] = p.runs
    st = r.stats()
    assert r.name == "check_02" and r.role == "evaluation"
    # The run starts mid-range and never returns to 0 V: its state is assumed (negative saturation, which is where
    # the FORC protocol left the stack) and the prediction says so.
    assert not r.state_known and "assumed" in r.initial and r.evaluated == r.samples
    # The hysteresis model is far better than the single-valued curve; errors are in µm and % of span.
    assert st["rms"] < 0.25 * st["baseline_rms"], st
    assert st["rms"] < 0.5 and st["rms_pct_span"] < 2.0 and 25.0 < p.span < 35.0, st
    assert st["rms_pct_span"] == pytest.approx(100 * st["rms"] / p.span)
    # Estimated instead of assumed: the same state is found.
    est = predict(back, b, initial="estimate").runs[0]
    assert est.state_known and "estimated" in est.initial and est.rms <= 1.05 * r.rms
    # A bundle in other units of the same quantities is converted to the model's.
    mm = _import(piezo_logs, output="x:um:mm").bundle
    assert mm.quantities.output.unit == "mm"
    assert predict(back, mm).runs[0].rms == pytest.approx(r.rms, rel=1e-9)


def test_cli_import_identify_predict(piezo_logs, tmp_path, capsys):
    bundle = tmp_path / "stack"
    assert main(["import", str(piezo_logs["forc_01"]), str(piezo_logs["check_02"]), "--input", "Vout",
                 "--output", "x:um", "--protocol", "forc-descending", "--holdout", "check_02",
                 "-o", str(bundle)]) == 0
    out = capsys.readouterr().out
    assert "2 runs (1 identification, 1 evaluation)" in out and "voltage (V) → displacement (µm)" in out
    assert json.loads((bundle / "manifest.json").read_text())["format"] == "bmr-bundle/2"
    model = tmp_path / "m.json"
    # One measured family (descending first-order curves) and least squares, the better kept.
    assert main(["identify", str(bundle), "--method", "both", "-o", str(model)]) == 0
    out = capsys.readouterr().out
    assert "held-out RMS [forc]" in out and "held-out RMS [lstsq]" in out
    assert "model's common offset" in out and "--offset run" in out  # why `bmr predict` reports other figures
    assert "voltage (V) → displacement (µm)" in out and "the device has no angle" in out and "µm" in out
    assert "N·mm" not in out
    js, fig = tmp_path / "p.json", tmp_path / "p.png"
    assert main(["predict", str(model), str(bundle), "--json", str(js), "--figure", str(fig)]) == 0
    out = capsys.readouterr().out
    assert "RMS (µm)" in out and "baseline RMS (µm)" in out and "check_02" in out and "N·mm" not in out
    content = json.loads(js.read_text())
    assert content["format"] == "bmr-prediction/1" and content["output_unit"] == "µm"
    run = content["runs"]["check_02"]
    assert run["rms"] < 0.25 * run["baseline_rms"] and run["evaluated"] > 1000 and not run["state_known"]
    assert fig.read_bytes()[:4] == b"\x89PNG"
    # Predicting identification runs on request; unknown runs are named.
    assert main(["predict", str(model), str(bundle), "--runs", "forc_01"]) == 0
    assert main(["predict", str(model), str(bundle), "--runs", "nope"]) == 2
    assert "no run named 'nope'" in capsys.readouterr().err


def test_analyzer_tables_become_runs_and_units_convert(tmp_path):
    t = np.arange(400) * 1e-4
    tables = []
    for k, amp in enumerate((4.0, 7.0, 10.0)):
        v = amp * np.sin(2 * np.pi * 25 * t)
        tables.append(({"Hysteresis Amplitude [V]": str(amp)}, ["Time s", "Vplus V", "P1 uC_per_cm2"],
                       np.column_stack([t, v, 20 * np.tanh(v / 3)])))
    p = write_aixacct(tmp_path / "cap.dat", tables)
    res = import_logs([p], input="Vplus:mV", output="P1:C/m2", holdout=["cap-3"])
    assert [r.name for r in res.runs] == ["cap-1", "cap-2", "cap-3"]
    r = res.bundle.run("cap-2")
    assert res.bundle.quantities.describe() == "voltage (mV) → polarization (C/m²)"
    np.testing.assert_allclose(r.input, 1000 * 7.0 * np.sin(2 * np.pi * 25 * t), rtol=1e-6, atol=1e-3)
    np.testing.assert_allclose(r.output, 0.01 * 20 * np.tanh(7.0 * np.sin(2 * np.pi * 25 * t) / 3), rtol=1e-6,
                               atol=1e-8)
    assert r.meta["Hysteresis Amplitude [V]"] == "7.0" and r.meta["reversals"] == 2
    assert res.rate.hz == 10000.0


def test_a_partial_first_measurement_is_kept_as_a_custom_run(tmp_path):
    # Analyzers often open a FORC series with a partial measurement (here 0 V → 10 V → 0 V, no reversal inside
    # the range): it is kept, labelled custom and named in the notes; the FORC tables stay first-order curves.
    t = np.linspace(0.0, 1.0, 201)
    first = 10.0 * np.sin(np.pi * t)
    tables = [({}, ["Time s", "Vplus V", "P1 uC_per_cm2"], np.column_stack([t, first, 2.0 * first]))]
    for r in (5.0, 0.0, -5.0, -10.0):
        v = np.r_[np.linspace(10.0, r, 100), np.linspace(r, 10.0, 101)[1:]]
        tt = np.arange(v.size) * 5e-3
        tables.append(({}, ["Time s", "Vplus V", "P1 uC_per_cm2"], np.column_stack([tt, v, 20 * np.tanh(v / 4)])))
    p = write_aixacct(tmp_path / "forc.dat", tables)
    res = import_logs([p], input="Vplus:V", output="P1:uC/cm2", protocol="forc-ascending")
    kinds = {r.name: r.kind for r in res.runs}
    assert kinds == {"forc-1": "custom", **{f"forc-{k}": "first_order_ascending" for k in range(2, 6)}}
    assert any("run 'forc-1'" in n and "kept as a custom run" in n for n in res.notes)
    assert len(res.bundle.runs) == 5  # nothing dropped
    # Without any run that follows the protocol, the import is still an error naming the file and run.
    with pytest.raises(bmr.BundleError, match=r"one.dat \(run 'one'\): protocol forc-ascending: no first-order curve"):
        import_logs([write_aixacct(tmp_path / "one.dat", tables[:1])], input="Vplus:V", output="P1:uC/cm2",
                    protocol="forc-ascending")


# ------------------------------------------------------------------------------------------------ bad input
def test_one_long_recording_is_split_into_a_head_that_identifies_and_a_tail_held_out(tmp_path, capsys):
    # A stage driven once through a long sweep: without a held-out run there is nothing to diagnose or predict;
    # --holdout-tail 0.4 cuts every identification run, the tail recorded right after its head (one history).
    stack = Piezo(seed=4)
    t = np.arange(0.0, 30.0, 1.0 / RATE_HZ)
    drive = 50.0 + 48.0 * np.sin(2 * np.pi * 0.25 * t) * np.minimum(1.0, t / 8.0)
    pd.DataFrame({"time_s": t, "drive_V": drive, "x_um": stack.run(drive)}).to_csv(tmp_path / "sweep.csv",
                                                                                 index=False)
    whole = import_logs([tmp_path / "sweep.csv"], input="drive_V:V", output="x_um:um")
    with pytest.raises(bmr.BmrError, match=r"no evaluation run .* `--holdout-tail 0.3`"):
        bmr.diagnose(whole.bundle, progress=False, closed_loop=False)
    split = import_logs([tmp_path / "sweep.csv"], input="drive_V:V", output="x_um:um", holdout_tail=0.4)
    head, tail = split.bundle.runs
    assert (head.name, head.role, tail.name, tail.role) == ("sweep", "identification", "sweep-tail", "evaluation")
    assert (len(head.time), len(tail.time)) == (18000, 12000)
    np.testing.assert_array_equal(np.concatenate([head.output, tail.output]), whole.bundle.runs[0].output)
    assert split.bundle.histories == [["sweep", "sweep-tail"]]
    assert any("the last 12000 of 30000 samples held out as run 'sweep-tail'" in n for n in split.notes)
    d = bmr.diagnose(split.bundle, progress=False, closed_loop=False)
    assert d.nominal_heldout_rms > 0 and d.residual_rms <= d.nominal_heldout_rms * (1 + 1e-9)
    out = tmp_path / "bundle"
    assert main(["import", str(tmp_path / "sweep.csv"), "--input", "drive_V:V", "--output", "x_um:um",
                 "--holdout-tail", "0.4", "-o", str(out)]) == 0
    assert "sweep-tail  evaluation" in capsys.readouterr().out
    for bad in (0.0, 1.0, float("nan")):
        with pytest.raises(bmr.BundleError, match=r"holdout_tail must be a share between 0 and 1"):
            import_logs([tmp_path / "sweep.csv"], input="drive_V:V", output="x_um:um", holdout_tail=bad)
    with pytest.raises(bmr.BundleError, match=r"30000 samples split at 0.0001 from the end leave 29997 and 3; each part needs at least 10"):
        import_logs([tmp_path / "sweep.csv"], input="drive_V:V", output="x_um:um", holdout_tail=0.0001)


def test_a_log_whose_sensor_hit_its_range_end_says_so(tmp_path):
    # The displacement channel clips at 25 µm (an amplifier at its rail) while the drive sweeps on.
    stack = Piezo(seed=5)
    t = np.arange(0.0, 12.0, 1.0 / RATE_HZ)
    drive = 50.0 + 48.0 * np.sin(2 * np.pi * 0.25 * t)
    x = stack.run(drive)
    for name, out in (("free", x), ("clipped", np.minimum(x, 25.0))):
        pd.DataFrame({"time_s": t, "drive_V": drive, "x_um": out}).to_csv(tmp_path / f"{name}.csv", index=False)
    free = import_logs([tmp_path / "free.csv"], input="drive_V:V", output="x_um:um")
    assert not any("range end" in n for n in free.notes)
    clipped = import_logs([tmp_path / "clipped.csv"], input="drive_V:V", output="x_um:um")
    held = int(np.count_nonzero(x >= 25.0))
    assert held > 100
    assert any(f"held at its range end (25 µm) on {held} of {t.size} samples" in n for n in clipped.notes)
    assert "range end" in clipped.summary()


def test_bad_inputs_are_named(piezo_logs, tmp_path):
    # File, column, run and protocol problems are bundle errors; units that do not convert are BmrErrors.
    with pytest.raises(bmr.BundleError, match=r"forc_01.mat \(forc_01\): no column for the output 'pos' \(columns: "
                                           r"time, Model Root/Amp/Vout, x\)"):
        _import(piezo_logs, output="pos:um")
    with pytest.raises(bmr.BundleError, match=r"forc_01.mat \(forc_01\): column 'x' states no unit; give the output "
                                           r"as x:UNIT"):
        _import(piezo_logs, output="x")
    with pytest.raises(bmr.BmrError, match=r"forc_01.mat \(forc_01\): column 'Model Root/Amp/Vout' \(input\): unit V "
                                           r"\(voltage\) does not convert to A \(current\)"):
        _import(piezo_logs, input="Vout:A")
    with pytest.raises(bmr.BmrError, match=r"output 'x': unknown unit 'furlong'"):
        _import(piezo_logs, output="x:furlong")
    with pytest.raises(bmr.BundleError, match=r"forc_01.mat \(forc_01\) \(run 'forc_01'\): protocol forc-ascending: no "
                                           r"first-order curve found; each curve must fall from the top of the "
                                           r"input range to a reversal and rise back to the top \(found 23 "
                                           r"reversal\(s\) at 8.333 V, 0 V, 16.67 V"):
        _import(piezo_logs, protocol="forc-ascending")
    with pytest.raises(bmr.BundleError, match=r"holdout 'check_03' names no imported run or file \(runs: forc_01, "
                                           r"check_02\)"):
        _import(piezo_logs, holdout=["check_03"])
    with pytest.raises(bmr.BundleError, match=r"forc_01.mat: binary content, not a text table"):
        _import(piezo_logs, format="slac")
    with pytest.raises(bmr.BundleError, match=r"forc_01.mat: cannot be read as Parquet"):
        _import(piezo_logs, format="parquet")
    with pytest.raises(bmr.BmrError, match="unknown protocol 'forc'"):
        _import(piezo_logs, protocol="forc")
    (tmp_path / "empty.csv").write_bytes(b"")
    with pytest.raises(bmr.BundleError, match=r"empty.csv: the file is empty"):
        import_logs([tmp_path / "empty.csv"], input="u:V", output="y:um")
    pd.DataFrame({"u": [0.0, 1.0, 2.0], "y": [0.0, 1.0, np.nan]}).to_csv(tmp_path / "cut.csv", index=False)
    with pytest.raises(bmr.BundleError, match=r"cut.csv: run 'cut': column 'displacement_um' has 1 non-finite "
                                           r"value\(s\), first at row 2"):
        import_logs([tmp_path / "cut.csv"], input="u:V", output="y:um", sample_rate_hz=10.0)
    # Without a time column (a quasi-static record) the samples are numbered 1 s apart, and the notes say so.
    pd.DataFrame({"u": [0.0, 1.0, 2.0], "y": [0.0, 1.0, 0.5]}).to_csv(tmp_path / "untimed.csv", index=False)
    untimed = import_logs([tmp_path / "untimed.csv"], input="u:V", output="y:um")
    np.testing.assert_array_equal(untimed.bundle.runs[0].time, [0.0, 1.0, 2.0])
    assert any("untimed.csv: no time column (looked for t_s, time, t, zeit, timestamp, tout); samples numbered 1 s "
               "apart (give --time COL[:UNIT] or --sample-rate HZ" in n for n in untimed.notes), untimed.notes


def test_cli_errors_are_one_line(piezo_logs, tmp_path, capsys):
    out = tmp_path / "b"
    out.mkdir()
    (out / "x").write_text("")
    assert main(["import", str(piezo_logs["forc_01"]), "--input", "Vout", "--output", "x:um", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists; give a new (or empty) folder" in err
    assert main(["import", str(piezo_logs["forc_01"]), "--input", "Vout", "--output", "x:um", "--protocol",
                 "major-loop", "-o", str(tmp_path / "c")]) == 0
    model = tmp_path / "m.json"
    bundle = tmp_path / "c"
    assert main(["identify", str(bundle), "--method", "lstsq", "-o", str(model)]) == 0
    assert main(["predict", str(model), str(bundle)]) == 2
    assert "no evaluation runs" in capsys.readouterr().err
    assert main(["predict", str(model), str(bundle), "--runs", "forc_01", "--json",
                 str(tmp_path / "no" / "p.json")]) == 2
    assert "folder" in capsys.readouterr().err and not (tmp_path / "no").exists()


def test_actuator_log_with_angle_imports_to_the_actuator_quantities(tmp_path):
    from bmr.simulation.experiments import simulate_bundle

    run = simulate_bundle("ideal", quick=True, seed=2).run("multipeak")
    pd.DataFrame({"Time": run.t, "I_cmd": run.current / 0.125, "Encoder": np.degrees(run.theta),
                  "Torque": run.torque / 1000.0}).to_csv(tmp_path / "mp.csv", index=False)
    res = import_logs([tmp_path / "mp.csv"], input="I_cmd:0.125A:A", output="Torque:N*m:N*mm",
                      angle="Encoder:deg:rad", time="Time:s")
    assert res.bundle.quantities.is_actuator and res.bundle.quantities.angle is not None
    got = res.bundle.run("mp")
    np.testing.assert_allclose(got.current, run.current, atol=1e-12)
    np.testing.assert_allclose(got.theta, run.theta, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.torque, run.torque, rtol=1e-12, atol=1e-9)
    assert res.bundle.sample_rate_hz == 500.0
    # The angle is stored in rad: a single unit given for it is the file's.
    again = import_logs([tmp_path / "mp.csv"], input="I_cmd:0.125A:A", output="Torque:N*m:N*mm", angle="Encoder:deg")
    np.testing.assert_array_equal(again.bundle.run("mp").theta, got.theta)
    with pytest.raises(bmr.BmrError, match=r"the angle is stored in rad; give it as Encoder:deg or Encoder:deg:rad"):
        import_logs([tmp_path / "mp.csv"], input="I_cmd:0.125A:A", output="Torque:N*m:N*mm", angle="Encoder:deg:mrad")
