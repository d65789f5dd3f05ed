"""The command line: version, help that documents choices and units, and one-line errors (rc 2)."""
from __future__ import annotations

import pytest

import bmr
from bmr.cli import main


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"bmr {bmr.__version__}"


@pytest.mark.parametrize("command, words", [
    ("demo", ["bmr2013", "ideal", "rig_preisach", "seed"]),
    ("simulate", ["bmr2013", "--effect", "--override", "seed"]),
    ("identify", ["forc", "lstsq", "held-out", "bundle folder"]),
    ("diagnose", ["blocked folds", "bundle folder", "bootstrap"]),
    ("import", ["COL:UNIT", "COL:SOURCE:UNIT", "forc-ascending", "forc-descending", "major-loop", "--holdout",
                "ControlDesk", "SLAC"]),
    ("predict", ["evaluation runs", "--calibration", "estimate", "extrapolate", "bmr-prediction/1", "bundle folder"]),
])
def test_help_documents_choices(command, words, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for w in words:
        assert w in text, (command, w)


def test_unknown_preset_is_a_usage_error_before_any_work(tmp_path, capsys):
    out = tmp_path / "demo"
    with pytest.raises(SystemExit) as e:
        main(["demo", "--preset", "nope", "--out", str(out)])
    assert e.value.code == 2
    assert "invalid choice: 'nope'" in capsys.readouterr().err
    assert not out.exists()
