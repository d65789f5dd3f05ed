"""Synthetic bundles for the identification tests: a known Preisach plant (``bmr.EverettModel``) plus known
angle-periodic friction and Gaussian torque noise, driven by the paper's protocols."""
from __future__ import annotations

import numpy as np
import pandas as pd

import bmr
from bmr.data.bundle import Bundle, Run

I_MAX_A = 1.25


def plant_everett(n_intervals: int = 24) -> bmr.EverettModel:
    """A smooth Preisach density (Gaussian ridge near the diagonal plus a reversible part), about ±500 N·mm."""
    g = np.linspace(-I_MAX_A, I_MAX_A, n_intervals + 1)
    c = 0.5 * (g[:-1] + g[1:])
    h = g[1] - g[0]
    masses = []
    for p in range(n_intervals):
        for q in range(p, n_intervals):
            beta, alpha = c[p], c[q]
            width = alpha - beta
            centre = 0.5 * (alpha + beta)
            dens = np.exp(-((width - 0.8) / 0.6) ** 2 - (centre / 0.7) ** 2)
            masses.append(dens * h * h * (0.5 if p == q else 1.0) + (40.0 * h if p == q else 0.0))
    masses = np.asarray(masses)
    m = bmr.EverettModel(g, masses, 0.0)
    span = m.everett(-I_MAX_A, I_MAX_A)
    return bmr.EverettModel(g, masses * (1000.0 / span), -500.0)


def ramp(points, samples_per_a: float = 400.0) -> np.ndarray:
    out = [np.array([points[0]], float)]
    for a, b in zip(points[:-1], points[1:]):
        n = max(2, int(abs(b - a) * samples_per_a))
        out.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(out)


def protocols() -> dict[str, tuple[str, np.ndarray]]:
    s = I_MAX_A
    opening = [0.0, s, -s]
    asc = opening + [s]
    for m in np.linspace(-0.9, 0.9, 10) * s:
        asc += [m, s]
    desc = [0.0, -s, s, -s]
    for big_m in np.linspace(0.9, -0.9, 10) * s:
        desc += [big_m, -s]
    tri = [0.0, s, -s] + [x for a in (0.8, 0.5, 0.9, 0.3) for x in (a * s, -a * s)] + [0.0]
    rng = np.random.default_rng(7)
    peaks = [0.0, s, -s]
    for k in range(14):
        peaks.append(float(rng.uniform(0.1, 0.95) * s * (1 if k % 2 == 0 else -1)))
    return {
        "first_order_ascending": ("first_order_ascending", ramp(asc)),
        "first_order_descending": ("first_order_descending", ramp(desc)),
        "triangle": ("triangle", ramp(tri)),
        "multipeak": ("multipeak", ramp(peaks)),
    }


FRICTION = (12.0, [6.0, 0.0, 1.5], [-3.0, 2.0, 0.0])


def friction_nmm(theta, c0=FRICTION[0], a=FRICTION[1], b=FRICTION[2]):
    y = np.full_like(theta, c0)
    for k, (ak, bk) in enumerate(zip(a, b), start=1):
        y += ak * np.sin(k * theta) + bk * np.cos(k * theta)
    return y


def synthetic_bundle(seed: int = 0, noise_nmm: float = 1.0, friction=FRICTION, plant=None) -> Bundle:
    rng = np.random.default_rng(seed)
    plant = plant or plant_everett()
    runs = []
    speed_rad_s = 2.0
    dt = 1e-3
    n_off = 40000
    theta = np.cumsum(np.full(n_off, speed_rad_s * dt))
    torque = friction_nmm(theta, *friction) + rng.normal(0, noise_nmm, n_off)
    runs.append(Run("off_state", "off_state", pd.DataFrame({
        "t_s": np.arange(n_off) * dt, "current_a": np.zeros(n_off), "theta_rad": theta, "torque_nmm": torque})))
    for name, (kind, u) in protocols().items():
        th = 0.37 + np.cumsum(np.full(u.size, speed_rad_s * dt))
        y = plant.simulate(u) + friction_nmm(th, *friction) + rng.normal(0, noise_nmm, u.size)
        runs.append(Run(name, kind, pd.DataFrame({
            "t_s": np.arange(u.size) * dt, "current_a": u, "theta_rad": th, "torque_nmm": y})))
    return Bundle("synthetic Preisach plant", 1.0 / dt, runs)
