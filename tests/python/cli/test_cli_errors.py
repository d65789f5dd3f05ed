"""The CLI never shows a traceback for a file problem: status 2 and one line naming the file and the problem,
found before the work starts, printed below a closed progress bar, and no empty output folder left behind."""
from __future__ import annotations

import subprocess
import sys

import pytest

import bmr
import bmr.demo
import bmr.diagnosis.procedure
import bmr.simulation.excitation
from bmr.cli import main


def _one_line_error(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "Traceback" not in err
    for n in needles:
        assert n in err, err
    return err


@pytest.mark.parametrize("argv", [
    ["simulate", "--quick", "-o", "{file}"],
    ["simulate", "--quick", "-o", "{file}/sub"],
    ["demo", "--quick", "--out", "{file}"],
    ["demo", "--quick", "--out", "{file}/sub"],
    ["identify", "{missing}", "-o", "{file}/model.json"],
    ["diagnose", "{missing}", "--json", "{file}/d.json"],
    ["diagnose", "{missing}", "--report", "{folder}"],
])
def test_unusable_outputs_fail_first_with_one_line(tmp_path, capsys, monkeypatch, argv):
    # `bmr simulate -o <existing file>`, `bmr demo --out <existing file>` and `-o file/sub` printed tracebacks
    # (rc 1); `bmr diagnose --json <unwritable>` failed only after the whole diagnosis.
    (tmp_path / "file").write_text("x")
    paths = {"file": tmp_path / "file", "missing": tmp_path / "no-bundle", "folder": tmp_path}
    argv = [a.format(**paths) for a in argv]

    def no_work(*args, **kwargs):
        raise AssertionError("the work started before the outputs were checked")

    monkeypatch.setattr(bmr.simulation.experiments, "simulate_bundle", no_work)
    monkeypatch.setattr(bmr.demo, "simulate_bundle", no_work)
    monkeypatch.setattr(bmr.diagnosis.procedure, "diagnose", no_work)
    assert main(argv) == 2
    _one_line_error(capsys, f"bmr {argv[0]}: error:", str(tmp_path))


def test_a_failing_demo_leaves_no_empty_folder_and_prints_below_the_bar(tmp_path, capsys, monkeypatch):
    out = tmp_path / "demo-out"

    def fails(*args, **kwargs):
        raise bmr.BmrError("simulated failure in the first stage")

    monkeypatch.setattr(bmr.demo, "simulate_bundle", fails)
    assert main(["demo", "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]
    assert last == "bmr demo: error: simulated failure in the first stage"
    # The bar was closed (its line ends) before the error was printed.
    assert "\n" in err[: err.rindex(last)] or err.startswith(last)
    assert not out.exists()


def test_os_errors_from_anywhere_are_one_line(capsys, monkeypatch):
    def denied(args):
        raise PermissionError(13, "Permission denied", "/root/secret.csv")

    monkeypatch.setattr(bmr.simulation.excitation, "run_cli", denied)
    assert main(["simulate", "-o", "x"]) == 2
    _one_line_error(capsys, "bmr simulate: error: '/root/secret.csv': Permission denied")


def test_no_traceback_from_the_installed_command(tmp_path):
    (tmp_path / "file").write_text("x")
    proc = subprocess.run([sys.executable, "-m", "bmr.cli", "simulate", "--quick", "-o", str(tmp_path / "file")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip() == f"bmr simulate: error: bundle folder {str(tmp_path / 'file')!r} is a file, not a folder"


@pytest.mark.parametrize("problem", ["oversized", "infinite_score_as_text", "wrong_types"])
def test_a_hostile_model_file_is_one_line_from_bmr_diagnose(tmp_path, capsys, problem):
    # A 10 MB model file without a digest aborted the interpreter in `bmr diagnose --model`; wrong field types
    # printed a traceback.
    import json

    import numpy as np
    import pandas as pd

    from bmr.data.bundle import write_bundle

    t = np.arange(200) / 500.0
    run = bmr.Run("r", "custom", pd.DataFrame({"t_s": t, "current_a": np.sin(t), "theta_rad": t,
                                               "torque_nmm": np.cos(t)}))
    bundle = write_bundle(bmr.Bundle("rig", 500.0, [run]), tmp_path / "b")
    u = np.linspace(-1, 1, 9)
    asc = [(u[k:], 100 * (u[k:] + 1)) for k in range(4)]
    desc = [(u[::-1][k:], 100 * (u[::-1][k:] + 1)) for k in range(4)]
    content = bmr.Model.from_curves(asc, desc).to_dict()
    if problem == "oversized":
        content["hysteresis"]["ascending"] = [[[0.0, 1.0], [0.0, 1.0]]] * 100_001
    elif problem == "infinite_score_as_text":
        content["friction"] = {"c0": 1.0, "a": [0.5], "b": [0.1], "scores": {"1": "inf"}}
    else:
        content["limits"] = {"current_a": [1, 0]}
    path = tmp_path / "m.json"
    path.write_text(json.dumps(content))
    assert main(["diagnose", str(bundle), "--model", str(path)]) == 2
    _one_line_error(capsys, "bmr diagnose: error:", str(path))


def test_a_bug_ends_in_one_line_too(monkeypatch, tmp_path, capsys):
    import bmr.identification.prediction as prediction

    def broken(args):
        raise TypeError("must be real number, not NoneType")

    monkeypatch.setattr(prediction, "run_cli", broken)
    assert main(["predict", str(tmp_path / "m.json"), str(tmp_path / "b")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "bmr predict: internal error (a bug in bmr" in err and "TypeError: must be real number" in err
