"""A second plant family, written independently of bmr's virtual actuator and of its effect stages: for every
effect of the vocabulary at least one physically different mechanism that produces it, on the Preisach core of
``independent_preisach`` (its Everett table; stepped here one sample at a time so that mechanisms can feed the
output back into the field). Bundles use bmr's experiment protocols (``bmr.simulation.experiments``) through a
duck-typed rig, so the excitation is the one the diagnosis is calibrated on; nothing else of bmr's simulation runs.

Units as on the rig: current A, torque N·mm, angle rad, time s. The field path: converter current ``i`` → coil
circuit → field drive ``h`` (A-equivalent) → Preisach core (output ``y``, N·mm, about ±``FULL_SCALE_NMM``) →
field torque → plus seal friction of the rotor angle → torque sensor (gain, offset, noise 1.5 N·mm, 0.19 N·mm
steps). Every mechanism is off unless switched on; a seed fixes every sample (sensor noise, per-recording
calibration draws).

Mechanisms (``MECHANISMS``: the effect names the diagnosis should give each, a medium size, the parameters scaled
with the size):

* ``coil_eddy_circuit`` (coil_lag): the coil current follows the converter with L/R time ``tau_coil_s`` and a
  shorted eddy-current loop (time ``tau_eddy_s``) opposes a share ``eddy_share`` of every change of it;
* ``fractional_delay`` (time_delay): a transport delay of ``delay_s`` read by linear interpolation between samples;
* ``eddy_field`` (rate_dependence): the core sees ``h - k_s * dy/dt / S_REF`` (a dynamic field opposing the change
  of flux, backward Euler with the slope of the previous sample);
* ``rate_loss`` (rate_dependence or viscous): a loss torque ``c_nmm_s_per_a * di/dt`` independent of the loop's
  slope (shear-thinning: it saturates above 10 A/s, so a current step's loss stays bounded);
* ``log_after_effect`` (creep): a thermal fluctuation field ``viscosity_a * ln(1 + t/t0_s)`` along the input's last
  direction, t the time since the last reversal — unbounded, it never settles within a run;
* ``coil_heating`` (thermal_drift): coil temperature driven by ``I^2 R(T)`` (copper, 0.39 %/K) with time constant
  ``tau_s`` to ``rise_k`` at steady full current; the field torque falls by ``gain_per_k`` per kelvin;
* ``cubic_yield`` (non_congruent): the fluid's yield stress a cubic map of the steel's flux after a congruent core;
* ``moving_preisach`` (non_congruent): a mean-field (moving) Preisach, the core sees ``h + feedback_a * y / S``;
* ``field_normal_force`` (friction_current): the angle-dependent seal friction grows with the square of the field
  (magnetic pull on the seals), ``1 + growth * (y/S)^2``;
* ``seal_lobes`` (friction_harmonics): lobed seal contact, a flattened sine ``tanh(2 sin(order θ + phase))``;
* ``eccentric_gap`` (torque_ripple): the field torque goes as the inverse square of the gap
  ``1 - eccentricity cos(θ + phase)``;
* ``bridge_warmup`` (sensor_drift): the strain bridge's offset warms up towards ``drift_nmm`` with time
  ``tau_s`` from the rig's start;
* ``recalibration`` (run_gain_offset): each recording's sensor gain and offset drawn uniformly within
  ``1 ± gain_span`` and ``± offset_span_nmm``;
* ``parallel_conductance`` (leakage): a conductance across the sample, slightly nonlinear (``u + 0.3 u³``), whose
  current a charge amplifier with feedback time ``tau_amp_s`` integrates from the start of each recording;
* ``reptation`` (accommodation): at every reversal after the second since a saturation, the output shift moves a
  share ``per_reversal`` of the way to ``-share`` times the last two reversal outputs' mean.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

import independent_preisach as P
from bmr.data.bundle import Bundle, Run
from bmr.simulation import experiments as X
from bmr.simulation.excitation import minor_loops, repeated_loops

FULL_SCALE_NMM = 600.0  # S: the core's output at positive saturation (N·mm)
S_REF = 1200.0 / 2.5  # the major loop's mean slope (N·mm per A): output span over input span
NOISE_NMM = 1.5
STEP_NMM = 0.19
SPEED_RAD_S = 2 * math.pi
RATE_LOSS_SATURATION_A_PER_S = 10.0  # the fluid thins at high rates: the loss of a current step stays bounded


@dataclass(frozen=True)
class Mechanism:
    names: tuple[str, ...]  # effect names that are right for it (any one of them)
    medium: dict[str, float]
    scaled: tuple[str, ...]


MECHANISMS: dict[str, Mechanism] = {
    "coil_eddy_circuit": Mechanism(("coil_lag",), {"tau_coil_s": 0.012, "eddy_share": 0.4, "tau_eddy_s": 0.03},
                                   ("tau_coil_s", "tau_eddy_s")),
    "fractional_delay": Mechanism(("time_delay",), {"delay_s": 0.017}, ("delay_s",)),
    "eddy_field": Mechanism(("rate_dependence",), {"k_s": 0.01}, ("k_s",)),
    "rate_loss": Mechanism(("rate_dependence", "viscous"), {"c_nmm_s_per_a": 6.0}, ("c_nmm_s_per_a",)),
    "log_after_effect": Mechanism(("creep",), {"viscosity_a": 0.003, "t0_s": 0.05}, ("viscosity_a",)),
    "coil_heating": Mechanism(("thermal_drift",), {"rise_k": 40.0, "tau_s": 60.0, "gain_per_k": 0.0025},
                              ("gain_per_k",)),
    "cubic_yield": Mechanism(("non_congruent",), {"cubic": 0.5}, ("cubic",)),
    "moving_preisach": Mechanism(("non_congruent",), {"feedback_a": 0.15}, ("feedback_a",)),
    "field_normal_force": Mechanism(("friction_current",), {"growth": 0.8}, ("growth",)),
    "seal_lobes": Mechanism(("friction_harmonics",), {"order": 6.0, "amplitude_nmm": 5.0, "phase_rad": 0.3},
                            ("amplitude_nmm",)),
    "eccentric_gap": Mechanism(("torque_ripple",), {"eccentricity": 0.025, "phase_rad": 0.8}, ("eccentricity",)),
    "bridge_warmup": Mechanism(("sensor_drift",), {"drift_nmm": 40.0, "tau_s": 600.0}, ("drift_nmm",)),
    "recalibration": Mechanism(("run_gain_offset",), {"gain_span": 0.05, "offset_span_nmm": 7.0},
                               ("gain_span", "offset_span_nmm")),
    "parallel_conductance": Mechanism(("leakage",), {"conductance": 0.5, "tau_amp_s": 300.0}, ("conductance",)),
    "reptation": Mechanism(("accommodation",), {"share": 0.08, "per_reversal": 0.3}, ("share",)),
}

# Seal friction of the rotor angle (N·mm): mean and harmonics 1-3 (amplitude, phase).
FRICTION_MEAN_NMM = 15.0
FRICTION_HARMONICS = ((25.0, 0.3), (8.0, 1.7), (4.0, -0.6))


def at_size(mechanism: str, size: float) -> dict[str, float]:
    """The parameters of ``mechanism`` at ``size`` times its medium size."""
    m = MECHANISMS[mechanism]
    return {k: v * size if k in m.scaled else v for k, v in m.medium.items()}


class Core(P.Plant):
    """The independent Preisach plant stepped one sample at a time (scalar Everett look-ups)."""

    def __init__(self) -> None:
        super().__init__(coercivity=0.15, coercivity_width=0.12, interaction_width=0.35, reversible=0.3,
                         scale=2 * FULL_SCALE_NMM, cells=400)
        self._rev_scale = self.k * self.reversible * float(self.table[0, self.cells])
        self._e = self.table.tolist()

    def _everett(self, beta: float, alpha: float) -> float:
        beta = min(max(beta, P.LO), P.HI)
        alpha = min(max(alpha, P.LO), P.HI)
        if alpha <= beta:
            return 0.0
        fi = (beta - P.LO) / self.h
        i = min(int(fi), self.cells - 1)
        s = fi - i
        fj = (alpha - P.LO) / self.h
        j = min(int(fj), self.cells - 1)
        t = fj - j
        e0, e1 = self._e[i], self._e[i + 1]
        v = (1 - s) * ((1 - t) * e0[j] + t * e0[j + 1]) + s * ((1 - t) * e1[j] + t * e1[j + 1])
        return max(v, 0.0) * 2 * self.k

    def _branch(self, x: float) -> float:
        ref_u, ref_y = self.stack[-1]
        if len(self.stack) % 2 == 1:
            return ref_y + self._everett(ref_u, x)
        return ref_y - self._everett(x, ref_u)

    def step(self, u: float) -> tuple[float, bool]:
        """The output at input ``u`` and whether the input turned here (a new reversal point)."""
        u = min(max(u, P.LO), P.HI)
        st = self.stack
        rising = len(st) % 2 == 1
        turned = (rising and u < self.x) or (not rising and u > self.x)
        if turned:
            st.append((self.x, self._branch(self.x)))
            rising = not rising
        while len(st) >= 2 and ((rising and u > st[-2][0]) or (not rising and u < st[-2][0])):
            del st[-2:]  # wiped out
        self.x = u
        return self._branch(u) + self._rev_scale * math.tanh(u / 0.6), turned

    # Within this of an end of the input range the core is saturated (every hysteron of this density switched: a
    # delayed or lagged drive comes within a fraction of a sample's step of the end, not onto it).
    SATURATION_A = 0.01

    def saturated(self) -> bool:
        """At a saturation end of the input: the memory is wiped out."""
        return self.x <= P.LO + self.SATURATION_A or self.x >= P.HI - self.SATURATION_A

    def turned_at_end(self) -> bool:
        """The newest reversal point is a saturation end (leaving saturation is not a reversal of a loop)."""
        if len(self.stack) < 2:
            return False
        u = self.stack[-1][0]
        return u <= P.LO + self.SATURATION_A or u >= P.HI - self.SATURATION_A


class IndependentRig:
    """The rig with ``mechanisms`` (name → parameters) switched on; quacks like the virtual actuator for bmr's
    protocol functions (``sample_rate_hz``, ``time_s``, ``run``)."""

    name = "independent rig (Preisach core, own effect mechanisms)"

    def __init__(self, mechanisms: dict[str, dict[str, float]] | None = None, *, seed: int = 0,
                 sample_rate_hz: float = 500.0) -> None:
        self.mechanisms = {k: dict(v) for k, v in (mechanisms or {}).items()}
        unknown = sorted(set(self.mechanisms) - set(MECHANISMS))
        if unknown:
            raise ValueError(f"unknown mechanisms {unknown}; known: {', '.join(MECHANISMS)}")
        for name, params in self.mechanisms.items():
            self.mechanisms[name] = {**MECHANISMS[name].medium, **params}
        self.sample_rate_hz = float(sample_rate_hz)
        self.rng = np.random.default_rng(seed)  # sensor noise
        self.calibration_rng = np.random.default_rng([seed, 1])  # per-recording calibration draws
        self.core = Core()
        self.core.reset()
        self.time_s = 0.0
        self.theta = 0.0
        # Continuous states across recordings.
        self.i_prev = 0.0
        self.coil = 0.0
        self.eddy = 0.0
        self.temp_k = 0.0
        self.history: list[float] = [0.0]  # converter current of past samples (fractional delay)
        self.y_prev = self.core.step(0.0)[0]
        self.h_prev = 0.0
        self.dy_prev = S_REF
        self.direction = 0.0
        self.since_reversal_s = 0.0
        self.shift = 0.0
        self.reversal_outputs: list[float] = []
        self.calibrations: list[tuple[float, float]] = []

    def _get(self, name: str) -> dict[str, float] | None:
        return self.mechanisms.get(name)

    def run(self, current_a: np.ndarray) -> dict[str, np.ndarray]:
        """One recording of ``current_a`` (A, one sample per period): its columns."""
        i_cmd = np.asarray(current_a, dtype=float)
        n = i_cmd.size
        dt = 1.0 / self.sample_rate_hz
        m = self.mechanisms
        gain, offset = 1.0, 0.0
        if "recalibration" in m:
            p = m["recalibration"]
            gain = 1.0 + float(self.calibration_rng.uniform(-p["gain_span"], p["gain_span"]))
            offset = float(self.calibration_rng.uniform(-p["offset_span_nmm"], p["offset_span_nmm"]))
        self.calibrations.append((gain, offset))
        delay = m.get("fractional_delay")
        coil = m.get("coil_eddy_circuit")
        eddy_field = m.get("eddy_field")
        rate_loss = m.get("rate_loss")
        after = m.get("log_after_effect")
        heating = m.get("coil_heating")
        cubic = m.get("cubic_yield")
        moving = m.get("moving_preisach")
        normal = m.get("field_normal_force")
        lobes = m.get("seal_lobes")
        gap = m.get("eccentric_gap")
        warm = m.get("bridge_warmup")
        leak = m.get("parallel_conductance")
        rept = m.get("reptation")
        lag_d = (delay["delay_s"] / dt) if delay else 0.0
        hist = self.history
        torque = np.empty(n)
        theta_out = np.empty(n)
        charge = 0.0
        core = self.core
        for k in range(n):
            i = float(i_cmd[k])
            hist.append(i)
            # Converter current reaching the coils (transport delay, linear interpolation).
            if lag_d > 0:
                back = min(lag_d, len(hist) - 1.0)
                j = int(back)
                f = back - j
                a = hist[-1 - j]
                b = hist[-2 - j] if j + 1 < len(hist) else a
                i_coil_in = (1 - f) * a + f * b
            else:
                i_coil_in = i
            # Coil L/R and a shorted eddy loop opposing a share of every change (backward Euler).
            if coil:
                prev = self.coil
                tc, te = coil["tau_coil_s"], coil["tau_eddy_s"]
                self.coil = (tc * self.coil + dt * i_coil_in) / (tc + dt)
                self.eddy = (te * self.eddy - coil["eddy_share"] * te * (self.coil - prev)) / (te + dt)
                h = self.coil + self.eddy
            else:
                h = i_coil_in
            # Thermal fluctuation field along the last direction of the drive (log of the time since it turned).
            step_dir = math.copysign(1.0, i - self.i_prev) if i != self.i_prev else 0.0
            if step_dir != 0.0 and step_dir != self.direction:
                self.direction = step_dir
                self.since_reversal_s = 0.0
            else:
                self.since_reversal_s += dt
            if after:
                h += self.direction * after["viscosity_a"] * math.log1p(self.since_reversal_s / after["t0_s"])
            if eddy_field:
                # Dynamic field against the flux change: h_core = h - k dy/dt / S_REF with dy = slope * dh_core.
                c = eddy_field["k_s"] * self.dy_prev / S_REF / dt
                h = (h + c * core.x) / (1 + c)
            if moving:
                h += moving["feedback_a"] * self.y_prev / FULL_SCALE_NMM
            y_core, turned = core.step(h)
            dh = h - self.h_prev
            if abs(dh) > 1e-9:
                self.dy_prev = abs((y_core - self.y_prev) / dh)  # the branch's slope (N·mm/A)
            self.h_prev = h
            self.y_prev = y_core
            y = y_core
            if rept:
                if core.saturated():
                    self.shift = 0.0
                    self.reversal_outputs = []
                elif turned and not core.turned_at_end():
                    self.reversal_outputs = (self.reversal_outputs + [y_core])[-2:]
                    if len(self.reversal_outputs) == 2:
                        centre = 0.5 * (self.reversal_outputs[0] + self.reversal_outputs[1])
                        self.shift += rept["per_reversal"] * (-rept["share"] * centre - self.shift)
                y += self.shift
            if cubic:
                nrm = y / FULL_SCALE_NMM
                y = FULL_SCALE_NMM * (nrm + cubic["cubic"] * nrm ** 3) / (1 + cubic["cubic"])
            if heating:
                # Temperature rise driven by I^2 R(T): steady rise_k at full current and ambient resistance.
                p = (i / P.HI) ** 2 * (1 + 0.0039 * self.temp_k)
                self.temp_k += dt / heating["tau_s"] * (heating["rise_k"] * p - self.temp_k)
                y *= 1 - heating["gain_per_k"] * self.temp_k
            # Rotor angle: 1 rev/s with 1 % speed ripple over the revolution.
            self.theta += dt * SPEED_RAD_S * (1 + 0.01 * math.sin(self.theta))
            th = self.theta
            if gap:
                y *= 1.0 / (1 - gap["eccentricity"] * math.cos(th + gap["phase_rad"])) ** 2
            if rate_loss:
                r = (i - self.i_prev) / dt
                y += rate_loss["c_nmm_s_per_a"] * r / (1 + abs(r) / RATE_LOSS_SATURATION_A_PER_S)
            wave = sum(a * math.cos((q + 1) * th + ph) for q, (a, ph) in enumerate(FRICTION_HARMONICS))
            if normal:
                wave *= 1 + normal["growth"] * (y_core / FULL_SCALE_NMM) ** 2
            if lobes:
                wave += lobes["amplitude_nmm"] * math.tanh(2 * math.sin(lobes["order"] * th + lobes["phase_rad"])) \
                    / math.tanh(2.0)
            reading = y + FRICTION_MEAN_NMM + wave
            if leak:
                charge += dt * (leak["conductance"] * (i + 0.3 * i ** 3) - charge / leak["tau_amp_s"])
                reading += charge
            if warm:
                reading += warm["drift_nmm"] * (1 - math.exp(-self.time_s / warm["tau_s"]))
            torque[k] = gain * reading + offset
            theta_out[k] = th % (2 * math.pi)
            self.i_prev = i
            self.time_s += dt
        del hist[:-64]
        torque += self.rng.normal(0.0, NOISE_NMM, n)
        torque = np.round(torque / STEP_NMM) * STEP_NMM
        return {"current_a": i_cmd.copy(), "theta_rad": theta_out, "torque_nmm": torque,
                "coil1_a": i_cmd.copy(), "coil2_a": i_cmd.copy()}


# ------------------------------------------------------------------------------------------------ bundles
PROTOCOLS = ("diagnosis", "coarse")


def _plan(protocol: str) -> list[Callable[[Any], Run]]:
    """bmr's quick experiment set with 11 first-order curves per family (``diagnosis``: plus the nested and the
    repeated minor loops of ``bmr.simulation.excitation.diagnosis_bundle``; ``coarse``: the paper's set alone)."""
    o = {"opening_rate_a_per_s": 2.5}
    plan: list[Callable[[Any], Run]] = [
        lambda a: X.off_state(a, duration_s=8.0, **o),
        lambda a: X.multi_step(a, duration_s=42.0, **o),
        lambda a: X.first_order_ascending(a, reversals=11, rate_a_per_s=1.0, **o),
        lambda a: X.first_order_descending(a, reversals=11, rate_a_per_s=1.0, **o),
        lambda a: X.triangle(a, rate_a_per_s=0.5, duration_s=20.0, **o),
        lambda a: X.multipeak(a, duration_s=20.0, **o),
    ]
    if protocol == "diagnosis":
        plan += [lambda a: minor_loops(a, **o), lambda a: repeated_loops(a, **o)]
    elif protocol != "coarse":
        raise ValueError(f"unknown protocol {protocol!r}; known: {', '.join(PROTOCOLS)}")
    return plan


def independent_bundle(mechanisms: dict[str, dict[str, float]] | None = None, *, seed: int = 0,
                       protocol: str = "diagnosis", sample_rate_hz: float = 500.0) -> Bundle:
    """A bundle of the independent rig with ``mechanisms`` switched on (name → parameters; missing parameters
    at their medium size), recorded back to back with bmr's protocols. The manifest keeps the mechanisms under
    ``"independent_plant"`` (not ``"simulator"``: no bmr simulator can rebuild this plant). At 1500 Hz the
    diagnosis protocol is 327 k samples."""
    rig = IndependentRig(mechanisms, seed=seed, sample_rate_hz=sample_rate_hz)
    runs = [fn(rig) for fn in _plan(protocol)]
    for r, (g, o) in zip(runs, rig.calibrations):
        if "recalibration" in rig.mechanisms:
            r.meta["calibration"] = {"gain": g, "offset_nmm": o}
    meta = {"independent_plant": {"seed": int(seed), "protocol": protocol, "mechanisms": rig.mechanisms}}
    return Bundle(actuator=rig.name, sample_rate_hz=rig.sample_rate_hz, runs=runs, meta=meta)
