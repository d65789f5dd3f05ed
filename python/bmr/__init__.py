"""bmr: accurate torque control of bi-directional magneto-rheological actuators.

Core (Rust): ``Hysteresis`` (CBH operator), ``Friction`` (angle-periodic seal friction), ``VirtualActuator``
(a physical simulator of the rig; ``EFFECTS`` names its switchable effects, ``effect_parameters()`` documents
them). Experiment protocols and bundles of them: ``bmr.experiments``.
Units: current in A (nominal current spans both coils: negative = coil 1, positive = coil 2), torque in N·mm,
angles in rad, time in s.
"""
from bmr._core import (
    EFFECTS,
    PRESETS,
    BmrError,
    Friction,
    Hysteresis,
    HysteresisState,
    VirtualActuator,
    effect_parameters,
)
from bmr.bundle import Bundle, Run, read_bundle, write_bundle

__all__ = [
    "EFFECTS",
    "PRESETS",
    "BmrError",
    "Bundle",
    "Friction",
    "Hysteresis",
    "HysteresisState",
    "Run",
    "VirtualActuator",
    "effect_parameters",
    "read_bundle",
    "write_bundle",
]
__version__ = "0.1.0"
