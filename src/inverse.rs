//! Exact inverse of the CBH operator: the input that makes the next output equal a target.
//!
//! Given the memory, the output as a function of the next input is monotone (rising branches above the current
//! point, falling ones below, each closing exactly on its target). So: pick the direction from the target, walk
//! down the memory levels of that direction until one's output range holds the target (what wiping-out would
//! do), and invert that one branch in closed form inside a table cell. `forward(inverse(T)) = T` to round-off
//! for every reachable `T`; unreachable targets saturate at the input range and are flagged. No allocation.
use crate::cbh::{Hysteresis, Turn, branch_scale, push_reversal};
use crate::everett::{Hit, Strip, StripHint};
use crate::history::Reversal;

/// Result of an inverse query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseInput {
    /// Input (A) that produces the target (or the nearest saturation).
    pub input: f64,
    /// The target lies outside the outputs reachable from this state.
    pub saturated: bool,
    /// The table cell holding `input` when the search found it (the commit's next search hint).
    pub(crate) cell: Option<usize>,
    /// What the answer does to the shortcut (see [`FastBranch`]).
    pub(crate) fast: Shortcut,
    /// The reversal at the current point the search built for a turning answer (the commit pushes it).
    pub(crate) turn: Option<Turn>,
}

/// What an inverse's answer does to the operator's shortcut once committed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Shortcut {
    /// The answer came from the shortcut: it still holds.
    Kept,
    /// A full search found the answer on this branch and cell.
    New(FastBranch),
    /// No shortcut for the next query.
    None,
}

/// The inverse's shortcut: the branch (newest reversal, moving its way) and table cell of the last exact inverse
/// committed. A next target on the same branch whose answer lies in the same cell is inverted with the very
/// arithmetic of the full search (same bits), skipping branch selection and cell search. Held by the operator
/// (not its state) and dropped by every other change of the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FastBranch {
    up: bool,
    len: usize,
    r_y: f64,
    r_k: f64,
    end_u: f64,
    end_y: f64,
    t_tri: f64,
    r_next: f64,
    cell: usize,
    f_lo: f64,
    f_hi: f64,
    g_lo: f64,
    g_hi: f64,
}

impl FastBranch {
    /// The input for `target` from output `y_c`, if it lies on this branch inside this cell.
    #[inline(always)]
    fn invert(&self, target: f64, y_c: f64) -> Option<f64> {
        let (dy, inside) = if self.up {
            (target - self.r_y, target > y_c && target <= self.end_y)
        } else {
            (self.r_y - target, target < y_c && target >= self.end_y)
        };
        if !inside {
            return None;
        }
        let e = dy / self.r_k;
        if !(e > self.t_tri && self.f_lo < e && e <= self.f_hi) {
            return None;
        }
        // `invert_monotone`'s cell interpolation and the clamps of `everett_inverse_cell` and `invert_branch`.
        let t = (e - self.f_lo) / (self.f_hi - self.f_lo);
        let v = (self.g_lo + t.clamp(0.0, 1.0) * (self.g_hi - self.g_lo)).max(self.r_next);
        Some(if self.up {
            v.min(self.end_u)
        } else {
            (-v).max(self.end_u)
        })
    }
}

impl InverseInput {
    pub fn new(input: f64, saturated: bool) -> Self {
        InverseInput {
            input,
            saturated,
            cell: None,
            fast: Shortcut::None,
            turn: None,
        }
    }
}

/// The answer kept on the side of `from_u` the output moves to (`up`: increasing input): the current input, or
/// the input of the last entry wiped out on the way to the branch. Where the tables are flat the branch's first
/// input reaching the target can lie behind it (the output has not changed since); stepping back there would turn
/// the input, or not wipe the entry out, and leave the branch.
#[inline(always)]
fn beyond(input: f64, from_u: f64, up: bool) -> f64 {
    if up {
        input.max(from_u)
    } else {
        input.min(from_u)
    }
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
    #[inline(always)]
    pub fn inverse_input(&self, target: f64) -> InverseInput {
        if target.is_nan() {
            return InverseInput::new(f64::NAN, true);
        }
        let st = &self.state;
        let (u_c, y_c) = (st.u, st.y);
        if target == y_c {
            return InverseInput::new(u_c, false);
        }
        if let Some(f) = &self.fast
            && st.history.len() == f.len
            && st.history.rising() == f.up
            && let Some(input) = f.invert(target, y_c)
        {
            return InverseInput {
                input: beyond(input, u_c, f.up),
                saturated: false,
                cell: Some(f.cell),
                fast: Shortcut::Kept,
                turn: None,
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
        let mut turn = None;
        let virtual_entry;
        // Where the answer may start: the current input on the first level, the input of the entry wiped out to
        // reach each deeper one.
        let mut from_u = u_c;
        let top = h.top();
        let (mut level, mut below): (&Reversal, usize) = if up == h.rising() {
            (top, len - 1)
        } else if u_c == top.u && len > 1 {
            // Never left the newest reversal: turning back just continues the branch below it.
            (h.get(len - 2), len - 2)
        } else if len >= 2 && (if up { target > top.y } else { target < top.y }) {
            // A turn back over the newest entry (a dither): the new reversal's branch ends at that entry's output
            // short of the target, so the search starts on the branch below without building the reversal.
            from_u = top.u;
            (h.get(len - 2), len - 2)
        } else {
            virtual_entry = self.new_reversal_at(u_c, y_c, top, up, h.next_strip_hint());
            turn = Some(Turn {
                reversal: virtual_entry,
                below_u: top.u,
                below_y: top.y,
                up,
            });
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
                let (input, hit) = self.invert_branch(level, target, up, (end_u, end_y));
                // The shortcut holds for the branch of a remembered entry, which the commit's wipe-outs make the
                // newest (its closure target unchanged); not for a reversal the commit has yet to push.
                let fast = match hit {
                    Some((hit, t_tri, r_next))
                        if below < len && level.via.is_none() && level.k > 0.0 =>
                    {
                        let g = if up {
                            self.asc.grid()
                        } else {
                            self.desc.grid()
                        };
                        Shortcut::New(FastBranch {
                            up,
                            len: below + 1,
                            r_y: level.y,
                            r_k: level.k,
                            end_u,
                            end_y,
                            t_tri,
                            r_next,
                            cell: hit.cell,
                            f_lo: hit.f_lo,
                            f_hi: hit.f_hi,
                            g_lo: g[hit.cell],
                            g_hi: g[hit.cell + 1],
                        })
                    }
                    _ => Shortcut::None,
                };
                return InverseInput {
                    input: beyond(input, from_u, up),
                    saturated: false,
                    cell: hit.map(|h| h.0.cell),
                    fast,
                    turn,
                };
            }
            if below < 2 {
                // Past the anchor's branch (up) or the first maximum's (down): saturation.
                let input = if up { self.hi } else { self.lo };
                return InverseInput::new(input, true);
            }
            from_u = end_u;
            level = h.get(below - 2);
            below -= 2;
        }
    }

    /// The reversal `push_reversal` would create at the current point (same arithmetic, no state change).
    fn new_reversal_at(
        &self,
        u: f64,
        y: f64,
        below: &Reversal,
        up: bool,
        strip_hint: StripHint,
    ) -> Reversal {
        // The search starts from the family's hint (the entry below was reached moving that family's way); a
        // hint only speeds the search, the cell is the same.
        let mut hint = if up {
            self.state.hint_a
        } else {
            self.state.hint_d
        };
        if up {
            let strip: Strip = self.asc.strip_hinted(u, strip_hint);
            let e = self.asc.everett(&strip, below.u, &mut hint);
            Reversal::scaled(u, y, strip, branch_scale(below.y - y, e))
        } else {
            let strip = self.desc.strip_hinted(-u, strip_hint);
            let e = self.desc.everett(&strip, -below.u, &mut hint);
            Reversal::scaled(u, y, strip, branch_scale(y - below.y, e))
        }
    }

    /// Input on `r`'s branch where the output equals `target` (inside the branch's output range); `end` is the
    /// branch's closure target `(input, output)`. With the input, the table cell it was found in (for the
    /// shortcut; None for straight pieces and flat tables).
    #[inline(always)]
    fn invert_branch(
        &self,
        r: &Reversal,
        target: f64,
        up: bool,
        end: (f64, f64),
    ) -> (f64, Option<(Hit, f64, f64)>) {
        let end_u = end.0;
        // Straight-line pieces (see `Reversal::linear`) invert in closed form.
        let second = matches!(r.via, Some(v) if (up && target > v.y) || (!up && target < v.y));
        match r.via {
            Some(v) if second && v.linear => {
                return (line_inverse(v.u, v.y, end.0, end.1, target), None);
            }
            Some(v) if !second && r.linear => {
                return (line_inverse(r.u, r.y, v.u, v.y, target), None);
            }
            None if r.linear => return (line_inverse(r.u, r.y, end.0, end.1, target), None),
            _ => {}
        }
        // Increment along the branch, in the family's rising orientation, and the input where the piece ends.
        let dy = if up { target - r.y } else { r.y - target };
        let (e, piece_end) = match r.via {
            Some(v) if second => {
                let e = if v.k > 0.0 {
                    v.e + (if up { target - v.y } else { v.y - target }) / v.k
                } else {
                    f64::INFINITY
                };
                (e, end_u)
            }
            // The first piece ends at the via point: a target at its output must not search past it (round-off
            // can put `dy / k` a hair above `v.e`, and where the table is flat beyond `v` the search would run on
            // to the closure target).
            Some(v) => (if r.k > 0.0 { (dy / r.k).min(v.e) } else { v.e }, v.u),
            None => (if r.k > 0.0 { dy / r.k } else { f64::INFINITY }, end_u),
        };
        if e.is_infinite() {
            return (piece_end, None);
        }
        let s = &r.strip;
        let tri = s.tri;
        if up {
            let (u, hit) = self.asc.everett_inverse_cell(s, e, self.state.hint_a);
            (u.min(piece_end), hit.map(|h| (h, tri, s.r_next)))
        } else {
            let (u, hit) = self.desc.everett_inverse_cell(s, e, self.state.hint_d);
            ((-u).max(piece_end), hit.map(|h| (h, tri, s.r_next)))
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
            self.commit(inv.input, target, &inv);
        }
        inv
    }

    /// Apply input `u` whose output `y` is already known (from the exact inverse): the memory update of `step`
    /// without evaluating the branch again.
    /// `inv`: the inverse's answer it comes from (its cell, shortcut and turn).
    #[inline(always)]
    pub(crate) fn commit(&mut self, u: f64, y: f64, inv: &InverseInput) {
        let (cell, fast) = (inv.cell, inv.fast);
        // Inside the range already (the inverse's answers are); NaN never reaches here.
        let u = if u < self.lo {
            self.lo
        } else if u > self.hi {
            self.hi
        } else {
            u
        };
        // An answer from the shortcut moves along the newest branch its way, so it cannot turn; strictly before the
        // branch's closure target it wipes nothing out either, and the memory update is a no-op.
        let on_branch = matches!(fast, Shortcut::Kept)
            && self
                .fast
                .is_some_and(|f| if f.up { u < f.end_u } else { u > f.end_u });
        if !on_branch {
            self.advance(u, inv.turn.as_ref());
        }
        // Keep the search hint on the input's cell: the next inverse starts there (the inverse usually knows it).
        let st = &mut self.state;
        let hint = if st.history.rising() {
            &mut st.hint_a
        } else {
            &mut st.hint_d
        };
        match cell {
            Some(k) => *hint = k,
            None if st.history.rising() => {
                self.asc.locate(u, &mut st.hint_a);
            }
            None => {
                self.desc.locate(-u, &mut st.hint_d);
            }
        }
        st.u = u;
        st.y = y;
        // The shortcut holds while the branch it was made for is still the newest (no wipe-out on the way).
        match fast {
            Shortcut::Kept => {}
            Shortcut::New(f) if f.len == st.history.len() => self.fast = Some(f),
            _ => self.fast = None,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::{BuildOptions, Hysteresis, Initial};
    use preisach_plant::{Rng, measure_first_order};

    /// The reversal the inverse built and the commit or step pushes is the one `push_reversal` would build: two
    /// operators driven alike, one given the inverse's answers whole and one with their reversal dropped, stay
    /// equal to the bit. The targets jitter around a slow ramp (a reversal every few samples) and some steps go
    /// to a limited input instead of the answer (the compensator's limited path), through merges of a full memory.
    #[test]
    fn reusing_the_inverse_s_reversal_changes_no_bit() {
        let (asc, desc) = measure_first_order(40, 9);
        let (a, d): (Vec<_>, Vec<_>) = (asc, desc);
        let mut with = Hysteresis::<Vec<f64>, 8>::from_curve_data(
            &a,
            &d,
            &BuildOptions::default(),
            Initial::Negative,
        )
        .unwrap();
        let mut without = with.clone();
        let (lo, hi) = with.output_range();
        let mut rng = Rng(7);
        let mut turns = 0;
        for i in 0..20_000 {
            let slow = 0.8 * libm::sin(i as f64 * 0.003);
            let target = lo + (hi - lo) * (0.5 + 0.5 * slow + 0.02 * (rng.uniform() - 0.5));
            let inv = with.inverse_input(target);
            let mut bare = inv;
            bare.turn = None;
            turns += usize::from(inv.turn.is_some());
            if i % 7 == 3 || inv.saturated {
                let u = 0.97 * inv.input;
                with.step_made(u, inv.turn.as_ref());
                without.step(u);
            } else {
                with.commit(inv.input, target, &inv);
                without.commit(inv.input, target, &bare);
            }
            assert_eq!(
                with.snapshot().to_words(),
                without.snapshot().to_words(),
                "sample {i}"
            );
        }
        assert!(
            turns > 2_000,
            "only {turns} turning answers: the test does not exercise the reuse"
        );
    }

    /// Under a dither (a target that reverses at almost every sample, as noisy feedback makes it) every reversal
    /// pushed, its strip searched from the strip of the entry of its kind before it and its scale from the cell
    /// hints, is the one the operator rebuilds afresh from the remembered points alone (`state_from_words`
    /// searches every strip and cell from nothing): the whole state to the bit after every sample, through the
    /// exact inverse's commits, steps to limited inputs and merges of a full memory.
    #[test]
    fn a_dither_s_reversals_are_those_built_afresh() {
        let (a, d) = measure_first_order(40, 9);
        let mut op = Hysteresis::<Vec<f64>, 8>::from_curve_data(
            &a,
            &d,
            &BuildOptions::default(),
            Initial::Negative,
        )
        .unwrap();
        let (lo, hi) = op.output_range();
        let mut rng = Rng(11);
        let (mut reversals, mut full) = (0, 0);
        for i in 0..20_000 {
            let slow = 0.8 * libm::sin(i as f64 * 0.002);
            let target = lo + (hi - lo) * (0.5 + 0.5 * slow + 0.01 * (rng.uniform() - 0.5));
            let before = op.state().history().len();
            let inv = op.inverse_input(target);
            if i % 5 == 2 || inv.saturated {
                op.step_made(0.98 * inv.input, inv.turn.as_ref());
            } else {
                op.commit(inv.input, target, &inv);
            }
            let len = op.state().history().len();
            reversals += usize::from(len > before);
            full += usize::from(len == 8);
            // Every remembered entry whole (strip, scales, second piece); the words hold the rest of the state.
            let afresh = op.state_from_words(&op.snapshot().to_words()).unwrap();
            assert_eq!(
                format!("{:?}", afresh.history().entries()),
                format!("{:?}", op.state().history().entries()),
                "sample {i}"
            );
        }
        assert!(
            reversals > 5_000 && full > 500,
            "{reversals} reversals, {full} samples at a full memory: the test does not exercise the dither"
        );
    }
}
