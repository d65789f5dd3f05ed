//! `sincos` for the friction model's hot path: two-part Cody-Waite reduction by π/2 and the classic minimax
//! kernels on [-π/4, π/4]; about a third of a general-purpose `sincos`. Angles beyond ±1.6e6 rad (the two-part
//! reduction's exact range) use `libm::sincos`. Accuracy: within a few 1e-16 of `libm` (tested).

// The constants keep their published digits; the compiler rounds them to the nearest f64.
#![allow(clippy::excessive_precision)]

const FRAC_2_PI: f64 = core::f64::consts::FRAC_2_PI;
/// π/2 split: the first 33 bits (so `n * PIO2_HI` is exact for |n| < 2^20) and the rest.
const PIO2_HI: f64 = 1.570_796_326_734_125_614_17e0;
const PIO2_LO: f64 = 6.077_100_506_506_192_249_32e-11;
const LIMIT: f64 = 1.6e6;
const ROUND_SHIFT: f64 = 6_755_399_441_055_744.0;

// sin(x) ≈ x + x³(S1 + x²(S2 + …)) and cos(x) ≈ 1 − x²/2 + x⁴(C1 + x²(C2 + …)) on |x| ≤ π/4.
const S1: f64 = -1.666_666_666_666_663_243_48e-01;
const S2: f64 = 8.333_333_333_322_489_461_22e-03;
const S3: f64 = -1.984_126_982_985_794_931_22e-04;
const S4: f64 = 2.755_731_370_707_006_767_89e-06;
const S5: f64 = -2.505_076_025_340_686_341_95e-08;
const S6: f64 = 1.589_690_995_211_550_070_49e-10;
const C1: f64 = 4.166_666_666_666_660_190_37e-02;
const C2: f64 = -1.388_888_888_887_410_957_49e-03;
const C3: f64 = 2.480_158_728_947_672_941_57e-05;
const C4: f64 = -2.755_731_435_139_066_330_35e-07;
const C5: f64 = 2.087_572_321_298_174_827_87e-09;
const C6: f64 = -1.135_964_755_778_819_482_37e-11;

/// `(sin x, cos x)`; NaN in, NaN out.
#[inline]
pub fn sincos(x: f64) -> (f64, f64) {
    if x.is_nan() || x.abs() >= LIMIT {
        return libm::sincos(x);
    }
    // Round to nearest by the 1.5·2^52 shift (exact for |x·2/π| < 2^51; here < 2^20).
    let n = (x * FRAC_2_PI + ROUND_SHIFT) - ROUND_SHIFT;
    let r = (x - n * PIO2_HI) - n * PIO2_LO;
    let z = r * r;
    let s = r + r * z * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    let c =
        w + (((1.0 - w) - hz) + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))));
    match (n as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn matches_libm() {
        let mut worst: f64 = 0.0;
        let mut x = -1.7e6;
        while x < 1.7e6 {
            let (s, c) = super::sincos(x);
            let (ls, lc) = libm::sincos(x);
            worst = worst.max((s - ls).abs()).max((c - lc).abs());
            x += 12.345_678_9;
        }
        for i in 0..100_000 {
            let x = -10.0 + 2e-4 * i as f64;
            let (s, c) = super::sincos(x);
            let (ls, lc) = libm::sincos(x);
            worst = worst.max((s - ls).abs()).max((c - lc).abs());
        }
        assert!(worst < 1e-15, "worst deviation from libm {worst:e}");
        assert!(super::sincos(f64::NAN).0.is_nan());
    }
}
