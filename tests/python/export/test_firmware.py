"""Model file → firmware: `bmr export` writes the compensator as static Rust (built by nostd-check) and as C
tables for the C ABI; a C program compiled with the system compiler runs an exported extended model and matches
Python's `Compensator.run` bit for bit."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bmr
from bmr.cli import main

REPO = Path(__file__).resolve().parents[3]
MODEL = REPO / "tests" / "data" / "extended_model.json"
DT_S = 0.002


def reference(n: int = 6000) -> tuple[np.ndarray, np.ndarray]:
    """An opening beyond reach both ways, then a two-tone torque reference; the rotor at 2 rad/s."""
    t = np.arange(n) * DT_S
    opening = np.concatenate([np.linspace(0, 1500, 300), np.linspace(1500, -1500, 600), np.linspace(-1500, 0, 300)])
    ref = np.concatenate([opening, 150 * np.sin(1.3 * t) + 30 * np.sin(3.1 * t)])[:n]
    return ref, np.mod(2.0 * t, 2 * np.pi)


def test_test_model_is_the_one_its_script_makes():
    sys.path.insert(0, str(REPO / "tests" / "data"))
    try:
        from make_extended_model import build
    finally:
        sys.path.pop(0)
    made, stored = build().to_dict(), bmr.Model.load(MODEL).to_dict()
    # The plant's curves are numpy sums: their last bits depend on the processor's vector units, so the tables
    # agree to round-off of the output span and everything else exactly.
    for family in ("ascending", "descending"):
        a, b = made["hysteresis"].pop(family), stored["hysteresis"].pop(family)
        assert len(a) == len(b)
        for (ua, ya), (ub, yb) in zip(a, b):
            assert ua == ub
            np.testing.assert_allclose(ya, yb, rtol=0, atol=1e-12 * 600.0)
    made.pop("sha256", None), stored.pop("sha256", None)
    assert made == stored


def test_nostd_check_builds_the_current_export_of_the_extended_model(tmp_path, capsys):
    out = tmp_path / "model.rs"
    assert main(["export", str(MODEL), "--rust", str(out)]) == 0
    printed = capsys.readouterr().out
    for stage in ("time_delay", "coil_lag", "non_congruent", "thermal_drift", "torque_ripple", "friction_current"):
        assert f"{stage}: on" in printed
    committed = (REPO / "nostd-check" / "src" / "model.rs").read_text()
    assert out.read_text() == committed, "re-export: bmr export tests/data/extended_model.json --rust " \
                                         "nostd-check/src/model.rs"
    assert "EffectValues { kind: 0, values: [0.015, 0.0, 0.0, 0.0, 0.0] }" in committed  # coil_lag, vocabulary #0


def test_export_errors_are_clear(tmp_path):
    m = bmr.Model.load(MODEL)
    with pytest.raises(bmr.BmrError, match="expected 'rust' or 'c'"):
        m.export(tmp_path / "x", "go")
    with pytest.raises(bmr.BmrError, match="C identifier"):
        m.export(tmp_path / "x.h", "c", prefix="1bad")
    comp = m.compensator(DT_S, inverse="paper")
    with pytest.raises(bmr.BmrError, match="exact inverse"):
        bmr._core.export_source(comp, "c")
    assert main(["export", str(tmp_path / "missing.json"), "--c", str(tmp_path / "m.h")]) == 2


def _tool(name: str) -> str:
    path = shutil.which(name) or (str(Path.home() / ".cargo" / "bin" / name)
                                  if (Path.home() / ".cargo" / "bin" / name).exists() else None)
    if path is None:
        pytest.skip(f"needs {name} on PATH")
    return path


def test_c_header_is_the_one_cbindgen_writes(tmp_path):
    cbindgen = _tool("cbindgen")
    out = tmp_path / "bmr.h"
    subprocess.run([cbindgen, "--quiet", "--config", "cbindgen.toml", "--output", str(out), "src/ffi.rs"],
                   cwd=REPO, check=True)
    assert out.read_text() == (REPO / "include" / "bmr.h").read_text(), \
        "regenerate: cbindgen --config cbindgen.toml --output include/bmr.h src/ffi.rs"


def _c_program(tmp_path: Path, source: str, model: Path = MODEL) -> Path:
    """``tests/c/<source>.c`` compiled against the no_std static library and the exported ``model``."""
    cc, cargo = _tool("cc"), _tool("cargo")
    env = dict(os.environ, CARGO_TERM_COLOR="never")
    subprocess.run([cargo, "build", "--release", "--quiet", "--manifest-path", "nostd-check/Cargo.toml"],
                   cwd=REPO, check=True, env=env)
    lib = REPO / "nostd-check" / "target" / "release" / "libbmr_nostd_check.a"
    assert main(["export", str(model), "--c", str(tmp_path / "model.h")]) == 0
    exe = tmp_path / source
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-I", str(REPO / "include"), "-I",
                    str(tmp_path), str(REPO / "tests" / "c" / f"{source}.c"), str(lib), "-Wl,--gc-sections",
                    "-o", str(exe)], check=True)
    return exe


@pytest.mark.slow
def test_c_program_matches_python_run_bit_for_bit(tmp_path):
    exe = _c_program(tmp_path, "run_model")
    ref, theta = reference()
    python = bmr.Model.load(MODEL).compensator(DT_S).run(ref, theta)["current_a"]
    text = f"{ref.size}\n" + "".join(f"{r.hex()} {a.hex()}\n" for r, a in zip(ref, theta))
    out = subprocess.run([str(exe), repr(DT_S)], input=text, capture_output=True, text=True, check=True)
    c = np.array([float.fromhex(v) for v in out.stdout.split()])
    assert c.size == ref.size
    assert np.array_equal(c.view(np.uint64), python.view(np.uint64)), np.flatnonzero(c != python)[:5]
    # Every stage did something: the extended commands differ from the nominal model's.
    nominal = bmr.Model.load(MODEL).compensator(stages=[]).run(ref, theta)["current_a"]
    assert np.max(np.abs(c - nominal)) > 0.05


@pytest.mark.slow
def test_c_program_with_creeps_fluctuation_field_matches_python_bit_for_bit(tmp_path):
    # Creep's log-time after-effect: its fluctuation field is taken off the core input, in C as in Python.
    m = bmr.Model.load(MODEL)
    m.extensions = list(m.extensions) + [{"name": "creep", "params": {"fraction": 0.01, "fluctuation": 0.004,
                                                                      "tau0_s": 0.05}}]
    path = m.save(tmp_path / "creep_model.json")
    exe = _c_program(tmp_path, "run_model", path)
    ref, theta = reference()
    python = bmr.Model.load(path).compensator(DT_S).run(ref, theta)["current_a"]
    text = f"{ref.size}\n" + "".join(f"{r.hex()} {a.hex()}\n" for r, a in zip(ref, theta))
    out = subprocess.run([str(exe), repr(DT_S)], input=text, capture_output=True, text=True, check=True)
    c = np.array([float.fromhex(v) for v in out.stdout.split()])
    assert np.array_equal(c.view(np.uint64), python.view(np.uint64)), np.flatnonzero(c != python)[:5]
    # The field changed the commands.
    without = bmr.Model.load(MODEL).compensator(DT_S).run(ref, theta)["current_a"]
    assert np.max(np.abs(c - without)) > 1e-3


@pytest.mark.slow
def test_c_program_with_a_mean_field_matches_python_bit_for_bit(tmp_path):
    # non_congruent's mean field (a moving Preisach core): the core's last output times feedback/S is taken off
    # the command, in C as in Python.
    m = bmr.Model.load(MODEL)
    m.extensions = [{**e, "params": {**e["params"], "feedback": 0.05}} if e["name"] == "non_congruent" else e
                    for e in m.extensions]
    path = m.save(tmp_path / "mean_field_model.json")
    exe = _c_program(tmp_path, "run_model", path)
    ref, theta = reference()
    python = bmr.Model.load(path).compensator(DT_S).run(ref, theta)["current_a"]
    text = f"{ref.size}\n" + "".join(f"{r.hex()} {a.hex()}\n" for r, a in zip(ref, theta))
    out = subprocess.run([str(exe), repr(DT_S)], input=text, capture_output=True, text=True, check=True)
    c = np.array([float.fromhex(v) for v in out.stdout.split()])
    assert np.array_equal(c.view(np.uint64), python.view(np.uint64)), np.flatnonzero(c != python)[:5]
    # The mean field changed the commands.
    without = bmr.Model.load(MODEL).compensator(DT_S).run(ref, theta)["current_a"]
    assert np.max(np.abs(c - without)) > 1e-3


@pytest.mark.slow
def test_c_controller_matches_python_bit_for_bit(tmp_path):
    exe = _c_program(tmp_path, "run_controller")
    ref, theta = reference()
    # A measurement 10 % weak with an offset and a ripple, and dropouts: the loop and the adaptation both act.
    measured = 0.9 * ref + 3.0 + 2.0 * np.sin(0.05 * np.arange(ref.size))
    measured[::97] = np.nan
    ctl = bmr.Controller.from_model(MODEL, dt_s=DT_S)
    python = np.array([ctl.step(float(r), float(t), float(y)).current_a for r, t, y in zip(ref, theta, measured)])
    text = f"{ref.size}\n" + "".join(f"{r.hex()} {a.hex()} {y.hex()}\n" for r, a, y in zip(ref, theta, measured))
    out = subprocess.run([str(exe), repr(DT_S)], input=text, capture_output=True, text=True, check=True)
    c = np.array([float.fromhex(v) for v in out.stdout.split()])
    assert c.size == ref.size
    assert np.array_equal(c.view(np.uint64), python.view(np.uint64)), np.flatnonzero(c != python)[:5]
    assert float.fromhex(out.stderr.split()[-1]) == ctl.gain != 1.0
