//! The sine and cosine of a joint angle, together: what every forward kinematics of a
//! hybrid query starts with, one pair a joint.
//!
//! `f64::sin_cos` calls the platform's library, an opaque call a joint that the compiler
//! can neither inline nor overlap with the next joint's. [`sin_cos`] is fdlibm's method
//! (as musl has it, public domain) written inline and without branches for the angles a
//! joint takes: one Cody–Waite reduction by π/2 shared by the sine and the cosine, fdlibm's
//! minimax kernels on the reduced angle `r` (`|r| ≤ π/4`, carried in two parts), and the
//! quadrant's swap and signs applied by selection. Beyond `2²⁰ · π/2` (1.6 · 10⁶ rad), where
//! the reduction's product would no longer be exact, and for non-finite angles, it is
//! `f64::sin_cos`. [`sin_cos_each`] takes a chain's angles together, so that the compiler
//! runs two at a time in a vector register. Tests hold it to `f64::sin_cos` within one unit
//! in the last place (over two turns each way, 6 % of angles differ from glibc's by one
//! unit, none by more).

// fdlibm's constants as it writes them, to 21 digits: each the double it names.
#![allow(clippy::excessive_precision)]

use crate::lanes::{Lanes, Pair};

/// `2⁵² + 2⁵¹`: adding and subtracting it rounds a double below `2⁵¹` to an integer.
const TO_INT: f64 = 6755399441055744.0;
const INV_PIO2: f64 = std::f64::consts::FRAC_2_PI;
/// π/2 in three parts (fdlibm's `pio2_1`, `pio2_2`, `pio2_2t`): the first two hold 33 bits
/// each, so that their products with a quotient of up to 20 bits are exact.
const PIO2_1: f64 = 1.570_796_326_734_125_614_17;
const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
/// The largest angle the reduction serves: a quotient of at most 2²⁰.
const REDUCED_UP_TO: f64 = 1_647_099.0;

/// fdlibm's sine kernel coefficients (`__sin`).
const S1: f64 = -1.666_666_666_666_663_243_48e-1;
const S2: f64 = 8.333_333_333_322_489_461_24e-3;
const S3: f64 = -1.984_126_982_985_794_931_34e-4;
const S4: f64 = 2.755_731_370_707_006_767_89e-6;
const S5: f64 = -2.505_076_025_340_686_341_95e-8;
const S6: f64 = 1.589_690_995_211_550_102_21e-10;

/// fdlibm's cosine kernel coefficients (`__cos`).
const C1: f64 = 4.166_666_666_666_660_190_37e-2;
const C2: f64 = -1.388_888_888_887_410_957_49e-3;
const C3: f64 = 2.480_158_728_947_672_941_78e-5;
const C4: f64 = -2.755_731_435_139_066_330_35e-7;
const C5: f64 = 2.087_572_321_298_174_827_90e-9;
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

/// `(sin x, cos x)`, within one unit in the last place of `f64::sin_cos` (module docs).
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if reduces(x) {
        reduced_sin_cos(x)
    } else {
        x.sin_cos()
    }
}

/// [`sin_cos`] of each of `angles` into `out` (as many as the shorter holds): one test of
/// them all, then two angles at a time without branches, side by side in a vector register
/// ([`crate::lanes`]), each pair's lanes to the bit what [`sin_cos`] gives of each angle.
#[inline]
pub fn sin_cos_each(angles: &[f64], out: &mut [(f64, f64)]) {
    let n = angles.len().min(out.len());
    let (angles, out) = (&angles[..n], &mut out[..n]);
    if !angles.iter().all(|&x| reduces(x)) {
        for (o, &x) in out.iter_mut().zip(angles) {
            *o = x.sin_cos();
        }
        return;
    }
    let mut pairs = out.chunks_exact_mut(2);
    for (o, x) in (&mut pairs).zip(angles.chunks_exact(2)) {
        let (sin, cos) = reduced_sin_cos_pair(Pair([x[0], x[1]]));
        o[0] = (sin.0[0], cos.0[0]);
        o[1] = (sin.0[1], cos.0[1]);
    }
    if let (Some(o), Some(&x)) = (pairs.into_remainder().first_mut(), angles.last()) {
        *o = reduced_sin_cos(x);
    }
}

/// Whether the reduction serves `x` (false for NaN and the infinities).
#[inline]
fn reduces(x: f64) -> bool {
    x.abs() <= REDUCED_UP_TO
}

/// [`sin_cos`] for an angle the reduction serves, without a branch.
#[inline]
fn reduced_sin_cos(x: f64) -> (f64, f64) {
    let (shifted, s, c) = reduced_kernels(x);
    let (sin, cos) = by_quadrant(shifted.to_bits(), s.to_bits(), c.to_bits());
    (f64::from_bits(sin), f64::from_bits(cos))
}

/// [`reduced_sin_cos`] of two angles at once, lane by lane.
#[inline]
fn reduced_sin_cos_pair(x: Pair) -> (Pair, Pair) {
    let (shifted, s, c) = reduced_kernels(x);
    let (quadrant, s, c) = (shifted.to_bits(), s.to_bits(), c.to_bits());
    let [a, b] = [0, 1].map(|l| by_quadrant(quadrant[l], s[l], c[l]));
    (Pair::from_bits([a.0, b.0]), Pair::from_bits([a.1, b.1]))
}

/// The reduction and the kernels, written once for one angle and for a [`Pair`]: the
/// nearest multiple `n` of π/2 as `shifted` (whose last bits hold `n mod 4`), and the sine
/// and cosine of `x − n π/2`.
#[inline(always)]
fn reduced_kernels<T: Lanes>(x: T) -> (T, T, T) {
    let k = T::splat;
    // The nearest multiple n of π/2, and `r = x − n π/2` as `hi + lo` (fdlibm's second
    // round, good to 118 bits, taken always rather than when the first round cancels).
    let shifted = x * k(INV_PIO2) + k(TO_INT);
    let n = shifted - k(TO_INT);
    let t = x - n * k(PIO2_1);
    let w = n * k(PIO2_2);
    let r = t - w;
    let w = n * k(PIO2_2T) - ((t - r) - w);
    let hi = r - w;
    let lo = (r - hi) - w;
    (shifted, kernel_sin(hi, lo), kernel_cos(hi, lo))
}

/// The sine and cosine of an angle (as bits) from those of its reduction by `n` quarter
/// turns: `sin x = (s, c, −s, −c)[n mod 4]`, `cos x = (c, −s, −c, s)[n mod 4]`, by
/// selection and sign flips, without a branch.
#[inline(always)]
fn by_quadrant(quadrant: u64, s: u64, c: u64) -> (u64, u64) {
    // All ones for an odd quadrant, which swaps the sine and the cosine.
    let swap = 0u64.wrapping_sub(quadrant & 1);
    let (sin, cos) = ((s & !swap) | (c & swap), (c & !swap) | (s & swap));
    let sin_sign = (quadrant & 2) << 62;
    let cos_sign = (quadrant.wrapping_add(1) & 2) << 62;
    (sin ^ sin_sign, cos ^ cos_sign)
}

/// fdlibm's `__sin(x, y, 1)`: `sin(x + y)` for `|x| ≤ π/4`, `|y|` below half an ulp of `x`.
#[inline(always)]
fn kernel_sin<T: Lanes>(x: T, y: T) -> T {
    let k = T::splat;
    let z = x * x;
    let w = z * z;
    let r = k(S2) + z * (k(S3) + z * k(S4)) + z * w * (k(S5) + z * k(S6));
    let v = z * x;
    x - ((z * (k(0.5) * y - v * r) - y) - v * k(S1))
}

/// fdlibm's `__cos(x, y)`: `cos(x + y)` for `|x| ≤ π/4`, `|y|` below half an ulp of `x`.
#[inline(always)]
fn kernel_cos<T: Lanes>(x: T, y: T) -> T {
    let k = T::splat;
    let z = x * x;
    let w = z * z;
    let r = z * (k(C1) + z * (k(C2) + z * k(C3))) + w * w * (k(C4) + z * (k(C5) + z * k(C6)));
    let hz = k(0.5) * z;
    let w = k(1.0) - hz;
    w + (((k(1.0) - w) - hz) + (z * r - x * y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The distance between two doubles in units in the last place (0 for equal ones,
    /// including +0 and −0).
    fn ulps(a: f64, b: f64) -> u64 {
        let key = |v: f64| {
            let bits = v.to_bits() as i64;
            if bits < 0 {
                i64::MIN - bits
            } else {
                bits
            }
        };
        key(a).abs_diff(key(b))
    }

    fn worst(angles: impl Iterator<Item = f64>) -> u64 {
        angles
            .map(|x| {
                let (s, c) = sin_cos(x);
                let (ws, wc) = x.sin_cos();
                ulps(s, ws).max(ulps(c, wc))
            })
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn a_dense_sweep_of_joint_angles_is_within_one_ulp_of_the_library() {
        // Two turns each way in steps of about 3e-6 rad: 8 · 10⁶ angles, every quadrant
        // and every octant boundary many times over.
        let steps = 8_000_000;
        let span = 4.0 * std::f64::consts::TAU;
        let sweep = (0..=steps).map(|i| -span / 2.0 + span * i as f64 / steps as f64);
        assert!(worst(sweep) <= 1);
    }

    #[test]
    fn multiples_of_a_quarter_turn_and_their_neighbours_are_within_one_ulp() {
        // Where the reduction cancels most: the doubles next to k π/2.
        let near = (-4096_i32..=4096).flat_map(|k| {
            let at = f64::from(k) * std::f64::consts::FRAC_PI_2;
            let bits = at.to_bits();
            (0..8_u64).flat_map(move |d| {
                [
                    f64::from_bits(bits + d),
                    f64::from_bits(bits.saturating_sub(d)),
                ]
            })
        });
        assert!(worst(near) <= 1);
    }

    #[test]
    fn special_angles_are_the_library_s() {
        for x in [0.0, -0.0, f64::MIN_POSITIVE, -5e-324, 1e-300, 1e-9] {
            let (s, c) = sin_cos(x);
            assert_eq!(s.to_bits(), x.sin().to_bits(), "{x}");
            assert_eq!(c, 1.0, "{x}");
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan());
        }
        for x in [REDUCED_UP_TO, -REDUCED_UP_TO, 2e6, -1e300, f64::MAX] {
            let (s, c) = sin_cos(x);
            let (ws, wc) = x.sin_cos();
            assert!(ulps(s, ws) <= 1 && ulps(c, wc) <= 1, "{x}");
        }
    }

    #[test]
    fn each_angle_of_a_batch_is_its_own_sin_cos() {
        let angles = [0.3, -2.9, 7.0, -1e-5, 1e5, std::f64::consts::PI, 0.0, -12.5];
        let mut out = [(0.0, 0.0); 8];
        sin_cos_each(&angles, &mut out);
        for (o, x) in out.iter().zip(angles) {
            assert_eq!(*o, sin_cos(x));
        }
        // One angle beyond the reduction: the library's, for every one of them.
        let far = [0.3, 1e300, -2.0];
        let mut out = [(0.0, 0.0); 3];
        sin_cos_each(&far, &mut out);
        for (o, x) in out.iter().zip(far) {
            assert_eq!(*o, x.sin_cos());
        }
        // Fewer outputs than angles: as many as fit, and no panic.
        let mut short = [(0.0, 0.0); 2];
        sin_cos_each(&angles, &mut short);
        assert_eq!(short[1], sin_cos(-2.9));
    }

    #[test]
    fn a_pair_s_lanes_are_each_angle_s_own_to_the_bit() {
        // Every quadrant and the doubles next to its boundaries, in both lanes and against
        // a neighbour of another quadrant.
        let angles: Vec<f64> = (-64_i32..=64)
            .flat_map(|k| {
                let at = f64::from(k) * std::f64::consts::FRAC_PI_4;
                [at, f64::from_bits(at.to_bits() + 1), at + 1e-3, -at]
            })
            .collect();
        for (&a, &b) in angles.iter().zip(angles.iter().rev()) {
            let (sin, cos) = reduced_sin_cos_pair(Pair([a, b]));
            for (lane, x) in [a, b].into_iter().enumerate() {
                let (s, c) = reduced_sin_cos(x);
                assert_eq!(
                    [sin.0[lane].to_bits(), cos.0[lane].to_bits()],
                    [s.to_bits(), c.to_bits()],
                    "{x}"
                );
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]
        #[test]
        fn random_angles_are_within_one_ulp(x in -REDUCED_UP_TO..REDUCED_UP_TO) {
            let (s, c) = sin_cos(x);
            let (ws, wc) = x.sin_cos();
            prop_assert!(ulps(s, ws) <= 1 && ulps(c, wc) <= 1, "{x}: {s} {c} vs {ws} {wc}");
        }

        #[test]
        fn random_pairs_are_their_angles_own_to_the_bit(
            a in -REDUCED_UP_TO..REDUCED_UP_TO,
            b in -10.0..10.0_f64,
        ) {
            let (sin, cos) = reduced_sin_cos_pair(Pair([a, b]));
            for (lane, x) in [a, b].into_iter().enumerate() {
                let (s, c) = reduced_sin_cos(x);
                prop_assert_eq!(sin.0[lane].to_bits(), s.to_bits());
                prop_assert_eq!(cos.0[lane].to_bits(), c.to_bits());
            }
        }
    }
}
