"""The input and output of a run as identification sees them: the bundle's declared input and output
(:attr:`bmr.Run.input`, :attr:`bmr.Run.output`, in the units of ``bundle.quantities``), with the angle-periodic
friction removed from the output when a friction model is given and the run has an angle."""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["run_input", "run_output"]


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
