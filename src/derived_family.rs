//! One family of first-order curves plus the opposite major branch determines the other family (congruency).
//!
//! In a Preisach system both families are slices of one Everett function `E(β, α)` (the output rise from a
//! reversal minimum `β` up to `α`): the measured family's row `j` is `E(r_j, ·)`, dense along `α` but known only at
//! the measured reversals `r_j` along `β`. The other family needs `E(β, M)` at every `β` for its reversals `M`.
//!
//! Between two measured reversals (a *strip* `r_j ≤ β < r_{j+1}`) the mass of the density above the strip is a
//! rectangle `R_j(α) = E_j(α) − E_{j+1}(α) − T_j` (`T_j = E_j(r_{j+1})`, the strip's own triangle). The share of it
//! with `β ≥ m` is written `f(m) R_j(α)`: a uniform density across the strip (the operator's own off-grid rule,
//! [`crate::everett`]) has `f = 1 − λ`. The opposite major branch is the slice `α = hi` measured at *every* `β`, so
//! it gives `f(m)` itself: `f(m) = (E(m, hi) − E_{j+1}(hi) − Tri(m)) / R_j(hi)`, corrected to be exactly 1 and 0 at
//! the strip ends (so measured curves are reproduced), clamped to `[0, 1]` and nonincreasing. Then
//! `E(m, α) = E_{j+1}(α) + Tri(m) + f(m) R_j(α)` for `α ≥ r_{j+1}`, and the strip's triangle model below it. This is
//! exact for a density that is separable inside each strip (any shape across the strip, any along it), exact at
//! measured reversals, and reproduces the measured opposite major branch.
//!
//! Everything is in rising orientation: the measured family `A` in its own (`v`), the derived family `B` in its own
//! (`w = −v`): `B_k(w) = E_A(m = −w, α = −w_k)`.
use alloc::vec::Vec;

use crate::everett::{Family, Strip};

/// Where the opposite major branch used for a derivation came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MajorSource {
    /// Measured as a curve of the derived family.
    Measured,
    /// Traced by the reversal points of the measured curves (each starts on it): exact there, linear between.
    ReversalPoints,
}

/// A derived family on its grid, in rising orientation (ready for [`Family::new`] after node selection).
#[derive(Debug, Clone, PartialEq)]
pub struct DerivedFamily {
    pub grid: Vec<f64>,
    pub reversals: Vec<f64>,
    /// One row per reversal, at every grid node.
    pub rows: Vec<Vec<f64>>,
    /// Largest correction that kept a derived row nondecreasing (output units; zero for Preisach data).
    pub adjusted: f64,
}

/// Linear interpolation of `(x, e)` (x increasing) at `at`, held flat outside.
fn interp(x: &[f64], e: &[f64], at: f64) -> f64 {
    let n = x.len();
    if at <= x[0] {
        return e[0];
    }
    if at >= x[n - 1] {
        return e[n - 1];
    }
    let k = x.partition_point(|&v| v <= at) - 1;
    let t = (at - x[k]) / (x[k + 1] - x[k]);
    e[k] + t * (e[k + 1] - e[k])
}

/// A slice `α = alpha` of the Everett function known densely along `β`: the opposite major branch (`α = hi`) or
/// a measured curve of the opposite family (`α = M_k`).
enum Slice<'a> {
    /// The opposite major branch in the opposite family's rising orientation (`w = -β`, increments from 0).
    Major { w: &'a [f64], e: &'a [f64] },
    /// A curve of the opposite family (its table and the strip of its reversal `-M_k`).
    Row {
        fam: &'a Family<Vec<f64>>,
        strip: Strip,
    },
}

impl Slice<'_> {
    /// `E(m, alpha)` on this slice.
    fn e_at(&self, m: f64, hint: &mut usize) -> f64 {
        match self {
            Slice::Major { w, e } => interp(w, e, -m),
            Slice::Row { fam, strip } => fam.everett(strip, -m, hint),
        }
    }
}

/// The measured family `a` with its strip shapes calibrated on slices of the opposite family.
struct Shape<'a> {
    a: &'a Family<Vec<f64>>,
    /// Slices by increasing `alpha` (the last at `a.hi()`).
    slices: Vec<(f64, Slice<'a>)>,
}

/// Where a reversal minimum `m` sits: its strip `j`, the strip triangle `Tri(m)`, the uniform share `1 − λ`, and
/// the shape `f(m)` on every slice above the strip (`(alpha, f)`, increasing alpha).
#[derive(Clone)]
struct At {
    j: usize,
    tri: f64,
    uniform: f64,
    f: Vec<(f64, f64)>,
}

impl<'a> Shape<'a> {
    /// Calibrated on the opposite major branch only (`major_w`, `major_e` as in [`derive_family`]).
    fn on_major(a: &'a Family<Vec<f64>>, major_w: &'a [f64], major_e: &'a [f64]) -> Self {
        Shape {
            a,
            slices: alloc::vec![(
                a.hi(),
                Slice::Major {
                    w: major_w,
                    e: major_e
                }
            )],
        }
    }

    /// Calibrated on every curve of the measured opposite family `b` (rising orientation).
    fn on_family(a: &'a Family<Vec<f64>>, b: &'a Family<Vec<f64>>) -> Self {
        let mut slices: Vec<(f64, Slice<'a>)> = b
            .reversals()
            .iter()
            .map(|&v| {
                (
                    (-v).min(a.hi()),
                    Slice::Row {
                        fam: b,
                        strip: b.strip(v),
                    },
                )
            })
            .collect();
        slices.sort_by(|x, y| x.0.total_cmp(&y.0));
        Shape { a, slices }
    }

    fn r(&self) -> &[f64] {
        self.a.reversals()
    }

    fn r_next(&self, j: usize) -> f64 {
        let r = self.r();
        if j + 1 < r.len() {
            r[j + 1]
        } else {
            self.a.hi()
        }
    }

    /// `E_j(x)`; zero for the virtual curve at saturation above the last measured reversal.
    fn row_at(&self, j: usize, x: f64, hint: &mut usize) -> f64 {
        if j >= self.r().len() {
            return 0.0;
        }
        let s = self.a.strip(self.r()[j]);
        self.a.everett(&s, x, hint)
    }

    /// Strip, triangle and (unclamped, endpoint-corrected) shapes of reversal minimum `m`.
    fn locate(&self, m: f64, hint: &mut usize) -> At {
        let (lo, hi) = (self.a.lo(), self.a.hi());
        let r = self.r();
        let n = r.len();
        let m = m.clamp(lo, hi);
        let j = (r.partition_point(|&x| x <= m).max(1) - 1).min(n - 1);
        let r_next = self.r_next(j);
        let lambda = if r_next > r[j] {
            ((m - r[j]) / (r_next - r[j])).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let t_j = self.row_at(j, r_next, hint);
        let one_l = 1.0 - lambda;
        let tri = self.triangle_total(j, m, lambda, hint);
        let mut at = At {
            j,
            tri,
            uniform: one_l,
            f: Vec::new(),
        };
        if j + 1 >= n {
            return at; // the last strip closes on saturation: nothing above it to share
        }
        let scale = self.row_at(0, hi, hint).abs();
        for (alpha, slice) in &self.slices {
            let alpha = *alpha;
            if alpha <= r_next {
                continue;
            }
            let above = self.row_at(j + 1, alpha, hint);
            let rect = self.row_at(j, alpha, hint) - above - t_j;
            if rect.is_nan() || rect <= 1e-9 * scale {
                continue;
            }
            let mut raw = |mm: f64, tri_m: f64| (slice.e_at(mm, hint) - above - tri_m) / rect;
            // Exact at the strip ends (measured curves reproduced): remove the endpoint mismatch linearly.
            let f = raw(m, tri) - one_l * (raw(r[j], t_j) - 1.0) - lambda * raw(r_next, 0.0);
            at.f.push((alpha, f));
        }
        at
    }

    /// The opposite family's slice at `alpha`, if one was measured there.
    fn slice_at(&self, alpha: f64) -> Option<&Slice<'_>> {
        let eps = 1e-12 * (self.a.hi() - self.a.lo());
        self.slices
            .iter()
            .find(|(a, _)| (a - alpha).abs() <= eps)
            .map(|(_, s)| s)
    }

    /// `D(d) = E(r_j, r_j + d)`: curve `j` as a function of the distance from its reversal.
    fn profile(&self, j: usize, d: f64, hint: &mut usize) -> f64 {
        self.row_at(j, self.r()[j] + d.max(0.0), hint)
    }

    /// `Tri(m) = E(m, r_next)`, the strip triangle's total from minimum `m`: read on the opposite family's curve
    /// at `r_next` when one was measured there (its mismatch with curve `j` removed linearly, so measured curves
    /// are reproduced), else the shift model `D(r_next − m)` (exact for a density that depends on `α − β` only
    /// inside the strip, uniform included).
    fn triangle_total(&self, j: usize, m: f64, lambda: f64, hint: &mut usize) -> f64 {
        let r_j = self.r()[j];
        let r_next = self.r_next(j);
        let t_j = self.row_at(j, r_next, hint);
        let v = match self.slice_at(r_next) {
            Some(edge) => {
                edge.e_at(m, hint)
                    - (1.0 - lambda) * (edge.e_at(r_j, hint) - t_j)
                    - lambda * edge.e_at(r_next, hint)
            }
            None => self.profile(j, r_next - m, hint),
        };
        v.clamp(0.0, t_j.max(0.0))
    }

    /// `E(m, α)` inside the strip's triangle (`m < α <= r_next`): the shift model corrected linearly in `α` to
    /// meet `Tri(m)` at `r_next` (exact on all three edges of the triangle).
    fn triangle(&self, at: &At, m: f64, alpha: f64, hint: &mut usize) -> f64 {
        let r_next = self.r_next(at.j);
        let d = self.profile(at.j, alpha - m, hint);
        if r_next <= m {
            return d;
        }
        let full = self.profile(at.j, r_next - m, hint);
        d + (alpha - m) / (r_next - m) * (at.tri - full)
    }

    /// Shapes at increasing reversal minima `ms`, clamped to [0, 1] and nonincreasing in `m` inside each strip.
    fn locate_all(&self, ms: impl Iterator<Item = f64>, hint: &mut usize) -> Vec<At> {
        let mut out: Vec<At> = ms.map(|m| self.locate(m, hint)).collect();
        for at in &mut out {
            for (_, f) in &mut at.f {
                *f = f.clamp(0.0, 1.0);
            }
        }
        for i in 1..out.len() {
            if out[i].j == out[i - 1].j && out[i].f.len() == out[i - 1].f.len() {
                let prev: Vec<f64> = out[i - 1].f.iter().map(|&(_, f)| f).collect();
                for ((_, f), p) in out[i].f.iter_mut().zip(prev) {
                    *f = f.min(p);
                }
            }
        }
        out
    }

    /// The shape at `alpha`: linear between the calibrated slices, held at the nearest one outside them,
    /// uniform where none lies above the strip.
    fn shape_at(at: &At, alpha: f64) -> f64 {
        let f = &at.f;
        match f.len() {
            0 => at.uniform,
            _ if alpha <= f[0].0 => f[0].1,
            _ if alpha >= f[f.len() - 1].0 => f[f.len() - 1].1,
            _ => {
                let k = f.partition_point(|&(a, _)| a <= alpha) - 1;
                let (a0, f0) = f[k];
                let (a1, f1) = f[k + 1];
                f0 + (f1 - f0) * (alpha - a0) / (a1 - a0)
            }
        }
    }

    /// `E(m, α)` for reversal minimum `m` (located as `at`).
    fn everett(&self, m: f64, at: &At, alpha: f64, hint: &mut usize) -> f64 {
        if alpha <= m {
            return 0.0;
        }
        let r_next = self.r_next(at.j);
        let v = if alpha <= r_next {
            self.triangle(at, m, alpha, hint)
        } else {
            let t_j = self.row_at(at.j, r_next, hint);
            let above = self.row_at(at.j + 1, alpha, hint);
            let rect = self.row_at(at.j, alpha, hint) - above - t_j;
            above + at.tri + Self::shape_at(at, alpha) * rect
        };
        v.max(0.0)
    }
}

/// Sort, merge nodes closer than round-off (keeping `exact` nodes exact).
fn merged_grid(mut grid: Vec<f64>, exact: &[f64], span: f64) -> Vec<f64> {
    grid.sort_by(f64::total_cmp);
    let eps = 1e-12 * span;
    let mut merged: Vec<f64> = Vec::with_capacity(grid.len());
    for x in grid {
        match merged.last_mut() {
            Some(last) if x - *last <= eps => {
                if exact.binary_search_by(|v| v.total_cmp(&x)).is_ok() {
                    *last = x;
                }
            }
            _ => merged.push(x),
        }
    }
    merged
}

/// `subdivisions − 1` points between each pair of consecutive values of `r` (and `r_last .. end`), with `r`.
fn subdivided(r: &[f64], end: f64, subdivisions: usize) -> Vec<f64> {
    let k = subdivisions.max(1);
    let mut out = Vec::with_capacity(r.len() * k + 1);
    for j in 0..r.len() {
        let (p, q) = (r[j], if j + 1 < r.len() { r[j + 1] } else { end });
        for l in 0..k {
            out.push(p + (q - p) * l as f64 / k as f64);
        }
    }
    out.push(end);
    out.dedup();
    out
}

/// Keep each row nondecreasing; return the largest correction that took.
fn monotone_rows(rows: &mut [Vec<f64>]) -> f64 {
    let mut adjusted = 0.0f64;
    for row in rows {
        let mut peak = 0.0f64;
        for v in row.iter_mut() {
            if *v < peak {
                adjusted = adjusted.max(peak - *v);
                *v = peak;
            }
            peak = *v;
        }
    }
    adjusted
}

/// Derive the opposite family of `a` (measured, rising orientation) from the opposite major branch given in the
/// derived family's rising orientation (`major_w` increasing from `-a.hi()` to `-a.lo()`, `major_e` its increments
/// from 0). The derived reversals are `a`'s range end, its reversals and `subdivisions − 1` points between each
/// pair of them (mirrored); the grid holds every node of `a`, every sample of the major branch and the reversals.
pub fn derive_family(
    a: &Family<Vec<f64>>,
    major_w: &[f64],
    major_e: &[f64],
    subdivisions: usize,
) -> DerivedFamily {
    let (lo, hi) = (a.lo(), a.hi());
    let shape = Shape::on_major(a, major_w, major_e);
    // Derived reversals (maxima M in a's orientation, lo excluded), mirrored and increasing.
    let maxima = subdivided(a.reversals(), hi, subdivisions);
    let reversals: Vec<f64> = maxima
        .iter()
        .rev()
        .filter(|&&m| m > lo)
        .map(|&m| -m)
        .collect();
    let mut grid: Vec<f64> = a.grid().iter().map(|&x| -x).collect();
    grid.extend(major_w.iter().copied().filter(|&w| w > -hi && w < -lo));
    grid.extend_from_slice(&reversals);
    let mut exact = reversals.clone();
    exact.push(-lo);
    exact.sort_by(f64::total_cmp);
    let grid = merged_grid(grid, &exact, hi - lo);

    let mut hint = 0usize;
    // Grid in increasing w is increasing reversal minimum m = -w when walked backwards.
    let mut ats = shape.locate_all(grid.iter().rev().map(|&w| -w), &mut hint);
    ats.reverse();
    let mut rows: Vec<Vec<f64>> = reversals
        .iter()
        .map(|&wk| {
            grid.iter()
                .zip(&ats)
                .map(|(&w, at)| {
                    if w <= wk {
                        0.0
                    } else {
                        shape.everett(-w, at, -wk, &mut hint)
                    }
                })
                .collect()
        })
        .collect();
    let adjusted = monotone_rows(&mut rows);
    DerivedFamily {
        grid,
        reversals,
        rows,
        adjusted,
    }
}

/// The measured family `a` with `subdivisions − 1` more curves between each pair of its reversals, each from the
/// strip shapes calibrated on the opposite major branch (same arguments as [`derive_family`]). Measured curves
/// are kept exactly; the operator's off-grid rule then only spans the narrower strips.
pub fn densify_family(
    a: &Family<Vec<f64>>,
    major_w: &[f64],
    major_e: &[f64],
    subdivisions: usize,
) -> DerivedFamily {
    densify(&Shape::on_major(a, major_w, major_e), subdivisions)
}

/// [`densify_family`] with the strip shapes calibrated on every curve of the measured opposite family `b`
/// (rising orientation): where both families were measured, each one's curves show how the density varies
/// across the other's strips.
pub fn densify_with_family(
    a: &Family<Vec<f64>>,
    b: &Family<Vec<f64>>,
    subdivisions: usize,
) -> DerivedFamily {
    densify(&Shape::on_family(a, b), subdivisions)
}

fn densify(shape: &Shape<'_>, subdivisions: usize) -> DerivedFamily {
    let a = shape.a;
    let (lo, hi) = (a.lo(), a.hi());
    let mut reversals = subdivided(a.reversals(), hi, subdivisions);
    reversals.retain(|&m| m < hi);
    let mut grid: Vec<f64> = a.grid().to_vec();
    grid.extend_from_slice(&reversals);
    let mut exact = reversals.clone();
    exact.push(hi);
    exact.sort_by(f64::total_cmp);
    let grid = merged_grid(grid, &exact, hi - lo);
    let mut hint = 0usize;
    let ats = shape.locate_all(reversals.iter().copied(), &mut hint);
    let measured = a.reversals();
    let mut rows: Vec<Vec<f64>> = reversals
        .iter()
        .zip(&ats)
        .map(|(&m, at)| {
            if let Ok(j) = measured.binary_search_by(|x| x.total_cmp(&m)) {
                // A measured curve, exactly.
                let s = a.strip(measured[j]);
                return grid.iter().map(|&x| a.everett(&s, x, &mut hint)).collect();
            }
            grid.iter()
                .map(|&x| shape.everett(m, at, x, &mut hint))
                .collect()
        })
        .collect();
    let adjusted = monotone_rows(&mut rows);
    DerivedFamily {
        grid,
        reversals,
        rows,
        adjusted,
    }
}
