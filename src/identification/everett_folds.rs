//! Cross-validation of the Everett-table least squares ([`super::fit_everett`]) over held-out folds, with the
//! regressors built once: the rows of every sample are accumulated into the normal equations of the fold that
//! holds it out (and into the total), so that each fold's training problem is the total less its own part and
//! its held-out error is a quadratic form of the same part. Trying another smoothing then costs one
//! (warm-started) nonnegative solve per fold and no pass over the data.
use alloc::vec::Vec;

use super::error::IdentificationError;
use super::everett_fit::{EverettFitOptions, check_options, data_matrix, regularise, solve_masses};
use super::everett_large::{EverettRows, needs_large_path};
use super::everett_regressors::{EverettGrid, NormalEquations};
use crate::limits::{self, MAX_CV_FOLDS};

/// One run of an [`EverettFolds`]: as [`super::EverettRun`], with the fold that holds each sample out
/// (`fold[i] < n_folds`; any larger value: never held out, always in the training part). Samples with weight 0
/// drive the memory and enter no fold.
#[derive(Clone, Copy, Debug)]
pub struct EverettFoldRun<'a> {
    /// Input samples.
    pub u: &'a [f64],
    /// Output samples.
    pub y: &'a [f64],
    /// Row weights.
    pub weight: &'a [f64],
    /// Fold holding each sample out.
    pub fold: &'a [usize],
    /// Offset column of this run (`< n_offsets`).
    pub offset_col: usize,
    /// Inputs applied after negative saturation before the run starts (its initial state).
    pub history: &'a [f64],
    /// Calibration gain of this run (1 for none).
    pub gain: f64,
    /// Drift regressor on this run's samples (empty: none); one coefficient shared by the runs.
    pub drift: &'a [f64],
}

/// One fold's cross-validated result: the weighted squared error and weight of its held-out rows under the
/// table fitted on the rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FoldScore {
    /// Weighted sum of squared held-out errors (output units²).
    pub sse: f64,
    /// Sum of the held-out rows' weights.
    pub weight: f64,
    /// Whether the training fit's nonnegative solve met its optimality conditions.
    pub converged: bool,
}

/// The least squares of [`super::fit_everett`] on one grid, split into folds for cross-validation (see the
/// module). Each fold keeps the solver's passive set of every smoothing tried and warm-starts a new one from
/// the nearest (in log scale), and keeps its training part's unregularised mass-space matrix (the same for
/// every smoothing): a smoothing after the first costs a copy, the regularisation and the solve.
#[derive(Clone, Debug)]
pub struct EverettFolds {
    kind: FoldsKind,
}

// Up to the dense solver's unknowns: normal equations per fold; past them: the rows kept, solved matrix-free.
#[derive(Clone, Debug)]
enum FoldsKind {
    Dense(DenseFolds),
    Large(EverettRows),
}

#[derive(Clone, Debug)]
struct DenseFolds {
    grid: EverettGrid,
    total: NormalEquations,
    held: Vec<NormalEquations>,
    // Per fold: (smoothing, passive set) of every solve so far.
    warm: Vec<Vec<(f64, Vec<bool>)>>,
    // Per fold, once prepared: its training part.
    train: Vec<Option<TrainingPart>>,
}

/// A fold's training problem (the total less its own part) without the Gram matrix the scores do not need.
#[derive(Clone, Debug)]
struct TrainingPart {
    rhs: Vec<f64>,
    // The unregularised mass-space matrix (`data_matrix`).
    q: Vec<f64>,
}

impl EverettFolds {
    /// Regressors of `runs` on `grid` with `n_offsets` free offsets, split into `n_folds` folds (at least 2).
    pub fn new(
        grid: &EverettGrid,
        runs: &[EverettFoldRun<'_>],
        n_offsets: usize,
        n_folds: usize,
    ) -> Result<Self, IdentificationError> {
        check_options(n_offsets, EverettFitOptions::default())?;
        if n_folds < 2 {
            return Err(IdentificationError::TooFewFolds { folds: n_folds });
        }
        limits::check("cross-validation folds", n_folds, MAX_CV_FOLDS)?;
        let with_drift = runs.iter().any(|r| !r.drift.is_empty());
        let cols = limits::sum(n_offsets, usize::from(with_drift));
        if needs_large_path(limits::sum(grid.n_cells(), cols)) {
            return Ok(Self {
                kind: FoldsKind::Large(EverettRows::new(grid, runs, n_offsets, n_folds)?),
            });
        }
        let mut total = NormalEquations::new(grid, cols)?;
        let mut held = Vec::with_capacity(n_folds);
        for _ in 0..n_folds {
            held.push(NormalEquations::new(grid, cols)?);
        }
        for (k, run) in runs.iter().enumerate() {
            let lengths = super::RunError::Lengths {
                inputs: run.u.len(),
                outputs: run.y.len(),
                weights: run.weight.len(),
            };
            if run.y.len() != run.u.len() || run.fold.len() != run.u.len() {
                return Err(IdentificationError::Run {
                    run: k,
                    error: lengths,
                });
            }
            let mut rhs = core::mem::take(&mut total.rhs);
            let mut yy = total.yy;
            total
                .add_rows(
                    grid,
                    run.u,
                    run.weight,
                    run.offset_col,
                    run.history,
                    run.gain,
                    (!run.drift.is_empty()).then_some((n_offsets, run.drift)),
                    |i, w, row| {
                        let y = run.y[i];
                        if !y.is_finite() {
                            return Err(super::RunError::NonFinite {
                                what: "output",
                                sample: i,
                                value: y,
                            });
                        }
                        for &(a, va) in row {
                            rhs[a] += w * va * y;
                        }
                        yy += w * y * y;
                        if let Some(part) = held.get_mut(run.fold[i]) {
                            part.add_row(w, row, y);
                        }
                        Ok(())
                    },
                )
                .map_err(|error| IdentificationError::Run { run: k, error })?;
            total.rhs = rhs;
            total.yy = yy;
        }
        if total.n_rows == 0 {
            return Err(IdentificationError::NoSamples);
        }
        total.finish();
        for part in &mut held {
            part.finish();
        }
        Ok(Self {
            kind: FoldsKind::Dense(DenseFolds {
                grid: grid.clone(),
                total,
                warm: alloc::vec![Vec::new(); n_folds],
                train: alloc::vec![None; n_folds],
                held,
            }),
        })
    }

    /// Number of unknowns (cell masses, offsets and the drift coefficient when any run has a drift regressor).
    pub fn n_unknowns(&self) -> usize {
        match &self.kind {
            FoldsKind::Dense(d) => d.total.n_cols(),
            FoldsKind::Large(rows) => rows.n_unknowns(),
        }
    }

    /// Whether the folds are solved matrix-free (a table past the dense solver's unknowns).
    pub fn is_large(&self) -> bool {
        matches!(self.kind, FoldsKind::Large(_))
    }

    /// Every fold's held-out error of the table fitted with `options` on the rest (a fold without held-out rows
    /// scores 0 on weight 0). A fold's first solve starts from `warm_start` (e.g. the passive set of a fit of the
    /// whole, ignored unless it has [`Self::n_unknowns`] entries), later ones from the nearest smoothing's. An
    /// error when a fold's training part cannot be fitted (e.g. a run whose samples are all held out leaves its
    /// offset column empty).
    /// On the matrix-free path each fold warm-starts from its own earlier solutions only.
    pub fn score(
        &mut self,
        options: EverettFitOptions,
        warm_start: Option<&[bool]>,
    ) -> Result<Vec<FoldScore>, IdentificationError> {
        match &mut self.kind {
            FoldsKind::Dense(d) => d.score(options, warm_start),
            FoldsKind::Large(rows) => rows.score(options),
        }
    }
}

impl DenseFolds {
    fn n_unknowns(&self) -> usize {
        self.total.n_cols()
    }

    fn score(
        &mut self,
        options: EverettFitOptions,
        warm_start: Option<&[bool]>,
    ) -> Result<Vec<FoldScore>, IdentificationError> {
        let given = warm_start.filter(|w| w.len() == self.n_unknowns());
        check_options(self.total.n_offsets, options)?;
        let mut out = Vec::with_capacity(self.held.len());
        for ((part, warm), train) in self.held.iter().zip(&mut self.warm).zip(&mut self.train) {
            if part.n_rows == 0 {
                out.push(FoldScore {
                    sse: 0.0,
                    weight: 0.0,
                    converged: true,
                });
                continue;
            }
            let train = match train {
                Some(t) => t,
                None => train.insert(training_part(&self.grid, &self.total, part)?),
            };
            let mut q = train.q.clone();
            regularise(&self.grid, &mut q, part.n_cols(), part.n_nodes, options)?;
            let (sol, model, offsets, _) = solve_masses(
                &self.grid,
                &train.rhs,
                part.n_nodes,
                &q,
                options,
                nearest(warm, options.smoothing).or(given),
                None,
            )?;
            drop(q);
            // Held-out error as a quadratic form of the fold's own part: yy − 2 zᵀ r + zᵀ G z, z = [C w, offsets].
            let mut z = model.node_values().to_vec();
            z.extend_from_slice(&offsets);
            let m = z.len();
            let mut zgz = 0.0;
            for i in 0..m {
                let gi = &part.gram[i * m..(i + 1) * m];
                zgz += z[i] * gi.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
            }
            let zr: f64 = z.iter().zip(&part.rhs).map(|(a, b)| a * b).sum();
            out.push(FoldScore {
                sse: (part.yy - 2.0 * zr + zgz).max(0.0),
                weight: part.weight_sum,
                converged: sol.converged,
            });
            warm.push((options.smoothing, sol.passive));
        }
        Ok(out)
    }
}

/// The training part of the fold `part` of `total`: its right-hand side and unregularised mass-space matrix.
fn training_part(
    grid: &EverettGrid,
    total: &NormalEquations,
    part: &NormalEquations,
) -> Result<TrainingPart, IdentificationError> {
    let mut train = total.clone();
    for (t, h) in train.gram.iter_mut().zip(&part.gram) {
        *t -= h;
    }
    for (t, h) in train.rhs.iter_mut().zip(&part.rhs) {
        *t -= h;
    }
    train.n_rows -= part.n_rows;
    if train.n_rows == 0 {
        return Err(IdentificationError::NoSamples);
    }
    let q = data_matrix(grid, &train);
    Ok(TrainingPart { rhs: train.rhs, q })
}

/// What the solve whose smoothing is nearest to `smoothing` in log scale kept for a warm start (its passive set,
/// or its solution), 0 counting as the smallest smoothing.
pub(super) fn nearest<T>(warm: &[(f64, Vec<T>)], smoothing: f64) -> Option<&[T]> {
    let log = |s: f64| libm::log(s.max(f64::MIN_POSITIVE));
    warm.iter()
        .min_by(|a, b| {
            let (da, db) = (
                (log(a.0) - log(smoothing)).abs(),
                (log(b.0) - log(smoothing)).abs(),
            );
            da.total_cmp(&db)
        })
        .map(|(_, kept)| kept.as_slice())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identification::{EverettRun, fit_everett};

    fn dense(cv: &EverettFolds) -> &DenseFolds {
        match &cv.kind {
            FoldsKind::Dense(d) => d,
            FoldsKind::Large(_) => panic!("a small table takes the dense path"),
        }
    }

    fn triangle(n: usize, amps: &[f64]) -> Vec<f64> {
        let mut u = Vec::new();
        for &a in amps {
            for i in 0..n {
                u.push(-a + 2.0 * a * i as f64 / n as f64);
            }
            for i in 0..n {
                u.push(a - 2.0 * a * i as f64 / n as f64);
            }
        }
        u
    }

    #[test]
    fn fold_scores_match_fits_on_the_rest() {
        // A smooth hysteretic output with a little deterministic "noise", two runs, three folds of blocks.
        let grid = EverettGrid::uniform(-1.0, 1.0, 8).unwrap();
        let us = [
            triangle(40, &[1.0, 0.6, 0.9, 0.3]),
            triangle(30, &[1.0, 0.5, 0.8]),
        ];
        let ys: Vec<Vec<f64>> = us
            .iter()
            .map(|u| {
                let mut prev = u[0];
                u.iter()
                    .enumerate()
                    .map(|(i, &x)| {
                        let up = x >= prev;
                        prev = x;
                        libm::tanh(2.0 * x)
                            + if up { -0.1 } else { 0.1 }
                            + 0.01 * libm::sin(i as f64)
                    })
                    .collect()
            })
            .collect();
        let folds: Vec<Vec<usize>> = us
            .iter()
            .map(|u| (0..u.len()).map(|i| (i * 9 / u.len()) % 3).collect())
            .collect();
        let ones: Vec<Vec<f64>> = us.iter().map(|u| alloc::vec![1.0; u.len()]).collect();
        let runs: Vec<EverettFoldRun<'_>> = (0..2)
            .map(|k| EverettFoldRun {
                u: &us[k],
                y: &ys[k],
                weight: &ones[k],
                fold: &folds[k],
                offset_col: k,
                history: &[],
                gain: 1.0,
                drift: &[],
            })
            .collect();
        let mut cv = EverettFolds::new(&grid, &runs, 2, 3).unwrap();
        for smoothing in [1e-3, 1e-5] {
            let options = EverettFitOptions {
                smoothing,
                ..EverettFitOptions::default()
            };
            let scores = cv.score(options, None).unwrap();
            for (f, s) in scores.iter().enumerate() {
                // The same fold by hand: fit with the held-out rows weighted 0, then their squared errors.
                let train_w: Vec<Vec<f64>> = folds
                    .iter()
                    .map(|fk| fk.iter().map(|&g| f64::from(u8::from(g != f))).collect())
                    .collect();
                let plain: Vec<EverettRun<'_>> = (0..2)
                    .map(|k| EverettRun {
                        u: &us[k],
                        y: &ys[k],
                        weight: &train_w[k],
                        offset_col: k,
                        history: &[],
                        gain: 1.0,
                        drift: &[],
                    })
                    .collect();
                let fit = fit_everett(&grid, &plain, 2, options).unwrap();
                let (mut sse, mut n) = (0.0, 0.0);
                for k in 0..2 {
                    let p = fit.model.simulate(&us[k], Some(fit.offsets[k]));
                    for i in 0..us[k].len() {
                        if folds[k][i] == f {
                            sse += (ys[k][i] - p[i]) * (ys[k][i] - p[i]);
                            n += 1.0;
                        }
                    }
                }
                assert_eq!(s.weight, n);
                assert!(
                    (s.sse - sse).abs() <= 1e-7 * sse.max(1e-12),
                    "fold {f}: {} vs {sse}",
                    s.sse
                );
            }
        }
    }

    #[test]
    fn a_fold_prepares_its_training_matrix_once_for_every_smoothing() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 6).unwrap();
        let u = triangle(30, &[1.0, 0.7, 0.4, 0.9]);
        let y: Vec<f64> = u.iter().map(|&x| libm::tanh(1.5 * x)).collect();
        let fold: Vec<usize> = (0..u.len()).map(|i| (i * 6 / u.len()) % 2).collect();
        let w = alloc::vec![1.0; u.len()];
        let run = EverettFoldRun {
            u: &u,
            y: &y,
            weight: &w,
            fold: &fold,
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift: &[],
        };
        let mut cv = EverettFolds::new(&grid, &[run], 1, 2).unwrap();
        assert!(dense(&cv).train.iter().all(Option::is_none));
        let options = |smoothing| EverettFitOptions {
            smoothing,
            ..EverettFitOptions::default()
        };
        cv.score(options(1e-4), None).unwrap();
        let prepared: Vec<*const f64> = dense(&cv)
            .train
            .iter()
            .map(|t| t.as_ref().expect("prepared by the first score").q.as_ptr())
            .collect();
        let second = cv.score(options(1e-2), None).unwrap();
        let again: Vec<*const f64> = dense(&cv)
            .train
            .iter()
            .map(|t| t.as_ref().unwrap().q.as_ptr())
            .collect();
        assert_eq!(prepared, again, "a later smoothing rebuilt a fold's matrix");
        // The kept matrix gives the scores of a fresh preparation.
        let fresh = EverettFolds::new(&grid, &[run], 1, 2)
            .unwrap()
            .score(options(1e-2), None)
            .unwrap();
        for (a, b) in second.iter().zip(&fresh) {
            assert_eq!(a.weight, b.weight);
            assert!((a.sse - b.sse).abs() <= 1e-9 * b.sse.max(1e-12));
        }
    }

    #[test]
    fn bad_folds_and_lengths_are_errors() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 4).unwrap();
        let u = triangle(10, &[1.0]);
        let fold = alloc::vec![0usize; u.len() - 1];
        let w = alloc::vec![1.0; u.len()];
        let run = EverettFoldRun {
            u: &u,
            y: &u,
            weight: &w,
            fold: &fold,
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift: &[],
        };
        assert!(EverettFolds::new(&grid, &[run], 1, 3).is_err());
        let fold = alloc::vec![0usize; u.len()];
        let run = EverettFoldRun { fold: &fold, ..run };
        assert!(EverettFolds::new(&grid, &[run], 1, 1).is_err());
        // Every sample held out in fold 0: its training part is empty.
        let mut cv = EverettFolds::new(&grid, &[run], 1, 2).unwrap();
        assert!(cv.score(EverettFitOptions::default(), None).is_err());
    }
}
