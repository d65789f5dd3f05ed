"""pytest-benchmark benches of the Python entry points (skipped in the normal run by `--benchmark-skip`; run with
`python -m pytest tests/test_benchmarks.py --benchmark-only`)."""
import numpy as np
import pytest

import bmr
from preisach_plant import first_order_curves


@pytest.fixture(scope="module")
def hyst():
    asc, desc = first_order_curves(200, 21)
    scale = lambda fam: [(1.25 * u, y) for u, y in fam]  # noqa: E731
    return bmr.Hysteresis.from_curves(scale(asc), scale(desc))


@pytest.fixture(scope="module")
def reference():
    rng = np.random.default_rng(0)
    knots = rng.uniform(-280, 280, 200)
    return np.interp(np.linspace(0, 199, 100_000), np.arange(200), knots)


def test_hysteresis_step(benchmark, hyst):
    benchmark(hyst.step, 0.3)


def test_hysteresis_run(benchmark, hyst, reference):
    benchmark(hyst.run, reference / 240.0)


def test_compensator_step(benchmark, hyst):
    c = bmr.Compensator(hyst, bmr.Friction.from_amplitude_phase(12, [25, 8, 4], [0.3, 1.1, -0.7]))
    benchmark(c.step, 100.0, 0.5)


def test_compensator_run(benchmark, hyst, reference):
    c = bmr.Compensator(hyst, bmr.Friction.from_amplitude_phase(12, [25, 8, 4], [0.3, 1.1, -0.7]))
    theta = np.linspace(0, 200, reference.size)
    benchmark(c.run, reference, theta)
