//! The extrema memory: a fixed-capacity stack of the reversal points that still matter.
//!
//! Index 0 is always the negative-saturation anchor (a minimum at the lowest input). Above it minima and maxima
//! alternate: even indices are minima (the output rises from them), odd indices are maxima (it falls from them).
//! The entry below each one is its *closure target*: when the input passes the target, the pair is wiped out and
//! the output returns exactly to the stored output (return-point memory). The anchor's target is positive
//! saturation.
use crate::everett::{Strip, StripHint};

/// A point where the output follows a second piece after a merge (see [`History::merge_candidate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Via {
    /// Input where the second piece starts (the merged-away closure target).
    pub u: f64,
    /// Output there.
    pub y: f64,
    /// Everett increment from this entry's reversal to `u`.
    pub e: f64,
    /// Scale of the second piece, so that it closes on the new target.
    pub k: f64,
    /// The tables give no increment towards the new target: the piece is a straight line in the input to it.
    pub linear: bool,
}

/// One remembered reversal point and the branch that leaves it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reversal {
    /// Input at the reversal.
    pub u: f64,
    /// Output at the reversal.
    pub y: f64,
    /// Branch scale: output = `y ± k·E(reversal, input)`; 1 for congruent (Preisach-consistent) tables, otherwise
    /// chosen so that the branch closes exactly on its target's output (continuity at wipe-out).
    pub k: f64,
    /// Where the reversal sits in its curve family.
    pub strip: Strip,
    /// Second branch piece after a merge.
    pub via: Option<Via>,
    /// The tables give no increment towards the closure target (a flat Everett function where the outputs still
    /// differ, as in measured families that disagree): the branch is a straight line in the input to the target
    /// instead, so that the output stays continuous and monotone.
    pub linear: bool,
}

impl Reversal {
    pub const EMPTY: Reversal = Reversal {
        u: 0.0,
        y: 0.0,
        k: 1.0,
        strip: Strip::ZERO,
        via: None,
        linear: false,
    };
}

/// Fixed-capacity reversal stack. `N >= 4`; never allocates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct History<const N: usize> {
    entries: [Reversal; N],
    len: usize,
}

impl<const N: usize> History<N> {
    const CAPACITY_OK: () = assert!(N >= 4, "history capacity must be at least 4");

    /// A history holding only the anchor.
    pub fn new(anchor: Reversal) -> Self {
        let () = Self::CAPACITY_OK;
        let mut entries = [Reversal::EMPTY; N];
        entries[0] = anchor;
        History { entries, len: 1 }
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    pub const fn capacity(&self) -> usize {
        N
    }
    #[inline]
    pub fn top(&self) -> &Reversal {
        &self.entries[self.len - 1]
    }
    #[inline]
    pub fn get(&self, i: usize) -> &Reversal {
        &self.entries[i]
    }
    /// True when the newest entry is a minimum (the output is on a rising branch).
    #[inline]
    pub fn rising(&self) -> bool {
        (self.len - 1).is_multiple_of(2)
    }
    /// The newest entry's closure target, or `None` for the anchor (target: positive saturation).
    #[inline]
    pub fn target(&self) -> Option<&Reversal> {
        if self.len >= 2 {
            Some(&self.entries[self.len - 2])
        } else {
            None
        }
    }
    pub fn entries(&self) -> &[Reversal] {
        &self.entries[..self.len]
    }
    pub fn is_full(&self) -> bool {
        self.len == N
    }

    #[inline]
    pub fn push(&mut self, r: Reversal) {
        debug_assert!(self.len < N);
        self.entries[self.len] = r;
        self.len += 1;
    }

    /// Remove the newest `n` entries; the anchor always stays.
    #[inline]
    pub fn pop(&mut self, n: usize) {
        self.len = (self.len - n).max(1);
    }

    /// Keep only the anchor.
    pub fn clear(&mut self) {
        self.len = 1;
    }

    /// The interior pair `(j, j+1)` to merge away when the memory is full: the one with the smallest input
    /// excursion (the newest on ties) whose upper neighbour `j+2` has no second piece yet. With `N >= 4` one
    /// always exists (the newest entry has no piece). See `cbh::merge` for what the merge does to the branches.
    pub fn merge_candidate(&self) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for j in 1..self.len.saturating_sub(2) {
            if self.entries[j + 2].via.is_some() {
                continue;
            }
            let excursion = (self.entries[j].u - self.entries[j + 1].u).abs();
            if best.is_none_or(|(_, e)| excursion <= e) {
                best = Some((j, excursion));
            }
        }
        best.map(|(j, _)| j)
    }

    /// Where to start the strip search of a reversal pushed next: the strip of the newest entry of the same kind
    /// (minimum or maximum, so the same curve family), the one below the newest entry. A reversal pushed after a
    /// short excursion usually lies in the same strip.
    #[inline]
    pub(crate) fn next_strip_hint(&self) -> StripHint {
        if self.len >= 2 {
            StripHint::of(&self.entries[self.len - 2].strip)
        } else {
            StripHint::NONE
        }
    }

    /// Mutable access to entry `i` (merging reshapes the neighbours of the removed pair).
    #[inline]
    pub(crate) fn get_mut(&mut self, i: usize) -> &mut Reversal {
        &mut self.entries[i]
    }

    /// Remove the interior pair `(j, j+1)`; the entries above move down by two.
    pub(crate) fn remove_pair(&mut self, j: usize) {
        debug_assert!(j >= 1 && j + 1 < self.len);
        self.entries.copy_within(j + 2..self.len, j);
        self.len -= 2;
    }
}
