//! The sine and cosine of a joint angle, together: what every forward kinematics of a
//! hybrid query starts with, one pair a joint.
//!
//! `f64::sin_cos` calls the platform's library, an opaque call a joint that the compiler
//! can neither inline nor overlap with the next joint's. [`sin_cos`] is written inline and
//! without branches for the angles a joint takes: one Cody–Waite reduction by π/2 shared by
//! the sine and the cosine, fdlibm's minimax polynomials (as musl has them, public domain)
//! on the reduced angle `r` (`|r| ≤ π/4`), and the quadrant's swap and signs applied by
//! selection. Beyond `2²⁰ · π/2` (1.6 · 10⁶ rad), where the reduction's product would no
//! longer be exact, and for non-finite angles, it is `f64::sin_cos`. [`sin_cos_each`] takes
//! a chain's angles together, so that the compiler runs two at a time in a vector register.
//!
//! # Accuracy: absolute, as lengths need it
//!
//! A joint's sine and cosine multiply lengths, so what a pose needs of them is an absolute
//! bound: an error `ε` moves a point a metre out by `ε` metres. Tests hold both to
//! `f64::sin_cos` within `2⁻⁵¹` (4.4 · 10⁻¹⁶) absolute over two turns each way, at the doubles
//! next to every multiple of π/2 up to 6,400 rad, and at random angles up to the reduction's
//! limit; the largest difference they meet is `2⁻⁵²`, 2.2 · 10⁻¹⁶ (0.2 fm at a metre).
//! fdlibm's own form is also accurate *relative* to a result near zero: a second reduction
//! round and the reduced angle carried in two parts, which doubles the chain of dependent
//! operations every joint's walk waits for, to improve what is already below 10⁻¹⁶ of
//! the reach. The reduction here is one round, `r = (x − n·p₁) − n·p₁ₜ` with `n·p₁` exact,
//! and the polynomials are evaluated in Estrin's form (powers of `r²` side by side) rather
//! than Horner's, for the same reason.

// fdlibm's constants as it writes them, to 21 digits: each the double it names.
#![allow(clippy::excessive_precision)]

use crate::lanes::{Lanes, Pair};

/// `2⁵² + 2⁵¹`: adding and subtracting it rounds a double below `2⁵¹` to an integer.
const TO_INT: f64 = 6755399441055744.0;
const INV_PIO2: f64 = std::f64::consts::FRAC_2_PI;
/// π/2 in two parts (fdlibm's `pio2_1`, `pio2_1t`): the first holds 33 bits, so that its
/// product with a quotient of up to 20 bits is exact; the second is the rest of π/2.
const PIO2_1: f64 = 1.570_796_326_734_125_614_17;
const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
/// The largest angle the reduction serves: a quotient of at most 2²⁰.
const REDUCED_UP_TO: f64 = 1_647_099.0;

/// fdlibm's sine kernel coefficients (`__sin`): `sin r ≈ r + r³ Σ S_i r^(2i−2)`.
const S1: f64 = -1.666_666_666_666_663_243_48e-1;
const S2: f64 = 8.333_333_333_322_489_461_24e-3;
const S3: f64 = -1.984_126_982_985_794_931_34e-4;
const S4: f64 = 2.755_731_370_707_006_767_89e-6;
const S5: f64 = -2.505_076_025_340_686_341_95e-8;
const S6: f64 = 1.589_690_995_211_550_102_21e-10;

/// fdlibm's cosine kernel coefficients (`__cos`): `cos r ≈ 1 − r²/2 + r⁴ Σ C_i r^(2i−2)`.
const C1: f64 = 4.166_666_666_666_660_190_37e-2;
const C2: f64 = -1.388_888_888_887_410_957_49e-3;
const C3: f64 = 2.480_158_728_947_672_941_78e-5;
const C4: f64 = -2.755_731_435_139_066_330_35e-7;
const C5: f64 = 2.087_572_321_298_174_827_90e-9;
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

/// `(sin x, cos x)`, each within `2⁻⁵¹` of `f64::sin_cos`'s, absolute (module docs).
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
    by_quadrant_pair(shifted, s, c)
}

/// [`by_quadrant`] of both lanes, on SSE2's integer lanes: the selection and the signs in
/// the vector register, where lane by lane each double went to a general register and back.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
fn by_quadrant_pair(shifted: Pair, s: Pair, c: Pair) -> (Pair, Pair) {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi64, _mm_and_si128, _mm_andnot_si128, _mm_or_si128, _mm_set1_epi64x,
        _mm_setzero_si128, _mm_slli_epi64, _mm_sub_epi64, _mm_xor_si128,
    };
    // SAFETY: two doubles and two 64-bit integers, every bit pattern valid in both.
    let bits = |p: Pair| unsafe { std::mem::transmute::<[f64; 2], __m128i>(p.0) };
    // SAFETY: as above.
    let pair = |r: __m128i| Pair(unsafe { std::mem::transmute::<__m128i, [f64; 2]>(r) });
    let (quadrant, s, c) = (bits(shifted), bits(s), bits(c));
    // SAFETY: SSE2 instructions, which the function's `cfg` has.
    unsafe {
        let (one, two) = (_mm_set1_epi64x(1), _mm_set1_epi64x(2));
        let swap = _mm_sub_epi64(_mm_setzero_si128(), _mm_and_si128(quadrant, one));
        let sin = _mm_or_si128(_mm_andnot_si128(swap, s), _mm_and_si128(c, swap));
        let cos = _mm_or_si128(_mm_andnot_si128(swap, c), _mm_and_si128(s, swap));
        let sin_sign = _mm_slli_epi64::<62>(_mm_and_si128(quadrant, two));
        let cos_sign = _mm_slli_epi64::<62>(_mm_and_si128(_mm_add_epi64(quadrant, one), two));
        (
            pair(_mm_xor_si128(sin, sin_sign)),
            pair(_mm_xor_si128(cos, cos_sign)),
        )
    }
}

/// [`by_quadrant`] of both lanes, one after the other.
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
#[inline(always)]
fn by_quadrant_pair(shifted: Pair, s: Pair, c: Pair) -> (Pair, Pair) {
    let (quadrant, s, c) = (shifted.to_bits(), s.to_bits(), c.to_bits());
    let a = by_quadrant(quadrant[0], s[0], c[0]);
    let b = by_quadrant(quadrant[1], s[1], c[1]);
    (Pair::from_bits([a.0, b.0]), Pair::from_bits([a.1, b.1]))
}

/// The reduction and the polynomials, written once for one angle and for a [`Pair`]: the
/// nearest multiple `n` of π/2 as `shifted` (whose last bits hold `n mod 4`), and the sine
/// and cosine of `r = x − n π/2`.
#[inline(always)]
fn reduced_kernels<T: Lanes>(x: T) -> (T, T, T) {
    let k = T::splat;
    let shifted = x * k(INV_PIO2) + k(TO_INT);
    let n = shifted - k(TO_INT);
    // `x − n·p₁` is exact (`n·p₁` is, and it is within a factor of two of `x` or `n` is 0);
    // `n·p₁ₜ` is below `2⁻¹³`, so its rounding is below 10⁻²⁰ and `r`'s own remains.
    let r = (x - n * k(PIO2_1)) - n * k(PIO2_1T);
    let z = r * r;
    let z2 = z * z;
    let z4 = z2 * z2;
    // `sin r = r + r³ P(r²)`, `cos r = 1 − r²/2 + r⁴ Q(r²)`, each polynomial's three pairs
    // of terms side by side.
    let p = (k(S1) + z * k(S2)) + z2 * (k(S3) + z * k(S4)) + z4 * (k(S5) + z * k(S6));
    let q = (k(C1) + z * k(C2)) + z2 * (k(C3) + z * k(C4)) + z4 * (k(C5) + z * k(C6));
    let sin = r + (r * z) * p;
    let cos = (k(1.0) - k(0.5) * z) + z2 * q;
    (shifted, sin, cos)
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

#[cfg(target_arch = "x86_64")]
pub(crate) mod wide;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The bound [`sin_cos`] is held to: `2⁻⁵¹`, absolute (module docs).
    const BOUND: f64 = 2.0 * f64::EPSILON;

    /// The largest absolute difference from `f64::sin_cos` over `angles`, sine or cosine.
    fn worst(angles: impl Iterator<Item = f64>) -> f64 {
        angles
            .map(|x| {
                let (s, c) = sin_cos(x);
                let (ws, wc) = x.sin_cos();
                (s - ws).abs().max((c - wc).abs())
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_dense_sweep_of_joint_angles_is_within_the_bound_of_the_library() {
        // Two turns each way in steps of about 3e-6 rad: 8 · 10⁶ angles, every quadrant
        // and every octant boundary many times over.
        let steps = 8_000_000;
        let span = 4.0 * std::f64::consts::TAU;
        let sweep = (0..=steps).map(|i| -span / 2.0 + span * i as f64 / steps as f64);
        assert!(worst(sweep) <= BOUND);
    }

    #[test]
    fn multiples_of_a_quarter_turn_and_their_neighbours_are_within_the_bound() {
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
        assert!(worst(near) <= BOUND);
    }

    #[test]
    fn special_angles_are_the_library_s() {
        for x in [f64::MIN_POSITIVE, -5e-324, 1e-300, 1e-9, -1e-9] {
            let (s, c) = sin_cos(x);
            assert_eq!(s.to_bits(), x.sin().to_bits(), "{x}");
            assert_eq!(c, 1.0, "{x}");
        }
        // A zero angle's sine is zero, of either sign for −0 (a length times it is zero).
        for x in [0.0, -0.0] {
            assert_eq!(sin_cos(x), (0.0, 1.0), "{x}");
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan());
        }
        for x in [REDUCED_UP_TO, -REDUCED_UP_TO] {
            assert!(worst([x].into_iter()) <= BOUND, "{x}");
        }
        // Beyond the reduction: the library's own.
        for x in [2e6, -1e300, f64::MAX] {
            assert_eq!(sin_cos(x), x.sin_cos(), "{x}");
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

    /// [`wide::sin_cos_each`] where it is compiled: in a function compiled for AVX2.
    ///
    /// # Safety
    ///
    /// The processor has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn wide_sin_cos_each(angles: &[f64], out: &mut [(f64, f64)]) {
        wide::sin_cos_each(angles, out)
    }

    /// Four at a time on AVX2, each angle's [`sin_cos`] to the bit: every quadrant and its
    /// boundaries in every lane, batches of 1 to 12 (the padded last group), and an angle
    /// beyond the reduction sending the batch to the library.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn four_lanes_are_each_angle_s_own_to_the_bit() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let angles: Vec<f64> = (-64_i32..=64)
            .flat_map(|k| {
                let at = f64::from(k) * std::f64::consts::FRAC_PI_4;
                [at, f64::from_bits(at.to_bits() + 1), at + 1e-3, -at, -0.0]
            })
            .collect();
        for len in 1..=12 {
            for batch in angles.windows(len) {
                let mut out = [(0.0, 0.0); 12];
                // SAFETY: the processor has AVX2 (above).
                unsafe { wide_sin_cos_each(batch, &mut out) };
                for (o, &x) in out.iter().zip(batch) {
                    let (s, c) = sin_cos(x);
                    assert_eq!(
                        [o.0.to_bits(), o.1.to_bits()],
                        [s.to_bits(), c.to_bits()],
                        "{x}"
                    );
                }
            }
        }
        let far = [0.3, 1e300, -2.0, f64::NAN, 5.0];
        let mut out = [(0.0, 0.0); 5];
        // SAFETY: as above.
        unsafe { wide_sin_cos_each(&far, &mut out) };
        for (o, x) in out.iter().zip(far) {
            let (s, c) = x.sin_cos();
            assert_eq!(
                [o.0.to_bits(), o.1.to_bits()],
                [s.to_bits(), c.to_bits()],
                "{x}"
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]
        #[test]
        fn random_angles_are_within_the_bound(x in -REDUCED_UP_TO..REDUCED_UP_TO) {
            let (s, c) = sin_cos(x);
            let (ws, wc) = x.sin_cos();
            prop_assert!(worst([x].into_iter()) <= BOUND, "{x}: {s} {c} vs {ws} {wc}");
        }

        #[cfg(target_arch = "x86_64")]
        #[test]
        fn random_quads_are_their_angles_own_to_the_bit(
            angles in proptest::collection::vec(-REDUCED_UP_TO..REDUCED_UP_TO, 1..=12),
        ) {
            if std::arch::is_x86_feature_detected!("avx2") {
                let mut out = [(0.0, 0.0); 12];
                // SAFETY: the processor has AVX2.
                unsafe { wide_sin_cos_each(&angles, &mut out) };
                for (o, &x) in out.iter().zip(&angles) {
                    let (s, c) = reduced_sin_cos(x);
                    prop_assert_eq!([o.0.to_bits(), o.1.to_bits()], [s.to_bits(), c.to_bits()]);
                }
            }
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
