//! Hysteretic steel of one magnetic circuit: coil current → flux density in the MR gap (Preisach model).
//!
//! The Preisach density is physical: hysterons are distributed in coercive field `h_c = (α − β)/2` as a
//! Gaussian around the coercivity with a width, and in interaction field `h_u = (α + β)/2` as a Gaussian whose
//! width sets how fast the steel saturates; a reversible (anhysteretic) share lies on the diagonal `α = β` with
//! a `tanh` profile. Fields are expressed in coil-current units (A), so coercivity is "the current that
//! reverses half of the steel".
//!
//! The density is integrated once at construction into an Everett table `F(α, β)` on a square grid (mass of
//! hysterons in the triangle `β ≤ β' ≤ α' ≤ α`), and `F` is evaluated by bilinear interpolation. That
//! interpolant is itself the Everett function of a valid Preisach model (piecewise-constant density off the
//! diagonal, a line density on it), so the plant is *exactly* Preisach — wiping-out and congruency hold to
//! round-off — while each step costs O(1): the memory keeps prefix sums of the staircase contributions.
//! Inputs beyond `±range_a` act as saturation.

use super::{PlantError, check_range};

/// Physical parameters of one steel circuit (fields in coil-current units, A).
#[derive(Clone, Debug, PartialEq)]
pub struct SteelParams {
    /// Flux density (T) in the gap with every hysteron up (and the reversible part saturated).
    pub saturation_t: f64,
    /// Centre of the coercive-field distribution (A): half the width of the major loop in current.
    pub coercivity_a: f64,
    /// Standard deviation of the coercive-field distribution (A).
    pub coercivity_width_a: f64,
    /// Standard deviation of the interaction-field distribution (A): sets how gradually the steel saturates.
    pub interaction_width_a: f64,
    /// Share of the saturation flux that is reversible (anhysteretic), in [0, 1).
    pub reversible_fraction: f64,
    /// Current scale (A) of the reversible part's `tanh` profile.
    pub reversible_width_a: f64,
    /// Half-width of the Preisach plane (A); larger inputs are saturating.
    pub range_a: f64,
    /// Everett table nodes per axis.
    pub grid: usize,
}

impl Default for SteelParams {
    fn default() -> Self {
        SteelParams {
            saturation_t: 0.6,
            coercivity_a: 0.07,
            coercivity_width_a: 0.035,
            interaction_width_a: 0.9,
            reversible_fraction: 0.25,
            reversible_width_a: 1.0,
            range_a: 3.0,
            grid: 241,
        }
    }
}

impl SteelParams {
    /// Whether `other` describes the same hysteron density on the same grid (its Everett table is this one's,
    /// bit for bit): every parameter but `saturation_t`.
    fn same_density(&self, other: &SteelParams) -> bool {
        SteelParams {
            saturation_t: other.saturation_t,
            ..self.clone()
        } == *other
    }

    pub fn validate(&self, name: &str) -> Result<(), PlantError> {
        check_range(
            &format!("{name}.saturation_t"),
            self.saturation_t,
            1e-6,
            10.0,
        )?;
        check_range(
            &format!("{name}.coercivity_a"),
            self.coercivity_a,
            0.0,
            self.range_a,
        )?;
        check_range(
            &format!("{name}.coercivity_width_a"),
            self.coercivity_width_a,
            1e-6,
            self.range_a,
        )?;
        check_range(
            &format!("{name}.interaction_width_a"),
            self.interaction_width_a,
            1e-6,
            100.0,
        )?;
        check_range(
            &format!("{name}.reversible_fraction"),
            self.reversible_fraction,
            0.0,
            0.999,
        )?;
        check_range(
            &format!("{name}.reversible_width_a"),
            self.reversible_width_a,
            1e-6,
            100.0,
        )?;
        check_range(&format!("{name}.range_a"), self.range_a, 1e-3, 100.0)?;
        if !(8..=2001).contains(&self.grid) {
            return Err(PlantError::InvalidParameter(format!(
                "{name}.grid = {} is outside [8, 2001]",
                self.grid
            )));
        }
        Ok(())
    }
}

/// The Everett table of a density, normalised to total mass 1, with its antisymmetric extension
/// `F(β, α) = −F(α, β)` so that bilinear interpolation works uniformly (also in diagonal cells).
#[derive(Clone, Debug)]
struct Everett {
    n: usize,
    lo: f64,
    h: f64,
    /// `n − 1` as a float: the last node's coordinate in cells.
    last_node: f64,
    table: Vec<f64>,
}

impl Everett {
    fn from_params(p: &SteelParams) -> Self {
        let n = p.grid;
        let lo = -p.range_a;
        let h = 2.0 * p.range_a / (n - 1) as f64;
        let x = |i: usize| lo + h * i as f64;
        // Hysteretic cell masses (α-cell p > β-cell q), midpoint rule with SUB×SUB points per cell.
        const SUB: usize = 3;
        let density = |a: f64, b: f64| {
            let hc = 0.5 * (a - b);
            let hu = 0.5 * (a + b);
            let zc = (hc - p.coercivity_a) / p.coercivity_width_a;
            let zu = hu / p.interaction_width_a;
            libm::exp(-0.5 * (zc * zc + zu * zu))
        };
        let mut cell = vec![0.0; n * n];
        let mut hyst_total = 0.0;
        for pa in 1..n - 1 {
            for qb in 0..pa {
                let mut m = 0.0;
                for i in 0..SUB {
                    for j in 0..SUB {
                        let a = x(pa) + h * (i as f64 + 0.5) / SUB as f64;
                        let b = x(qb) + h * (j as f64 + 0.5) / SUB as f64;
                        m += density(a, b);
                    }
                }
                cell[pa * n + qb] = m;
                hyst_total += m;
            }
        }
        // Reversible share as a line density on the diagonal: tanh profile, total mass `r`.
        let r = p.reversible_fraction;
        let w = p.reversible_width_a;
        let t_end = libm::tanh(p.range_a / w);
        let mut diag = vec![0.0; n - 1];
        for (i, d) in diag.iter_mut().enumerate() {
            *d = r * (libm::tanh(x(i + 1) / w) - libm::tanh(x(i) / w)) / (2.0 * t_end);
        }
        let scale = if hyst_total > 0.0 {
            (1.0 - r) / hyst_total
        } else {
            0.0
        };
        // F(i, j) = Σ_{pa=j}^{i-1} [diag(pa) + Σ_{qb=j}^{pa-1} cell(pa, qb)]
        let mut table = vec![0.0; n * n];
        for j in 0..n {
            let mut f = 0.0;
            for i in j + 1..n {
                let pa = i - 1;
                let row: f64 = cell[pa * n + j..pa * n + pa].iter().sum();
                f += diag[pa] + scale * row;
                table[i * n + j] = f;
                table[j * n + i] = -f;
            }
        }
        // Normalise exactly to total mass 1 (the sums above can differ by round-off).
        let total = table[(n - 1) * n];
        if total > 0.0 {
            for v in table.iter_mut() {
                *v /= total;
            }
        }
        Everett {
            n,
            lo,
            h,
            last_node: (n - 1) as f64,
            table,
        }
    }

    /// Everett function at (α, β), bilinear between table nodes; arguments are clamped to the plane.
    #[cfg(test)]
    fn eval(&self, alpha: f64, beta: f64) -> f64 {
        self.eval_located(self.locate(alpha), self.locate(beta))
    }

    /// [`Self::eval`] at arguments already located (`locate`: cell and fraction).
    #[inline]
    fn eval_located(&self, (ia, s): (usize, f64), (jb, t): (usize, f64)) -> f64 {
        let n = self.n;
        let f00 = self.table[ia * n + jb];
        let f10 = self.table[(ia + 1) * n + jb];
        let f01 = self.table[ia * n + jb + 1];
        let f11 = self.table[(ia + 1) * n + jb + 1];
        (1.0 - s) * ((1.0 - t) * f00 + t * f01) + s * ((1.0 - t) * f10 + t * f11)
    }

    #[inline]
    fn locate(&self, v: f64) -> (usize, f64) {
        // `max` then `min` is `clamp` for the non-NaN inputs it gets, without `clamp`'s check of its bounds.
        let z = ((v - self.lo) / self.h).max(0.0).min(self.last_node);
        // `z` is clamped to [0, n − 1]: the signed conversion is exact there and cheaper than the unsigned one.
        let i = (z as i64 as usize).min(self.n - 2);
        (i, z - i as f64)
    }
}

/// One steel circuit: Everett table + Preisach memory (a wiping-out stack of alternating extrema).
#[derive(Clone, Debug)]
pub struct PreisachSteel {
    params: SteelParams,
    everett: Everett,
    /// e[0] = −range (a minimum); then alternating maxima and minima, each nested in the previous pair.
    extrema: Vec<f64>,
    /// prefix[k] = Σ_{i=1..k} contribution of the staircase segment e[i-1] → e[i].
    prefix: Vec<f64>,
    input_a: f64,
    output: f64,
    /// Cells on the Everett grid (value bits, cell) of the extremum the last segment started from and of the
    /// last input: the newest extremum stays the same between reversals and a reversal starts at the last input,
    /// so a step locates only its new input (the same arithmetic, the same bits).
    from_cell: (u64, (usize, f64)),
    input_cell: (u64, (usize, f64)),
}

impl PreisachSteel {
    /// Build the table and start from the thermally demagnetised state (B = 0 at zero current).
    pub fn new(params: SteelParams) -> Result<Self, PlantError> {
        Self::new_beside(params, None)
    }

    /// [`Self::new`], taking the Everett table of `other` when its density is the same (every parameter but the
    /// saturation flux, which scales the output only): a second circuit of the same steel costs a copy of the
    /// table instead of its integration (a quarter of a million `exp` on the default grid).
    pub fn new_beside(
        params: SteelParams,
        other: Option<&PreisachSteel>,
    ) -> Result<Self, PlantError> {
        params.validate("steel")?;
        let everett = match other {
            Some(o) if o.params.same_density(&params) => o.everett.clone(),
            _ => Everett::from_params(&params),
        };
        let mut s = PreisachSteel {
            params,
            everett,
            extrema: Vec::new(),
            prefix: Vec::new(),
            input_a: 0.0,
            output: 0.0,
            from_cell: (f64::NAN.to_bits(), (0, 0.0)),
            input_cell: (f64::NAN.to_bits(), (0, 0.0)),
        };
        s.demagnetise();
        Ok(s)
    }

    pub fn params(&self) -> &SteelParams {
        &self.params
    }

    /// Alternating field of decaying amplitude down to zero: the demagnetised staircase along α = −β.
    pub fn demagnetise(&mut self) {
        let r = self.params.range_a;
        self.extrema.clear();
        self.extrema.push(-r);
        self.prefix.clear();
        self.prefix.push(0.0);
        self.input_a = -r;
        self.output = -1.0;
        let mut amp = r;
        let mut sign = 1.0;
        while amp > 1e-4 * r {
            self.apply(sign * amp);
            amp *= 0.8;
            sign = -sign;
        }
        self.apply(0.0);
    }

    /// Staircase segment contribution to the "up" mass: rising a→b adds F(b, a), falling a→b removes F(a, b).
    #[inline(always)]
    fn segment(&mut self, from: f64, to: f64, rising: bool) -> f64 {
        let bits = from.to_bits();
        if self.from_cell.0 != bits {
            self.from_cell = if self.input_cell.0 == bits {
                self.input_cell
            } else {
                (bits, self.everett.locate(from))
            };
        }
        let bits = to.to_bits();
        if self.input_cell.0 != bits {
            self.input_cell = (bits, self.everett.locate(to));
        }
        let (at_from, at_to) = (self.from_cell.1, self.input_cell.1);
        if rising {
            self.everett.eval_located(at_to, at_from)
        } else {
            -self.everett.eval_located(at_from, at_to)
        }
    }

    /// Apply coil current `current_a` (A); returns the flux density in the gap (T).
    #[inline]
    pub fn apply(&mut self, current_a: f64) -> f64 {
        self.apply_normalised(current_a) * self.params.saturation_t
    }

    /// Apply an input; returns the normalised Preisach output in [−1, 1].
    #[inline(always)]
    pub fn apply_normalised(&mut self, current_a: f64) -> f64 {
        let r = self.params.range_a;
        // NaN is treated as "no change" so the memory can never be corrupted.
        let u = if current_a.is_nan() {
            self.input_a
        } else {
            current_a.clamp(-r, r)
        };
        if u == self.input_a {
            return self.output;
        }
        let mut n = self.extrema.len() - 1;
        let mut rising = n.is_multiple_of(2);
        if (rising && u < self.input_a) || (!rising && u > self.input_a) {
            if n >= 1
                && (if rising {
                    u <= self.extrema[n]
                } else {
                    u >= self.extrema[n]
                })
            {
                // Back over the newest extremum at once (a dither): the reversal at the previous input would be
                // pushed and wiped out with that extremum in this step, so only the extremum goes.
                self.extrema.truncate(n);
                self.prefix.truncate(n);
                n -= 1;
            } else {
                // Reversal at the previous input: it becomes a new extremum.
                let contribution = self.segment(self.extrema[n], self.input_a, rising);
                self.prefix.push(self.prefix[n] + contribution);
                self.extrema.push(self.input_a);
                n += 1;
            }
            rising = !rising;
        }
        // Wiping-out: passing the previous extremum of the same kind removes that max/min pair.
        while n >= 2
            && ((rising && u >= self.extrema[n - 1]) || (!rising && u <= self.extrema[n - 1]))
        {
            self.extrema.truncate(n - 1);
            self.prefix.truncate(n - 1);
            n -= 2;
        }
        if !rising && n == 1 && u <= -r {
            // Negative saturation: everything is down, forget the last maximum.
            self.extrema.truncate(1);
            self.prefix.truncate(1);
            n = 0;
            rising = true;
        }
        self.input_a = u;
        self.output = 2.0 * (self.prefix[n] + self.segment(self.extrema[n], u, rising)) - 1.0;
        self.output
    }

    /// The output at the current state normalised to saturation (±1).
    pub fn normalised_output(&self) -> f64 {
        self.output
    }

    /// Flux density (T) at the current state.
    pub fn flux_t(&self) -> f64 {
        self.output * self.params.saturation_t
    }

    pub(crate) fn save_state(&self, out: &mut Vec<u64>) {
        out.push(self.extrema.len() as u64);
        out.extend(self.extrema.iter().map(|v| v.to_bits()));
        out.extend(self.prefix.iter().map(|v| v.to_bits()));
        out.extend([self.input_a.to_bits(), self.output.to_bits()]);
    }

    pub(crate) fn load_state(&mut self, r: &mut super::StateReader<'_>) -> Result<(), PlantError> {
        let n = r.count()?;
        let range = self.params.range_a;
        let inside = |v: f64| (-range..=range).contains(&v);
        let mut extrema = Vec::with_capacity(n);
        for _ in 0..n {
            extrema.push(r.float()?);
        }
        let mut prefix = Vec::with_capacity(n);
        for _ in 0..n {
            prefix.push(r.float()?);
        }
        let (input, output) = (r.float()?, r.float()?);
        if extrema.first() != Some(&-range) || !extrema.iter().all(|&v| inside(v)) || !inside(input)
        {
            return Err(PlantError::BadState(
                "steel memory outside its current range or without its saturation anchor",
            ));
        }
        self.extrema = extrema;
        self.prefix = prefix;
        self.input_a = input;
        self.output = output;
        Ok(())
    }

    /// Number of reversal points the memory holds (for tests and diagnostics).
    pub fn memory_depth(&self) -> usize {
        self.extrema.len() - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steel() -> PreisachSteel {
        PreisachSteel::new(SteelParams::default()).unwrap()
    }

    #[test]
    fn demagnetised_starts_near_zero_and_saturates() {
        let mut s = steel();
        assert!(s.flux_t().abs() < 1e-3, "B0 = {}", s.flux_t());
        let sat = s.params().saturation_t;
        assert!((s.apply(10.0) - sat).abs() < 1e-12);
        assert!((s.apply(-10.0) + sat).abs() < 1e-12);
        assert_eq!(s.memory_depth(), 0);
    }

    #[test]
    fn remanence_and_return_point_memory() {
        let mut s = steel();
        s.apply(1.25);
        let b_r = s.apply(0.0);
        assert!(b_r > 0.01, "remanence {b_r}");
        // Minor loop 0.2 → 0.8 → 0.4 → 0.8 returns to the same point; wiping out restores the outer branch.
        s.apply(0.2);
        let b_08 = s.apply(0.8);
        s.apply(0.4);
        assert_eq!(s.apply(0.8), b_08);
        let depth = s.memory_depth();
        s.apply(0.5);
        s.apply(0.9);
        assert!(s.memory_depth() <= depth);
    }

    #[test]
    fn branches_are_monotone() {
        let mut s = steel();
        s.apply(-3.0);
        let mut prev = s.apply(-3.0);
        for k in 0..=600 {
            let b = s.apply(-3.0 + 0.01 * k as f64);
            assert!(b >= prev - 1e-15);
            prev = b;
        }
        for k in 0..=600 {
            let b = s.apply(3.0 - 0.01 * k as f64);
            assert!(b <= prev + 1e-15);
            prev = b;
        }
    }

    #[test]
    fn minor_loops_between_the_same_extremes_are_congruent() {
        // Preisach congruency: after different histories that both reverse at 0.3 below a maximum above 0.9, the
        // loop 0.3 ↔ 0.9 has the same shape (offset only).
        let loop_path: Vec<f64> = (0..=60)
            .map(|k| 0.3 + 0.01 * k as f64)
            .chain((0..=60).map(|k| 0.9 - 0.01 * k as f64))
            .collect();
        let shape = |history: &[f64]| {
            let mut s = steel();
            for &u in history {
                s.apply(u);
            }
            let b: Vec<f64> = loop_path.iter().map(|&u| s.apply(u)).collect();
            b.iter().map(|v| v - b[0]).collect::<Vec<f64>>()
        };
        let a = shape(&[1.25, 0.0, 1.0, 0.3]);
        let b = shape(&[-2.0, 1.6, 0.1, 1.1, 0.3]);
        assert!((a[60] - a[0]).abs() > 1e-3);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
    }

    /// A circuit built beside another takes its table only for the same density: the same outputs as one built
    /// alone, also after a different saturation flux, and a different coercivity still integrates its own.
    #[test]
    fn a_table_taken_from_a_circuit_beside_is_the_one_it_would_build() {
        let path: Vec<f64> = (0..400)
            .map(|k| 1.4 * libm::sin(0.05 * k as f64) * (1.0 - k as f64 / 500.0))
            .collect();
        let outputs = |mut s: PreisachSteel| {
            path.iter()
                .map(|&u| s.apply(u).to_bits())
                .collect::<Vec<u64>>()
        };
        let first = steel();
        for p in [
            SteelParams::default(),
            SteelParams {
                saturation_t: 0.55,
                ..SteelParams::default()
            },
            SteelParams {
                coercivity_a: 0.08,
                ..SteelParams::default()
            },
        ] {
            let alone = PreisachSteel::new(p.clone()).unwrap();
            let beside = PreisachSteel::new_beside(p.clone(), Some(&first)).unwrap();
            assert_eq!(alone.everett.table, beside.everett.table);
            assert_eq!(outputs(alone), outputs(beside));
        }
        assert!(!first.params.same_density(&SteelParams {
            coercivity_a: 0.08,
            ..SteelParams::default()
        }));
    }

    /// `PreisachSteel::segment` with both ends located afresh.
    fn segment_afresh(s: &PreisachSteel, from: f64, to: f64, rising: bool) -> f64 {
        if rising {
            s.everett.eval(to, from)
        } else {
            -s.everett.eval(from, to)
        }
    }

    /// `apply_normalised` with every reversal pushed before the wipe-out (no shortcut for a dither back over the
    /// newest extremum).
    fn apply_long(s: &mut PreisachSteel, current_a: f64) -> f64 {
        let r = s.params.range_a;
        let u = current_a.clamp(-r, r);
        if u == s.input_a {
            return s.output;
        }
        let mut n = s.extrema.len() - 1;
        let mut rising = n.is_multiple_of(2);
        if (rising && u < s.input_a) || (!rising && u > s.input_a) {
            let contribution = segment_afresh(s, s.extrema[n], s.input_a, rising);
            s.prefix.push(s.prefix[n] + contribution);
            s.extrema.push(s.input_a);
            n += 1;
            rising = !rising;
        }
        while n >= 2 && ((rising && u >= s.extrema[n - 1]) || (!rising && u <= s.extrema[n - 1])) {
            s.extrema.truncate(n - 1);
            s.prefix.truncate(n - 1);
            n -= 2;
        }
        if !rising && n == 1 && u <= -r {
            s.extrema.truncate(1);
            s.prefix.truncate(1);
            n = 0;
            rising = true;
        }
        s.input_a = u;
        s.output = 2.0 * (s.prefix[n] + segment_afresh(s, s.extrema[n], u, rising)) - 1.0;
        s.output
    }

    /// A dither back over the newest extremum drops it without pushing the reversal first, and each step reuses
    /// the values it located before: outputs and memory are the long way's (every segment located afresh) to the
    /// bit, through saturation both ways.
    #[test]
    fn a_dither_back_over_the_newest_extremum_is_the_long_way_to_the_bit() {
        let mut short = steel();
        let mut long = short.clone();
        let mut rng = crate::plant::rng::Rng::new(5);
        let mut dropped = 0;
        for k in 0..20_000 {
            let u = 3.4 * libm::sin(0.003 * k as f64) + 0.02 * rng.normal();
            let depth = short.memory_depth();
            let (a, b) = (short.apply_normalised(u), apply_long(&mut long, u));
            assert_eq!(a.to_bits(), b.to_bits(), "sample {k}");
            assert_eq!(short.extrema, long.extrema, "sample {k}");
            assert_eq!(short.prefix, long.prefix, "sample {k}");
            dropped += usize::from(short.memory_depth() + 1 == depth);
        }
        assert!(
            dropped > 1_000,
            "only {dropped} dithers back: the test does not exercise them"
        );
    }

    #[test]
    fn nan_does_not_change_state() {
        let mut s = steel();
        let b = s.apply(0.7);
        assert_eq!(s.apply(f64::NAN), b);
        assert_eq!(s.apply(0.7), b);
    }
}
