"""The input and output of a run as identification sees them: the bundle's declared input and output
(:attr:`bmr.Run.input`, :attr:`bmr.Run.output`, in the units of ``bundle.quantities``), with the angle-periodic
friction removed from the output when a friction model is given and the run has an angle."""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["run_input", "run_output", "running_integral"]


def run_input(run: Any) -> np.ndarray:
    """The run's input samples (declared unit)."""
    return np.asarray(run.input, dtype=float)


def run_output(run: Any, friction: Any = None) -> np.ndarray:
    """The run's output samples (declared unit), less ``friction(angle)`` when both exist."""
    y = np.asarray(run.output, dtype=float)
    angle = run.angle
    if friction is not None and angle is not None:
        y = y - friction(np.asarray(angle, dtype=float))
    return y


def running_integral(u: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``∫u dt`` from the first sample (trapezoids; input unit × s): what a leakage current through the sample adds
    to a charge measurement, up to its conductance."""
    u = np.asarray(u, dtype=float)
    t = np.asarray(t, dtype=float)
    if u.size < 2:
        return np.zeros(u.size)
    return np.concatenate([[0.0], np.cumsum(0.5 * np.diff(t) * (u[1:] + u[:-1]))])
