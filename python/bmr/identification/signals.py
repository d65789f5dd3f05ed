"""The input and output of a run as identification sees them: the bundle's declared input and output quantities
(for an actuator bundle, nominal current in A and torque in N·mm), with the angle-periodic friction removed from
the output when a friction model is given (and the run has an angle)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bmr._core import BmrError

__all__ = ["Quantities", "ACTUATOR", "quantities_of", "run_input", "run_output"]


@dataclass(frozen=True)
class Quantities:
    """Names and units of a device's input and output (what every report and figure shows)."""

    input_name: str
    input_unit: str
    output_name: str
    output_unit: str

    def to_dict(self) -> dict[str, str]:
        return {"input": self.input_name, "input_unit": self.input_unit, "output": self.output_name,
                "output_unit": self.output_unit}


ACTUATOR = Quantities("current", "A", "torque", "N·mm")


def quantities_of(bundle: Any) -> Quantities:
    """The bundle's declared quantities (``bundle.quantities``, or ``meta["quantities"]`` with ``input``,
    ``input_unit``, ``output``, ``output_unit``), else the actuator's."""
    q = getattr(bundle, "quantities", None)
    if isinstance(q, Quantities):
        return q
    if q is not None and all(hasattr(q, k) for k in ("input_name", "input_unit", "output_name", "output_unit")):
        return Quantities(str(q.input_name), str(q.input_unit), str(q.output_name), str(q.output_unit))
    meta = getattr(bundle, "meta", None) or {}
    m = meta.get("quantities") if isinstance(meta, dict) else None
    if isinstance(m, dict) and all(k in m for k in ("input", "input_unit", "output", "output_unit")):
        return Quantities(str(m["input"]), str(m["input_unit"]), str(m["output"]), str(m["output_unit"]))
    return ACTUATOR


def run_input(run: Any) -> np.ndarray:
    """The run's input samples (``run.input`` when the bundle declares one, else the nominal current)."""
    u = getattr(run, "input", None)
    return np.asarray(u if u is not None and not callable(u) else run.current, dtype=float)


def run_output(run: Any, friction: Any = None) -> np.ndarray:
    """The run's output samples (``run.output`` or the torque), less ``friction(angle)`` when both exist."""
    y = getattr(run, "output", None)
    y = np.asarray(y if y is not None and not callable(y) else run.torque, dtype=float)
    if friction is not None:
        try:
            theta = run.theta
        except (BmrError, AttributeError):
            theta = None  # a device without an angle has no angle-periodic friction
        if theta is not None:
            y = y - friction(np.asarray(theta, dtype=float))
    return y
