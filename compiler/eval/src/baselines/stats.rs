//! Residual statistics and deterministic k-fold splits for comparing methods.
//!
//! The paper reports the mean and maximum residual after compensation; an evaluation also
//! wants the RMS (sensitive to large errors), a high percentile (robust to one bad sample,
//! unlike the maximum) and the per-axis breakdown (the paper's comparison with inverse
//! distance weighting differs by axis). Residuals are 3-vectors in the unit of the values
//! they come from: mm for position errors, rad for orientation errors.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Why statistics or splits could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StatsError {
    /// No residuals were given; every statistic would be undefined.
    #[error("no residuals given: statistics need at least one")]
    Empty,
    /// A residual holds a NaN or an infinity; it would make every statistic meaningless.
    #[error("residual {index} is not finite")]
    NonFinite {
        /// Index of the offending residual.
        index: usize,
    },
    /// The fold count does not suit the sample count.
    #[error("cannot split {sample_count} samples into {folds} folds: need 2 <= folds <= samples")]
    InvalidFolds {
        /// Number of samples to split.
        sample_count: usize,
        /// Number of folds asked for.
        folds: usize,
    },
}

/// Summary statistics of a set of residual vectors (prediction − truth, or the error left
/// after compensation).
///
/// "Norm" is the Euclidean length of one residual vector. All values are in the residuals'
/// unit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ResidualStats {
    /// Number of residuals summarised.
    pub count: usize,
    /// Mean of the residual norms.
    pub mean_norm: f64,
    /// Root mean square of the residual norms, `sqrt(Σ |r|² / n)`.
    pub rms_norm: f64,
    /// 95th percentile of the residual norms by the nearest-rank definition: the
    /// `⌈0.95 · n⌉`-th smallest norm (1-based), always one of the observed norms.
    pub p95_norm: f64,
    /// Largest residual norm.
    pub max_norm: f64,
    /// Signed mean of each component (x, y, z): a nonzero mean is a bias a method failed to
    /// capture.
    pub mean_per_axis: [f64; 3],
    /// Root mean square of each component (x, y, z).
    pub rms_per_axis: [f64; 3],
    /// Standard error of `mean_norm`, `s / √n` with `s` the sample standard deviation of
    /// the norms: how closely these points pin the mean down (20 points know a 0.08 mm
    /// mean to about ±0.008 mm). `None` for a single residual.
    pub mean_norm_standard_error: Option<f64>,
    /// Hotelling's T² test of `mean_per_axis` against zero: the probability that residuals
    /// with no common offset would show one at least this large. A small value says the
    /// points share an error the method did not remove; between a validation series and
    /// the samples, something no model of the samples can learn (a new registration, a
    /// change of temperature). `None` with fewer than four residuals or when their
    /// covariance is singular.
    pub mean_per_axis_p_value: Option<f64>,
}

impl ResidualStats {
    /// Summarises `residuals`.
    ///
    /// # Errors
    ///
    /// [`StatsError::Empty`] for no residuals, [`StatsError::NonFinite`] for a residual with
    /// a NaN or infinite component.
    pub fn from_residuals(residuals: &[[f64; 3]]) -> Result<Self, StatsError> {
        if residuals.is_empty() {
            return Err(StatsError::Empty);
        }
        if let Some(index) = residuals
            .iter()
            .position(|r| r.iter().any(|c| !c.is_finite()))
        {
            return Err(StatsError::NonFinite { index });
        }
        let n = residuals.len() as f64;
        let mut norms: Vec<f64> = residuals
            .iter()
            .map(|r| r.iter().map(|c| c * c).sum::<f64>().sqrt())
            .collect();
        let (mean_norm, mean_norm_standard_error) = mean_and_standard_error(&norms);
        let rms_norm = (norms.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
        norms.sort_unstable_by(f64::total_cmp);
        let p95_norm = percentile_nearest_rank(&norms, 95.0)
            .expect("norms are non-empty and 95 is a valid percentile");
        let max_norm = norms[norms.len() - 1];
        let mean_per_axis =
            [0, 1, 2].map(|axis| residuals.iter().map(|r| r[axis]).sum::<f64>() / n);
        let rms_per_axis = [0, 1, 2]
            .map(|axis| (residuals.iter().map(|r| r[axis] * r[axis]).sum::<f64>() / n).sqrt());
        Ok(Self {
            count: residuals.len(),
            mean_norm,
            rms_norm,
            p95_norm,
            max_norm,
            mean_per_axis,
            rms_per_axis,
            mean_norm_standard_error,
            mean_per_axis_p_value: offset_p_value(residuals, mean_per_axis),
        })
    }
}

/// The mean of non-empty `values` and its standard error, `s / √n` with `s` the sample
/// standard deviation (`None` for a single value).
pub fn mean_and_standard_error(values: &[f64]) -> (f64, Option<f64>) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let standard_error = (values.len() > 1).then(|| {
        let variance = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (variance / n).sqrt()
    });
    (mean, standard_error)
}

/// Hotelling's one-sample T² test of the mean vector `mean` of `residuals` against zero:
/// `T² = n mᵀ S⁻¹ m` with `S` the sample covariance, and `(n − 3) / (3 (n − 1)) T²`
/// follows the F distribution with (3, n − 3) degrees of freedom when the residuals are
/// Gaussian with zero mean. Returns the upper tail probability, or `None` with fewer than
/// four residuals or a covariance that is not positive definite.
fn offset_p_value(residuals: &[[f64; 3]], mean: [f64; 3]) -> Option<f64> {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    let n = residuals.len();
    if n < 4 {
        return None;
    }
    let m = nalgebra::Vector3::from(mean);
    let covariance = residuals
        .iter()
        .map(|r| {
            let d = nalgebra::Vector3::from(*r) - m;
            d * d.transpose()
        })
        .sum::<nalgebra::Matrix3<f64>>()
        / (n - 1) as f64;
    let t2 = n as f64 * covariance.cholesky()?.solve(&m).dot(&m);
    let f = (n - 3) as f64 / (3.0 * (n - 1) as f64) * t2;
    let distribution = FisherSnedecor::new(3.0, (n - 3) as f64).ok()?;
    let p = distribution.sf(f);
    p.is_finite().then_some(p)
}

/// A p value in words: three decimals, or two significant digits below 0.001 (where
/// three decimals would print zero).
pub fn p_value_text(p: f64) -> String {
    if p >= 1e-3 {
        format!("{p:.3}")
    } else {
        format!("{p:.1e}")
    }
}

/// The nearest-rank percentile of ascending `sorted` values: the `⌈percent / 100 · n⌉`-th
/// smallest (1-based; the smallest for `percent = 0`).
///
/// Nearest rank is chosen over interpolating definitions because it always reports an
/// observed residual, which is what an accuracy claim ("95 % of targets within x mm") means.
/// Returns `None` for an empty slice or a percent outside `[0, 100]`.
pub fn percentile_nearest_rank(sorted: &[f64], percent: f64) -> Option<f64> {
    if sorted.is_empty() || !(0.0..=100.0).contains(&percent) {
        return None;
    }
    let rank = (percent / 100.0 * sorted.len() as f64).ceil() as usize;
    Some(sorted[rank.clamp(1, sorted.len()) - 1])
}

/// One fold of a k-fold cross-validation: sample indices to build from and to test on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fold {
    /// Indices of the samples a method is built from, ascending.
    pub train: Vec<usize>,
    /// Indices of the held-out samples it is evaluated on, ascending.
    pub test: Vec<usize>,
}

/// Refuses a fold count that does not split `sample_count` samples: each fold holds at
/// least one, and there are at least two.
///
/// # Errors
///
/// [`StatsError::InvalidFolds`] unless `2 <= folds <= sample_count`.
pub fn check_folds(sample_count: usize, folds: usize) -> Result<(), StatsError> {
    if folds < 2 || folds > sample_count {
        return Err(StatsError::InvalidFolds {
            sample_count,
            folds,
        });
    }
    Ok(())
}

/// Splits `sample_count` samples into `folds` folds, deterministically for a given `seed`.
///
/// The samples are shuffled by a Fisher–Yates permutation driven by ChaCha8 seeded with
/// `ChaCha8Rng::seed_from_u64(seed)`, drawing `next_u64() % (i + 1)` for position `i` (the
/// modulo bias is below `n / 2^64`, negligible). Position `j` of the permutation goes to
/// fold `j % folds`, so fold sizes differ by at most one. Every sample is tested exactly
/// once. The scheme is written out here, not delegated to `rand`'s shuffle, so splits stay
/// identical across `rand` versions.
///
/// # Errors
///
/// [`StatsError::InvalidFolds`] unless `2 <= folds <= sample_count`.
pub fn k_fold_splits(
    sample_count: usize,
    folds: usize,
    seed: u64,
) -> Result<Vec<Fold>, StatsError> {
    check_folds(sample_count, folds)?;
    let mut permutation: Vec<usize> = (0..sample_count).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for i in (1..sample_count).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        permutation.swap(i, j);
    }
    let mut fold_of = vec![0usize; sample_count];
    for (position, &sample) in permutation.iter().enumerate() {
        fold_of[sample] = position % folds;
    }
    Ok((0..folds)
        .map(|fold| {
            let (test, train) = (0..sample_count).partition(|&i| fold_of[i] == fold);
            Fold { train, test }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_match_hand_computed_values() {
        // Norms 5, 0, 1 and 12.
        let residuals = [
            [3.0, 4.0, 0.0],
            [0.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 0.0, 12.0],
        ];
        let s = ResidualStats::from_residuals(&residuals).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12;
        assert_eq!(s.count, 4);
        assert!(close(s.mean_norm, 4.5));
        assert!(close(s.rms_norm, (170.0f64 / 4.0).sqrt()));
        // Nearest rank: ⌈0.95 · 4⌉ = 4, the largest.
        assert!(close(s.p95_norm, 12.0));
        assert!(close(s.max_norm, 12.0));
        assert_eq!(s.mean_per_axis, [0.5, 1.0, 3.0]);
        assert!(close(s.rms_per_axis[0], 2.5f64.sqrt()));
        assert!(close(s.rms_per_axis[1], 2.0));
        assert!(close(s.rms_per_axis[2], 6.0));
    }

    #[test]
    fn the_mean_is_given_its_standard_error_and_the_offset_its_test() {
        // Reference values from NumPy and SciPy: `np.linalg.norm(r, axis=1).std(ddof=1) /
        // sqrt(6)`, and `scipy.stats.f.sf(F, 3, 3)` with `F = 3 / 15 · T²`,
        // `T² = 6 mᵀ S⁻¹ m` = 50.3425129087780.
        let residuals = [
            [0.1, 0.2, -0.1],
            [0.3, -0.1, 0.0],
            [0.2, 0.1, 0.1],
            [0.25, 0.05, -0.05],
            [0.15, 0.0, 0.2],
            [0.35, 0.15, 0.05],
        ];
        let s = ResidualStats::from_residuals(&residuals).unwrap();
        approx::assert_abs_diff_eq!(
            s.mean_norm_standard_error.unwrap(),
            0.022977269125579174,
            epsilon = 1e-12
        );
        approx::assert_abs_diff_eq!(
            s.mean_per_axis_p_value.unwrap(),
            0.04483111678354557,
            epsilon = 1e-9
        );
        // Centred on zero, the same points show no offset at all: p = 1.
        let mean = s.mean_per_axis;
        let centred = residuals.map(|r| [0, 1, 2].map(|a| r[a] - mean[a]));
        let c = ResidualStats::from_residuals(&centred).unwrap();
        approx::assert_abs_diff_eq!(c.mean_per_axis_p_value.unwrap(), 1.0, epsilon = 1e-9);
        // Too few points for a covariance, or a singular one, give no test rather than a
        // meaningless one.
        let three = ResidualStats::from_residuals(&residuals[..3]).unwrap();
        assert_eq!(three.mean_per_axis_p_value, None);
        let flat = [
            [1.0, 2.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.5, 1.0, 0.0],
            [1.0, 1.5, 0.0],
        ];
        assert_eq!(
            ResidualStats::from_residuals(&flat)
                .unwrap()
                .mean_per_axis_p_value,
            None
        );
        assert_eq!(
            ResidualStats::from_residuals(&residuals[..1])
                .unwrap()
                .mean_norm_standard_error,
            None
        );
    }

    #[test]
    fn p95_is_the_nearest_rank() {
        // Norms 1..=20 along z: ⌈0.95 · 20⌉ = 19.
        let residuals: Vec<[f64; 3]> = (1..=20).map(|i| [0.0, 0.0, f64::from(i)]).collect();
        let s = ResidualStats::from_residuals(&residuals).unwrap();
        assert_eq!(s.p95_norm, 19.0);
        assert_eq!(s.max_norm, 20.0);
        let sorted: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(percentile_nearest_rank(&sorted, 95.0), Some(10.0));
        assert_eq!(percentile_nearest_rank(&sorted, 50.0), Some(5.0));
        assert_eq!(percentile_nearest_rank(&sorted, 0.0), Some(1.0));
        assert_eq!(percentile_nearest_rank(&sorted, 101.0), None);
        assert_eq!(percentile_nearest_rank(&[], 50.0), None);
    }

    #[test]
    fn rejects_empty_and_non_finite_residuals() {
        assert_eq!(ResidualStats::from_residuals(&[]), Err(StatsError::Empty));
        assert_eq!(
            ResidualStats::from_residuals(&[[0.0; 3], [0.0, f64::NAN, 0.0]]),
            Err(StatsError::NonFinite { index: 1 })
        );
    }

    #[test]
    fn serialises_with_named_fields() {
        let s = ResidualStats::from_residuals(&[[0.0, 0.0, 2.0]]).unwrap();
        let text = toml::to_string(&s).unwrap();
        assert!(text.contains("p95_norm = 2.0"), "{text}");
        assert!(text.contains("rms_per_axis = [0.0, 0.0, 2.0]"), "{text}");
    }

    #[test]
    fn k_fold_partitions_every_sample_once_and_is_deterministic() {
        let folds = k_fold_splits(23, 5, 42).unwrap();
        assert_eq!(folds.len(), 5);
        let mut tested: Vec<usize> = folds.iter().flat_map(|f| f.test.clone()).collect();
        tested.sort_unstable();
        assert_eq!(tested, (0..23).collect::<Vec<_>>());
        for fold in &folds {
            assert!(fold.test.len() == 4 || fold.test.len() == 5);
            assert_eq!(fold.train.len() + fold.test.len(), 23);
            assert!(fold.train.iter().all(|i| !fold.test.contains(i)));
            assert!(fold.test.windows(2).all(|w| w[0] < w[1]));
        }
        assert_eq!(k_fold_splits(23, 5, 42).unwrap(), folds);
        assert_ne!(k_fold_splits(23, 5, 43).unwrap(), folds);
        // A real shuffle, not a stride over the input order.
        assert_ne!(folds[0].test, vec![0, 5, 10, 15, 20]);
    }

    #[test]
    fn k_fold_rejects_impossible_fold_counts() {
        assert!(k_fold_splits(10, 1, 0).is_err());
        assert!(k_fold_splits(3, 4, 0).is_err());
        assert_eq!(k_fold_splits(3, 3, 0).unwrap().len(), 3);
    }
}
