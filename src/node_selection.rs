//! Choosing table nodes by an error bound: a node of a shared input grid is dropped only where linear
//! interpolation between the kept nodes stays within a tolerance for *every* row (curve) of the table.
//!
//! One left-to-right pass per tolerance (`O(nodes × rows)`): from the last kept node, each row keeps the interval
//! of slopes that pass within the tolerance of every node skipped so far; the segment is extended while the slope
//! to the next node lies inside every interval. The interpolant goes through the kept nodes' exact values, so the
//! bound holds at every dropped node (and, the rows being linear between nodes, everywhere).
use alloc::vec::Vec;

/// Kept node indices (increasing; always the first and last node and every node in `forced`) such that linear
/// interpolation between kept nodes is within `tol` of every row at every dropped node. `rows(r)` gives row `r`
/// at all `grid.len()` nodes; `forced` must be sorted.
pub fn select_nodes<'a>(
    grid: &[f64],
    n_rows: usize,
    rows: impl Fn(usize) -> &'a [f64],
    tol: f64,
    forced: &[usize],
) -> Vec<usize> {
    let n = grid.len();
    if n <= 2 {
        return (0..n).collect();
    }
    let mut keep = Vec::with_capacity(n);
    keep.push(0);
    let mut lo = alloc::vec![f64::NEG_INFINITY; n_rows];
    let mut hi = alloc::vec![f64::INFINITY; n_rows];
    let mut a = 0usize;
    let mut f = forced.partition_point(|&k| k == 0);
    let mut b = 1usize;
    while b < n {
        let is_forced = f < forced.len() && forced[f] == b;
        let dx = grid[b] - grid[a];
        let feasible = (0..n_rows).all(|r| {
            let row = rows(r);
            let s = (row[b] - row[a]) / dx;
            s >= lo[r] && s <= hi[r]
        });
        if !feasible {
            // End the segment at the previous node and restart from there.
            let prev = b - 1;
            keep.push(prev);
            a = prev;
            lo.fill(f64::NEG_INFINITY);
            hi.fill(f64::INFINITY);
            continue;
        }
        if is_forced || b == n - 1 {
            keep.push(b);
            a = b;
            lo.fill(f64::NEG_INFINITY);
            hi.fill(f64::INFINITY);
            if is_forced {
                f += 1;
            }
            b += 1;
            continue;
        }
        for (r, (l, h)) in lo.iter_mut().zip(hi.iter_mut()).enumerate() {
            let row = rows(r);
            *l = l.max((row[b] - tol - row[a]) / dx);
            *h = h.min((row[b] + tol - row[a]) / dx);
        }
        b += 1;
    }
    keep.dedup();
    keep
}

/// Largest deviation of linear interpolation over the kept nodes from the rows at the dropped nodes.
pub fn interpolation_error<'a>(
    grid: &[f64],
    n_rows: usize,
    rows: impl Fn(usize) -> &'a [f64],
    keep: &[usize],
) -> f64 {
    let mut worst = 0.0f64;
    for w in keep.windows(2) {
        let (a, b) = (w[0], w[1]);
        for k in a + 1..b {
            let t = (grid[k] - grid[a]) / (grid[b] - grid[a]);
            for r in 0..n_rows {
                let row = rows(r);
                let v = row[a] + t * (row[b] - row[a]);
                worst = worst.max(libm::fabs(v - row[k]));
            }
        }
    }
    worst
}

/// Node selection under a node budget: the tolerance `tol` if it keeps at most `max_nodes` nodes, otherwise the
/// smallest tolerance (found by bisection, to 1 %) that does. Returns the kept nodes and the tolerance used.
/// `max_nodes` below the forced node count keeps every forced node.
pub fn select_nodes_within<'a>(
    grid: &[f64],
    n_rows: usize,
    rows: impl Fn(usize) -> &'a [f64] + Copy,
    tol: f64,
    max_nodes: usize,
    forced: &[usize],
) -> (Vec<usize>, f64) {
    let keep = select_nodes(grid, n_rows, rows, tol, forced);
    if keep.len() <= max_nodes {
        return (keep, tol);
    }
    // Upper end: the whole output range of the rows always suffices.
    let mut span = 0.0f64;
    for r in 0..n_rows {
        let row = rows(r);
        let (mn, mx) = row
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        span = span.max(mx - mn);
    }
    let (mut lo, mut hi) = (tol.max(0.0), span.max(tol) * 2.0 + f64::MIN_POSITIVE);
    let mut best = select_nodes(grid, n_rows, rows, hi, forced);
    for _ in 0..64 {
        if hi - lo <= 0.01 * hi {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let k = select_nodes(grid, n_rows, rows, mid, forced);
        if k.len() <= max_nodes {
            hi = mid;
            best = k;
        } else {
            lo = mid;
        }
    }
    (best, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_stretches_collapse_and_kinks_stay() {
        let grid: Vec<f64> = (0..101).map(|i| i as f64 / 100.0).collect();
        // A kink at 0.5 and a second row with a kink at 0.25.
        let r0: Vec<f64> = grid
            .iter()
            .map(|&x| if x < 0.5 { x } else { 3.0 * x - 1.0 })
            .collect();
        let r1: Vec<f64> = grid.iter().map(|&x| (x - 0.25).max(0.0)).collect();
        let rows = [r0.as_slice(), r1.as_slice()];
        let keep = select_nodes(&grid, 2, |r| rows[r], 1e-9, &[]);
        assert_eq!(keep, [0, 25, 50, 100]);
        assert!(interpolation_error(&grid, 2, |r| rows[r], &keep) < 1e-9);
        let keep = select_nodes(&grid, 2, |r| rows[r], 1e-9, &[10]);
        assert_eq!(keep, [0, 10, 25, 50, 100]);
    }

    #[test]
    fn the_bound_holds_on_curved_rows_and_the_budget_raises_it() {
        let grid: Vec<f64> = (0..2001).map(|i| i as f64 / 2000.0).collect();
        let row: Vec<f64> = grid.iter().map(|&x| libm::sin(6.0 * x)).collect();
        for tol in [1e-2, 1e-4, 1e-6] {
            let keep = select_nodes(&grid, 1, |_| row.as_slice(), tol, &[]);
            let err = interpolation_error(&grid, 1, |_| row.as_slice(), &keep);
            assert!(err <= tol * (1.0 + 1e-9), "tol {tol}: error {err}");
        }
        let (keep, used) = select_nodes_within(&grid, 1, |_| row.as_slice(), 1e-9, 20, &[]);
        assert!(keep.len() <= 20 && used > 1e-9);
        assert!(interpolation_error(&grid, 1, |_| row.as_slice(), &keep) <= used * (1.0 + 1e-9));
    }
}
