//! The methods against the best of them, point by point.
//!
//! Twenty validation points know a 0.08 mm mean to about ±0.008 mm, and most good methods
//! lie within that of each other. Over the same points, two similar methods' residuals rise
//! and fall together (a point hard for one is hard for the other), so the paired difference
//! (this method's residual norm minus the best method's, at each point both predicted) is
//! known better than either mean: on the UR5's 20 poses, two krigings differ by
//! 0.0006 ± 0.0044 mm. Its standard error says whether the points tell two methods apart.

use crate::baselines::mean_and_standard_error;
use crate::{Method, MethodResult};

/// Every method with position residuals against the one with the lowest mean.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// The method compared against: of those that predicted every point, the one with the
    /// lowest mean position residual (of all methods with residuals when none predicted
    /// every point).
    pub reference: Method,
    /// Every other method with position residuals, smallest mean difference first.
    pub against: Vec<PairedDifference>,
}

/// One method against the reference over the points both predicted.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PairedDifference {
    /// The method.
    pub method: Method,
    /// How many points both predicted.
    pub points: usize,
    /// Mean over those points of this method's position residual norm minus the
    /// reference's, mm: positive where the reference leaves less.
    pub mean_difference_mm: f64,
    /// Standard error of that mean, `s / √n` of the per-point differences, mm; `None` for
    /// a single point.
    pub standard_error_mm: Option<f64>,
}

/// Compares `methods` (their predictions at points whose measured position errors are
/// `measured_error_mm`) with the best of them. `None` when no method has residuals.
pub fn compare(methods: &[MethodResult], measured_error_mm: &[[f64; 3]]) -> Option<Comparison> {
    // Per point, the residual norm where the method predicted.
    let norms = |m: &MethodResult| -> Vec<Option<f64>> {
        let mut norms = vec![None; measured_error_mm.len()];
        for (i, r) in m.position_residuals(measured_error_mm) {
            norms[i] = Some((r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt());
        }
        norms
    };
    let scored: Vec<(&MethodResult, f64)> = methods
        .iter()
        .filter_map(|m| m.position_mm.as_ref().map(|s| (m, s.mean_norm)))
        .collect();
    let complete = |m: &MethodResult| m.predictions.iter().all(Option::is_some);
    let lowest = |only_complete: bool| {
        scored
            .iter()
            .filter(|(m, _)| !only_complete || complete(m))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(m, _)| *m)
    };
    let reference = lowest(true).or_else(|| lowest(false))?;
    let reference_norms = norms(reference);
    let mut against: Vec<PairedDifference> = scored
        .iter()
        .filter(|(m, _)| m.method != reference.method)
        .filter_map(|(m, _)| {
            let differences: Vec<f64> = norms(m)
                .iter()
                .zip(&reference_norms)
                .filter_map(|(a, b)| Some((*a)? - (*b)?))
                .collect();
            (!differences.is_empty()).then(|| {
                let (mean, standard_error_mm) = mean_and_standard_error(&differences);
                PairedDifference {
                    method: m.method,
                    points: differences.len(),
                    mean_difference_mm: mean,
                    standard_error_mm,
                }
            })
        })
        .collect();
    against.sort_by(|a, b| a.mean_difference_mm.total_cmp(&b.mean_difference_mm));
    Some(Comparison {
        reference: reference.method,
        against,
    })
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::baselines::ResidualStats;
    use crate::PointPrediction;

    /// A method that predicts `predicted` (position errors) at the points, `None` where
    /// it does not.
    fn method(method: Method, predicted: &[Option<[f64; 3]>], truth: &[[f64; 3]]) -> MethodResult {
        let residuals: Vec<[f64; 3]> = predicted
            .iter()
            .zip(truth)
            .filter_map(|(p, e)| p.map(|p| [0, 1, 2].map(|a| e[a] - p[a])))
            .collect();
        MethodResult {
            method,
            unsupported: None,
            predictions: predicted
                .iter()
                .map(|p| {
                    p.map(|p| PointPrediction {
                        position_error_mm: p,
                        orientation_error_rad: None,
                        residual: None,
                        evidence: None,
                    })
                })
                .collect(),
            not_predicted: BTreeMap::new(),
            not_predicted_examples: BTreeMap::new(),
            position_mm: (!residuals.is_empty())
                .then(|| ResidualStats::from_residuals(&residuals).unwrap()),
            orientation_mrad: None,
            before_position_mm: None,
            beyond_evidence: None,
            residual: None,
        }
    }

    #[test]
    fn differences_are_paired_over_the_points_both_predicted() {
        let truth = [
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 3.0],
            [1.0, 1.0, 1.0],
        ];
        // Residual norms: a 0.1, 0.2, 0.3, 0.4 (every point); b 0.5, —, 0.2, 0.6 (a lower
        // mean, 0.433, but a point missed); c nothing predicted.
        let a = method(
            Method::Hybrid,
            &[
                Some([0.9, 0.0, 0.0]),
                Some([0.0, 1.8, 0.0]),
                Some([0.0, 0.0, 2.7]),
                Some([1.0, 1.0, 0.6]),
            ],
            &truth,
        );
        let b = method(
            Method::Kinematic,
            &[
                Some([1.5, 0.0, 0.0]),
                None,
                Some([0.0, 0.0, 3.2]),
                Some([1.0, 1.6, 1.0]),
            ],
            &truth,
        );
        let c = method(Method::Idw, &[None; 4], &truth);
        let comparison = compare(&[b.clone(), c, a.clone()], &truth).unwrap();
        // a is the reference although b's mean over its own points is not higher: only a
        // predicted every point.
        assert_eq!(comparison.reference, Method::Hybrid);
        assert_eq!(comparison.against.len(), 1);
        let d = &comparison.against[0];
        assert_eq!(d.method, Method::Kinematic);
        assert_eq!(d.points, 3);
        // Differences 0.4, -0.1, 0.2 over the three common points.
        approx::assert_abs_diff_eq!(d.mean_difference_mm, 0.5 / 3.0, epsilon = 1e-12);
        let mean: f64 = 0.5 / 3.0;
        let variance = ((0.4 - mean) * (0.4 - mean)
            + (-0.1 - mean) * (-0.1 - mean)
            + (0.2 - mean) * (0.2 - mean))
            / 2.0;
        approx::assert_abs_diff_eq!(
            d.standard_error_mm.unwrap(),
            (variance / 3.0).sqrt(),
            epsilon = 1e-12
        );
        // Without a method that predicted every point, the lowest mean is the reference.
        let only_b = compare(&[b], &truth).unwrap();
        assert_eq!(only_b.reference, Method::Kinematic);
        assert!(only_b.against.is_empty());
        assert_eq!(compare(&[], &truth), None);
    }
}
