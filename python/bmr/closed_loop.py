"""The closed loop in batch: a :class:`bmr.Controller` driving a :class:`bmr.VirtualActuator` sample by sample in
one Rust loop (no Python per step), for design studies; the result is a :class:`ClosedLoopRun` of named arrays."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bmr._core import Controller, VirtualActuator, _simulate_closed_loop


@dataclass(frozen=True)
class ClosedLoopRun:
    """One closed-loop run, one value per sample: time (s), the reference, the measured and the true torque
    (N·mm), the commanded current (A), the controller's integral correction (N·mm), adapted gain and offset
    (N·mm), and the command's ``saturated`` and ``fault`` flags."""

    t_s: np.ndarray
    reference_nmm: np.ndarray
    torque_nmm: np.ndarray
    torque_true_nmm: np.ndarray
    current_a: np.ndarray
    correction_nmm: np.ndarray
    gain: np.ndarray
    offset_nmm: np.ndarray
    saturated: np.ndarray
    fault: np.ndarray

    def tracking_rms_nmm(self, start: int = 0) -> float:
        """RMS (N·mm) of measured − reference torque from sample ``start`` on."""
        e = self.torque_nmm[start:] - self.reference_nmm[start:]
        return float(np.sqrt(np.mean(e * e)))


def simulate_closed_loop(controller: Controller, plant: VirtualActuator, reference: ArrayLike,
                         theta: ArrayLike | None = None) -> ClosedLoopRun:
    """Drive ``plant`` with ``controller`` along ``reference`` (N·mm, one value per sample at the plant's sample
    rate) from their present states; both advance. ``theta`` (rad): the rotor angle of each sample, default the
    plant's own (``plant.theta_ahead``). The controller gets each sample's reference and angle and the torque the
    plant measured at the sample before (none at the first)."""
    cols = _simulate_closed_loop(controller, plant, reference, theta)
    return ClosedLoopRun(**cols)
