"""Per-step cost of bmr from Python next to the peers a user would otherwise reach for, measured in one process.

    python benches/python_peers.py            (needs: pip install -e ".[bench]")

Peers: python-control's `friction_backlash_nonlinearity` (one play operator), a 20-operator Prandtl-Ishlinskii
sum built from it, and a numpy discrete Preisach model with ~5000 hysterons. bmr: `Hysteresis.step`,
`Compensator.step` (exact and paper inverse), `Controller.step` around the exact and the extended compensator, and
`Compensator.run` throughput. Ratios are peer / bmr.
"""
from __future__ import annotations

import argparse
import json
import re
import time

import numpy as np

import bmr


def per_call_us(fn, args_seq, repeat: int = 5) -> tuple[float, float]:
    """Mean wall and CPU time per call (µs) over the argument sequence, of the repeat with the least wall time."""
    best = (float("inf"), float("inf"))
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        for a in args_seq:
            fn(*a)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        best = min(best, (wall / len(args_seq), cpu / len(args_seq)))
    return best[0] * 1e6, best[1] * 1e6


def multipeak(n: int, seed: int = 0, amp: float = 280.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    knots = rng.uniform(-amp, amp, n // 500 + 2)
    x = np.linspace(0, len(knots) - 1, n)
    return np.interp(x, np.arange(len(knots)), knots)


class NumpyPreisach:
    """Discrete Preisach model: relays on a triangular threshold grid, vectorised numpy update."""

    def __init__(self, per_axis: int = 100):
        t = np.linspace(-1, 1, per_axis)
        a, b = np.meshgrid(t, t, indexing="ij")
        keep = b <= a
        self.alpha, self.beta = a[keep], b[keep]
        self.w = np.exp(-(((self.alpha - self.beta) / 2 - 0.25) / 0.2) ** 2) / keep.sum()
        self.s = -np.ones_like(self.alpha)

    def first_order_curves(self, count: int) -> tuple[list, list]:
        """The model's own first-order curves (``count`` per family, reversals on relay thresholds, sampled on the
        thresholds): the tables bmr is built from, so both sides model the same hysteresis."""
        t = np.unique(self.alpha)
        picks = np.linspace(0, t.size - 1, count).round().astype(int)[:-1]
        asc, desc = [], []
        for k in picks:
            self.s[:] = 1.0
            self.step(float(t[k]))
            u = t[k:]
            asc.append((u, np.array([self.step(float(x)) for x in u])))
            m = t.size - 1 - k
            self.s[:] = -1.0
            self.step(float(t[m]))
            u = t[: m + 1][::-1]
            desc.append((u, np.array([self.step(float(x)) for x in u])))
        self.s[:] = -1.0
        return asc, desc

    def step(self, u: float) -> float:
        self.s[self.alpha <= u] = 1.0
        self.s[self.beta >= u] = -1.0
        return float(self.w @ self.s)


EVERY_STAGE = [
    {"name": "time_delay", "params": {"delay_s": 0.01}},
    {"name": "coil_lag", "params": {"tau_s": 0.02}},
    {"name": "non_congruent", "params": {"curvature": 1.5}},
    {"name": "thermal_drift", "params": {"gain_loss": 0.1, "tau_s": 60.0}},
    {"name": "torque_ripple", "params": {"eps": 0.05, "phase_rad": 0.4}},
    {"name": "friction_harmonics", "params": {"order": 6.0, "amplitude_nmm": 5.0}},
    {"name": "friction_current", "params": {"gain_per_a": 0.5}},
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--json", action="store_true", help="also print the figures as one JSON line (last line)")
    args = ap.parse_args()
    n = args.steps
    asc, desc = NumpyPreisach(100).first_order_curves(21)
    scale = lambda fam: [(1.25 * u, 600.0 * y) for u, y in fam]  # noqa: E731  (about ±300 N·mm)
    h = bmr.Hysteresis.from_curves(scale(asc), scale(desc))
    f = bmr.Friction.from_amplitude_phase(12.0, [25.0, 8.0, 4.0], [0.3, 1.1, -0.7])
    ref = multipeak(n)
    theta = np.linspace(0, 0.002 * n, n)
    cur = ref / 240.0
    ref_l, th_l, cur_l = ref.tolist(), theta.tolist(), cur.tolist()

    results: dict[str, float] = {}
    results["bmr Hysteresis.step"] = per_call_us(h.step, [(u,) for u in cur_l])
    for inv in ("exact", "paper"):
        c = bmr.Compensator(h, f, inverse=inv)
        results[f"bmr Compensator.step ({inv})"] = per_call_us(c.step, list(zip(ref_l, th_l)))
    c = bmr.Compensator(h, f)
    buf = np.empty(7)
    results["bmr Compensator.step_into (exact)"] = per_call_us(c.step_into, [(r, t, buf) for r, t in zip(ref_l, th_l)])
    # The extended compensator with every stage (a 1 kHz loop's stages, as the diagnosis finds them).
    ext = bmr.Compensator(h, f, extensions=EVERY_STAGE, dt_s=0.001, full_torque_nmm=300.0)
    results["bmr Compensator.step (extended, every stage)"] = per_call_us(ext.step, list(zip(ref_l, th_l)))
    # The closed loop around them: the measurement is the model's torque (the loop is stepped, not simulated).
    meas_l = (0.95 * ref + 2.0).tolist()
    for label, comp in (("exact", bmr.Compensator(h, f)), ("extended, every stage", ext)):
        ctl = bmr.Controller(comp, dt_s=0.001)
        results[f"bmr Controller.step ({label})"] = per_call_us(ctl.step, list(zip(ref_l, th_l, meas_l)))
    big_ref, big_th = multipeak(2_000_000, 1), np.linspace(0, 4000, 2_000_000)
    rates = {}
    for label, comp, kw in (("Compensator.run()", c, {}),
                            ("Compensator.run(columns=['current_a'], out=...)", c,
                             {"columns": ["current_a"], "out": {"current_a": np.empty(big_ref.size)}}),
                            ("Compensator.run() (extended, current only)", ext,
                             {"columns": ["current_a"], "out": {"current_a": np.empty(big_ref.size)}})):
        best = (float("inf"), float("inf"))
        for _ in range(3):
            comp.reset()
            c0, t0 = time.process_time(), time.perf_counter()
            comp.run(big_ref, big_th, **kw)
            best = min(best, (time.perf_counter() - t0, time.process_time() - c0))
        rates[label] = (big_ref.size / best[0], big_ref.size / max(best[1], 1e-9))
    h2 = bmr.Hysteresis.from_curves(scale(asc), scale(desc))
    big_cur = big_ref / 240.0
    best = (float("inf"), float("inf"))
    for _ in range(3):
        h2.reset()
        c0, t0 = time.process_time(), time.perf_counter()
        h2.run(big_cur)
        best = min(best, (time.perf_counter() - t0, time.process_time() - c0))
    rates["Hysteresis.run()"] = (big_cur.size / best[0], big_cur.size / max(best[1], 1e-9))

    peers: dict[str, float] = {}
    try:
        import control as ct

        play = ct.friction_backlash_nonlinearity(0.05)
        peers["python-control play operator"] = per_call_us(play, [(u,) for u in cur_l])
        plays = [ct.friction_backlash_nonlinearity(r) for r in np.linspace(0.0, 1.0, 20)]
        weights = np.linspace(1.0, 0.1, 20).tolist()

        def pi_sum(u):
            return sum(w * p(u) for w, p in zip(weights, plays))

        peers["python-control 20-operator Prandtl-Ishlinskii"] = per_call_us(pi_sum, [(u,) for u in cur_l])
    except ImportError:
        print("python-control not installed (pip install control): its peers are skipped")
    pre = NumpyPreisach(100)
    peers[f"numpy discrete Preisach ({pre.alpha.size} hysterons)"] = per_call_us(pre.step, [(u,) for u in cur_l[:5000]])

    ref_step = results["bmr Compensator.step (exact)"][0]
    print(f"per-call cost from Python ({n} calls, best of 5; wall, CPU):")
    for name, (us, cpu) in results.items():
        print(f"  {name:52s} {us:8.3f} µs  {cpu:8.3f} µs CPU")
    for name, (us, _) in peers.items():
        print(f"  {name:52s} {us:8.3f} µs   = {us / ref_step:6.1f} × bmr Compensator.step (exact)")
    for label, (rate, cpu_rate) in rates.items():
        print(f"  {'bmr ' + label:52s} {rate / 1e6:8.1f} M samples/s  {cpu_rate / 1e6:8.1f} per CPU-s")
    if args.json:
        def short(name: str) -> str:
            return re.sub(r"\.(\w+)", r".\1()", name.replace("bmr ", ""), count=1)

        print(json.dumps({
            "per_call_us": {short(name): us for name, (us, _) in results.items()},
            "per_call_cpu_us": {short(name): cpu for name, (_, cpu) in results.items()},
            "ratio_to_compensator_step": {name: us / ref_step for name, (us, _) in peers.items()},
            "throughput_msps": {k: v / 1e6 for k, (v, _) in rates.items()},
            "throughput_cpu_msps": {k: c / 1e6 for k, (_, c) in rates.items()},
        }))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
