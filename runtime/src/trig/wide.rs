//! [`super::sin_cos_each`] four angles at a time, for x86-64 processors with AVX2 (found at
//! run time; [`crate::chain`]'s wide walk calls it): the reduction and the polynomials
//! ([`super::reduced_kernels`], written once for every width) in a 256-bit register, and
//! the quadrants' selection on AVX2's integer lanes. Each lane is
//! [`super::reduced_sin_cos`] of its angle to the bit: the same IEEE operations in the same
//! order (no fused multiply-add: no `fma` feature is enabled), the selection by bits.

use std::arch::x86_64::{
    __m256d, __m256i, _mm256_add_epi64, _mm256_add_pd, _mm256_and_si256, _mm256_andnot_si256,
    _mm256_castpd_si256, _mm256_castsi256_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_or_si256,
    _mm256_set1_epi64x, _mm256_set1_pd, _mm256_setzero_si256, _mm256_slli_epi64, _mm256_storeu_pd,
    _mm256_sub_epi64, _mm256_sub_pd, _mm256_xor_si256,
};
use std::ops::{Add, Mul, Sub};

use crate::lanes::Lanes;

/// Four doubles in one 256-bit register.
///
/// Its operations are AVX instructions: a `Quad` is made only inside this module's
/// functions, each compiled for AVX2 and called only where the processor has it.
#[derive(Clone, Copy)]
struct Quad(__m256d);

impl Lanes for Quad {
    #[inline(always)]
    fn splat(v: f64) -> Quad {
        // SAFETY: AVX, which every caller has (type docs).
        Quad(unsafe { _mm256_set1_pd(v) })
    }
}

impl Add for Quad {
    type Output = Quad;
    #[inline(always)]
    fn add(self, o: Quad) -> Quad {
        // SAFETY: as `splat`.
        Quad(unsafe { _mm256_add_pd(self.0, o.0) })
    }
}

impl Sub for Quad {
    type Output = Quad;
    #[inline(always)]
    fn sub(self, o: Quad) -> Quad {
        // SAFETY: as `splat`.
        Quad(unsafe { _mm256_sub_pd(self.0, o.0) })
    }
}

impl Mul for Quad {
    type Output = Quad;
    #[inline(always)]
    fn mul(self, o: Quad) -> Quad {
        // SAFETY: as `splat`.
        Quad(unsafe { _mm256_mul_pd(self.0, o.0) })
    }
}

/// [`super::sin_cos_each`] of `angles` into `out` (as many as the shorter holds), four at
/// a time when the reduction serves them all (the last four padded with zeros), the
/// library's otherwise, as there.
///
/// # Safety
///
/// Called only from a function compiled for AVX2 (inlined there: its instructions are
/// then AVX2's), on a processor that has it.
#[inline(always)]
pub(crate) unsafe fn sin_cos_each(angles: &[f64], out: &mut [(f64, f64)]) {
    let n = angles.len().min(out.len());
    let (angles, out) = (&angles[..n], &mut out[..n]);
    if !angles.iter().all(|&x| super::reduces(x)) {
        return super::sin_cos_each(angles, out);
    }
    for (o, x) in out.chunks_mut(4).zip(angles.chunks(4)) {
        // Lane by lane, not a copy of the slice: that was a call to `memcpy`.
        let lanes: [f64; 4] = std::array::from_fn(|l| x.get(l).copied().unwrap_or(0.0));
        let (shifted, s, c) = super::reduced_kernels(Quad(_mm256_loadu_pd(lanes.as_ptr())));
        let (sin, cos) = by_quadrant(
            _mm256_castpd_si256(shifted.0),
            _mm256_castpd_si256(s.0),
            _mm256_castpd_si256(c.0),
        );
        let (mut sin_lanes, mut cos_lanes) = ([0.0; 4], [0.0; 4]);
        _mm256_storeu_pd(sin_lanes.as_mut_ptr(), _mm256_castsi256_pd(sin));
        _mm256_storeu_pd(cos_lanes.as_mut_ptr(), _mm256_castsi256_pd(cos));
        for (l, o) in o.iter_mut().enumerate() {
            *o = (sin_lanes[l], cos_lanes[l]);
        }
    }
}

/// [`super::by_quadrant`] lane by lane: an odd quadrant's swap by selection, the signs by
/// exclusive or.
#[inline(always)]
unsafe fn by_quadrant(quadrant: __m256i, s: __m256i, c: __m256i) -> (__m256i, __m256i) {
    let (one, two) = (_mm256_set1_epi64x(1), _mm256_set1_epi64x(2));
    // All ones for an odd quadrant.
    let swap = _mm256_sub_epi64(_mm256_setzero_si256(), _mm256_and_si256(quadrant, one));
    let sin = _mm256_or_si256(_mm256_andnot_si256(swap, s), _mm256_and_si256(c, swap));
    let cos = _mm256_or_si256(_mm256_andnot_si256(swap, c), _mm256_and_si256(s, swap));
    let sin_sign = _mm256_slli_epi64::<62>(_mm256_and_si256(quadrant, two));
    let cos_sign = _mm256_slli_epi64::<62>(_mm256_and_si256(_mm256_add_epi64(quadrant, one), two));
    (
        _mm256_xor_si256(sin, sin_sign),
        _mm256_xor_si256(cos, cos_sign),
    )
}
