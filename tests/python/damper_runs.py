"""A damper-like recording (force N on displacement mm): stiffness, viscous force and a smooth yield force of the
velocity (the Bingham form of an MR damper), whose loops run clockwise."""
from __future__ import annotations

import numpy as np

import bmr
from bmr.data.quantities import Quantities, Quantity

FS_HZ = 100.0
# A damper-like force (N) on a displacement (mm): stiffness, viscous force and a smooth yield force of the velocity.
STIFFNESS_N_PER_MM = 20.0
VISCOUS_N_PER_MM_S = 4.0
YIELD_N = 300.0
YIELD_VELOCITY_MM_S = 5.0
FREQUENCY_HZ = 1.0


def _damper_run(name: str, amplitudes_mm: tuple[float, float], cycles: int, role: str,
                rng: np.random.Generator) -> bmr.Run:
    """A sinusoid whose amplitude moves from the first to the second of ``amplitudes_mm`` over ``cycles``."""
    import pandas as pd

    q = Quantities(Quantity.declare("mm", "displacement"), Quantity.declare("N", "force"))
    t = np.arange(int(cycles * FS_HZ / FREQUENCY_HZ)) / FS_HZ
    u = np.linspace(*amplitudes_mm, t.size) * np.sin(2 * np.pi * FREQUENCY_HZ * t)
    v = np.gradient(u, t)
    y = (STIFFNESS_N_PER_MM * u + VISCOUS_N_PER_MM_S * v + YIELD_N * np.tanh(v / YIELD_VELOCITY_MM_S)
         + rng.normal(0.0, 2.0, t.size))
    data = pd.DataFrame({"t_s": t, q.input.column: u, q.output.column: y})
    return bmr.Run(name, "custom", data, {}, q, role)


def damper_bundle() -> bmr.Bundle:
    rng = np.random.default_rng(7)
    runs = [_damper_run("growing", (1.0, 10.0), 8, "identification", rng),
            _damper_run("decaying", (10.0, 1.5), 8, "identification", rng),
            _damper_run("held", (8.5, 8.5), 4, "evaluation", rng)]
    return bmr.Bundle("rate-driven damper", FS_HZ, runs, quantities=runs[0].quantities)
