"""What a diagnosis shares between grid values and gives back once the search is over: creep's unbounded form
takes every onset's and every correction's response against one nominal field, the learned library is built in
place (no second copy of it), the model's tables are taken while the configuration's regression is still
prepared, and the freed heap goes back to the system when the search's caches are released."""
from __future__ import annotations

import copy
import platform
import tracemalloc
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import bmr
from bmr.diagnosis import discrepancy, field, selection
from bmr.diagnosis.effects import LIBRARY, Creep, _run_input
from bmr.diagnosis.procedure import nominal_model
from bmr.diagnosis.residuals import prepare, return_freed_memory
from bmr.simulation.excitation import diagnosis_bundle


class _CountingHysteresis:
    """A core that counts the runs of itself and of its copies."""

    def __init__(self, inner: Any, runs: list[int]) -> None:
        self.inner = inner
        self.runs = runs

    def __copy__(self) -> "_CountingHysteresis":
        return _CountingHysteresis(copy.copy(self.inner), self.runs)

    def run(self, u: np.ndarray) -> Any:
        self.runs[0] += 1
        return self.inner.run(u)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


class _Model:
    def __init__(self, inner: Any, hysteresis: Any) -> None:
        self.inner = inner
        self.hysteresis = hysteresis

    def forward_hysteresis(self) -> Any:
        return self.hysteresis  # the model has no signed table: its forward core is its tables

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


@pytest.fixture(scope="module")
def lag_bundle() -> Any:
    return diagnosis_bundle("rig_preisach", effects={"coil_lag": {"tau_s": 0.02}}, seed=7).decimated(4)


def _creep() -> Creep:
    return next(e for e in LIBRARY if isinstance(e, Creep))


def test_creeps_onsets_and_corrections_share_one_nominal_field(lag_bundle) -> None:
    model = nominal_model(lag_bundle)
    runs = [0]
    counting = _Model(model, _CountingHysteresis(model.hysteresis, runs))
    data = prepare(lag_bundle, model.hysteresis.input_range, 3, friction=model.friction)
    creep = _creep()
    columns = [creep.columns(data, ("log", tau0, 0.0), None, counting)[:, 0] for tau0 in (0.03, 0.3)]
    # The nominal field once, then one pushed run per onset (each response computed on its own: two per onset).
    assert runs[0] == 3 * len(data.runs)
    lo, hi = model.hysteresis.input_range
    eps = creep.LINEARISE_SHARE * (hi - lo)
    for col, tau0 in zip(columns, (0.03, 0.3)):
        alone = np.concatenate([Creep._fluctuation_response(model.hysteresis, _run_input(r), eps, tau0, r.dt_s)
                                [r.start:] / eps for r in data.runs])
        np.testing.assert_array_equal(col, alone)
    # The protocol runs: the nominal field of each once, then one pushed run per correction.
    run = lag_bundle.roles().protocol[0]
    pr = field.ProtocolRun(run, 0.0, counting)
    runs[0] = 0
    removed = [creep.remove(pr.torque, ("log", 0.1, 0.0), np.array([b]), pr) for b in (1e-4, 2e-4)]
    assert runs[0] == 3
    for out, b in zip(removed, (1e-4, 2e-4)):
        alone = pr.torque - Creep._fluctuation_response(model.hysteresis, pr.current, b * (hi - lo), 0.1, pr.dt)
        np.testing.assert_array_equal(out, alone)


def _library_runs(count: int, n: int) -> list[SimpleNamespace]:
    rng = np.random.default_rng(3)
    out = []
    for _ in range(count):
        t = np.arange(n) * 0.002
        u = np.sin(2 * np.pi * 0.5 * t) + 0.01 * rng.standard_normal(n)
        out.append(SimpleNamespace(t_s=t, u=u, y=np.tanh(2 * u), theta=0.7 * t, start=n // 10))
    return out


def test_the_learned_library_is_built_in_place(monkeypatch) -> None:
    runs = _library_runs(4, 20_000)
    # Each run's block as an array numpy allocates (the core's own arrays are not traced).
    signals = bmr._core.candidate_signals
    monkeypatch.setattr(discrepancy._core, "candidate_signals", lambda *a, **k: np.array(signals(*a, **k)))
    tracemalloc.start()
    try:
        lib = discrepancy.candidate_library(runs, deadband=0.02)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # The library plus one run's block (its opening included), not every run's block and the stacked copy.
    one_run = lib.matrix.shape[1] * runs[0].u.size * 8
    assert peak <= lib.matrix.nbytes + 1.2 * one_run, (peak, lib.matrix.nbytes)
    want = np.vstack([signals(r.t_s, r.u, r.y, deadband=0.02, theta_rad=r.theta,
                                                  harmonics=12)[r.start:] for r in runs])
    np.testing.assert_array_equal(lib.matrix, want)


def test_the_models_tables_are_taken_before_the_search_is_released(lag_bundle, monkeypatch) -> None:
    # The configuration's tables after the release would prepare its input history's regression again (tens of
    # MB on a long bundle, on top of the steps that follow).
    events: list[str] = []
    release, regression = selection.Fitter.release, field.Reidentifier._regression

    def on_release(self: Any) -> None:
        events.append("release")
        release(self)

    def on_regression(self: Any, path: Any) -> Any:
        events.append("regression")
        return regression(self, path)

    monkeypatch.setattr(selection.Fitter, "release", on_release)
    monkeypatch.setattr(field.Reidentifier, "_regression", on_regression)
    monkeypatch.setattr(selection, "return_freed_memory", lambda: events.append("heap given back"))
    d = bmr.diagnose(lag_bundle, progress=False, closed_loop=False)
    assert "coil_lag" in [e["name"] for e in d.effects]
    assert any(e["name"] == "core_tables" for e in d.extended_model.extensions)
    # Nothing is prepared after the release, which gives the freed heap back.
    assert events.count("release") == 1 and events[-2:] == ["release", "heap given back"], events[-5:]


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="the heap is given back through glibc's malloc_trim")
def test_freed_heap_is_given_back() -> None:
    def resident_mb() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * 4096 / 2**20

    big = np.ones(2 << 20)
    del big  # a freed 16 MB array raises glibc's threshold: the 1 MB arrays below come from the heap
    kept, freed = [], []
    for i in range(200):
        (freed if i % 2 == 0 else kept).append(np.ones(1 << 17))
        kept.append(np.ones(1 << 10))  # pins the heap between the freed arrays
    freed.clear()
    before = resident_mb()
    return_freed_memory()
    assert resident_mb() < before - 50.0
