"""Lab-data readers: CSV, Parquet, TDMS and MAT with column mapping and unit conversion."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.data.readers import convert_units

N = 50
T = np.arange(N) * 0.01
VOLTS = np.linspace(-10, 10, N)  # converter volts = paper's 0.125 A units
TORQUE_NM = np.linspace(-0.6, 0.6, N)
ANGLE_DEG = np.linspace(0, 720, N)

MAPPING = {"t_s": "Time", "current_a": "Icmd", "torque_nmm": "Torque", "theta_rad": "Encoder"}
UNITS = {"current_a": "0.125A", "torque_nmm": "N*m", "theta_rad": "deg"}


def _check(df):
    np.testing.assert_allclose(df["current_a"], VOLTS * 0.125)
    np.testing.assert_allclose(df["torque_nmm"], TORQUE_NM * 1000.0)
    np.testing.assert_allclose(df["theta_rad"], np.deg2rad(ANGLE_DEG))
    np.testing.assert_allclose(df["t_s"], T)


def _frame():
    return pd.DataFrame({"Time": T, "Icmd": VOLTS, "Torque": TORQUE_NM, "Encoder": ANGLE_DEG, "note": ["x"] * N})


def test_csv_and_parquet(tmp_path):
    _frame().to_csv(tmp_path / "r.csv", index=False)
    _check(bmr.read_table(tmp_path / "r.csv", MAPPING, UNITS))
    _frame().to_parquet(tmp_path / "r.parquet", index=False)
    _check(bmr.read_table(tmp_path / "r.parquet", MAPPING, UNITS))


def test_tdms(tmp_path):
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([ChannelObject("Data", "Time", T), ChannelObject("Data", "Icmd", VOLTS),
                         ChannelObject("Data", "Torque", TORQUE_NM), ChannelObject("Data", "Encoder", ANGLE_DEG)])
    _check(bmr.read_table(tmp_path / "r.tdms", MAPPING, UNITS))
    grouped = {k: f"Data/{v}" for k, v in MAPPING.items()}
    _check(bmr.read_table(tmp_path / "r.tdms", grouped, UNITS))


def test_mat(tmp_path):
    from scipy.io import savemat

    savemat(tmp_path / "r.mat", {"Time": T, "Icmd": VOLTS.reshape(-1, 1), "Torque": TORQUE_NM,
                                 "rig": {"Encoder": ANGLE_DEG}})
    mapping = dict(MAPPING, theta_rad="rig.Encoder")
    _check(bmr.read_table(tmp_path / "r.mat", mapping, UNITS))


def test_defaults_sample_rate_and_bundle(tmp_path):
    pd.DataFrame({"I": VOLTS, "Tq": TORQUE_NM}).to_csv(tmp_path / "a.csv", index=False)
    df = bmr.read_table(tmp_path / "a.csv", {"current_a": "I", "torque_nmm": "Tq"}, {"current_a": "V",
                        "torque_nmm": "Nm"}, defaults={"theta_rad": 0.0}, sample_rate_hz=100.0)
    np.testing.assert_allclose(df["t_s"], T)
    assert (df["theta_rad"] == 0).all()
    b = bmr.bundle_from_files([{"path": tmp_path / "a.csv", "name": "tri", "kind": "triangle"}],
                              mapping={"current_a": "I", "torque_nmm": "Tq"},
                              units={"current_a": "V", "torque_nmm": "Nm"},
                              defaults={"theta_rad": 0.0}, sample_rate_hz=100.0, actuator="rig 1")
    assert b.run("tri").kind == "triangle" and b.sample_rate_hz == 100.0
    bmr.write_bundle(b, tmp_path / "bundle")
    assert bmr.read_bundle(tmp_path / "bundle").run("tri").data.shape == (N, 4)


def test_errors_name_the_problem(tmp_path):
    _frame().to_csv(tmp_path / "r.csv", index=False)
    with pytest.raises(bmr.BmrError, match="required column.*theta_rad"):
        bmr.read_table(tmp_path / "r.csv", {k: v for k, v in MAPPING.items() if k != "theta_rad"}, UNITS)
    with pytest.raises(bmr.BmrError, match="column 'theta_rad': unknown angle unit 'furlong'; use one of rad"):
        bmr.read_table(tmp_path / "r.csv", MAPPING, dict(UNITS, theta_rad="furlong"))
    with pytest.raises(bmr.BmrError, match="'Nope' for column 'torque_nmm' not found"):
        bmr.read_table(tmp_path / "r.csv", dict(MAPPING, torque_nmm="Nope"), UNITS)
    with pytest.raises(bmr.BmrError, match="unknown bundle column"):
        bmr.read_table(tmp_path / "r.csv", dict(MAPPING, torque="Torque"), UNITS)
    with pytest.raises(bmr.BmrError, match="unsupported file type"):
        (tmp_path / "r.xyz").write_text("1")
        bmr.read_table(tmp_path / "r.xyz")
    (tmp_path / "bad.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(bmr.BmrError, match="MATLAB"):
        bmr.read_table(tmp_path / "bad.mat", MAPPING)
    (tmp_path / "bad.tdms").write_bytes(b"garbage")
    with pytest.raises(bmr.BmrError, match="TDMS"):
        bmr.read_table(tmp_path / "bad.tdms", MAPPING)


def test_unit_table():
    assert convert_units("temperature_c", np.array([273.15]), "K")[0] == pytest.approx(0.0)
    assert convert_units("speed_rad_s", np.array([60.0]), "rpm")[0] == pytest.approx(2 * math.pi)
    assert convert_units("torque_nmm", np.array([1.0]), "N·m")[0] == 1000.0
