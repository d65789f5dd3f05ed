//! The congruency-based hysteresis (CBH) operator: first-order curve tables + extrema memory → output.
//!
//! Rising from the newest minimum `m`: `y = y(m) + k·E^a(m, u)`; falling from the newest maximum `M`:
//! `y = y(M) − k·E^d(M, u)` (paper eq 12 and 16, docs/architecture.md §2.2). `k = 1` for tables whose two families agree
//! (Preisach data); otherwise `k` scales the branch so that it closes exactly on the stored output of its target,
//! which keeps the output continuous and monotone in the input when the measured families disagree.
//! Inputs outside the table range saturate at its ends. `step` is `O(log nodes)`, allocation-free and
//! deterministic to the bit.
use crate::error::{FamilyKind, TableError};
use crate::everett::Family;
use crate::history::{History, Reversal, Via};

/// Where the operator starts (or is reset to).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Initial {
    /// After negative saturation: at the lowest input, on the ascending major branch.
    Negative,
    /// After positive saturation: at the highest input, on the descending major branch.
    Positive,
    /// At this input on the ascending major branch (negative saturation, then up to it).
    Ascending(f64),
    /// At this input on the descending major branch (positive saturation, then down to it).
    Descending(f64),
}

/// Everything that evolves: memory, current input and output. A plain `Copy` value: snapshot/restore is a copy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State<const N: usize> {
    pub(crate) history: History<N>,
    pub(crate) u: f64,
    pub(crate) y: f64,
    pub(crate) hint_a: usize,
    pub(crate) hint_d: usize,
    fingerprint: u64,
}

impl<const N: usize> State<N> {
    /// Current (clamped) input.
    pub fn input(&self) -> f64 {
        self.u
    }
    /// Current output.
    pub fn output(&self) -> f64 {
        self.y
    }
    /// The remembered reversal points `(input, output)`, oldest (the saturation anchor) first.
    pub fn memory(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.history.entries().iter().map(|r| (r.u, r.y))
    }
    pub fn history(&self) -> &History<N> {
        &self.history
    }
}

/// The CBH operator over table storage `S` with a memory of at most `N` reversal points.
#[derive(Debug, Clone)]
pub struct Hysteresis<S, const N: usize> {
    pub(crate) asc: Family<S>,
    pub(crate) desc: Family<S>,
    pub(crate) y_lo: f64,
    pub(crate) y_hi: f64,
    pub(crate) lo: f64,
    pub(crate) hi: f64,
    pub(crate) anchor: Reversal,
    fingerprint: u64,
    pub(crate) state: State<N>,
    /// The exact inverse's shortcut for the branch and cell of its last committed answer (see
    /// `inverse::FastBranch`); dropped by every other change of the state.
    pub(crate) fast: Option<crate::inverse::FastBranch>,
}

impl<S: AsRef<[f64]>, const N: usize> Hysteresis<S, N> {
    /// Combine two validated families (descending in rising orientation, see [`crate::everett`]) with the
    /// major-loop outputs `y_lo` (negative saturation) and `y_hi` (positive saturation).
    pub fn new(
        asc: Family<S>,
        desc: Family<S>,
        y_lo: f64,
        y_hi: f64,
        initial: Initial,
    ) -> Result<Self, TableError> {
        if asc.kind() != FamilyKind::Ascending || desc.kind() != FamilyKind::Descending {
            return Err(TableError::BadTable {
                family: asc.kind(),
                what: "families passed in the wrong order",
                index: 0,
            });
        }
        let (lo, hi) = (asc.lo(), asc.hi());
        if desc.lo() != -hi || desc.hi() != -lo {
            return Err(TableError::BadTable {
                family: FamilyKind::Descending,
                what: "input range differs from the ascending family's",
                index: 0,
            });
        }
        if !(y_lo.is_finite() && y_hi.is_finite() && y_hi > y_lo) {
            return Err(TableError::NoOutputSpan { lo: y_lo, hi: y_hi });
        }
        for (name, value) in [("y_lo", y_lo), ("y_hi", y_hi)] {
            if value.abs() > crate::limits::MAX_MAGNITUDE {
                return Err(TableError::BadParameter { name, value });
            }
        }
        let strip = asc.strip(lo);
        let e_top = asc.everett_max(&strip);
        let k = branch_scale(y_hi - y_lo, e_top);
        let anchor = Reversal {
            u: lo,
            y: y_lo,
            k: k.unwrap_or(1.0),
            strip,
            via: None,
            linear: k.is_none(),
        };
        let fingerprint = fingerprint(&asc, &desc, y_lo, y_hi);
        let state = State {
            history: History::new(anchor),
            u: lo,
            y: y_lo,
            hint_a: 0,
            hint_d: 0,
            fingerprint,
        };
        let mut h = Hysteresis {
            asc,
            desc,
            y_lo,
            y_hi,
            lo,
            hi,
            anchor,
            fingerprint,
            state,
            fast: None,
        };
        h.reset(initial);
        Ok(h)
    }

    /// `(lowest, highest)` input of the table; inputs outside saturate.
    pub fn input_range(&self) -> (f64, f64) {
        (self.lo, self.hi)
    }
    /// `(output at negative saturation, output at positive saturation)`.
    pub fn output_range(&self) -> (f64, f64) {
        (self.y_lo, self.y_hi)
    }
    pub fn ascending(&self) -> &Family<S> {
        &self.asc
    }
    pub fn descending(&self) -> &Family<S> {
        &self.desc
    }
    /// The round-off an input carries at the scale of the input range (16 ulps of its larger end): where a branch
    /// is steeper than the tables can resolve, outputs are exact only to the change this much input makes.
    pub fn input_round_off(&self) -> f64 {
        16.0 * f64::EPSILON * self.lo.abs().max(self.hi.abs())
    }

    pub fn state(&self) -> &State<N> {
        &self.state
    }
    /// Current output.
    pub fn output(&self) -> f64 {
        self.state.y
    }
    /// A copy of the state (no allocation).
    pub fn snapshot(&self) -> State<N> {
        self.state
    }
    /// Return to a snapshot of this operator (or of one with identical tables).
    pub fn restore(&mut self, s: &State<N>) -> Result<(), TableError> {
        if s.fingerprint != self.fingerprint {
            return Err(TableError::ForeignState);
        }
        self.state = *s;
        self.fast = None;
        Ok(())
    }

    /// Forget all memory and start from `initial`. A major-branch input outside the range saturates.
    pub fn reset(&mut self, initial: Initial) {
        self.fast = None;
        let st = &mut self.state;
        st.history = History::new(self.anchor);
        st.u = self.lo;
        st.y = self.y_lo;
        match initial {
            Initial::Negative => {}
            Initial::Positive => self.saturate_positive(),
            Initial::Ascending(u) => {
                self.step(u);
            }
            Initial::Descending(u) => {
                self.saturate_positive();
                self.step(u);
            }
        }
    }

    /// Positive saturation with the descending major branch ahead.
    fn saturate_positive(&mut self) {
        self.step(self.hi);
        self.state.y = self.y_hi;
        self.push_reversal();
    }

    /// Apply input `u` and return the output. A NaN input leaves the memory untouched and returns NaN; infinite
    /// or out-of-range inputs saturate.
    #[inline]
    pub fn step(&mut self, u: f64) -> f64 {
        self.step_made(u, None)
    }

    /// [`Self::step`] with the reversal at the current point an exact inverse already built (`made`, pushed if
    /// this step turns there the same way).
    #[inline]
    pub(crate) fn step_made(&mut self, u: f64, made: Option<&Turn>) -> f64 {
        if u.is_nan() {
            return f64::NAN;
        }
        let u = u.clamp(self.lo, self.hi);
        self.fast = None;
        self.advance(u, made);
        let y = self.branch_output(u);
        self.state.u = u;
        self.state.y = y;
        y
    }

    /// Feed `inputs` through `step`, writing into `out` (same length; extra elements untouched).
    pub fn run_into(&mut self, inputs: &[f64], out: &mut [f64]) {
        for (o, &u) in out.iter_mut().zip(inputs) {
            *o = self.step(u);
        }
    }

    /// Update the memory for the move from the current input to `u`: a reversal if the direction changes, then
    /// wiping-out of every pair whose closure target the input passes.
    /// `made`: the reversal at the current point an exact inverse already built (used if it still fits).
    #[inline]
    pub(crate) fn advance(&mut self, u: f64, made: Option<&Turn>) {
        let h = &self.state.history;
        let cur = self.state.u;
        let rising = h.rising();
        if (rising && u < cur) || (!rising && u > cur) {
            let top = h.top().u;
            // A turn whose input passes the newest entry at once (a dither back over the last reversal): the new
            // reversal would be pushed and wiped out with that entry in the same step, so only the entry goes. A
            // full memory merges before it pushes, so it takes the long way.
            if h.len() >= 2 && !h.is_full() && (if rising { u <= top } else { u >= top }) {
                self.state.history.pop(1);
            } else {
                self.turn(made);
            }
        }
        self.wipe_out(u);
    }

    /// The direction changes at the current point: remember it, unless we never left the newest reversal.
    pub(crate) fn turn(&mut self, made: Option<&Turn>) {
        if self.state.u == self.state.history.top().u && self.state.history.len() > 1 {
            self.state.history.pop(1);
        } else {
            push_reversal_made(
                &self.asc,
                &self.desc,
                &mut self.state,
                (self.hi, self.y_hi),
                made,
            );
        }
    }

    #[inline]
    pub(crate) fn wipe_out(&mut self, u: f64) {
        loop {
            let h = &self.state.history;
            let Some(target) = h.target() else { return };
            let passed = if h.rising() {
                u >= target.u
            } else {
                u <= target.u
            };
            if !passed {
                return;
            }
            let n = if h.len() == 2 { 1 } else { 2 };
            self.state.history.pop(n);
        }
    }

    /// Push the current point as a reversal (a maximum if rising until now, else a minimum).
    pub(crate) fn push_reversal(&mut self) {
        push_reversal(&self.asc, &self.desc, &mut self.state, (self.hi, self.y_hi));
    }

    /// Output on the branch leaving the newest reversal, at input `u` (inside its range).
    #[inline]
    pub(crate) fn branch_output(&mut self, u: f64) -> f64 {
        let st = &mut self.state;
        let rising = st.history.rising();
        let top = st.history.top();
        if rising && u >= self.hi && st.history.len() == 1 {
            return self.y_hi; // positive saturation is exact, like the negative one
        }
        // Closure target of the newest entry (positive saturation for the anchor).
        let end = || {
            st.history
                .target()
                .map_or((self.hi, self.y_hi), |t| (t.u, t.y))
        };
        match top.via {
            Some(v) if (rising && u > v.u) || (!rising && u < v.u) => {
                if v.linear {
                    let (tu, ty) = end();
                    return line(v.u, v.y, tu, ty, u);
                }
                let e = if rising {
                    self.asc.everett(&top.strip, u, &mut st.hint_a)
                } else {
                    self.desc.everett(&top.strip, -u, &mut st.hint_d)
                };
                if rising {
                    v.y + v.k * (e - v.e)
                } else {
                    v.y - v.k * (e - v.e)
                }
            }
            via => {
                if top.linear {
                    let (tu, ty) = via.map_or_else(end, |v| (v.u, v.y));
                    return line(top.u, top.y, tu, ty, u);
                }
                if rising {
                    top.y + top.k * self.asc.everett(&top.strip, u, &mut st.hint_a)
                } else {
                    top.y - top.k * self.desc.everett(&top.strip, -u, &mut st.hint_d)
                }
            }
        }
    }
}

/// First word of a serialised [`State`] (format tag and version).
const STATE_TAG: u64 = 0x626d_725f_7374_0003;
/// Words before the memory entries: tag, fingerprint, length, input, output, two hints.
const STATE_HEADER: usize = 7;
/// Words per memory entry: input, output, second-piece flag and the second piece's start `(input, output)`.
const ENTRY_WORDS: usize = 5;

#[cfg(feature = "alloc")]
impl<const N: usize> State<N> {
    /// The state as plain words (for pickling and files); [`Hysteresis::state_from_words`] reads it back bit for
    /// bit. Only points are stored: where each sits in its table and the scales of its branch pieces are
    /// recomputed from the tables, exactly as they were made.
    pub fn to_words(&self) -> alloc::vec::Vec<u64> {
        let mut w = alloc::vec::Vec::with_capacity(STATE_HEADER + ENTRY_WORDS * self.history.len());
        w.extend([
            STATE_TAG,
            self.fingerprint,
            self.history.len() as u64,
            self.u.to_bits(),
            self.y.to_bits(),
            self.hint_a as u64,
            self.hint_d as u64,
        ]);
        for r in self.history.entries() {
            w.extend([r.u.to_bits(), r.y.to_bits()]);
            match r.via {
                None => w.extend([0, 0, 0]),
                Some(v) => w.extend([1, v.u.to_bits(), v.y.to_bits()]),
            }
        }
        w
    }
}

/// Input and output stored in serialised state words, and the memory length (`None` if the words are not a
/// state).
pub fn state_words_io(words: &[u64]) -> Option<(f64, f64, usize)> {
    if words.len() < STATE_HEADER || words[0] != STATE_TAG {
        return None;
    }
    Some((
        f64::from_bits(words[3]),
        f64::from_bits(words[4]),
        usize::try_from(words[2]).unwrap_or(usize::MAX),
    ))
}

impl<S: AsRef<[f64]>, const N: usize> Hysteresis<S, N> {
    /// Read back a state written by [`State::to_words`] from an operator with the same tables. Everything is
    /// checked: format, tables, memory length, the saturation anchor, finite points inside the input and output
    /// ranges, alternating and nested reversals (each inside its neighbours), second-piece points on their
    /// branches, and the current output on the current branch. Branch scales are recomputed from the tables, so
    /// every branch runs monotonically between checked points: a damaged or forged state gives an error or
    /// outputs inside the major loop, never an index outside the tables.
    pub fn state_from_words(&self, w: &[u64]) -> Result<State<N>, TableError> {
        let bad = |what| Err(TableError::BadState { what });
        if w.len() < STATE_HEADER || w[0] != STATE_TAG {
            return bad("not a serialised operator state");
        }
        if w[1] != self.fingerprint {
            return Err(TableError::ForeignState);
        }
        let len = match usize::try_from(w[2]) {
            Ok(len) if (1..=N).contains(&len) => len,
            _ => return bad("memory length outside 1..=capacity"),
        };
        if w.len() != STATE_HEADER + ENTRY_WORDS * len {
            return bad("word count does not match the memory length");
        }
        let f = f64::from_bits;
        // Outputs may pass the major-loop ends by round-off.
        let slack = 1e-9 * (self.y_hi - self.y_lo);
        let point_ok = |u: f64, y: f64| {
            u >= self.lo && u <= self.hi && y >= self.y_lo - slack && y <= self.y_hi + slack
        };
        // `x` lies between `a` and `b` (either order), ends included; outputs with the round-off slack.
        let between = |x: f64, a: f64, b: f64| x >= a.min(b) && x <= a.max(b);
        let between_y = |y: f64, a: f64, b: f64| y >= a.min(b) - slack && y <= a.max(b) + slack;
        let saturation = (self.hi, self.y_hi);
        let mut history = History::new(self.anchor);
        for i in 0..len {
            let e = &w[STATE_HEADER + ENTRY_WORDS * i..STATE_HEADER + ENTRY_WORDS * (i + 1)];
            let (u, y) = (f(e[0]), f(e[1]));
            let via_point = match e[2] {
                0 => None,
                1 => Some((f(e[3]), f(e[4]))),
                _ => return bad("second branch piece flag"),
            };
            let below = if i == 0 {
                saturation
            } else {
                let b = history.top();
                (b.u, b.y)
            };
            if i == 0 {
                if (u, y) != (self.anchor.u, self.anchor.y) {
                    return bad("first memory entry is not the saturation anchor");
                }
            } else {
                if !point_ok(u, y) {
                    return bad("memory entry outside the table's input or output range");
                }
                // Entry i sits between the one below it and that one's closure target.
                let outer = if i >= 2 {
                    let t = history.get(i - 2);
                    (t.u, t.y)
                } else {
                    saturation
                };
                if !(between(u, below.0, outer.0) && between_y(y, below.1, outer.1)) {
                    return bad("memory entries are not nested reversals");
                }
            }
            let strip = if i == 0 {
                self.anchor.strip
            } else if i % 2 == 1 {
                self.desc.strip(-u)
            } else {
                self.asc.strip(u)
            };
            let mut r = Reversal::scaled(u, y, strip, None);
            let first_to = match via_point {
                Some((vu, vy)) => {
                    if !(point_ok(vu, vy) && between(vu, u, below.0) && between_y(vy, y, below.1)) {
                        return bad("second branch piece outside its branch");
                    }
                    r.via = Some(second_piece(&self.asc, &self.desc, &r, (vu, vy), below));
                    (vu, vy)
                }
                None => below,
            };
            if i == 0 && via_point.is_none() {
                r = self.anchor;
            } else {
                let k = first_piece_scale(&self.asc, &self.desc, &r, first_to, 0);
                r.k = k.unwrap_or(1.0);
                r.linear = k.is_none();
            }
            if i == 0 {
                *history.get_mut(0) = r;
            } else {
                history.push(r);
            }
        }
        // Hints only speed searches up; keep them inside each family's cells all the same.
        let hint = |x: u64, fam: &Family<S>| {
            usize::try_from(x)
                .unwrap_or(usize::MAX)
                .min(fam.nodes() - 2)
        };
        let st = State {
            history,
            u: f(w[3]),
            y: f(w[4]),
            hint_a: hint(w[5], &self.asc),
            hint_d: hint(w[6], &self.desc),
            fingerprint: self.fingerprint,
        };
        // The current point lies on the newest entry's branch, between it and its closure target.
        let top = *st.history.top();
        let end = st.history.target().map_or(saturation, |t| (t.u, t.y));
        if !(point_ok(st.u, st.y) && between(st.u, top.u, end.0)) {
            return bad("current point outside the newest branch");
        }
        let mut probe = Hysteresis {
            asc: self.asc.view(),
            desc: self.desc.view(),
            y_lo: self.y_lo,
            y_hi: self.y_hi,
            lo: self.lo,
            hi: self.hi,
            anchor: self.anchor,
            fingerprint: self.fingerprint,
            state: st,
            fast: None,
        };
        let on_branch = probe.branch_output(st.u);
        let off = (on_branch - st.y).abs();
        // Where a branch is so steep that the input's own rounding moves its output further (a near-jump of the
        // tables), the exact inverse's committed output is only exact to that rounding: the branch's outputs a few
        // ulps of the input either side must bracket it.
        let d = self.input_round_off();
        let (b_lo, b_hi) = (top.u.min(end.0), top.u.max(end.0));
        let on = off <= slack || {
            let a = probe.branch_output((st.u - d).clamp(b_lo, b_hi));
            let b = probe.branch_output((st.u + d).clamp(b_lo, b_hi));
            a.min(b) - slack <= st.y && st.y <= a.max(b) + slack
        };
        if off.is_nan() || !on {
            return bad("current output is not on the newest branch");
        }
        Ok(st)
    }
}

/// Push the state's current point as a reversal, merging first when the memory is full. `saturation` is the
/// anchor's closure target `(hi, y_hi)`.
pub(crate) fn push_reversal<S: AsRef<[f64]>, const N: usize>(
    asc: &Family<S>,
    desc: &Family<S>,
    st: &mut State<N>,
    saturation: (f64, f64),
) {
    push_reversal_made(asc, desc, st, saturation, None);
}

/// A reversal at a point, as [`push_reversal`] would make it, with what it was made from: the entry below it and
/// the direction of its branch. The exact inverse builds it to search the new branch; the commit that follows
/// pushes it instead of building it again (the strip search and the scale are most of a reversal's cost).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Turn {
    pub reversal: Reversal,
    pub below_u: f64,
    pub below_y: f64,
    /// The new branch rises (the reversal is a minimum).
    pub up: bool,
}

impl Turn {
    /// Whether this is bit for bit the reversal [`push_reversal`] makes at `(u, y)` above `below` with the
    /// history moving `rising` until now: the same point, the same entry below, the strip of the same family and
    /// the scale towards `below` taken the same way.
    #[inline]
    fn fits(&self, u: f64, y: f64, below: &Reversal, rising: bool) -> bool {
        let r = &self.reversal;
        self.up != rising
            && (below.u > u) == self.up
            && r.u.to_bits() == u.to_bits()
            && r.y.to_bits() == y.to_bits()
            && self.below_u.to_bits() == below.u.to_bits()
            && self.below_y.to_bits() == below.y.to_bits()
    }
}

/// [`push_reversal`], taking `made` instead of building the reversal when it fits (see [`Turn::fits`]).
pub(crate) fn push_reversal_made<S: AsRef<[f64]>, const N: usize>(
    asc: &Family<S>,
    desc: &Family<S>,
    st: &mut State<N>,
    saturation: (f64, f64),
    made: Option<&Turn>,
) {
    if st.history.is_full() {
        merge(asc, desc, &mut st.history, saturation);
    }
    let (u, y) = (st.u, st.y);
    let below = *st.history.top();
    if let Some(t) = made
        && t.fits(u, y, &below, st.history.rising())
    {
        st.history.push(t.reversal);
        return;
    }
    // A maximum if rising until now (its branch follows the descending family), else a minimum. That family's cell
    // hint was left where the branch last moved its way, towards the entry below, where the scale is taken (hints
    // change no cell, no strip, so no bit).
    let hint = st.history.next_strip_hint();
    let (strip, cell) = if st.history.rising() {
        (desc.strip_hinted(-u, hint), st.hint_d)
    } else {
        (asc.strip_hinted(u, hint), st.hint_a)
    };
    let mut r = Reversal::scaled(u, y, strip, None);
    let k = first_piece_scale(asc, desc, &r, (below.u, below.y), cell);
    r.k = k.unwrap_or(1.0);
    r.linear = k.is_none();
    st.history.push(r);
}

/// Make room for one entry in a full memory by merging away the interior pair `(j, j+1)` chosen by
/// [`History::merge_candidate`]. Entry `j+2` keeps its branch up to the old target `j+1`, then follows a second
/// piece scaled to close on its new target `j-1`. Entry `j-1`, whose branch is only ever followed again from
/// `j+2`'s input on (after `j+2` is wiped out), now runs through `j+2`'s point and then closes on its own target.
/// No stored output changes, and the output stays continuous at every later wipe-out, of `j+2` and of `j-1`; only
/// the shape between the targets is approximated.
fn merge<S: AsRef<[f64]>, const N: usize>(
    asc: &Family<S>,
    desc: &Family<S>,
    h: &mut History<N>,
    saturation: (f64, f64),
) {
    let Some(j) = h.merge_candidate() else {
        // Unreachable for N >= 4 (see merge_candidate); dropping the newest pair keeps the stack valid regardless.
        h.pop(2);
        return;
    };
    let point = |r: &Reversal| (r.u, r.y);
    let (upper, old, lower) = (*h.get(j + 2), *h.get(j + 1), *h.get(j - 1));
    let lower_target = if j >= 2 {
        point(h.get(j - 2))
    } else {
        saturation
    };
    h.get_mut(j + 2).via = Some(second_piece(asc, desc, &upper, point(&old), point(&lower)));
    let k = first_piece_scale(asc, desc, &lower, point(&upper), 0);
    let via = second_piece(asc, desc, &lower, point(&upper), lower_target);
    let l = h.get_mut(j - 1);
    l.k = k.unwrap_or(1.0);
    l.linear = k.is_none();
    l.via = Some(via);
    h.remove_pair(j);
}

/// Scale of `entry`'s first branch piece so that it closes on `to` (`None`: a straight line, see
/// [`branch_scale`]). The branch rises from a minimum (`to` above it) and falls from a maximum. `hint`: where the
/// search for `to`'s cell in the family the branch follows starts (it changes no cell).
fn first_piece_scale<S: AsRef<[f64]>>(
    asc: &Family<S>,
    desc: &Family<S>,
    entry: &Reversal,
    to: (f64, f64),
    mut hint: usize,
) -> Option<f64> {
    if to.0 > entry.u {
        branch_scale(to.1 - entry.y, asc.everett(&entry.strip, to.0, &mut hint))
    } else {
        branch_scale(entry.y - to.1, desc.everett(&entry.strip, -to.0, &mut hint))
    }
}

/// Largest branch scale a table increment may be given. A scale is an output change over a table increment (both
/// output units): 1 on congruent tables, a few where measured families disagree. Far beyond, the increment is
/// round-off of a flat stretch of the tables, and the scale would magnify the rounding of the Everett values into
/// the output (at 1e6, at most 2e-10 of their magnitude).
const MAX_BRANCH_SCALE: f64 = 1e6;

/// Branch scale that makes an increment `e` produce the output change `dy`, or `None` when no scale can: the
/// tables give no increment (`e = 0`, or one that would need a scale above [`MAX_BRANCH_SCALE`]) while the output
/// must still rise. Such a branch is a straight line in the input to its target (see [`Reversal::linear`]).
#[inline]
pub(crate) fn branch_scale(dy: f64, e: f64) -> Option<f64> {
    if e > 0.0 {
        let k = dy / e;
        if k <= MAX_BRANCH_SCALE {
            Some(k.max(0.0))
        } else {
            None
        }
    } else if dy > 0.0 {
        None
    } else {
        Some(1.0)
    }
}

/// The straight line from `(u0, y0)` to `(u1, y1)` at `u` (the far end when the two inputs coincide).
#[inline]
pub(crate) fn line(u0: f64, y0: f64, u1: f64, y1: f64, u: f64) -> f64 {
    if u1 == u0 {
        return y1;
    }
    y0 + (y1 - y0) * ((u - u0) / (u1 - u0)).clamp(0.0, 1.0)
}

impl Reversal {
    /// A reversal whose branch follows the tables with scale `k`, or a straight line when `k` is `None`.
    #[inline]
    pub(crate) fn scaled(u: f64, y: f64, strip: crate::everett::Strip, k: Option<f64>) -> Reversal {
        Reversal {
            u,
            y,
            k: k.unwrap_or(1.0),
            strip,
            via: None,
            linear: k.is_none(),
        }
    }
}

/// Second branch piece of `entry` from the point `from` on its branch to `to` (`(input, output)` pairs; see
/// [`merge`]).
fn second_piece<S: AsRef<[f64]>>(
    asc: &Family<S>,
    desc: &Family<S>,
    entry: &Reversal,
    from: (f64, f64),
    to: (f64, f64),
) -> Via {
    let mut hint = 0;
    // Entry rises if it is a minimum, i.e. the points are above it.
    let (e_from, e_to, dy) = if from.0 > entry.u {
        (
            asc.everett(&entry.strip, from.0, &mut hint),
            asc.everett(&entry.strip, to.0, &mut hint),
            to.1 - from.1,
        )
    } else {
        (
            desc.everett(&entry.strip, -from.0, &mut hint),
            desc.everett(&entry.strip, -to.0, &mut hint),
            from.1 - to.1,
        )
    };
    let k = branch_scale(dy, e_to - e_from);
    Via {
        u: from.0,
        y: from.1,
        e: e_from,
        k: k.unwrap_or(1.0),
        linear: k.is_none(),
    }
}

/// A 64-bit hash of both tables (dimensions and every stored value) and the end points: tells snapshots of
/// different tables apart. Each word goes through a bijective mix, so a change of any single value (even its
/// last bit) changes the hash. `O(table size)`, once at construction.
fn fingerprint<S: AsRef<[f64]>>(asc: &Family<S>, desc: &Family<S>, y_lo: f64, y_hi: f64) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |x: u64| {
        h = (h ^ x).wrapping_mul(0x0000_0100_0000_01b3).rotate_left(29);
    };
    for f in [asc, desc] {
        mix(f.nodes() as u64);
        mix(f.curves() as u64);
        f.data().iter().for_each(|v| mix(v.to_bits()));
    }
    mix(y_lo.to_bits());
    mix(y_hi.to_bits());
    // Final avalanche (splitmix64) so that nearby tables do not give nearby hashes.
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

#[cfg(test)]
mod tests {
    use crate::{BuildOptions, Hysteresis, Initial};
    use preisach_plant::{Rng, measure_first_order};

    /// A turn back over the newest reversal drops that entry instead of pushing the turn and wiping both out: the
    /// memory and output are those of the long way to the bit. Inputs dither around a slow sweep (a turn nearly
    /// every sample, many of them back over the last reversal), through merges of a full memory.
    #[test]
    fn a_turn_back_over_the_newest_reversal_is_the_long_way_to_the_bit() {
        let (a, d) = measure_first_order(40, 9);
        let mut short = Hysteresis::<Vec<f64>, 8>::from_curve_data(
            &a,
            &d,
            &BuildOptions::default(),
            Initial::Negative,
        )
        .unwrap();
        let mut long = short.clone();
        let (lo, hi) = short.input_range();
        let mut rng = Rng(11);
        let mut dropped = 0;
        for i in 0..20_000 {
            let slow = 0.8 * libm::sin(i as f64 * 0.002);
            let u = lo + (hi - lo) * (0.5 + 0.5 * slow + 0.01 * (rng.uniform() - 0.5));
            let before = short.state().history().len();
            let y = short.step(u);
            // The long way: `step` with the turn always pushed, then the wipe-out.
            let h = long.state.history;
            let cur = long.state.u;
            if (h.rising() && u < cur) || (!h.rising() && u > cur) {
                long.turn(None);
            }
            long.wipe_out(u);
            let y_long = long.branch_output(u);
            long.state.u = u;
            long.state.y = y_long;
            dropped += usize::from(short.state().history().len() + 1 == before);
            assert_eq!(y.to_bits(), y_long.to_bits(), "sample {i}");
            assert_eq!(
                short.snapshot().to_words(),
                long.snapshot().to_words(),
                "sample {i}"
            );
        }
        assert!(
            dropped > 3_000,
            "only {dropped} turns back over the newest reversal: the test does not exercise them"
        );
    }
}
