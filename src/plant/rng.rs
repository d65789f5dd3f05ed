//! Small seeded PRNG: SplitMix64 expands the seed, xoshiro256** draws; Box-Muller gives normals.
//!
//! Written here (no `rand` dependency) so a seed fixes every simulated bit on every platform.

/// One SplitMix64 step; used to expand a 64-bit seed into the xoshiro state.
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// xoshiro256** with a cached second Box-Muller normal.
#[derive(Clone, Debug)]
pub struct Rng {
    s: [u64; 4],
    spare_normal: Option<f64>,
}

impl Rng {
    /// A generator fully determined by `seed`.
    pub fn new(seed: u64) -> Self {
        let mut sm = seed;
        let s = [
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
        ];
        Rng {
            s,
            spare_normal: None,
        }
    }

    pub(crate) fn save_state(&self, out: &mut Vec<u64>) {
        out.extend_from_slice(&self.s);
        match self.spare_normal {
            None => out.extend([0, 0]),
            Some(z) => out.extend([1, z.to_bits()]),
        }
    }

    pub(crate) fn load_state(
        &mut self,
        r: &mut super::StateReader<'_>,
    ) -> Result<(), super::PlantError> {
        let s = [r.word()?, r.word()?, r.word()?, r.word()?];
        let spare = match (r.word()?, r.float()?) {
            (0, _) => None,
            (1, z) => Some(z),
            _ => return Err(super::PlantError::BadState("noise generator flag")),
        };
        self.s = s;
        self.spare_normal = spare;
        Ok(())
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let result = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal (Box-Muller; the second value of each pair is kept for the next call).
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        // 1 - uniform() lies in (0, 1], so the logarithm is finite.
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        let r = libm::sqrt(-2.0 * libm::log(u1));
        let phi = 2.0 * core::f64::consts::PI * u2;
        // One argument reduction for both: `libm::sincos` is `(libm::sin, libm::cos)` to the bit.
        let (sin, cos) = libm::sincos(phi);
        self.spare_normal = Some(r * sin);
        r * cos
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pair from one `sincos` is the pair `sin`, `cos` gave: the normals of a seed do not change.
    #[test]
    fn normals_are_the_sin_and_cos_pair_to_the_bit() {
        let mut r = Rng::new(3);
        let mut u = Rng::new(3);
        for _ in 0..50_000 {
            let (a, b) = (r.normal(), r.normal());
            let r1 = libm::sqrt(-2.0 * libm::log(1.0 - u.uniform()));
            let phi = 2.0 * core::f64::consts::PI * u.uniform();
            assert_eq!(a.to_bits(), (r1 * libm::cos(phi)).to_bits());
            assert_eq!(b.to_bits(), (r1 * libm::sin(phi)).to_bits());
        }
    }

    #[test]
    fn same_seed_same_stream_and_normals_are_standard() {
        let mut a = Rng::new(7);
        let mut b = Rng::new(7);
        for _ in 0..100 {
            assert_eq!(a.next_u64(), b.next_u64());
        }
        let mut r = Rng::new(1);
        let n = 200_000;
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let z = r.normal();
            s1 += z;
            s2 += z * z;
        }
        let mean = s1 / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.01, "var {var}");
        assert_ne!(Rng::new(1).next_u64(), Rng::new(2).next_u64());
    }
}
