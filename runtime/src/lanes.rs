//! Two doubles side by side: the hybrid query's pairs of computations of one shape (two
//! joint angles' sines and cosines, the nominal and the calibrated chain walked together),
//! written so that the compiler holds both in one vector register (SSE2 on x86-64, its
//! baseline; NEON on aarch64) and issues one instruction for the two.
//!
//! Every operation is lane by lane IEEE arithmetic, the same products and sums in the same
//! order as the scalar code: each lane's result is the scalar code's to the bit, whatever
//! instructions the compiler chooses (no fused multiply-add is formed: Rust never contracts
//! `a * b + c`).
//!
//! On x86-64 each operation is its SSE2 instruction. Written as two scalar operations, the
//! compiler's vectoriser regrouped them across a walk's coordinates, with shuffles between
//! (a hybrid query's model part took 0.88 of its time once they were instructions).

use std::ops::{Add, Mul, Sub};

/// Arithmetic a computation written once needs of its numbers, so that it runs on one
/// `f64` (the reference) or on a [`Pair`] of them.
pub(crate) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self>
{
    /// `v` in every lane.
    fn splat(v: f64) -> Self;
}

impl Lanes for f64 {
    #[inline(always)]
    fn splat(v: f64) -> f64 {
        v
    }
}

/// Two doubles operated on together, lane by lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub(crate) struct Pair(pub(crate) [f64; 2]);

/// Bit patterns lane by lane, where the quadrant selection of [`crate::trig`] has no vector
/// instructions for them.
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
impl Pair {
    /// The lanes' bit patterns.
    #[inline(always)]
    pub(crate) fn to_bits(self) -> [u64; 2] {
        self.0.map(f64::to_bits)
    }

    /// Doubles of these bit patterns.
    #[inline(always)]
    pub(crate) fn from_bits(bits: [u64; 2]) -> Pair {
        Pair(bits.map(f64::from_bits))
    }
}

/// SSE2, part of every x86-64 processor: a [`Pair`] is one `__m128d` register.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod sse2 {
    pub(super) use std::arch::x86_64::{__m128d, _mm_add_pd, _mm_mul_pd, _mm_sub_pd};

    use super::Pair;

    impl Pair {
        /// `op` of the two pairs' registers.
        #[inline(always)]
        pub(super) fn sse2(self, o: Pair, op: impl FnOnce(__m128d, __m128d) -> __m128d) -> Pair {
            // SAFETY: two doubles either way, every bit pattern valid in both: a
            // reinterpretation of the bits.
            let register = |p: Pair| unsafe { std::mem::transmute::<[f64; 2], __m128d>(p.0) };
            // SAFETY: as above.
            let pair = |r: __m128d| Pair(unsafe { std::mem::transmute::<__m128d, [f64; 2]>(r) });
            pair(op(register(self), register(o)))
        }
    }
}

impl Lanes for Pair {
    #[inline(always)]
    fn splat(v: f64) -> Pair {
        Pair([v; 2])
    }
}

impl Add for Pair {
    type Output = Pair;
    #[inline(always)]
    fn add(self, o: Pair) -> Pair {
        // SAFETY: the intrinsic needs SSE2, which the module's `cfg` has.
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        return self.sse2(o, |a, b| unsafe { sse2::_mm_add_pd(a, b) });
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        Pair([self.0[0] + o.0[0], self.0[1] + o.0[1]])
    }
}

impl Sub for Pair {
    type Output = Pair;
    #[inline(always)]
    fn sub(self, o: Pair) -> Pair {
        // SAFETY: the intrinsic needs SSE2, which the module's `cfg` has.
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        return self.sse2(o, |a, b| unsafe { sse2::_mm_sub_pd(a, b) });
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        Pair([self.0[0] - o.0[0], self.0[1] - o.0[1]])
    }
}

impl Mul for Pair {
    type Output = Pair;
    #[inline(always)]
    fn mul(self, o: Pair) -> Pair {
        // SAFETY: the intrinsic needs SSE2, which the module's `cfg` has.
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        return self.sse2(o, |a, b| unsafe { sse2::_mm_mul_pd(a, b) });
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        Pair([self.0[0] * o.0[0], self.0[1] * o.0[1]])
    }
}
