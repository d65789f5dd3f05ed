"""Calibration figures of the bmr2013 virtual actuator against the paper's ranges, its throughput, and a PNG.

Usage: ``python benches/plant_calibration.py [--png /tmp/bmr2013_loops.png] [--seed 0]``

Everything plotted is "measured" data of the simulator: torque from the sensor, friction identified from the
off-state run by least squares (paper eq 21-22) and subtracted, like the paper's figs 12, 14 and 15.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import bmr
from bmr import plot
from bmr.simulation import experiments as ex

PAPER_TORQUE_NMM = 600.0
PAPER_FRICTION_BAND_NMM = (-20.0, 50.0)


def fit_friction(theta, torque, order=3):
    cols = [np.ones_like(theta)]
    for k in range(1, order + 1):
        cols += [np.sin(k * theta), np.cos(k * theta)]
    a = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(a, torque, rcond=None)

    def friction(th):
        th = np.asarray(th, dtype=float)
        out = np.full_like(th, coef[0])
        for k in range(1, order + 1):
            out += coef[2 * k - 1] * np.sin(k * th) + coef[2 * k] * np.cos(k * th)
        return out

    return friction


def body(run):
    return run.data[run.data.t_s >= run.meta["opening_end_s"]]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--png", default="/tmp/bmr2013_loops.png")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()

    # Throughput of the simulator from Python (GIL released, whole chain with noise).
    act = bmr.VirtualActuator("bmr2013", seed=args.seed)
    u = 1.25 * np.sin(np.arange(5_000_000) * 1e-4)
    t0 = time.perf_counter()
    act.run(u)
    rate = u.size / (time.perf_counter() - t0)

    t0 = time.perf_counter()
    bundle = ex.simulate_bundle("bmr2013", seed=args.seed)
    t_sim = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        bmr.write_bundle(bundle, Path(tmp) / "b")
        t_write = time.perf_counter() - t0
    rows = sum(len(r.data) for r in bundle.runs)

    off = body(bundle.run("off_state"))
    friction = fit_friction(off.theta_rad.to_numpy(), off.torque_nmm.to_numpy())
    grid = np.linspace(0, 2 * np.pi, 721)
    band = (friction(grid).min(), friction(grid).max())
    truth = bmr.VirtualActuator("bmr2013").true_friction(grid)

    def corrected(run):
        b = body(run)
        return b.current_a.to_numpy(), b.torque_nmm.to_numpy() - friction(b.theta_rad.to_numpy())

    ia, ta = corrected(bundle.run("first_order_ascending"))
    idn, tdn = corrected(bundle.run("first_order_descending"))
    # Torque at saturation: mean over the samples held at ±1.25 A on the first-order runs.
    t_pos = ta[ia == ia.max()].mean()
    t_neg = tdn[idn == idn.min()].mean()
    # Loop width: major descending (first curve of the ascending run goes +sat → −sat) vs major ascending.
    tri_i, tri_t = corrected(bundle.run("triangle"))
    n = len(tri_i)
    last = slice(n // 2, n)
    ci, ct = tri_i[last], tri_t[last]
    rising = np.r_[np.diff(ci) > 0, False]
    falling = np.r_[np.diff(ci) < 0, False]
    g = np.linspace(-1.0, 1.0, 81)

    def branch(mask):
        order = np.argsort(ci[mask])
        x, y = ci[mask][order], ct[mask][order]
        # Average the samples that share a current value (several cycles) before interpolating.
        xs, inv = np.unique(np.round(x, 6), return_inverse=True)
        ys = np.bincount(inv, weights=y) / np.bincount(inv)
        return np.interp(g, xs, ys)

    width = branch(falling) - branch(rising)

    print(f"simulator throughput: {rate / 1e6:.2f} M samples/s (Python, bmr2013, 5 M samples)")
    print(f"full bundle: {len(bundle)} runs, {rows} samples at {bundle.sample_rate_hz:g} Hz: simulated in "
          f"{t_sim:.2f} s, written (CSV) in {t_write:.2f} s")
    print(f"torque at +1.25 A: {t_pos:.0f} N·mm, at -1.25 A: {t_neg:.0f} N·mm (paper: about ±{PAPER_TORQUE_NMM:.0f})")
    print(f"off-state friction over a revolution (identified): {band[0]:.1f} … {band[1]:.1f} N·mm "
          f"(paper: about {PAPER_FRICTION_BAND_NMM[0]:.0f} … {PAPER_FRICTION_BAND_NMM[1]:.0f}); "
          f"identification error vs truth {np.max(np.abs(friction(grid) - truth)):.2f} N·mm")
    print(f"major-loop width (triangle, 0.125 A/s): max {width.max():.0f} N·mm at {g[np.argmax(width)]:+.2f} A, "
          f"{width.max() / (t_pos - t_neg) * 100:.0f} % of the range")

    with plot.style():
        _loops_figure(args, off, grid, friction, ia, ta, idn, tdn, bundle, corrected, ci, ct, width)


def _loops_figure(args, off, grid, friction, ia, ta, idn, tdn, bundle, corrected, ci, ct, width) -> None:
    fig, ax = plot.figure("panel3", nrows=2, ncols=2, height=8.0)
    a = ax[0, 0]
    a.plot(off.theta_rad, off.torque_nmm, ",", color="0.6", label="measured (off state)")
    a.plot(grid, friction(grid), "C3", label="identified friction (eq 21)")
    a.axhspan(*PAPER_FRICTION_BAND_NMM, color="C2", alpha=0.12, label="paper: about −20…50 N·mm")
    a.set(xlabel="rotor angle θ (rad)", ylabel="torque (N·mm)", title="Off-state friction (figs 11-12)")
    a.legend(loc="upper right")
    for a, (i, t, title) in zip((ax[0, 1], ax[1, 0]), ((ia, ta, "First-order ascending curves (fig 14)"),
                                                        (idn, tdn, "First-order descending curves (fig 15)"))):
        a.plot(i / 0.125, t, lw=0.6)
        a.axhline(PAPER_TORQUE_NMM, color="C2", ls="--", lw=0.8)
        a.axhline(-PAPER_TORQUE_NMM, color="C2", ls="--", lw=0.8, label="paper: about ±600 N·mm")
        a.set(xlabel="nominal current (units of 0.125 A)", ylabel="torque − friction (N·mm)", title=title)
        a.legend(loc="upper left")
    a = ax[1, 1]
    mp_i, mp_t = corrected(bundle.run("multipeak"))
    a.plot(mp_i / 0.125, mp_t, lw=0.3, color="0.5", label="random multi-peak (0.05-2.5 A/s)")
    a.plot(ci / 0.125, ct, lw=0.6, color="C0", label="triangle ±1.25 A, 0.125 A/s")
    a.axhline(PAPER_TORQUE_NMM, color="C2", ls="--", lw=0.8)
    a.axhline(-PAPER_TORQUE_NMM, color="C2", ls="--", lw=0.8)
    a.set(xlabel="nominal current (units of 0.125 A)", ylabel="torque − friction (N·mm)",
          title=f"Loops (max width {width.max():.0f} N·mm)")
    a.legend(loc="upper left")
    fig.suptitle(f"bmr2013 virtual actuator, seed {args.seed} (coil lag 8 ms, sensor noise 1.5 N·mm)")
    plot.save(fig, args.png)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
