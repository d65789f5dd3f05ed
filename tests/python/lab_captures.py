"""Captures shaped like those real rigs write, from hysteresis plants written independently of bmr:

- a dSPACE ControlDesk piezo rig (drive voltage → displacement-sensor voltage, both in V, 10 kHz): channels named
  ``"Model Root"/"P\\x1adrag"/"In1"`` (quoted path segments, a control byte where a block label held a line break);
  every recording starts with a 1 s hold at the negative drive limit and ends with the drive jumping back to 0 V
  on its last sample while the stack lags; each recording's sensor offset differs (about 0.14 V);
- an aixACCT analyzer's first-order reversal curves of a ferroelectric capacitor measured in one go, whose
  polarization integrates a leakage current through the sample (a drift of tens of % of the span over the file),
  and a repeat measurement of the same protocol with its own integration;
- a Princeton MicroMag VSM's FORC file and hysteresis-loop export of one magnetic sample of interacting particles
  (a Preisach density with a negative region below its coercivity peak), in cgs, with the instrument's moment gain
  drifting slowly over each measurement."""
from __future__ import annotations

from pathlib import Path

import numpy as np

import independent_preisach as ip
from lab_files import (Piezo, write_aixacct, write_controldesk, write_micromag_forc_measurement,
                       write_micromag_hysteresis)

# ------------------------------------------------------------------------------------------ ControlDesk piezo rig
RIG_HZ = 10_000.0
DRIVE_LO, DRIVE_HI = -2.0, 8.0  # amplifier input (V); the stack sees 10 V per V above DRIVE_LO
SENSOR_V_PER_UM = 0.25
DRIVE_CHANNEL = '"Model Root"/"P\x1adrag"/"In1"'
SENSOR_CHANNEL = '"Model Root"/"M\x1aling"/"In1"'


def _stack_volts(drive: np.ndarray) -> np.ndarray:
    return 10.0 * (np.asarray(drive) - DRIVE_LO)


def tracking_drive(kind: str, freq_hz: float, top: float, rng: np.random.Generator) -> np.ndarray:
    """2 s of a sine, triangle or PRBS between the negative drive limit and ``top`` (V), starting at the limit."""
    t = np.arange(int(2.0 * RIG_HZ)) / RIG_HZ
    phase = (freq_hz * t) % 1.0
    if kind == "sine":
        shape = 0.5 - 0.5 * np.cos(2 * np.pi * phase)
    elif kind == "triangle":
        shape = 1.0 - np.abs(2.0 * phase - 1.0)
    else:  # a pseudo-random binary sequence clocked at freq_hz, its edges smoothed by the amplifier (0.5 ms)
        bits = rng.integers(0, 2, int(2.0 * freq_hz) + 1).astype(float)
        bits[0] = 0.0
        raw = bits[np.minimum((t * freq_hz).astype(int), bits.size - 1)]
        a = np.exp(-1.0 / (0.5e-3 * RIG_HZ))
        shape = np.empty_like(raw)
        s = 0.0
        for k, x in enumerate(raw):
            s = a * s + (1 - a) * x
            shape[k] = s
    return DRIVE_LO + (top - DRIVE_LO) * shape


def identification_drive() -> np.ndarray:
    """Sweeps to growing maxima and back to the limit, then from the top down to growing depths and back up, at
    1000 V/s of drive (the tracking runs' rates)."""
    points = [DRIVE_LO]
    for m in np.linspace(DRIVE_LO + 1.0, DRIVE_HI, 10):
        points += [float(m), DRIVE_LO]
    points.append(DRIVE_HI)
    for m in np.linspace(DRIVE_HI - 1.0, DRIVE_LO, 10):
        points += [float(m), DRIVE_HI]
    points.append(DRIVE_LO)
    step = 1000.0 / RIG_HZ
    out = [np.array([points[0]])]
    for a, b in zip(points[:-1], points[1:]):
        out.append(np.linspace(a, b, max(2, int(abs(b - a) / step)) + 1)[1:])
    return np.concatenate(out)


def write_piezo_captures(folder: Path, seed: int = 0) -> tuple[Path, list[Path]]:
    """One identification capture and 18 tracking captures (sine, triangle, PRBS at 50-100 Hz) of one stack."""
    rng = np.random.default_rng(seed)
    stack = Piezo(n=60, noise_um=0.005, lag=1.0, seed=seed)
    hold = np.full(int(1.0 * RIG_HZ), DRIVE_LO)

    def capture(name: str, excitation: np.ndarray) -> Path:
        drive = np.concatenate([hold, excitation, [0.0]])  # the drive returns to 0 V on the last sample
        microns = stack.run(_stack_volts(drive))
        offset = 0.6 + 0.14 * rng.standard_normal()
        sensor = SENSOR_V_PER_UM * microns + offset + 0.002 * rng.standard_normal(drive.size)
        t = np.arange(drive.size) / RIG_HZ
        return write_controldesk(folder / f"{name}.mat", name.replace("-", "_"), [t], [
            (DRIVE_CHANNEL, '"Model Root"/"P\x1adrag"', drive, "V", 1),
            (SENSOR_CHANNEL, '"Model Root"/"M\x1aling"', sensor, "V", 1)])

    ident = capture("ident", identification_drive())
    tracking = []
    for k, (kind, f) in enumerate((kind, f) for kind in ("sine", "triangle", "prbs")
                                  for f in (50.0, 60.0, 70.0, 80.0, 90.0, 100.0)):
        top = (DRIVE_HI, 5.0, 2.0)[k % 3]
        tracking.append(capture(f"track_{kind}_{int(f)}", tracking_drive(kind, f, top, rng)))
    return ident, tracking


# ------------------------------------------------------------------------------------------ aixACCT FORCs, leaky
FE_HZ = 2000.0
FE_VOLTS = 8.0  # drive volts per plant input unit: the plant's [-1.25, 1.25] is ±10 V
FE_LEAK = 0.2  # µC/cm² per V·s: the leakage conductance seen as charge per unit drive-time


def _fe_table(plant: ip.Plant, vertices: list[float], rng: np.random.Generator) -> tuple[dict[str, str], list[str],
                                                                                         np.ndarray]:
    plant.reset()
    t, u = ip.ramps(vertices, 2.5, FE_HZ)
    p = plant.drive(u, 1.0 / FE_HZ)
    v = FE_VOLTS * u
    leak = FE_LEAK * np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    pol = p + leak + rng.normal(0.0, 0.05, u.size)
    return ({"Hysteresis Frequency [Hz]": "1", "Amplitude [V]": "10"}, ["Time s", "Vplus V", "P1 uC_per_cm2"],
            np.column_stack([t, v, pol]))


def write_leaky_forcs(folder: Path, seed: int = 0) -> tuple[Path, Path]:
    """The ascending first-order curves measured in one go (one table, one charge integration) and a repeat
    measurement (the same protocol with other reversal fields) in a second file."""
    rng = np.random.default_rng(seed)
    plant = ip.Plant(coercivity=0.45, coercivity_width=0.12, interaction_width=0.15, reversible=0.15, scale=50.0)
    forc = write_aixacct(folder / "forc.dat", [_fe_table(plant, ip.forc_vertices("ascending", 16), rng)])
    repeat = write_aixacct(folder / "repeat.dat", [_fe_table(plant, ip.forc_vertices("ascending", 11), rng)])
    return forc, repeat


# ------------------------------------------------------------------------------------------ MicroMag FORCs and loop
OE_PER_UNIT = 8000.0  # the plant's input unit in Oe: its range ±1.25 is ±10 kOe
MS_EMU = 1.28e-3  # saturation moment (emu)
H_SAT, H_CAL = 10_000.0, 6_800.0  # saturating field and the calibration field (Oe)
HR_TOP, HR_BOTTOM, H_STEP = 1_600.0, -6_400.0, 80.0  # reversal fields and the field step (Oe)
HC2, CURVE_TOP = 6_000.0, 6_400.0  # a curve ends at Hc = HC2 or at CURVE_TOP, whichever comes first (Oe)
MOMENT_NOISE = 1e-4 * MS_EMU  # emu
FIELD_NOISE = 0.05  # Oe, the Hall probe's reading
AVERAGING_S, PAUSE_S, SLEW_OE_PER_S = 0.2, 1.0, 10_000.0


def interacting_density(hc: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Switching fields spread about a 3.2 kOe coercivity, and the interactions' negative region below and left of
    the peak (smaller coercivity, negative interaction field; 3.5 % of the positive mass); in plant units."""
    peak = np.exp(-((hc - 0.4) / 0.09) ** 2) * np.exp(-((hi / 0.10) ** 2))
    negative = -0.05 * np.exp(-((hc - 0.2) / 0.1) ** 2) * np.exp(-(((hi + 0.15) / 0.08) ** 2))
    return peak + negative


def magnetic_sample() -> ip.Plant:
    """The sample: an independent Preisach plant with the interacting density and a reversible part, moment ±1."""
    return ip.Plant(density=interacting_density, reversible=0.3, scale=2.0)


class _Vsm:
    """The magnetometer's moment reading: the sample's moment × ``MS_EMU`` × a gain drifting with time (a thermal
    settling, ``gain(t) = g0 + dg·(1 - exp(-t/tau))``), plus white noise; the field read with its own noise."""

    def __init__(self, sample: ip.Plant, rng: np.random.Generator, g0: float, dg: float, tau_s: float):
        self.sample, self.rng, self.g0, self.dg, self.tau_s = sample, rng, g0, dg, tau_s
        self.t = 0.0

    def gain(self, t: np.ndarray | float) -> np.ndarray | float:
        return self.g0 + self.dg * (1.0 - np.exp(-np.asarray(t) / self.tau_s))

    def sweep_to(self, h_oe: float) -> None:
        """Move the field without measuring (slew and pause)."""
        self.t += abs(h_oe - self.sample.x * OE_PER_UNIT) / SLEW_OE_PER_S + PAUSE_S
        self.sample.drive(np.array([h_oe / OE_PER_UNIT]), 1.0)

    def measure(self, h_oe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = self.sample.drive(np.asarray(h_oe, float) / OE_PER_UNIT, 1.0)
        t = self.t + AVERAGING_S * (1 + np.arange(np.size(h_oe)))
        self.t = float(t[-1])
        moment = MS_EMU * m * self.gain(t) + self.rng.normal(0.0, MOMENT_NOISE, np.size(h_oe))
        return np.asarray(h_oe, float) + self.rng.normal(0.0, FIELD_NOISE, np.size(h_oe)), moment


def forc_fields() -> list[np.ndarray]:
    """Each curve's fields: from its reversal field up in ``H_STEP`` steps to Hc = HC2 or ``CURVE_TOP``."""
    out = []
    for hr in np.arange(HR_TOP, HR_BOTTOM - 0.5 * H_STEP, -H_STEP):
        top = min(hr + 2.0 * HC2, CURVE_TOP)
        out.append(hr + H_STEP * np.arange(int(round((top - hr) / H_STEP)) + 1))
    return out


def write_micromag_sample(folder: Path, seed: int = 0, drift: float = -0.0025,
                          loop_drift: tuple[float, float] = (1.0015, -0.0012)) -> tuple[Path, Path]:
    """The sample's FORC measurement (``sample.frc``: after each saturation at ``H_SAT``, the calibration point
    at ``H_CAL``, then the curve) and, later, its hysteresis loop (``sample.hys``: from ``H_SAT`` down to
    ``-H_SAT`` and back, ``H_STEP`` apart). ``drift``: the gain change over the FORC measurement (a settling with a
    time constant of half of it); ``loop_drift``: the loop's own gain at its start and its change over the loop."""
    rng = np.random.default_rng(seed)
    fields = forc_fields()
    points = sum(f.size + 1 for f in fields)
    duration = points * AVERAGING_S + len(fields) * (3 * PAUSE_S + 2 * (H_SAT - HR_BOTTOM) / SLEW_OE_PER_S)
    sample = magnetic_sample()
    vsm = _Vsm(sample, rng, 1.0, drift / (1.0 - np.exp(-2.0)), 0.5 * duration)
    curves, calibration = [], []
    for h in fields:
        vsm.sweep_to(H_SAT)
        vsm.sweep_to(H_CAL)
        hc, mc = vsm.measure(np.array([H_CAL]))
        calibration.append((float(hc[0]) + 3.8, float(mc[0])))  # the Hall probe reads the set field 3.8 Oe high
        vsm.sweep_to(float(h[0]))
        curves.append(vsm.measure(h))
    settings = [("Averaging time", AVERAGING_S), ("Hb1", -3000.0), ("Hb2", 3000.0), ("Hc1", 0.0), ("Hc2", HC2),
                ("HCal", H_CAL), ("HNcr", H_STEP), ("HSat", H_SAT), ("PauseCal", PAUSE_S), ("PauseNtl", PAUSE_S),
                ("PauseSat", PAUSE_S), ("SlewRate", SLEW_OE_PER_S), ("Smoothing", 3.0)]
    forc = write_micromag_forc_measurement(folder / "sample.frc", curves, calibration, settings)
    down = np.arange(H_SAT, -H_SAT - 0.5 * H_STEP, -H_STEP)
    loop_time = 2 * down.size * AVERAGING_S
    loop = _Vsm(sample, rng, loop_drift[0], loop_drift[1] / (1.0 - np.exp(-2.0)), 0.5 * loop_time)
    loop.sweep_to(H_SAT)
    branches = [loop.measure(down), loop.measure(down[::-1])]
    hys = write_micromag_hysteresis(folder / "sample.hys", branches, [
        ("Averaging time", AVERAGING_S), ("Field increment", H_STEP), ("Field range", H_SAT),
        ("PauseSat", PAUSE_S), ("SlewRate", SLEW_OE_PER_S)])
    return forc, hys
