"""bmr: accurate torque control of bi-directional magneto-rheological actuators.

Core (Rust): ``Hysteresis`` (CBH operator), ``Friction`` (angle-periodic seal friction), ``Compensator``
(exact or paper inverse + friction feedforward, coil split, current limit).
Units: current in A (nominal current spans both coils: negative = coil 1, positive = coil 2), torque in N·mm,
angles in rad, time in s, converter voltages in V.
"""
from bmr._core import (
    BmrError,
    Command,
    Compensator,
    CompensatorState,
    Friction,
    Hysteresis,
    HysteresisState,
)
from bmr.bundle import Bundle, Run, read_bundle, write_bundle

__all__ = [
    "BmrError",
    "Bundle",
    "Command",
    "Compensator",
    "CompensatorState",
    "Friction",
    "Hysteresis",
    "HysteresisState",
    "Run",
    "read_bundle",
    "write_bundle",
]
__version__ = "0.1.0"
