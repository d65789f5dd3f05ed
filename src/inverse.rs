//! Exact inverse of the CBH operator: the input that makes the next output equal a target.
//!
//! Given the memory, the output as a function of the next input is monotone (rising branches above the current
//! point, falling ones below, each closing exactly on its target). So: pick the direction from the target, walk
//! down the memory levels of that direction until one's output range holds the target (what wiping-out would
//! do), and invert that one branch in closed form inside a table cell. `forward(inverse(T)) = T` to round-off
//! for every reachable `T`; unreachable targets saturate at the input range and are flagged. No allocation.
use crate::cbh::{Hysteresis, branch_scale, push_reversal};
use crate::everett::Strip;
use crate::history::Reversal;

/// Result of an inverse query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseInput {
    /// Input (A) that produces the target (or the nearest saturation).
    pub input: f64,
    /// The target lies outside the outputs reachable from this state.
    pub saturated: bool,
}

/// Input where the straight line from `(u0, y0)` to `(u1, y1)` reaches `target` (clamped to the segment).
fn line_inverse(u0: f64, y0: f64, u1: f64, y1: f64, target: f64) -> f64 {
    if y1 == y0 {
        return u1;
    }
    u0 + (u1 - u0) * ((target - y0) / (y1 - y0)).clamp(0.0, 1.0)
}

impl<S: AsRef<[f64]>, const N: usize> Hysteresis<S, N> {
    /// The input whose `step` would output `target`, without changing the state. NaN target → NaN input.
    pub fn inverse_input(&self, target: f64) -> InverseInput {
        if target.is_nan() {
            return InverseInput {
                input: f64::NAN,
                saturated: true,
            };
        }
        let st = &self.state;
        let (u_c, y_c) = (st.u, st.y);
        if target == y_c {
            return InverseInput {
                input: u_c,
                saturated: false,
            };
        }
        let up = target > y_c;
        // The branch that leaves the current point in the wanted direction: the newest entry if we already move
        // that way, else a new reversal at the current point whose target is the newest entry. When the memory is
        // full that push merges a pair first, so it is made on a copy of the state (a plain copy, no allocation).
        let scratch;
        let turning = up != st.history.rising();
        let h = if turning
            && st.history.is_full()
            && !(u_c == st.history.top().u && st.history.len() > 1)
        {
            let mut s = *st;
            push_reversal(&self.asc, &self.desc, &mut s, (self.hi, self.y_hi));
            scratch = s;
            &scratch.history
        } else {
            &st.history
        };
        let len = h.len();
        let virtual_entry;
        let (mut level, mut below): (&Reversal, usize) = if up == h.rising() {
            (h.top(), len - 1)
        } else if u_c == h.top().u && len > 1 {
            // Never left the newest reversal: turning back just continues the branch below it.
            (h.get(len - 2), len - 2)
        } else {
            virtual_entry = self.new_reversal_at(u_c, y_c, h.top(), up);
            (&virtual_entry, len)
        };
        loop {
            // Closure target of `level`: the entry below it, or positive saturation for the anchor.
            let (end_u, end_y) = if below >= 1 {
                let t = h.get(below - 1);
                (t.u, t.y)
            } else {
                (self.hi, self.y_hi)
            };
            let inside = if up { target <= end_y } else { target >= end_y };
            if inside {
                return InverseInput {
                    input: self.invert_branch(level, target, up, (end_u, end_y)),
                    saturated: false,
                };
            }
            if below < 2 {
                // Past the anchor's branch (up) or the first maximum's (down): saturation.
                let input = if up { self.hi } else { self.lo };
                return InverseInput {
                    input,
                    saturated: true,
                };
            }
            level = h.get(below - 2);
            below -= 2;
        }
    }

    /// The reversal `push_reversal` would create at the current point (same arithmetic, no state change).
    fn new_reversal_at(&self, u: f64, y: f64, below: &Reversal, up: bool) -> Reversal {
        let mut hint = 0;
        if up {
            let strip: Strip = self.asc.strip(u);
            let e = self.asc.everett(&strip, below.u, &mut hint);
            Reversal::scaled(u, y, strip, branch_scale(below.y - y, e))
        } else {
            let strip = self.desc.strip(-u);
            let e = self.desc.everett(&strip, -below.u, &mut hint);
            Reversal::scaled(u, y, strip, branch_scale(y - below.y, e))
        }
    }

    /// Input on `r`'s branch where the output equals `target` (inside the branch's output range); `end` is the
    /// branch's closure target `(input, output)`.
    fn invert_branch(&self, r: &Reversal, target: f64, up: bool, end: (f64, f64)) -> f64 {
        let end_u = end.0;
        // Straight-line pieces (see `Reversal::linear`) invert in closed form.
        let second = matches!(r.via, Some(v) if (up && target > v.y) || (!up && target < v.y));
        match r.via {
            Some(v) if second && v.linear => return line_inverse(v.u, v.y, end.0, end.1, target),
            Some(v) if !second && r.linear => return line_inverse(r.u, r.y, v.u, v.y, target),
            None if r.linear => return line_inverse(r.u, r.y, end.0, end.1, target),
            _ => {}
        }
        // Increment along the branch, in the family's rising orientation.
        let dy = if up { target - r.y } else { r.y - target };
        let e = match r.via {
            Some(v) if second => {
                if v.k > 0.0 {
                    v.e + (if up { target - v.y } else { v.y - target }) / v.k
                } else {
                    f64::INFINITY
                }
            }
            _ => {
                if r.k > 0.0 {
                    dy / r.k
                } else {
                    f64::INFINITY
                }
            }
        };
        if up {
            if e.is_infinite() {
                return end_u;
            }
            self.asc
                .everett_inverse(&r.strip, e, self.state.hint_a)
                .min(end_u)
        } else {
            if e.is_infinite() {
                return end_u;
            }
            (-self.desc.everett_inverse(&r.strip, e, self.state.hint_d)).max(end_u)
        }
    }

    /// Drive the output to `target`: find the input with [`Self::inverse_input`] and commit it. A reachable target
    /// becomes the output exactly (the branch is not evaluated again); a saturated one is stepped to.
    pub fn step_inverse(&mut self, target: f64) -> InverseInput {
        let inv = self.inverse_input(target);
        if inv.saturated {
            if !inv.input.is_nan() {
                self.step(inv.input);
            }
        } else {
            self.commit(inv.input, target);
        }
        inv
    }

    /// Apply input `u` whose output `y` is already known (from the exact inverse): the memory update of `step`
    /// without evaluating the branch again.
    #[inline]
    pub(crate) fn commit(&mut self, u: f64, y: f64) {
        let u = u.clamp(self.lo, self.hi);
        self.advance(u);
        // Keep the search hint on the input's cell: the next inverse starts there.
        let st = &mut self.state;
        if st.history.rising() {
            self.asc.locate(u, &mut st.hint_a);
        } else {
            self.desc.locate(-u, &mut st.hint_d);
        }
        st.u = u;
        st.y = y;
    }
}
