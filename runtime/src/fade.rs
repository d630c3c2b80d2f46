//! How a hybrid table's residual fades where its evidence ends: outside the grid box
//! ([`crate::served`]), the posture term outside its box ([`crate::posture`]), and beyond the
//! joint angles the samples span ([`crate::joint_terms::RESIDUAL_FADE_RAD`]), each by the
//! same curve, so that the answer runs from the residual to the model alone without a
//! jump or a kink at either end.

/// `3t² − 2t³` for `t` clamped to `[0, 1]`: 0 and 1 at the ends, with zero slope there.
#[inline]
pub(crate) fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
