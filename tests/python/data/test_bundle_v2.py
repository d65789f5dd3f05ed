"""``bmr-bundle/2``: declared quantities, optional angle and sigma, run roles; ``bmr-bundle/1`` unchanged."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.data.bundle import FORMAT, FORMAT_V1
from bmr.data.quantities import ACTUATOR, Quantities, Quantity

PIEZO = Quantities(Quantity.declare("V"), Quantity.declare("um"),
                   output_sigma=Quantity("displacement sigma", "um", "displacement_um_sigma"))


def _piezo_run(name: str, role: str | None = None, n: int = 200) -> bmr.Run:
    t = np.arange(n) / 1000.0
    u = 50.0 + 50.0 * np.sin(2 * np.pi * 5 * t)
    df = pd.DataFrame({"t_s": t, "voltage_v": u, "displacement_um": 0.3 * u, "displacement_um_sigma": 0.01})
    return bmr.Run(name, "custom", df, {"source": "log.dat"}, PIEZO, role)


def test_generic_bundle_round_trips_with_quantities_and_roles(tmp_path):
    b = bmr.Bundle("piezo P-1", 1000.0, [_piezo_run("a", "identification"), _piezo_run("b", "evaluation")],
                   quantities=PIEZO)
    assert [r.name for r in b.identification_runs()] == ["a"]
    assert [r.name for r in b.evaluation_runs()] == ["b"]
    r = b.run("a")
    np.testing.assert_array_equal(r.output, 0.3 * r.input)
    assert r.angle is None and r.output_sigma is not None and r.time[1] == 0.001
    out = bmr.write_bundle(b, tmp_path / "p")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == FORMAT and manifest["device"] == "piezo P-1"
    assert manifest["quantities"]["output"] == {"name": "displacement", "unit": "µm", "column": "displacement_um"}
    assert manifest["runs"][1]["role"] == "evaluation"
    back = bmr.read_bundle(out)
    assert back.quantities == PIEZO and back.device == "piezo P-1"
    assert [x.role for x in back.runs] == ["identification", "evaluation"]
    assert back.run("b").meta == {"source": "log.dat"}
    np.testing.assert_array_equal(back.run("b").output, b.run("b").output)
    assert "voltage (V) → displacement (µm)" in repr(back) and "1 held out" in repr(back)


def test_actuator_bundle_is_still_written_and_read_as_version_1(tmp_path):
    t = np.arange(100) / 500.0
    df = pd.DataFrame({"t_s": t, "current_a": np.sin(t), "theta_rad": t, "torque_nmm": 100 * np.sin(t)})
    b = bmr.Bundle("rig", 500.0, [bmr.Run("tri", "triangle", df)])
    out = bmr.write_bundle(b, tmp_path / "v1")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == FORMAT_V1 and manifest["actuator"] == "rig" and "quantities" not in manifest
    back = bmr.read_bundle(out)
    assert back.quantities == ACTUATOR
    r = back.run("tri")
    np.testing.assert_array_equal(r.input, r.current)
    np.testing.assert_array_equal(r.output, r.torque)
    np.testing.assert_array_equal(r.angle, r.theta)
    # A role makes it a version 2 bundle with the actuator's quantities.
    b2 = bmr.Bundle("rig", 500.0, [bmr.Run("tri", "triangle", df, role="identification")])
    m2 = json.loads((bmr.write_bundle(b2, tmp_path / "v2") / "manifest.json").read_text())
    assert m2["format"] == FORMAT and m2["quantities"]["input"]["column"] == "current_a"
    assert bmr.read_bundle(tmp_path / "v2").run("tri").is_identification


def test_generic_runs_have_no_actuator_columns():
    r = _piezo_run("a")
    with pytest.raises(bmr.BmrError, match=r"run 'a' holds voltage \(V\) → displacement \(µm\), not the "
                                           r"actuator's 'current_a': use run.input"):
        _ = r.current


def test_bad_generic_runs_and_manifests(tmp_path):
    df = _piezo_run("a").data.drop(columns=["displacement_um"])
    with pytest.raises(bmr.BmrError, match=r"run 'x': missing required column\(s\) displacement_um .*"
                                           r"declares voltage \(V\) → displacement \(µm\)"):
        bmr.Run("x", "custom", df, quantities=PIEZO)
    with pytest.raises(bmr.BmrError, match="unknown role 'training'"):
        bmr.Run("x", "custom", _piezo_run("a").data, quantities=PIEZO, role="training")
    with pytest.raises(bmr.BmrError, match=r"run 'a' holds voltage \(V\).* but the bundle declares current"):
        bmr.Bundle("x", 1000.0, [_piezo_run("a")])
    b = bmr.Bundle("p", 1000.0, [_piezo_run("a")], quantities=PIEZO)
    out = bmr.write_bundle(b, tmp_path / "b")
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["quantities"]["input"]["unit"] = "furlong"
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(bmr.BmrError, match=r"manifest.json: quantities.input: quantity 'voltage': unknown unit "
                                           r"'furlong'"):
        bmr.read_bundle(out)
    del manifest["quantities"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(bmr.BmrError, match="quantities must be an object"):
        bmr.read_bundle(out)
    manifest["format"] = "bmr-bundle/3"
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(bmr.BmrError, match="upgrade bmr"):
        bmr.read_bundle(out)
