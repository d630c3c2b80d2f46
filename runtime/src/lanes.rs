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

    /// `op` of the two pairs as SSE2 registers.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn sse2(
        self,
        o: Pair,
        op: unsafe fn(
            std::arch::x86_64::__m128d,
            std::arch::x86_64::__m128d,
        ) -> std::arch::x86_64::__m128d,
    ) -> Pair {
        use std::arch::x86_64::__m128d;
        use std::mem::transmute;
        // SAFETY: `__m128d` is two doubles, as `[f64; 2]` is (a plain bit reinterpretation
        // both ways), and `op` is an SSE2 arithmetic intrinsic: SSE2 is part of x86-64.
        unsafe {
            let (a, b) = (
                transmute::<[f64; 2], __m128d>(self.0),
                transmute::<[f64; 2], __m128d>(o.0),
            );
            Pair(transmute::<__m128d, [f64; 2]>(op(a, b)))
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
        #[cfg(target_arch = "x86_64")]
        return Pair::sse2(self, o, std::arch::x86_64::_mm_add_pd);
        #[cfg(not(target_arch = "x86_64"))]
        Pair([self.0[0] + o.0[0], self.0[1] + o.0[1]])
    }
}

impl Sub for Pair {
    type Output = Pair;
    #[inline(always)]
    fn sub(self, o: Pair) -> Pair {
        #[cfg(target_arch = "x86_64")]
        return Pair::sse2(self, o, std::arch::x86_64::_mm_sub_pd);
        #[cfg(not(target_arch = "x86_64"))]
        Pair([self.0[0] - o.0[0], self.0[1] - o.0[1]])
    }
}

impl Mul for Pair {
    type Output = Pair;
    #[inline(always)]
    fn mul(self, o: Pair) -> Pair {
        #[cfg(target_arch = "x86_64")]
        return Pair::sse2(self, o, std::arch::x86_64::_mm_mul_pd);
        #[cfg(not(target_arch = "x86_64"))]
        Pair([self.0[0] * o.0[0], self.0[1] * o.0[1]])
    }
}
