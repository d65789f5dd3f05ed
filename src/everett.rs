//! One family of first-order reversal curves as an Everett table, and its evaluation at any reversal point.
//!
//! The family is stored in *rising orientation*: an ascending family as measured, a descending family mirrored
//! (`v = -u`, increments taken positive). Row `j` holds `E_j(g_k) = S(r_j, g_k) - S(r_j, r_j)` on one shared grid
//! `g` that contains every reversal `r_j`; `E_j = 0` at and below `r_j`. Values between nodes are linear in the
//! input, so every evaluation and its inverse are closed-form inside one grid cell.
//!
//! Off-grid reversals (`r_j <= m < r_{j+1}`, `λ = (m - r_j)/(r_{j+1} - r_j)`) split the strip `[r_j, r_{j+1})` of
//! the Preisach plane into its triangle (`β <= α <= r_{j+1}`, total `T_j = E_j(r_{j+1})`) and the rectangle above it:
//! - inside the triangle the curve keeps its shape relative to its reversal, `E(m,u) = E_j(r_j + (u - m))` for
//!   `m < u <= r_{j+1}` (exact for a density that depends on `α - β` only there: uniform, and a reversible part on
//!   the diagonal alike), so the triangle's total from `m` is `Tri(m) = E_j(r_j + r_{j+1} - m)`;
//! - the rectangle's density is uniform across the strip: for `u > r_{j+1}`,
//!   `E(m,u) = (1-λ) E_j(u) + λ E_{j+1}(u) - [(1-λ) T_j - Tri(m)]`.
//!
//! This is exact at measured reversals (`λ = 0`), continuous in `m` and `u`, monotone in both, and exact for a
//! density uniform in each strip (where `Tri(m) = (1-λ)² T_j`) as well as for a reversible part (a diagonal mass,
//! where `Tri(m) = (1-λ) T_j` and the curves are linear in `m`, as the least-squares tables are). The simpler
//! interpolation `(1-λ)[E_j(u) - E_j(m)] + λ E_{j+1}(u)` misses the strip's triangle under both.
//! Above the highest measured reversal the strip closes on a virtual curve at saturation (`E ≡ 0`).
use crate::error::{FamilyKind, TableError};
use crate::limits::{self, MAX_MAGNITUDE};

/// Where a reversal point sits in the family: the strip `[r_j, r_next)` and its interpolation weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Strip {
    /// Reversal input (rising orientation), clamped to the table range.
    pub m: f64,
    /// Index of the measured curve at or below `m`.
    pub j: usize,
    /// Reversal input of curve `j`.
    pub r_j: f64,
    /// Reversal input of curve `j + 1`, or the saturation input above the last curve.
    pub r_next: f64,
    /// `(m - r_j) / (r_next - r_j)` in `[0, 1)`.
    pub lambda: f64,
    /// `E_j(r_next)`: the strip triangle's total increment.
    pub t_j: f64,
    /// Grid node index of `r_j`.
    pub k_j: usize,
    /// Grid node index of `r_next`.
    pub k_next: usize,
    /// Offset of row `j` in the table storage (row `j + 1` follows it).
    pub row_j: usize,
    /// `Tri(m) = E_j(r_j + r_next - m)`: the strip triangle's total from `m`.
    pub tri: f64,
    /// `(1-λ)T_j - Tri(m)`, the strip combination's constant (precomputed for the per-step evaluation).
    pub shift: f64,
}

impl Strip {
    /// A strip that evaluates to zero everywhere (used for empty state slots).
    pub const ZERO: Strip = Strip {
        m: 0.0,
        j: 0,
        r_j: 0.0,
        r_next: 0.0,
        lambda: 0.0,
        t_j: 0.0,
        k_j: 0,
        k_next: 0,
        row_j: 0,
        tri: 0.0,
        shift: 0.0,
    };
}

/// A strip of the family found before (its curve and the grid nodes of its ends): a search hint for
/// [`Family::strip_hinted`] that only speeds it up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StripHint {
    j: usize,
    k_j: usize,
    k_next: usize,
}

impl StripHint {
    /// No strip to start from.
    pub(crate) const NONE: StripHint = StripHint {
        j: usize::MAX,
        k_j: 0,
        k_next: 0,
    };

    /// Start from strip `s` (of the same family).
    pub(crate) fn of(s: &Strip) -> StripHint {
        StripHint {
            j: s.j,
            k_j: s.k_j,
            k_next: s.k_next,
        }
    }
}

/// A validated family table over storage `S` (owned `Vec<f64>` or a `&'static [f64]` on embedded targets).
///
/// `data` = `[grid (nodes) | reversals (curves) | values (curves × nodes, row-major)]`.
#[derive(Debug, Clone)]
pub struct Family<S> {
    data: S,
    nodes: usize,
    curves: usize,
    kind: FamilyKind,
}

/// Total storage length (in `f64`) of a family table with these dimensions (saturating at `usize::MAX`, which
/// no storage has).
pub const fn family_len(nodes: usize, curves: usize) -> usize {
    limits::sum(limits::sum(nodes, curves), limits::product(curves, nodes))
}

impl<S: AsRef<[f64]>> Family<S> {
    /// Validate a raw table once: strictly increasing finite grid within ±[`MAX_MAGNITUDE`], reversals on grid
    /// nodes, rows zero up to their reversal, non-decreasing after it and at most `MAX_MAGNITUDE`.
    /// `O(curves × nodes)`; nothing is checked again per step.
    pub fn new(data: S, nodes: usize, curves: usize, kind: FamilyKind) -> Result<Self, TableError> {
        let bad = |what, index| TableError::BadTable {
            family: kind,
            what,
            index,
        };
        if curves < 2 {
            return Err(TableError::TooFewCurves {
                family: kind,
                curves,
            });
        }
        if nodes < 2 {
            return Err(bad("fewer than 2 grid nodes", nodes));
        }
        if data.as_ref().len() != family_len(nodes, curves) {
            return Err(bad(
                "storage length is not nodes + curves + curves*nodes",
                data.as_ref().len(),
            ));
        }
        let f = Family {
            data,
            nodes,
            curves,
            kind,
        };
        let g = f.grid();
        for (i, w) in g.windows(2).enumerate() {
            if !(w[0].is_finite() && w[1].is_finite()) {
                return Err(bad("grid value not finite", i));
            }
            if w[0].abs() > MAX_MAGNITUDE || w[1].abs() > MAX_MAGNITUDE {
                return Err(bad("grid value beyond the supported magnitude 1e150", i));
            }
            if w[1] <= w[0] {
                return Err(bad("grid not strictly increasing", i + 1));
            }
        }
        let r = f.reversals();
        if r[0] != g[0] {
            return Err(bad(
                "first reversal must be the grid's first node (major branch)",
                0,
            ));
        }
        for j in 0..curves {
            if j > 0 && r[j] <= r[j - 1] {
                return Err(bad("reversals not strictly increasing", j));
            }
            let Ok(node) = g.binary_search_by(|x| x.total_cmp(&r[j])) else {
                return Err(bad("reversal is not a grid node", j));
            };
            if node + 1 >= nodes {
                return Err(bad(
                    "reversal at the last grid node (saturation) has no curve",
                    j,
                ));
            }
            let row = f.row(j);
            for (k, &v) in row.iter().enumerate() {
                if !v.is_finite() {
                    return Err(TableError::NonFinite {
                        family: kind,
                        curve: j,
                        sample: k,
                    });
                }
                if v > MAX_MAGNITUDE {
                    return Err(TableError::OutOfRange {
                        family: kind,
                        curve: j,
                        sample: k,
                        what: "increment",
                        value: v,
                    });
                }
                if k <= node && v != 0.0 {
                    return Err(bad(
                        "row must be zero at and below its reversal",
                        j * nodes + k,
                    ));
                }
                if k > 0 && v < row[k - 1] {
                    return Err(bad("row decreases along the input", j * nodes + k));
                }
            }
        }
        Ok(f)
    }

    /// The same table over borrowed storage (no copy, no validation again).
    pub(crate) fn view(&self) -> Family<&[f64]> {
        Family {
            data: self.data.as_ref(),
            nodes: self.nodes,
            curves: self.curves,
            kind: self.kind,
        }
    }

    pub fn kind(&self) -> FamilyKind {
        self.kind
    }
    pub fn nodes(&self) -> usize {
        self.nodes
    }
    pub fn curves(&self) -> usize {
        self.curves
    }
    /// The raw storage (for serialisation).
    pub fn data(&self) -> &[f64] {
        self.data.as_ref()
    }
    pub fn grid(&self) -> &[f64] {
        &self.data.as_ref()[..self.nodes]
    }
    pub fn reversals(&self) -> &[f64] {
        &self.data.as_ref()[self.nodes..self.nodes + self.curves]
    }
    /// `E_j` at every grid node.
    pub fn row(&self, j: usize) -> &[f64] {
        let start = self.nodes + self.curves + j * self.nodes;
        &self.data.as_ref()[start..start + self.nodes]
    }
    /// Lowest input (negative saturation in rising orientation).
    pub fn lo(&self) -> f64 {
        self.grid()[0]
    }
    /// Highest input (positive saturation in rising orientation).
    pub fn hi(&self) -> f64 {
        self.grid()[self.nodes - 1]
    }

    /// Grid cell `k` with `g[k] <= u < g[k+1]` (the last cell also holds `g[nodes-1]`), hunting from `hint` (a
    /// cache that only speeds the search: the cell, and so every value interpolated in it, does not depend on it).
    #[inline]
    pub fn locate(&self, u: f64, hint: &mut usize) -> usize {
        let g = self.grid();
        let last = self.nodes - 2;
        let h = (*hint).min(last);
        let holds = |k: usize| g[k] <= u && (u < g[k + 1] || (k == last && u <= g[k + 1]));
        let k = if holds(h) {
            h
        } else if h < last && holds(h + 1) {
            h + 1
        } else if h > 0 && holds(h - 1) {
            h - 1
        } else {
            // First node above u, minus one: the cell holding u.
            g.partition_point(|&x| x <= u).clamp(1, last + 1) - 1
        };
        *hint = k;
        k
    }

    /// `E_j(u)` by linear interpolation in cell `k`.
    #[inline]
    fn row_at(&self, j: usize, k: usize, u: f64) -> f64 {
        let g = self.grid();
        let row = self.row(j);
        let t = (u - g[k]) / (g[k + 1] - g[k]);
        row[k] + t * (row[k + 1] - row[k])
    }

    /// The strip holding reversal `m` (clamped to the table range). `O(log curves + log nodes)`; called at
    /// reversals only.
    pub fn strip(&self, m: f64) -> Strip {
        self.strip_hinted(m, StripHint::NONE)
    }

    /// [`Self::strip`], starting from a strip `hint` found before (a new reversal usually falls in the strip of
    /// the last one of its family): the strip's curve and its grid nodes are taken from the hint when that curve
    /// still holds `m`, else searched. The strip is the same, bit for bit, for any hint.
    #[inline]
    pub(crate) fn strip_hinted(&self, m: f64, hint: StripHint) -> Strip {
        let m = m.clamp(self.lo(), self.hi());
        let r = self.reversals();
        let g = self.grid();
        let StripHint { j, k_j, k_next } = hint;
        // The hint's curve holds m (the last curve at or below it) and its nodes are those of that curve: a hint
        // from another table never passes.
        let held = j < self.curves
            && r[j] <= m
            && (j + 1 == self.curves || m < r[j + 1])
            && k_j <= k_next
            && k_next < self.nodes
            && g[k_j] == r[j]
            && g[k_next]
                == if j + 1 < self.curves {
                    r[j + 1]
                } else {
                    self.hi()
                };
        let (j, k_j, k_next) = if held {
            (j, k_j, k_next)
        } else {
            let j = r.partition_point(|&x| x <= m).max(1) - 1;
            let r_next = if j + 1 < self.curves {
                r[j + 1]
            } else {
                self.hi()
            };
            // Reversals and the range end are exact grid nodes (validated).
            let k_j = g.partition_point(|&x| x < r[j]);
            // r_next >= r_j: every node before k_j is below it too.
            let k_next = k_j + g[k_j..].partition_point(|&x| x < r_next);
            (j, k_j, k_next)
        };
        let r_j = r[j];
        let r_next = if j + 1 < self.curves {
            r[j + 1]
        } else {
            self.hi()
        };
        let lambda = ((m - r_j) / (r_next - r_j)).clamp(0.0, 1.0);
        let t_j = self.row(j)[k_next];
        let row_j = self.nodes + self.curves + j * self.nodes;
        let tri = if lambda == 0.0 {
            t_j
        } else {
            self.strip_row(j, k_j, k_next, r_j + (r_next - m))
        };
        let shift = (1.0 - lambda) * t_j - tri;
        Strip {
            m,
            j,
            r_j,
            r_next,
            lambda,
            t_j,
            k_j,
            k_next,
            row_j,
            tri,
            shift,
        }
    }

    /// `E_j(v)` for `v` inside the strip's cells `[k_j, k_next]`.
    #[inline]
    fn strip_row(&self, j: usize, k_j: usize, k_next: usize, v: f64) -> f64 {
        let g = &self.grid()[k_j..=k_next];
        let k = k_j + g.partition_point(|&x| x <= v).clamp(1, g.len() - 1) - 1;
        self.row_at(j, k, v)
    }

    /// `E(m, u)`: the output increment from reversal `s.m` to input `u` (rising orientation).
    #[inline]
    pub fn everett(&self, s: &Strip, u: f64, hint: &mut usize) -> f64 {
        if u <= s.m {
            return 0.0;
        }
        if u <= s.r_next {
            // Inside the strip's triangle: the measured curve j, shifted to start at m.
            return self.strip_row(s.j, s.k_j, s.k_next, s.r_j + (u - s.m));
        }
        let k = self.locate(u, hint);
        let lo = self.combined_node(s, k);
        let hi = self.combined_node(s, k + 1);
        let g = self.grid();
        let t = (u - g[k]) / (g[k + 1] - g[k]);
        lo + t * (hi - lo)
    }

    /// The strip combination `(1-λ)E_j + λE_{j+1} - [(1-λ)T_j - Tri(m)]` at grid node `k` (only for nodes at or
    /// above r_next).
    #[inline]
    fn combined_node(&self, s: &Strip, k: usize) -> f64 {
        let d = self.data.as_ref();
        let a = d[s.row_j + k];
        if s.lambda == 0.0 {
            return a; // on a measured curve (row j + 1 may not exist)
        }
        let b = d[s.row_j + self.nodes + k];
        (1.0 - s.lambda) * a + s.lambda * b - s.shift
    }

    /// `E(m, hi)`: the largest increment reachable from reversal `s.m`.
    pub fn everett_max(&self, s: &Strip) -> f64 {
        let mut h = self.nodes - 2;
        self.everett(s, self.hi(), &mut h)
    }

    /// Smallest input `u >= s.m` with `E(m, u) = e`, for `0 <= e <= everett_max(s)`; `e` beyond the range clamps
    /// to `s.m` or `hi`. Closed form inside one cell; the cell is found by galloping from `hint` (the cell of a
    /// nearby input), so slowly varying targets cost O(1) and any hint gives the same answer.
    #[inline]
    pub fn everett_inverse(&self, s: &Strip, e: f64, hint: usize) -> f64 {
        self.everett_inverse_cell(s, e, hint).0
    }

    /// [`Self::everett_inverse`] and, when the answer lies beyond the strip's own curve, the grid cell holding it
    /// with the Everett values at its nodes (the next query's search hint and shortcut).
    #[inline(always)]
    pub(crate) fn everett_inverse_cell(
        &self,
        s: &Strip,
        e: f64,
        hint: usize,
    ) -> (f64, Option<Hit>) {
        if e <= 0.0 || s.m >= self.hi() {
            return (s.m, None);
        }
        let g = self.grid();
        if e <= s.tri {
            // Invert E_j on [r_j, r_next], then shift back to start at m.
            let row = self.row(s.j);
            let v = invert_monotone(g, |k| row[k], e, s.k_j, s.k_next, s.k_j).value;
            return ((s.m + (v - s.r_j)).min(s.r_next), None);
        }
        if s.j + 1 >= self.curves {
            return (self.hi(), None);
        }
        let hit = invert_monotone(
            g,
            |k| self.combined_node(s, k),
            e,
            s.k_next,
            self.nodes - 1,
            hint,
        );
        (hit.value.max(s.r_next), Some(hit))
    }
}

/// Input where the piecewise-linear function with node values `f(k)` on `grid` first reaches `target`, searching
/// nodes `start..=end` (`f` non-decreasing there). Returns `grid[end]` if `target` is never reached. The answer
/// does not depend on `hint`; a hint near the answer makes the search O(1).
/// Where [`invert_monotone`] found its answer: the value, the cell (nodes `cell`, `cell + 1`) and `f` there
/// (NaN when the answer is an end of the range, not inside a cell).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    pub value: f64,
    pub cell: usize,
    pub f_lo: f64,
    pub f_hi: f64,
}

impl Hit {
    fn edge(value: f64, cell: usize) -> Hit {
        Hit {
            value,
            cell,
            f_lo: f64::NAN,
            f_hi: f64::NAN,
        }
    }
}

#[inline]
fn invert_monotone(
    grid: &[f64],
    f: impl Fn(usize) -> f64,
    target: f64,
    start: usize,
    end: usize,
    hint: usize,
) -> Hit {
    let cell = |lo: usize, hi: usize, f0: f64, f1: f64| {
        let t = if f1 > f0 {
            (target - f0) / (f1 - f0)
        } else {
            1.0
        };
        Hit {
            value: grid[lo] + t.clamp(0.0, 1.0) * (grid[hi] - grid[lo]),
            cell: lo,
            f_lo: f0,
            f_hi: f1,
        }
    };
    let h = hint.clamp(start, end - 1);
    // Fast path: the hinted cell holds the answer (f(h) < target <= f(h+1) makes h+1 the first node reaching it).
    let (fh, fh1) = (f(h), f(h + 1));
    if fh < target && target <= fh1 {
        return cell(h, h + 1, fh, fh1);
    }
    // Gallop away from the hint to bracket the answer: f(lo) < target <= f(hi).
    let (mut lo, mut hi);
    if fh1 < target {
        lo = h + 1;
        let mut step = 1;
        loop {
            if lo == end {
                return Hit::edge(grid[end], end - 1); // never reached
            }
            let probe = (lo + step).min(end);
            if f(probe) >= target {
                hi = probe;
                break;
            }
            lo = probe;
            step *= 2;
        }
    } else {
        hi = h;
        let mut step = 1;
        loop {
            if hi == start {
                return Hit::edge(grid[start], start); // reached at the start
            }
            let probe = hi.saturating_sub(step).max(start);
            if f(probe) < target {
                lo = probe;
                break;
            }
            hi = probe;
            step *= 2;
        }
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if f(mid) >= target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    cell(lo, hi, f(lo), f(hi))
}

#[cfg(test)]
mod tests {
    use super::StripHint;
    use crate::{BuildOptions, Hysteresis, Initial};
    use preisach_plant::measure_first_order;

    /// A strip searched from a hint is the strip searched afresh, bit for bit, for every hint: a strip of the same
    /// curve, of another curve, of the other family's table, none, and one whose nodes lie outside the table.
    #[test]
    fn a_strip_from_any_hint_is_the_strip_searched_afresh() {
        let (a, d) = measure_first_order(40, 9);
        let op = Hysteresis::<Vec<f64>, 8>::from_curve_data(
            &a,
            &d,
            &BuildOptions::default(),
            Initial::Negative,
        )
        .unwrap();
        let (asc, desc) = (op.ascending(), op.descending());
        let mut held = 0;
        for (fam, other) in [(asc, desc), (desc, asc)] {
            let (lo, hi) = (fam.lo(), fam.hi());
            let ms: Vec<f64> = (0..=300)
                .map(|i| lo + (hi - lo) * i as f64 / 300.0)
                .chain(fam.reversals().iter().copied())
                .chain([lo - 1.0, hi + 1.0, f64::NAN, f64::INFINITY])
                .collect();
            let foreign = StripHint {
                j: 1,
                k_j: usize::MAX - 1,
                k_next: usize::MAX,
            };
            let hints: Vec<StripHint> = ms
                .iter()
                .map(|&m| StripHint::of(&fam.strip(m)))
                .chain(
                    other
                        .reversals()
                        .iter()
                        .map(|&m| StripHint::of(&other.strip(m))),
                )
                .chain([StripHint::NONE, foreign])
                .collect();
            for &m in &ms {
                let afresh = format!("{:?}", fam.strip(m));
                for &h in &hints {
                    let s = fam.strip_hinted(m, h);
                    assert_eq!(format!("{s:?}"), afresh, "m = {m}, hint {h:?}");
                    held += usize::from(h == StripHint::of(&s));
                }
            }
        }
        // Many hints hold the very strip: the reuse is exercised, not only the search.
        assert!(held > 10_000, "only {held} hints held their strip");
    }
}
