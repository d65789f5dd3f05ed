//! The congruency-based hysteresis (CBH) operator: first-order curve tables + extrema memory → output.
//!
//! Rising from the newest minimum `m`: `y = y(m) + k·E^a(m, u)`; falling from the newest maximum `M`:
//! `y = y(M) − k·E^d(M, u)` (paper eq 12 and 16, DESIGN section 2). `k = 1` for tables whose two families agree
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
    anchor: Reversal,
    fingerprint: u64,
    pub(crate) state: State<N>,
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
        Ok(())
    }

    /// Forget all memory and start from `initial`. A major-branch input outside the range saturates.
    pub fn reset(&mut self, initial: Initial) {
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
        if u.is_nan() {
            return f64::NAN;
        }
        let u = u.clamp(self.lo, self.hi);
        self.advance(u);
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
    #[inline]
    pub(crate) fn advance(&mut self, u: f64) {
        let h = &self.state.history;
        let cur = self.state.u;
        if (h.rising() && u < cur) || (!h.rising() && u > cur) {
            self.turn();
        }
        self.wipe_out(u);
    }

    /// The direction changes at the current point: remember it, unless we never left the newest reversal.
    pub(crate) fn turn(&mut self) {
        if self.state.u == self.state.history.top().u && self.state.history.len() > 1 {
            self.state.history.pop(1);
        } else {
            self.push_reversal();
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
        push_reversal(&self.asc, &self.desc, &mut self.state);
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
const STATE_TAG: u64 = 0x626d_725f_7374_0002;
/// Words before the memory entries: tag, fingerprint, length, input, output, two hints.
const STATE_HEADER: usize = 7;
/// Words per memory entry: input, output, scale, flags (second piece present, branch linear, second piece linear)
/// and the second piece's four values.
const ENTRY_WORDS: usize = 8;

#[cfg(feature = "alloc")]
impl<const N: usize> State<N> {
    /// The state as plain words (for pickling and files); [`Hysteresis::state_from_words`] reads it back
    /// bit for bit. Where a reversal sits in its table is not stored: it is recomputed from the table.
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
            w.extend([r.u.to_bits(), r.y.to_bits(), r.k.to_bits()]);
            match r.via {
                None => w.extend([0, 0, 0, 0, 0]),
                Some(v) => w.extend([
                    1,
                    v.u.to_bits(),
                    v.y.to_bits(),
                    v.e.to_bits(),
                    v.k.to_bits(),
                ]),
            }
        }
        w
    }
}

/// Input and output stored in serialised state words (`None` if the words are too short to be a state).
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
    /// checked (format, tables, memory length, finite values inside the input range, the saturation anchor), so
    /// damaged words give an error, never a state that could index outside the tables.
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
        let in_range = |u: f64| u >= self.lo && u <= self.hi;
        let (u, y) = (f(w[3]), f(w[4]));
        if !(in_range(u) && y.is_finite()) {
            return bad("input outside the table range or output not finite");
        }
        // Hints only speed searches up; keep them inside each family's cells all the same.
        let hint = |x: u64, fam: &Family<S>| {
            usize::try_from(x)
                .unwrap_or(usize::MAX)
                .min(fam.nodes() - 2)
        };
        let mut history = History::new(self.anchor);
        for i in 0..len {
            let e = &w[STATE_HEADER + ENTRY_WORDS * i..STATE_HEADER + ENTRY_WORDS * (i + 1)];
            let (ru, ry, rk) = (f(e[0]), f(e[1]), f(e[2]));
            if !(in_range(ru) && ry.is_finite() && rk.is_finite()) {
                return bad("memory entry outside the table range or not finite");
            }
            let flags = e[3];
            if flags > 7 || (flags & 1 == 0 && flags & 4 != 0) {
                return bad("memory entry flags");
            }
            let via = match flags & 1 {
                0 => None,
                _ => {
                    let v = Via {
                        u: f(e[4]),
                        y: f(e[5]),
                        e: f(e[6]),
                        k: f(e[7]),
                        linear: flags & 4 != 0,
                    };
                    if !(in_range(v.u) && v.y.is_finite() && v.e.is_finite() && v.k.is_finite()) {
                        return bad("second branch piece outside the table range or not finite");
                    }
                    Some(v)
                }
            };
            let linear = flags & 2 != 0;
            if i == 0 {
                let a = self.anchor;
                if (ru, ry, rk, linear) != (a.u, a.y, a.k, a.linear) || via.is_some() {
                    return bad("first memory entry is not the saturation anchor");
                }
                continue;
            }
            // Even entries are minima (ascending branch ahead), odd ones maxima (see crate::history).
            let strip = if i % 2 == 1 {
                self.desc.strip(-ru)
            } else {
                self.asc.strip(ru)
            };
            history.push(Reversal {
                u: ru,
                y: ry,
                k: rk,
                strip,
                via,
                linear,
            });
        }
        Ok(State {
            history,
            u,
            y,
            hint_a: hint(w[5], &self.asc),
            hint_d: hint(w[6], &self.desc),
            fingerprint: self.fingerprint,
        })
    }
}

/// Push the state's current point as a reversal, merging first when the memory is full.
pub(crate) fn push_reversal<S: AsRef<[f64]>, const N: usize>(
    asc: &Family<S>,
    desc: &Family<S>,
    st: &mut State<N>,
) {
    if st.history.is_full() {
        st.history
            .make_room(|entry, old, new| second_piece(asc, desc, entry, old, new));
    }
    let (u, y) = (st.u, st.y);
    let below = *st.history.top();
    let r = if st.history.rising() {
        let strip = desc.strip(-u);
        let e = desc.everett(&strip, -below.u, &mut st.hint_d);
        Reversal::scaled(u, y, strip, branch_scale(y - below.y, e))
    } else {
        let strip = asc.strip(u);
        let e = asc.everett(&strip, below.u, &mut st.hint_a);
        Reversal::scaled(u, y, strip, branch_scale(below.y - y, e))
    };
    st.history.push(r);
}

/// Branch scale that makes an increment `e` produce the output change `dy`, or `None` when no scale can: the
/// tables give no increment (`e = 0`) while the output must still rise, or the scale overflows. Such a branch is a
/// straight line in the input to its target (see [`Reversal::linear`]).
#[inline]
pub(crate) fn branch_scale(dy: f64, e: f64) -> Option<f64> {
    if e > 0.0 {
        let k = dy / e;
        if k.is_finite() {
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

/// Second branch piece of `entry` from its old target to its new one (see [`History::make_room`]).
fn second_piece<S: AsRef<[f64]>>(
    asc: &Family<S>,
    desc: &Family<S>,
    entry: &Reversal,
    old: &Reversal,
    new: &Reversal,
) -> Via {
    let mut hint = 0;
    // Entry rises if it is a minimum, i.e. its targets are maxima above it.
    let (e_old, e_new, dy) = if old.u > entry.u {
        (
            asc.everett(&entry.strip, old.u, &mut hint),
            asc.everett(&entry.strip, new.u, &mut hint),
            new.y - old.y,
        )
    } else {
        (
            desc.everett(&entry.strip, -old.u, &mut hint),
            desc.everett(&entry.strip, -new.u, &mut hint),
            old.y - new.y,
        )
    };
    let k = branch_scale(dy, e_new - e_old);
    Via {
        u: old.u,
        y: old.y,
        e: e_old,
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
