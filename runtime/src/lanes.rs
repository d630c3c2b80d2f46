//! Two doubles side by side: the hybrid query's pairs of computations of one shape (two
//! joint angles' sines and cosines, the nominal and the calibrated chain walked together),
//! written so that the compiler holds both in one vector register (SSE2 on x86-64, its
//! baseline; NEON on aarch64) and issues one instruction for the two.
//!
//! Every operation is lane by lane IEEE arithmetic, the same products and sums in the same
//! order as the scalar code: each lane's result is the scalar code's to the bit, whatever
//! instructions the compiler chooses (no fused multiply-add is formed: Rust never contracts
//! `a * b + c`).

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
        Pair([self.0[0] + o.0[0], self.0[1] + o.0[1]])
    }
}

impl Sub for Pair {
    type Output = Pair;
    #[inline(always)]
    fn sub(self, o: Pair) -> Pair {
        Pair([self.0[0] - o.0[0], self.0[1] - o.0[1]])
    }
}

impl Mul for Pair {
    type Output = Pair;
    #[inline(always)]
    fn mul(self, o: Pair) -> Pair {
        Pair([self.0[0] * o.0[0], self.0[1] * o.0[1]])
    }
}
