//! A hybrid query's model part four lanes wide ([`ReachPair::posed_model_at`]), for x86-64
//! processors with AVX2 (found when a table is opened: the baseline x86-64 has SSE2 alone,
//! two lanes).
//!
//! The walk carries three vectors per chain from the tool back: the TCP's position, its
//! approach (z) axis and its x axis. With two lanes (one per chain) each coordinate of
//! each vector is one instruction; here both chains' axes share one 256-bit register per
//! coordinate (`[z_a, z_b, x_a, x_b]`), so a joint's rotation of the two axes is one
//! instruction where it was two, and the point stays a pair (the low half of each turned
//! row). A joint's work falls from 66 vector operations to 51. The sines and cosines come
//! four at a time ([`crate::trig::wide`]).
//!
//! Every lane does the arithmetic of the two-lane walk in its order (the same products and
//! sums; no fused multiply-add, which no enabled feature forms), so the model's values are
//! the two-lane walk's to the bit (tested).

use std::arch::x86_64::{
    __m128d, _mm256_add_pd, _mm256_broadcast_pd, _mm256_castpd256_pd128, _mm256_mul_pd,
    _mm256_set_m128d, _mm256_storeu_pd, _mm256_sub_pd, _mm_add_pd, _mm_loadu_pd, _mm_mul_pd,
    _mm_set1_pd, _mm_storeu_pd,
};

use super::{ModelAt, PosedPair, ReachPair, MAX_JOINTS};
use crate::lanes::{Lanes, Pair};

/// Whether this processor runs the four-lane walk: std's detection, read once per process
/// (an atomic load after the first call).
#[inline]
pub(crate) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// [`ReachPair::posed_model_at`] compiled for AVX2, to the bit: the joints' sines and
/// cosines four at a time ([`crate::trig::wide`]), the four-lane walk and the model's values
/// from the frames, in one function (the model's values written where the query reads them).
/// Always `Some` (the form the caller returns). The whole served query compiled for AVX2
/// instead, this inlined into it, was slower: 153 ns against 148.
///
/// # Safety
///
/// The processor has AVX2 ([`available`]).
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn posed_model_at(pair: &ReachPair, q: &[f64]) -> Option<ModelAt> {
    let n = q.len().min(MAX_JOINTS);
    let mut sin_cos = [(0.0, 1.0); MAX_JOINTS];
    crate::trig::wide::sin_cos_each(&q[..n], &mut sin_cos);
    Some(walk_posed(pair, q, &sin_cos[..n]).model_at())
}

/// [`ReachPair::posed_model_at_moved`] compiled for AVX2: the chains' sines and cosines
/// four at a time, the calibrated chain's moved by `moved` (from `q` and its sines and
/// cosines), the four-lane walk with each chain at its own angles and the model's values.
///
/// # Safety
///
/// The processor has AVX2 ([`available`]).
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn posed_model_at_moved(
    pair: &ReachPair,
    q: &[f64],
    moved: impl FnOnce(&[f64], &[(f64, f64)], &mut [(f64, f64)]),
) -> Option<ModelAt> {
    let n = q.len().min(MAX_JOINTS);
    let mut sin_cos = [(0.0, 1.0); MAX_JOINTS];
    crate::trig::wide::sin_cos_each(&q[..n], &mut sin_cos);
    let mut moved_sin_cos = [(0.0, 1.0); MAX_JOINTS];
    moved(&q[..n], &sin_cos[..n], &mut moved_sin_cos[..n]);
    let posed = walk_posed_by(pair, q, n, |j| {
        let ((sa, ca), (sb, cb)) = (sin_cos[j], moved_sin_cos[j]);
        (Pair([sa, sb]), Pair([ca, cb]))
    });
    Some(posed.model_at())
}

/// [`ReachPair::walk_posed`], to the bit.
///
/// # Safety
///
/// Called only from a function compiled for AVX2 (inlined there), on a processor that has
/// it.
#[inline(always)]
pub(crate) unsafe fn walk_posed(pair: &ReachPair, q: &[f64], sin_cos: &[(f64, f64)]) -> PosedPair {
    walk_posed_by(pair, q, sin_cos.len(), |j| {
        let (s, c) = sin_cos[j];
        (Pair::splat(s), Pair::splat(c))
    })
}

/// The four-lane walk with joint `j`'s turn by `turn_of(j)`, its sines and cosines chain
/// by chain (`ReachPair::walk_posed_by`'s, to the bit), for `j` below `len`.
///
/// # Safety
///
/// Called only from a function compiled for AVX2 (inlined there), on a processor that has
/// it.
#[inline(always)]
unsafe fn walk_posed_by(
    pair: &ReachPair,
    q: &[f64],
    len: usize,
    turn_of: impl Fn(usize) -> (Pair, Pair),
) -> PosedPair {
    let n = pair.len.min(MAX_JOINTS).min(q.len()).min(len);
    let load = |p: &Pair| _mm_loadu_pd(p.0.as_ptr());
    let mut point = [
        load(&pair.tool_mm[0]),
        load(&pair.tool_mm[1]),
        load(&pair.tool_mm[2]),
    ];
    // `[z_a, z_b, x_a, x_b]`: the approach axes in the low half, the x axes in the high.
    let axes =
        |i: usize| _mm256_set_m128d(load(&pair.tool_across[i]), load(&pair.tool_approach[i]));
    let mut axes = [axes(0), axes(1), axes(2)];
    // Each entry `[r_a, r_b]` in both halves, one load. The reference to `__m128d` is
    // sound: a `Pair` is two doubles aligned to 16 bytes (`repr(C, align(16))`), as the
    // register's type needs, and every bit pattern is a valid one.
    let wide = |p: &Pair| _mm256_broadcast_pd(&*(p.0.as_ptr() as *const __m128d));
    for j in (0..n).rev() {
        let (s, c) = if pair.prismatic[j] {
            point[2] = _mm_add_pd(point[2], _mm_set1_pd(q[j]));
            (Pair::splat(0.0), Pair::splat(1.0))
        } else {
            turn_of(j)
        };
        // `[a, b, a, b]`: chain `a`'s angle in the lanes of its axes, `b`'s in its own.
        let (s, c) = (
            _mm256_set_m128d(load(&s), load(&s)),
            _mm256_set_m128d(load(&c), load(&c)),
        );
        let [p0, p1, p2] = point;
        let [v0, v1, v2] = axes;
        for (i, row) in pair.frames[j].iter().enumerate() {
            // `super::turned_row`, each entry in both halves; the point takes the low half.
            let [r0, r1, r2] = [wide(&row[0]), wide(&row[1]), wide(&row[2])];
            let m = [
                _mm256_add_pd(_mm256_mul_pd(r0, c), _mm256_mul_pd(r1, s)),
                _mm256_sub_pd(_mm256_mul_pd(r1, c), _mm256_mul_pd(r0, s)),
                r2,
            ];
            // `super::moved` and `super::rotated`.
            let low = m.map(|e| _mm256_castpd256_pd128(e));
            point[i] = _mm_add_pd(
                _mm_add_pd(_mm_mul_pd(low[0], p0), _mm_mul_pd(low[1], p1)),
                _mm_add_pd(_mm_mul_pd(low[2], p2), load(&row[3])),
            );
            axes[i] = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(m[0], v0), _mm256_mul_pd(m[1], v1)),
                _mm256_mul_pd(m[2], v2),
            );
        }
    }
    let mut p = [[0.0; 2]; 3];
    let mut a = [[0.0; 4]; 3];
    for i in 0..3 {
        _mm_storeu_pd(p[i].as_mut_ptr(), point[i]);
        _mm256_storeu_pd(a[i].as_mut_ptr(), axes[i]);
    }
    PosedPair {
        a_mm: [p[0][0], p[1][0], p[2][0]],
        a_x: [a[0][2], a[1][2], a[2][2]],
        a_z: [a[0][0], a[1][0], a[2][0]],
        b_mm: [p[0][1], p[1][1], p[2][1]],
        b_x: [a[0][3], a[1][3], a[2][3]],
        b_z: [a[0][1], a[1][1], a[2][1]],
    }
}
