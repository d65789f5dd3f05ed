"""What a user meets when holding a bundle: a one-line summary, an honest sample rate, numpy scalars accepted."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.data.signals import nominal_sample_rate


def _run(name: str, n: int = 2000, rate: float = 500.0) -> bmr.Run:
    t = np.arange(n) / rate
    df = pd.DataFrame({"t_s": t, "current_a": np.sin(t), "theta_rad": t, "torque_nmm": 100 * np.sin(t)})
    return bmr.Run(name, "custom", df)


def test_repr_is_a_summary_not_a_dump():
    b = bmr.Bundle("rig A", 500.0, [_run("a"), _run("b", 4000)])
    text = repr(b)
    assert "\n" not in text and len(text) < 200
    assert "2 runs" in text and "6000 samples" in text and "500 Hz" in text
    r = repr(b.runs[1])
    assert "\n" not in r and "4000 samples" in r and "'custom'" in r


@pytest.mark.parametrize("t, expected", [
    (np.arange(10_000) / 500.0, 500.0),                      # 1/500 is not exact in binary
    (np.round(np.arange(9000) / 3000.0, 6), 3000.0),          # times stored to the microsecond
    (1.7e9 + np.arange(1000) * 1e-3, 1000.0),                 # absolute (epoch) timestamps
    (np.cumsum(np.full(1000, 1 / 48_000.0)), 48_000.0),       # accumulated float steps
    (np.arange(100) * 0.0125, 80.0),
])
def test_sample_rate_is_rounded_to_what_the_timestamps_resolve(t, expected):
    assert nominal_sample_rate(t) == expected


def test_inferred_rate_of_a_read_log(tmp_path):
    p = tmp_path / "log.csv"
    t = np.arange(5000) / 500.0
    pd.DataFrame({"time": t, "i": np.sin(t), "angle": t, "torque": np.cos(t)}).to_csv(p, index=False)
    b = bmr.bundle_from_files([{"path": p, "name": "r", "kind": "custom"}],
                              mapping={"t_s": "time", "current_a": "i", "theta_rad": "angle", "torque_nmm": "torque"})
    assert b.sample_rate_hz == 500.0


def test_numpy_scalars_are_numbers_and_bools_are_not():
    assert bmr.Bundle("x", np.int64(500), [_run("a")]).sample_rate_hz == 500.0
    assert bmr.Bundle("x", np.float32(250.0), [_run("a")]).sample_rate_hz == 250.0
    with pytest.raises(bmr.BmrError, match="sample_rate_hz"):
        bmr.Bundle("x", True, [_run("a")])
