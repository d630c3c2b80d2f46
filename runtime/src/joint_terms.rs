//! Joint-space error terms of a calibrated model: errors periodic in a joint's angle.
//!
//! A joint's gear train (strain-wave or cycloidal gears, the encoder's mounting) turns the
//! joint by slightly more or less than commanded, by an amount that repeats with the
//! joint's angle. Its first two harmonics are the part a calibration can see over one
//! turn of the joint:
//!
//! ```text
//! q_j' = q_j + a1_j sin q_j + b1_j cos q_j + a2_j sin 2q_j + b2_j cos 2q_j
//! ```
//!
//! `q` the commanded joint angle, `q'` the one the arm turns to (rad), before its gravity
//! deflection. A term is known only over the angles it was identified from: beyond the
//! joint's range of those (`range_rad`) it is held at its value at the range's nearer end
//! rather than extrapolated, since two harmonics fitted over part of a turn can swing far
//! outside it. Unlike a residual learnt in the base frame, such a term moves with the arm:
//! it predicts the same joint error wherever the joint's angle recurs, in any other part of
//! the workspace, and on any turn of the joint. `q` and `q + 2πk` are the same angle of
//! the link, which a program tells apart only by the turn it writes (a KUKA Turn, a
//! Yaskawa `///RCONF` R ≥ 180°): the range is a part of the circle, and a commanded angle
//! is measured against it around the circle ([`beyond_range`]), so that one posture has
//! one answer whichever turn reaches it. The calibrated chain of a hybrid table is evaluated at `q'`
//! ([`crate::model::PreparedModel`]); a revolute joint's terms only (a prismatic joint's
//! are zero).
//!
//! Cost on the query path: per joint a few multiplications from the `sin_cos` of `q`
//! already taken (the second harmonic by the double-angle formulas, a held end's value
//! computed at open), and the sine and cosine of `q'` from those of `q` by the
//! angle-addition formulas (a term's own sine and cosine by their series; a `sin_cos` of
//! `q'` only for terms that may exceed 1/64 rad). The calibrated chain then walks beside
//! the nominal one as it does without terms, each at its own angles
//! ([`crate::model::PreparedModel`]). Allocation-free and panic-free.

use crate::chain::{ChainError, JointKind, MAX_JOINTS};

/// How far beyond the angles a joint's terms were identified over a commanded angle may be,
/// rad (3°), before the answer is flagged ([`crate::Evidence::JOINTS`]): the held value is
/// continuous at the range's ends, and a few degrees past them the term a gear gives has
/// not moved far from it; beyond that the held value is no evidence of the joint's error.
pub const TERMS_MARGIN_RAD: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// How far beyond the angles its samples span (the recorded ranges) a revolute joint may be
/// commanded before a version-6 hybrid table's residual has faded to zero, rad (3°). The
/// residual is learnt in the base frame at the samples' joint angles: at a position the
/// samples reached with the shoulder, elbow or wrist the other way, or at a joint angle no
/// sample had, it is no evidence of the error (what depends on the joints is the model's,
/// which carries there). It fades rather than stops, `s(1 − d / L)` with `s` the smoothstep,
/// `d` the farthest joint's angle beyond its range and `L` this, so that the answer stays
/// continuous in the joint values; the same margin as [`TERMS_MARGIN_RAD`].
pub const RESIDUAL_FADE_RAD: f64 = TERMS_MARGIN_RAD;

/// Coefficients per joint: `[a1, b1, a2, b2]`, rad (module docs).
pub const COEFFICIENTS_PER_JOINT: usize = 4;

/// Where commanded angle `q` lies against the range `[lo, hi]` (rad) around the circle:
/// `None` when one of its representatives `q + 2πk` is within (a range of a whole turn or
/// more holds every angle), else the nearer end (`false` the lower, `true` the upper) and
/// how far beyond it `q` lies around the circle (rad, at most π; NaN for a non-finite `q`,
/// which then counts as beyond). Within `[lo, hi]` as written it costs two comparisons.
#[inline(always)]
pub fn beyond_range(q: f64, lo: f64, hi: f64) -> Option<(bool, f64)> {
    if q >= lo && q <= hi {
        return None;
    }
    let span = hi - lo;
    if span >= std::f64::consts::TAU {
        return None;
    }
    // `q`'s representative at or above `lo`, less than a turn above it.
    let r = (q - lo).rem_euclid(std::f64::consts::TAU);
    if r <= span {
        return None;
    }
    let above_hi = r - span;
    let below_lo = std::f64::consts::TAU - r;
    if above_hi <= below_lo {
        Some((true, above_hi))
    } else {
        Some((false, below_lo))
    }
}

/// How far commanded angle `q` (rad, finite) lies beyond `[lo, hi]` around the circle,
/// rad: 0 within (or for a range of a whole turn or more, or an unbounded one), else the
/// shorter way to the nearer end, at most π: [`beyond_range`]'s distance to rounding, for
/// the query path. Without a branch, which random joint values would mispredict half the
/// time, and without the exact remainder `beyond_range` takes (a library call): the angle
/// from the range's middle brought within ±π by the nearest whole number of turns, found
/// by truncating `d / 2π ± ½` to an integer (saturating beyond 2⁶³ turns, where the angle
/// stays far beyond). An unbounded range's middle is NaN, and so is `d`: `max` gives 0.
#[inline(always)]
pub(crate) fn angle_beyond(q: f64, lo: f64, hi: f64) -> f64 {
    use std::f64::consts::TAU;
    let half = 0.5 * (hi - lo);
    let d = q - (lo + half);
    let turns = (d * (1.0 / TAU) + 0.5f64.copysign(d)) as i64 as f64;
    ((d - turns * TAU).abs() - half).max(0.0)
}

/// The largest coefficient a table may carry, rad (0.1 rad, 5.7°): a calibration holds
/// anything beyond a few mrad as implausible, and a term this large is no small error.
pub const MAX_COEFFICIENT_RAD: f64 = 0.1;

/// The joint-space terms of a calibrated chain (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTerms {
    /// Per joint `[a1, b1, a2, b2]`, rad; zero beyond the chain's joints.
    pub coefficients_rad: [[f64; COEFFICIENTS_PER_JOINT]; MAX_JOINTS],
    /// Per joint the range of commanded angles `[lowest, highest]` the terms were
    /// identified from, rad: beyond it, around the circle ([`beyond_range`]), a term is
    /// held at the nearer end's value.
    pub range_rad: [[f64; 2]; MAX_JOINTS],
}

impl JointTerms {
    /// No term: `q' = q`.
    pub const NONE: JointTerms = JointTerms {
        coefficients_rad: [[0.0; COEFFICIENTS_PER_JOINT]; MAX_JOINTS],
        range_rad: [[f64::NEG_INFINITY, f64::INFINITY]; MAX_JOINTS],
    };

    /// Terms of the first `joints.len()` joints; `None` for more than [`MAX_JOINTS`].
    pub fn new(joints: &[[f64; COEFFICIENTS_PER_JOINT]]) -> Option<JointTerms> {
        let mut terms = JointTerms::NONE;
        terms
            .coefficients_rad
            .get_mut(..joints.len())?
            .copy_from_slice(joints);
        Some(terms)
    }

    /// Whether every coefficient is zero (the model has no joint-space terms).
    pub fn is_none(&self) -> bool {
        self.coefficients_rad.iter().flatten().all(|&c| c == 0.0)
    }

    /// Checks the terms against a chain's joints: finite, within
    /// [`MAX_COEFFICIENT_RAD`], zero for a prismatic joint and beyond the chain; every
    /// range ordered (no NaN).
    ///
    /// # Errors
    ///
    /// [`ChainError::Invalid`] naming what is wrong.
    pub fn check(&self, kinds: &[JointKind]) -> Result<(), ChainError> {
        for [lo, hi] in self.range_rad {
            if lo.is_nan() || hi.is_nan() || lo > hi {
                return Err(ChainError::Invalid("a joint term's range is not ordered"));
            }
        }
        for (j, c) in self.coefficients_rad.iter().enumerate() {
            if !c.iter().all(|v| v.is_finite()) {
                return Err(ChainError::Invalid("a joint term is not finite"));
            }
            if c.iter().any(|v| v.abs() > MAX_COEFFICIENT_RAD) {
                return Err(ChainError::Invalid("a joint term is beyond 0.1 rad"));
            }
            let revolute = kinds.get(j) == Some(&JointKind::Revolute);
            if !revolute && c.iter().any(|&v| v != 0.0) {
                return Err(ChainError::Invalid(
                    "a joint term on a prismatic joint or beyond the chain",
                ));
            }
        }
        Ok(())
    }

    /// Joint `j`'s term at its commanded angle `q`, from that angle's sine and cosine,
    /// rad (zero beyond [`MAX_JOINTS`]); beyond the term's range around the circle
    /// ([`beyond_range`]), at the nearer end.
    #[inline]
    pub fn offset(&self, j: usize, q: f64, sin_cos: (f64, f64)) -> f64 {
        let (Some(&[a1, b1, a2, b2]), Some(&[lo, hi])) =
            (self.coefficients_rad.get(j), self.range_rad.get(j))
        else {
            return 0.0;
        };
        let (sin, cos) = match beyond_range(q, lo, hi) {
            None => sin_cos,
            Some((false, _)) => lo.sin_cos(),
            Some((true, _)) => hi.sin_cos(),
        };
        let sin2 = 2.0 * sin * cos;
        let cos2 = (cos - sin) * (cos + sin);
        a1 * sin + b1 * cos + a2 * sin2 + b2 * cos2
    }

    /// `q'` (module docs) of commanded `q` whose sines and cosines are `sin_cos`, into
    /// `out`; as many joints as the shortest of the three.
    #[inline]
    pub fn apply(&self, q: &[f64], sin_cos: &[(f64, f64)], out: &mut [f64]) {
        for (j, ((o, &value), &sc)) in out.iter_mut().zip(q).zip(sin_cos).enumerate() {
            *o = value + self.offset(j, value, sc);
        }
    }

    /// `q'` of commanded `q` (module docs), the sines and cosines taken here; `None` for
    /// more than [`MAX_JOINTS`] values.
    ///
    /// A joint without terms takes no sine: its offset is `+0` at any finite angle (of
    /// the four products of zero, the second is `+0` unless the cosine is negative, and
    /// then the third is, since the sine of twice the angle is positive), so `q + 0.0`
    /// is the same bits. An identification without terms computes this at every sample
    /// of every step.
    pub fn joints(&self, q: &[f64]) -> Option<[f64; MAX_JOINTS]> {
        let mut out = [0.0; MAX_JOINTS];
        let out_q = out.get_mut(..q.len())?;
        for (j, (o, &value)) in out_q.iter_mut().zip(q).enumerate() {
            let without_terms =
                (self.coefficients_rad.get(j)).is_none_or(|c| c.iter().all(|&c| c == 0.0));
            *o = if without_terms && value.is_finite() {
                value + 0.0
            } else {
                value + self.offset(j, value, value.sin_cos())
            };
        }
        Some(out)
    }
}

/// [`JointTerms`] ready for the query path ([`crate::model::PreparedModel`]): each joint's
/// held values (its term at the ends of its range) computed once, so that a commanded
/// angle beyond the range costs no `sin_cos`, and the sines and cosines of `q'` taken from
/// those of `q` by the angle-addition formulas when every term is small.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PreparedTerms {
    coefficients_rad: [[f64; COEFFICIENTS_PER_JOINT]; MAX_JOINTS],
    range_rad: [[f64; 2]; MAX_JOINTS],
    /// Joint `j`'s term at `range_rad[j][0]` and at `range_rad[j][1]`, rad, as
    /// [`JointTerms::offset`] computes it there (zero at an infinite end, never read).
    held_rad: [[f64; 2]; MAX_JOINTS],
    /// Whether every joint's term is at most [`SMALL_TERM_RAD`] at any angle (the sum of
    /// its coefficients' magnitudes bounds it): [`PreparedTerms::moved_sin_cos`] then
    /// applies.
    small: bool,
}

/// The largest term, rad, whose sine and cosine [`PreparedTerms::moved_sin_cos`] takes by
/// its Taylor series (exact to rounding up to 2⁻⁶; the terms a calibration keeps are a
/// few mrad).
const SMALL_TERM_RAD: f64 = 1.0 / 64.0;

impl PreparedTerms {
    /// The terms prepared (any terms; [`JointTerms::check`] is the caller's).
    pub(crate) fn new(terms: &JointTerms) -> PreparedTerms {
        let mut held_rad = [[0.0; 2]; MAX_JOINTS];
        for (j, (held, range)) in held_rad.iter_mut().zip(&terms.range_rad).enumerate() {
            for (h, &end) in held.iter_mut().zip(range) {
                if end.is_finite() {
                    *h = terms.offset(j, end, end.sin_cos());
                }
            }
        }
        let bound = |c: &[f64; COEFFICIENTS_PER_JOINT]| c.iter().map(|v| v.abs()).sum::<f64>();
        PreparedTerms {
            coefficients_rad: terms.coefficients_rad,
            range_rad: terms.range_rad,
            held_rad,
            small: terms
                .coefficients_rad
                .iter()
                .all(|c| bound(c) <= SMALL_TERM_RAD),
        }
    }

    /// [`JointTerms::offset`] of joint `j` (`j <` [`MAX_JOINTS`], else zero), to the bit,
    /// with the held values read rather than computed.
    #[inline(always)]
    pub(crate) fn offset(&self, j: usize, q: f64, (sin, cos): (f64, f64)) -> f64 {
        let (Some(&[a1, b1, a2, b2]), Some(&[lo, hi]), Some(&[held_lo, held_hi])) = (
            self.coefficients_rad.get(j),
            self.range_rad.get(j),
            self.held_rad.get(j),
        ) else {
            return 0.0;
        };
        match beyond_range(q, lo, hi) {
            None => {}
            Some((false, _)) => return held_lo,
            Some((true, _)) => return held_hi,
        }
        let sin2 = 2.0 * sin * cos;
        let cos2 = (cos - sin) * (cos + sin);
        a1 * sin + b1 * cos + a2 * sin2 + b2 * cos2
    }

    /// Whether a joint with a term is commanded more than [`TERMS_MARGIN_RAD`] beyond the
    /// range its terms were identified over, around the circle ([`beyond_range`]; `q` one
    /// angle per joint, rad). A joint without terms (all four coefficients zero) is never
    /// beyond.
    #[inline]
    pub(crate) fn beyond(&self, q: &[f64]) -> bool {
        let mut beyond = false;
        for ((&value, c), &[lo, hi]) in q.iter().zip(&self.coefficients_rad).zip(&self.range_rad) {
            let has_term = c.iter().any(|&v| v != 0.0);
            beyond |= has_term
                && beyond_range(value, lo, hi)
                    .is_some_and(|(_, by)| by.is_nan() || by > TERMS_MARGIN_RAD);
        }
        beyond
    }

    /// The factor on a version-6 hybrid table's residual at commanded `q` (one angle per
    /// joint, rad, finite): 1 while every joint is within its range around the circle
    /// ([`beyond_range`]), then the smoothstep of `1 − d /` [`RESIDUAL_FADE_RAD`], `d` the
    /// largest angle a joint lies beyond its range, down to 0. A joint whose range is
    /// unbounded (a prismatic joint's) is never beyond.
    #[inline]
    pub(crate) fn residual_scale(&self, q: &[f64]) -> f64 {
        // Every joint within its range as written, tested without a branch a joint: the
        // one branch then goes the way a controller's queries mostly go.
        let mut within = true;
        for (&value, &[lo, hi]) in q.iter().zip(&self.range_rad) {
            within &= (value >= lo) & (value <= hi);
        }
        if within {
            return 1.0;
        }
        let mut beyond_rad = 0.0f64;
        for (&value, &[lo, hi]) in q.iter().zip(&self.range_rad) {
            beyond_rad = beyond_rad.max(angle_beyond(value, lo, hi));
        }
        // 1 at no angle beyond (within around the circle), exactly.
        crate::fade::smoothstep(1.0 - beyond_rad / RESIDUAL_FADE_RAD)
    }

    /// [`JointTerms::apply`], to the bit.
    #[inline]
    pub(crate) fn apply(&self, q: &[f64], sin_cos: &[(f64, f64)], out: &mut [f64]) {
        for (j, ((o, &value), &sc)) in out.iter_mut().zip(q).zip(sin_cos).enumerate() {
            *o = value + self.offset(j, value, sc);
        }
    }

    /// The sines and cosines of `q'` (module docs) into `out`, from those of the commanded
    /// `q`, `sin_cos`, by the angle-addition formulas with the term `δ`: `sin q' = sin q +
    /// (cos q sin δ − sin q (1 − cos δ))`, `cos q' = cos q − (sin q sin δ + cos q (1 −
    /// cos δ))`, `sin δ` and `1 − cos δ` by their Taylor series. `false`, with `out`
    /// untouched, when a term may exceed [`SMALL_TERM_RAD`] (the caller then takes the
    /// `sin_cos` of `q'` itself).
    ///
    /// Each result is within a few units of 2⁻⁵³ of `sin_cos(q + δ)` computed from the
    /// same `sin q` and `cos q` exactly: the correction is at most `δ` and is rounded
    /// once, where `sin_cos` of the rounded `q'` adds its own error of up to 2⁻⁵¹ and the
    /// rounding of `q + δ` (2⁻⁵³ of `q`).
    #[inline]
    pub(crate) fn moved_sin_cos(
        &self,
        q: &[f64],
        sin_cos: &[(f64, f64)],
        out: &mut [(f64, f64)],
    ) -> bool {
        if !self.small {
            return false;
        }
        for (j, ((o, &value), &(s, c))) in out.iter_mut().zip(q).zip(sin_cos).enumerate() {
            let d = self.offset(j, value, (s, c));
            // `small_sin_cos`'s series (module `chain`): sin δ to δ⁷, 1 − cos δ to δ⁸.
            let d2 = d * d;
            let sin_d = d
                * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))));
            let versine_d = d2
                * 0.5
                * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0) * (1.0 - d2 * (1.0 / 56.0))));
            *o = (
                s + (c * sin_d - s * versine_d),
                c - (s * sin_d + c * versine_d),
            );
        }
        true
    }
}

impl Default for JointTerms {
    fn default() -> Self {
        JointTerms::NONE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The query path's distance beyond a range is `beyond_range`'s, to 1e-12 rad, at
    /// angles within and beyond ranges of every width, a few turns away either side, and
    /// at the ends themselves.
    #[test]
    fn the_angle_beyond_a_range_is_beyond_ranges_distance() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || crate::testing::uniform(&mut state);
        for i in 0..200_000 {
            let lo = -7.0 + 14.0 * next();
            let hi = lo + 7.0 * next() * next();
            let q = match i % 5 {
                0 => lo,
                1 => hi,
                _ => -30.0 + 60.0 * next(),
            };
            let reference = beyond_range(q, lo, hi).map_or(0.0, |(_, by)| by);
            let fast = angle_beyond(q, lo, hi);
            assert!(
                (fast - reference).abs() < 1e-12,
                "{q} [{lo}, {hi}]: {fast} vs {reference}"
            );
        }
        assert!(angle_beyond(1e300, -1.0, 1.0) > 0.0);
        assert_eq!(angle_beyond(5.0, f64::NEG_INFINITY, f64::INFINITY), 0.0);
    }

    #[test]
    fn the_offset_is_the_two_harmonics_of_the_commanded_angle() {
        let mut terms = JointTerms::NONE;
        terms.coefficients_rad[2] = [1e-3, -2e-3, 5e-4, 7e-4];
        for q in [-3.0, -1.1, 0.0, 0.4, 2.9, 7.5] {
            let want = 1e-3 * f64::sin(q) - 2e-3 * f64::cos(q)
                + 5e-4 * f64::sin(2.0 * q)
                + 7e-4 * f64::cos(2.0 * q);
            let got = terms.offset(2, q, f64::sin_cos(q));
            assert!((got - want).abs() < 1e-17, "{q}: {got} vs {want}");
            assert_eq!(terms.offset(1, q, f64::sin_cos(q)), 0.0);
        }
        let q = [0.1, 0.2, 0.3];
        let moved = terms.joints(&q).unwrap();
        assert_eq!(moved[..2], q[..2]);
        assert_eq!(moved[2], 0.3 + terms.offset(2, 0.3, f64::sin_cos(0.3)));
        assert!(terms.joints(&[0.0; MAX_JOINTS + 1]).is_none());
    }

    /// A joint without terms is moved by its offset computed all the same, to the bit:
    /// angles of every quadrant, on the axes, signed zeros, subnormals, huge, and not
    /// finite; ranges open and closed; beside a joint with terms.
    #[test]
    fn a_joint_without_terms_is_moved_as_its_offset_says() {
        let angles = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE / 4.0,
            -f64::MIN_POSITIVE,
            1e-300,
            0.3,
            -0.3,
            1.9,
            -1.9,
            2.8,
            -2.8,
            std::f64::consts::FRAC_PI_2,
            -std::f64::consts::FRAC_PI_2,
            std::f64::consts::PI,
            -std::f64::consts::PI,
            4.0,
            -4.0,
            5.5,
            1e6,
            -1e15,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for range in [[f64::NEG_INFINITY, f64::INFINITY], [-0.5, 1.0], [2.0, 3.0]] {
            let mut terms = JointTerms::NONE;
            terms.coefficients_rad[1] = [1e-3, -2e-3, 5e-4, 7e-4];
            terms.range_rad = [range; MAX_JOINTS];
            for &a in &angles {
                for &b in &angles {
                    let q = [a, b, a];
                    let moved = terms.joints(&q).unwrap();
                    for j in 0..3 {
                        let want = q[j] + terms.offset(j, q[j], q[j].sin_cos());
                        assert_eq!(moved[j].to_bits(), want.to_bits(), "{j}: {q:?} {range:?}");
                    }
                }
            }
        }
    }

    /// Beyond the range the terms were identified over, a term is its value at the
    /// nearer end, not the harmonics extrapolated.
    #[test]
    fn beyond_its_range_a_term_is_held_at_the_nearer_end() {
        let mut terms = JointTerms::NONE;
        terms.coefficients_rad[0] = [1e-3, -2e-3, 5e-4, 7e-4];
        terms.range_rad[0] = [-0.5, 1.0];
        let at = |q: f64| terms.offset(0, q, q.sin_cos());
        assert_eq!(at(-2.0), at(-0.5));
        assert_eq!(at(3.0), at(1.0));
        assert_ne!(at(0.2), at(1.0));
        assert_eq!(terms.joints(&[3.0]).unwrap()[0], 3.0 + at(1.0));
        terms.range_rad[0] = [1.0, -1.0];
        assert!(terms.check(&[JointKind::Revolute]).is_err());
        terms.range_rad[0] = [f64::NAN, 1.0];
        assert!(terms.check(&[JointKind::Revolute]).is_err());
    }

    /// `q` and `q + 2πk` are one angle of the link: the same term on every turn, and an
    /// angle beyond the range held at the end nearer around the circle, not along the
    /// number line.
    #[test]
    fn a_term_is_the_same_on_every_turn_and_held_at_the_end_nearer_around_the_circle() {
        use std::f64::consts::TAU;
        let mut terms = JointTerms::NONE;
        terms.coefficients_rad[0] = [1e-3, -2e-3, 5e-4, 7e-4];
        terms.range_rad[0] = [-0.5, 1.0];
        let prepared = PreparedTerms::new(&terms);
        let at = |q: f64, sc: (f64, f64)| terms.offset(0, q, sc);
        for q in [-0.5f64, -0.2, 0.3, 1.0] {
            let sc = q.sin_cos();
            for k in [-2.0, -1.0, 1.0, 3.0] {
                assert_eq!(at(q + k * TAU, sc), at(q, sc), "{q} + {k} turns");
                assert_eq!(prepared.offset(0, q + k * TAU, sc), at(q, sc));
                assert!(!prepared.beyond(&[q + k * TAU]));
            }
        }
        // 2.0 lies 1.0 above the upper end, 3.78 below the lower one (around the circle):
        // the upper end; 5.0 lies 0.78 below the lower end (−1.28): the lower end.
        for (q, end) in [
            (2.0f64, 1.0f64),
            (5.0, -0.5),
            (2.0 - TAU, 1.0),
            (-1.5, -0.5),
        ] {
            assert_eq!(at(q, q.sin_cos()), at(end, end.sin_cos()), "{q}");
            assert_eq!(prepared.offset(0, q, q.sin_cos()), at(q, q.sin_cos()));
        }
        assert_eq!(beyond_range(0.9 + TAU, -0.5, 1.0), None);
        let (upper, by) = beyond_range(1.0 + 0.5 * TERMS_MARGIN_RAD + TAU, -0.5, 1.0).unwrap();
        assert!(upper && (by - 0.5 * TERMS_MARGIN_RAD).abs() < 1e-12);
        assert!(!prepared.beyond(&[1.0 + 0.5 * TERMS_MARGIN_RAD - 2.0 * TAU]));
        assert!(prepared.beyond(&[-0.5 - 2.0 * TERMS_MARGIN_RAD + TAU]));
        assert!(prepared.beyond(&[f64::INFINITY]));
        assert!(prepared.beyond(&[f64::NAN]));
        assert!(beyond_range(f64::NAN, -0.5, 1.0).is_some());
        // A range of a whole turn or more holds every angle.
        assert_eq!(beyond_range(100.0, -4.0, 4.0), None);
    }

    #[test]
    fn check_refuses_non_finite_large_and_prismatic_terms() {
        let kinds = [JointKind::Revolute, JointKind::Prismatic];
        let mut terms = JointTerms::NONE;
        terms.coefficients_rad[0] = [1e-3, 0.0, 0.0, -1e-3];
        assert!(terms.check(&kinds).is_ok());
        terms.coefficients_rad[0][1] = f64::NAN;
        assert!(terms.check(&kinds).is_err());
        terms.coefficients_rad[0][1] = 0.2;
        assert!(terms.check(&kinds).is_err());
        terms.coefficients_rad[0][1] = 0.0;
        terms.coefficients_rad[1][0] = 1e-3;
        assert!(terms.check(&kinds).is_err());
        terms.coefficients_rad[1][0] = 0.0;
        terms.coefficients_rad[2][0] = 1e-3;
        assert!(terms.check(&kinds).is_err());
    }
}
