//! Reversal points of a sampled input: dead-band extrema and the reversal order of every sample.
//!
//! Both are streaming state machines (`no_std`, no allocation): feed samples one at a time, as they come off the
//! bench or from a recorded array.
//!
//! - [`ReversalFinder`]: a maximum (minimum) is confirmed once the input has come back from it by more than the
//!   dead-band, so noise and small backward slips below the dead-band are not reversals. The direction is unknown
//!   until the input first leaves its starting range by more than the dead-band; what came before is no reversal.
//! - [`ReversalOrder`]: how many reversals (beyond the dead-band) the input made since it last reached a
//!   saturation end: 0 on the major loop, 1 on a first-order curve, 2 after a further reversal, and so on.

/// Streaming dead-band reversal detector. `push` returns the index of a reversal extremum when one is confirmed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReversalFinder {
    deadband: f64,
    /// Samples seen so far.
    n: usize,
    i_max: usize,
    x_max: f64,
    i_min: usize,
    x_min: f64,
    /// 0 unknown, +1 rising, -1 falling.
    direction: i8,
}

/// A reversal confirmed by [`ReversalFinder::push`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReversalPoint {
    /// Sample index of the extremum.
    pub index: usize,
    /// Input at the extremum.
    pub input: f64,
    /// `true` for a maximum (the input falls after it), `false` for a minimum.
    pub maximum: bool,
}

impl ReversalFinder {
    /// A detector with dead-band `deadband` (> 0, finite; input units). `None` for an invalid dead-band.
    pub fn new(deadband: f64) -> Option<Self> {
        if !(deadband > 0.0 && deadband.is_finite()) {
            return None;
        }
        Some(ReversalFinder {
            deadband,
            n: 0,
            i_max: 0,
            x_max: 0.0,
            i_min: 0,
            x_min: 0.0,
            direction: 0,
        })
    }

    /// The dead-band.
    pub fn deadband(&self) -> f64 {
        self.deadband
    }

    /// Current direction: +1 rising, -1 falling, 0 not yet known.
    pub fn direction(&self) -> i8 {
        self.direction
    }

    /// Feed the next sample (NaN samples are skipped but counted). Returns the reversal this sample confirms.
    pub fn push(&mut self, x: f64) -> Option<ReversalPoint> {
        let i = self.n;
        self.n += 1;
        if x.is_nan() {
            return None;
        }
        if i == 0 || (self.x_max.is_nan() && self.x_min.is_nan()) {
            self.i_max = i;
            self.i_min = i;
            self.x_max = x;
            self.x_min = x;
            return None;
        }
        if self.direction >= 0 && x > self.x_max {
            self.i_max = i;
            self.x_max = x;
        }
        if self.direction <= 0 && x < self.x_min {
            self.i_min = i;
            self.x_min = x;
        }
        match self.direction {
            0 => {
                // The first move larger than the dead-band sets the direction.
                if self.x_max - x > self.deadband {
                    self.direction = -1;
                    self.i_min = i;
                    self.x_min = x;
                } else if x - self.x_min > self.deadband {
                    self.direction = 1;
                    self.i_max = i;
                    self.x_max = x;
                }
                None
            }
            1 if self.x_max - x > self.deadband => {
                let r = ReversalPoint {
                    index: self.i_max,
                    input: self.x_max,
                    maximum: true,
                };
                self.direction = -1;
                self.i_min = i;
                self.x_min = x;
                Some(r)
            }
            -1 if x - self.x_min > self.deadband => {
                let r = ReversalPoint {
                    index: self.i_min,
                    input: self.x_min,
                    maximum: false,
                };
                self.direction = 1;
                self.i_max = i;
                self.x_max = x;
                Some(r)
            }
            _ => None,
        }
    }
}

/// Indices of the dead-band reversal extrema of `u`, written into `out` (at most `out.len()` are written);
/// returns how many reversals there are in total (which may exceed `out.len()`). `None` for an invalid dead-band.
pub fn find_reversals_into(u: &[f64], deadband: f64, out: &mut [usize]) -> Option<usize> {
    let mut f = ReversalFinder::new(deadband)?;
    let mut count = 0;
    for &x in u {
        if let Some(r) = f.push(x) {
            if let Some(slot) = out.get_mut(count) {
                *slot = r.index;
            }
            count += 1;
        }
    }
    Some(count)
}

/// Streaming reversal-order counter: 0 after a saturation end, +1 at every reversal beyond the dead-band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReversalOrder {
    lo: f64,
    hi: f64,
    deadband: f64,
    saturation_tol: f64,
    order: u32,
    direction: i8,
    extreme: f64,
    started: bool,
}

impl ReversalOrder {
    /// Saturation ends `lo < hi`, dead-band and saturation tolerance (how close to an end counts as reaching
    /// it), all in input units. `None` if any is not finite, `hi <= lo`, the dead-band is not positive or the
    /// tolerance is negative.
    pub fn new(lo: f64, hi: f64, deadband: f64, saturation_tol: f64) -> Option<Self> {
        let finite = lo.is_finite() && hi.is_finite() && deadband.is_finite();
        if !(finite && hi > lo && deadband > 0.0 && saturation_tol >= 0.0) {
            return None;
        }
        Some(ReversalOrder {
            lo,
            hi,
            deadband,
            saturation_tol,
            order: 0,
            direction: 0,
            extreme: 0.0,
            started: false,
        })
    }

    /// Feed the next sample; returns the reversal order of the curve it lies on (NaN keeps the order).
    pub fn push(&mut self, x: f64) -> u32 {
        if x.is_nan() {
            return self.order;
        }
        if !self.started {
            self.started = true;
            self.extreme = x;
        }
        if x >= self.hi - self.saturation_tol || x <= self.lo + self.saturation_tol {
            self.order = 0;
            self.direction = if x >= self.hi - self.saturation_tol {
                1
            } else {
                -1
            };
            self.extreme = x;
        } else if self.direction >= 0 {
            if x > self.extreme {
                self.extreme = x;
                self.direction = 1;
            } else if self.extreme - x > self.deadband {
                // Leaving the (unknown) start downwards is not a reversal.
                if self.direction != 0 {
                    self.order += 1;
                }
                self.direction = -1;
                self.extreme = x;
            }
        } else if x < self.extreme {
            self.extreme = x;
        } else if x - self.extreme > self.deadband {
            self.order += 1;
            self.direction = 1;
            self.extreme = x;
        }
        self.order
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reversals(u: &[f64], db: f64) -> [usize; 16] {
        let mut out = [usize::MAX; 16];
        find_reversals_into(u, db, &mut out).unwrap();
        out
    }

    #[test]
    fn triangle_with_noise_below_the_deadband() {
        // Up to 1.0 (index 4), down to -1.0 (index 9), up again; wiggles of 0.05 inside a 0.1 dead-band.
        let u = [
            0.0, 0.3, 0.6, 0.95, 1.0, 0.96, 0.5, 0.0, -0.5, -1.0, -0.96, -0.99, -0.5, 0.0,
        ];
        let r = reversals(&u, 0.1);
        assert_eq!(&r[..3], &[4, 9, usize::MAX]);
    }

    #[test]
    fn direction_unknown_until_the_deadband_is_left() {
        // Starts flat with a dip smaller than the dead-band, then rises: the start is no reversal.
        let u = [0.0, -0.05, 0.02, 0.5, 1.0, 0.5];
        let r = reversals(&u, 0.1);
        assert_eq!(&r[..2], &[4, usize::MAX]);
        assert!(ReversalFinder::new(0.0).is_none());
        assert!(ReversalFinder::new(f64::NAN).is_none());
    }

    #[test]
    fn counts_beyond_the_output_buffer() {
        let u: [f64; 9] = [0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0];
        let mut out = [0usize; 2];
        assert_eq!(find_reversals_into(&u, 0.5, &mut out), Some(7));
        assert_eq!(out, [1, 2]);
    }

    #[test]
    fn reversal_order_resets_at_saturation() {
        let mut o = ReversalOrder::new(-1.0, 1.0, 0.05, 0.002).unwrap();
        let path = [0.0, 1.0, 0.2, 0.6, 0.3, -1.0, 0.5];
        let got: [u32; 7] = core::array::from_fn(|i| o.push(path[i]));
        assert_eq!(got, [0, 0, 1, 2, 3, 0, 1]);
    }
}
