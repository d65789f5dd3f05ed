//! The candidate library for learning what no named effect explains: signals built from one run, against which
//! a diagnosis regresses the residual sparsely (sequentially thresholded least squares, as in SINDy). Each
//! candidate has a name, a unit template (`{u}` the input unit, `{y}` the output unit) and a definition; the
//! per-sample loops (reversal times, running integrals) run here.
//!
//! Reversals are the dead-band extrema of the input ([`crate::reversals::ReversalFinder`]); the time since the
//! last reversal is counted from the extremum (known once the dead-band confirms it, back-filled here) and from
//! the run's start before the first one. Running integrals start at zero at the run's start.

use crate::reversals::ReversalFinder;
use alloc::vec;
use alloc::vec::Vec;

/// One candidate signal of the library.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    pub name: &'static str,
    /// Unit template: `{u}` input unit, `{y}` output unit, `s` seconds, `1` dimensionless.
    pub unit: &'static str,
    pub doc: &'static str,
}

const fn c(name: &'static str, unit: &'static str, doc: &'static str) -> Candidate {
    Candidate { name, unit, doc }
}

/// The run signals of the library, in column order (angle harmonics follow when the run has an angle).
pub static CANDIDATES: &[Candidate] = &[
    c("u", "{u}", "input"),
    c("|u|", "{u}", "input magnitude"),
    c("u^2", "{u}^2", "input squared"),
    c("du/dt", "{u}/s", "input rate (central difference)"),
    c("y", "{y}", "model output"),
    c("t", "s", "time since the run's start"),
    c("t_rev", "s", "time since the last input reversal"),
    c(
        "ln(1+t_rev/dt)",
        "1",
        "logarithm of the time since the last reversal in sample periods",
    ),
    c(
        "dir",
        "1",
        "direction of the current branch (+1 rising input, -1 falling)",
    ),
    c(
        "dir*ln(1+t_rev/dt)",
        "1",
        "direction times the logarithm of the time since the last reversal",
    ),
    c(
        "dy_rev*ln(1+t_rev/dt)",
        "{y}",
        "model-output change since the last reversal times the logarithm of the time since it",
    ),
    c("int(u dt)", "{u}*s", "running integral of the input"),
    c(
        "int(u^2 dt)",
        "{u}^2*s",
        "running integral of the squared input",
    ),
    c(
        "y*t",
        "{y}*s",
        "model output times the time since the run's start",
    ),
    c(
        "y*int(u^2 dt)",
        "{y}*{u}^2*s",
        "model output times the running integral of the squared input",
    ),
];

/// Number of columns of a library with `harmonics` angle harmonics (0 without an angle): each harmonic `k` adds
/// `sin(k·θ)` and `cos(k·θ)`.
pub fn library_width(harmonics: usize) -> usize {
    CANDIDATES.len() + 2 * harmonics
}

/// The library of one run, row-major `n × library_width(harmonics)`: time `t_s` (increasing), input `u`, model
/// output `y`, optional angle `theta_rad` (with `harmonics` > 0), input dead-band `deadband` (> 0). `None` when
/// the lengths differ, the dead-band is invalid or a time step is not positive.
pub fn candidate_library(
    t_s: &[f64],
    u: &[f64],
    y: &[f64],
    theta_rad: Option<&[f64]>,
    harmonics: usize,
    deadband: f64,
) -> Option<Vec<f64>> {
    let n = u.len();
    if t_s.len() != n || y.len() != n || theta_rad.is_some_and(|th| th.len() != n) {
        return None;
    }
    if !t_s.windows(2).all(|w| w[1] > w[0]) {
        return None;
    }
    let harmonics = if theta_rad.is_some() { harmonics } else { 0 };
    let width = library_width(harmonics);
    let mut out = vec![0.0; n * width];
    if n == 0 {
        return Some(out);
    }
    // Reversal extrema (back-filled): last_rev[i] = index of the latest reversal at or before i.
    let mut finder = ReversalFinder::new(deadband)?;
    let mut rev_at = vec![usize::MAX; n];
    for &x in u {
        if let Some(r) = finder.push(x) {
            rev_at[r.index] = r.index;
        }
    }
    let dt_med = {
        let mut d: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            1.0
        } else {
            let mid = d.len() / 2;
            d.select_nth_unstable_by(mid, f64::total_cmp);
            d[mid]
        }
    };
    let mut last_rev: Option<usize> = None;
    let mut int_u = 0.0;
    let mut int_u2 = 0.0;
    let mut dir = 0.0;
    for i in 0..n {
        if rev_at[i] != usize::MAX {
            last_rev = Some(i);
        }
        if i > 0 {
            let h = t_s[i] - t_s[i - 1];
            // Trapezoids: exact for the piecewise-linear input between samples.
            int_u += 0.5 * h * (u[i] + u[i - 1]);
            int_u2 += 0.5 * h * (u[i] * u[i] + u[i - 1] * u[i - 1]);
        }
        let rate = if n == 1 {
            0.0
        } else if i == 0 {
            (u[1] - u[0]) / (t_s[1] - t_s[0])
        } else if i == n - 1 {
            (u[i] - u[i - 1]) / (t_s[i] - t_s[i - 1])
        } else {
            (u[i + 1] - u[i - 1]) / (t_s[i + 1] - t_s[i - 1])
        };
        if rate > 0.0 {
            dir = 1.0;
        } else if rate < 0.0 {
            dir = -1.0;
        }
        let (t_rev, y_rev) = match last_rev {
            Some(k) => (t_s[i] - t_s[k], y[k]),
            None => (t_s[i] - t_s[0], y[0]),
        };
        let ln_t = libm::log1p(t_rev / dt_med);
        let t = t_s[i] - t_s[0];
        let row = &mut out[i * width..(i + 1) * width];
        row[0] = u[i];
        row[1] = libm::fabs(u[i]);
        row[2] = u[i] * u[i];
        row[3] = rate;
        row[4] = y[i];
        row[5] = t;
        row[6] = t_rev;
        row[7] = ln_t;
        row[8] = dir;
        row[9] = dir * ln_t;
        row[10] = (y[i] - y_rev) * ln_t;
        row[11] = int_u;
        row[12] = int_u2;
        row[13] = y[i] * t;
        row[14] = y[i] * int_u2;
        if let Some(th) = theta_rad {
            for k in 1..=harmonics {
                let (s, co) = (libm::sin(k as f64 * th[i]), libm::cos(k as f64 * th[i]));
                row[CANDIDATES.len() + 2 * (k - 1)] = s;
                row[CANDIDATES.len() + 2 * (k - 1) + 1] = co;
            }
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_follow_their_definitions() {
        let n = 401;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        // Up to 1 at t = 1 s, down to -1 at t = 3 s, then up.
        let u: Vec<f64> = t
            .iter()
            .map(|&t| {
                if t <= 1.0 {
                    t
                } else if t <= 3.0 {
                    2.0 - t
                } else {
                    t - 4.0
                }
            })
            .collect();
        let y: Vec<f64> = u.iter().map(|x| 2.0 * x).collect();
        let th: Vec<f64> = t.iter().map(|t| 0.5 * t).collect();
        let w = library_width(2);
        let lib = candidate_library(&t, &u, &y, Some(&th), 2, 0.05).unwrap();
        let at = |i: usize, j: usize| lib[i * w + j];
        // Sample 150 (t = 1.5 s): falling since the maximum at t = 1 s.
        assert!((at(150, 6) - 0.5).abs() < 1e-12);
        assert_eq!(at(150, 8), -1.0);
        assert!((at(150, 7) - libm::log1p(50.0)).abs() < 1e-12);
        assert!((at(150, 10) - (y[150] - 2.0) * libm::log1p(50.0)).abs() < 1e-12);
        // Sample 50: before any reversal, time since the start.
        assert!((at(50, 6) - 0.5).abs() < 1e-12);
        // Integral of u up to t = 2 s: 1/2 + 1/2 = 1 (two triangles of area 0.5).
        assert!((at(200, 11) - 1.0).abs() < 1e-9);
        assert!((at(100, 12) - 1.0 / 3.0).abs() < 1e-4);
        assert!((at(100, 3) - 1.0).abs() < 1e-9 || (at(100, 3)).abs() < 1e-9);
        assert!((at(300, CANDIDATES.len() + 1) - libm::cos(1.5)).abs() < 1e-12);
        assert!(candidate_library(&t, &u[..3], &y, None, 0, 0.05).is_none());
        assert!(candidate_library(&t, &u, &y, None, 0, 0.0).is_none());
        assert_eq!(
            candidate_library(&t, &u, &y, None, 5, 0.05).unwrap().len(),
            n * CANDIDATES.len()
        );
    }
}
