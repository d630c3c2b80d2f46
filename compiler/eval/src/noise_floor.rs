//! The noise floor: how much of the error no predictor built from these samples can remove.
//!
//! What a method leaves at a held-out point is the part of the error it cannot predict from
//! the samples around it. Two samples at (nearly) the same place differ by measurement
//! noise, repeatability and variation on scales finer than the sample spacing; no method
//! built from these samples can predict that part. Geostatistics calls its variance the
//! *nugget*: the semivariance `γ(h) = ½ E|r(x) − r(x + h)|²` extrapolated to lag `h → 0`.
//!
//! # What is estimated
//!
//! The field `r` is the residual the kinematic model leaves on the training samples
//! (measured error − the identified model's prediction), or the measured errors themselves
//! when there is no robot model. It is estimated twice: with the lag measured as the
//! Cartesian distance of the samples' nominal positions (mm), and as the Euclidean
//! distance of their joint values (degrees; a prismatic joint's millimetres count as
//! degrees). The semivariance of a pair is `½ |r_i − r_j|²`, summed over the three axes (the
//! trace of the matrix variogram, as the kriging baseline uses), so it compares directly
//! with the total variance `E|r − r̄|²` of the residuals.
//!
//! # How
//!
//! 1. The spacing `s` is the median distance from a sample to its nearest other sample
//!    (samples at the same place are skipped).
//! 2. Every pair closer than `3 s` enters the empirical semivariogram (Matheron's
//!    estimator), in [`BINS`] equal-width bins of lag; bins with fewer than
//!    [`MIN_PAIRS`] pairs are dropped.
//! 3. A straight line `γ(h) = nugget + slope · h` is fitted by unweighted least squares to
//!    the (mean lag, mean semivariance) of the [`FIT_BINS`] populated bins of smallest
//!    lag, and its intercept is the nugget, at most `γ` of the first bin; an intercept at or
//!    below zero gives no estimate (the low lags do not show the nugget). Only
//!    the lowest bins, and unweighted, so that the many pairs at larger lags, where the
//!    semivariogram bends towards its sill, do not pull the line down at zero. A fitted
//!    slope below zero (no spatial structure at these lags) means a pure nugget: the mean
//!    of the bins is taken instead.
//!
//! A straight line is the low-lag behaviour of the usual variogram models (exponential,
//! spherical) and of a field with small-scale roughness; a field smooth at the sample
//! spacing rises like `h²` there and a line then *under*-estimates the nugget slightly,
//! so the floor is, if anything, optimistic.
//!
//! # The best mean residual it implies
//!
//! Assuming what is left at the floor is a Gaussian residual, independent and of equal
//! variance on the three axes, with per-axis variance `σ² = nugget / 3` (the nugget sums
//! the three axes), its norm follows a Maxwell distribution of mean `σ · 2 · sqrt(2/π)`:
//! the mean residual norm a perfect predictor would leave ([`best_mean_mm`]). The smaller
//! of the two nuggets gives it: both bound the unpredictable part from above, and the
//! Cartesian one also counts, as "noise", differences between samples close in space but
//! reached with other joint angles, which a predictor using joints can resolve.

use std::cmp::Ordering;

use adwi_samples::SampleSet;

/// Number of equal-width lag bins up to three spacings.
pub const BINS: usize = 6;

/// The line is fitted to at most this many populated bins, those of smallest lag.
pub const FIT_BINS: usize = 3;

/// A bin with fewer pairs than this is left out of the fit.
pub const MIN_PAIRS: usize = 30;

/// The maximum lag, in spacings.
pub const MAX_LAG_SPACINGS: f64 = 3.0;

/// One bin of an empirical semivariogram.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LagBin {
    /// The mean lag of the pairs in the bin (mm, or degrees in joint space).
    pub lag: f64,
    /// The mean of `½ |r_i − r_j|²` over the pairs, mm².
    pub semivariance_mm2: f64,
    /// How many pairs fell in the bin.
    pub pairs: usize,
}

/// A nugget estimated from the low lags of an empirical semivariogram (module docs).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NuggetEstimate {
    /// The nugget, mm² (summed over the three axes).
    pub nugget_mm2: f64,
    /// The fitted slope, mm² per unit of lag (0 for a pure nugget).
    pub slope_mm2_per_unit: f64,
    /// The median nearest-neighbour distance (mm, or degrees).
    pub spacing: f64,
    /// The bins the line was fitted to, smallest lag first.
    pub bins: Vec<LagBin>,
}

/// The noise floor of a sample set ([module docs](self)).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NoiseFloor {
    /// Which field was analysed: `"kinematic residuals"` or `"measured errors"`.
    pub basis: String,
    /// How many training samples it was computed from.
    pub samples: usize,
    /// Total variance of the field about its mean, `E|r − r̄|²`, mm².
    pub total_variance_mm2: f64,
    /// The nugget with Cartesian lags (nominal positions, mm), mm².
    pub nugget_mm2_cartesian: Option<f64>,
    /// The nugget with joint-space lags (degrees), mm², when the samples have joints.
    pub nugget_mm2_joint: Option<f64>,
    /// The mean residual norm a perfect predictor would leave ([`best_mean_mm`] of the
    /// smaller nugget), mm.
    pub best_mean_mm: Option<f64>,
    /// The Cartesian fit.
    pub cartesian: Option<NuggetEstimate>,
    /// The joint-space fit.
    pub joint: Option<NuggetEstimate>,
}

/// The mean norm of a 3-D Gaussian residual with per-axis variance `nugget_mm2 / 3`
/// (`nugget_mm2` summed over the three axes): `σ · 2 · sqrt(2/π)`, the mean of a Maxwell
/// distribution. Assumes independent axes of equal variance and zero mean.
pub fn best_mean_mm(nugget_mm2: f64) -> f64 {
    (nugget_mm2.max(0.0) / 3.0).sqrt() * 2.0 * (2.0 / std::f64::consts::PI).sqrt()
}

/// Points of dimension `dim`, flat.
struct Points<'a> {
    coordinates: &'a [f64],
    dim: usize,
}

impl Points<'_> {
    fn len(&self) -> usize {
        self.coordinates.len() / self.dim
    }

    fn point(&self, i: usize) -> &[f64] {
        &self.coordinates[i * self.dim..(i + 1) * self.dim]
    }

    fn distance(&self, i: usize, j: usize) -> f64 {
        self.point(i)
            .iter()
            .zip(self.point(j))
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt()
    }
}

/// Indices sorted by the first coordinate, for sweeps.
fn sweep_order(points: &Points) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        points.point(a)[0]
            .partial_cmp(&points.point(b)[0])
            .unwrap_or(Ordering::Equal)
    });
    order
}

/// The median distance from a point to its nearest point at a positive distance.
fn median_spacing(points: &Points, order: &[usize]) -> Option<f64> {
    let first = |k: usize| points.point(order[k])[0];
    let mut nearest: Vec<f64> = (0..order.len())
        .filter_map(|k| {
            let mut best = f64::INFINITY;
            for dir in [-1isize, 1] {
                let mut m = k as isize + dir;
                while m >= 0 && (m as usize) < order.len() {
                    let gap = (first(m as usize) - first(k)).abs();
                    if gap > best {
                        break;
                    }
                    let d = points.distance(order[k], order[m as usize]);
                    if d > 0.0 && d < best {
                        best = d;
                    }
                    m += dir;
                }
            }
            best.is_finite().then_some(best)
        })
        .collect();
    if nearest.is_empty() {
        return None;
    }
    nearest.sort_by(|a, b| a.partial_cmp(b).unwrap_or(Ordering::Equal));
    Some(nearest[nearest.len() / 2])
}

/// Estimates the nugget of `values` at `points` (flat, `dim` coordinates each) by the
/// module's procedure; `None` when there are too few close pairs to fit (fewer than two
/// bins with [`MIN_PAIRS`] pairs), or when the fitted line meets zero lag at or below zero.
///
/// # Panics
///
/// When `coordinates.len() != values.len() * dim` or `dim == 0`.
pub fn estimate_nugget(
    coordinates: &[f64],
    dim: usize,
    values: &[[f64; 3]],
) -> Option<NuggetEstimate> {
    assert!(dim > 0 && coordinates.len() == values.len() * dim);
    let points = Points { coordinates, dim };
    let order = sweep_order(&points);
    let spacing = median_spacing(&points, &order)?;
    let max_lag = MAX_LAG_SPACINGS * spacing;
    let width = max_lag / BINS as f64;
    let mut sums = [(0.0f64, 0.0f64, 0usize); BINS];
    for k in 0..order.len() {
        let i = order[k];
        let x = points.point(i)[0];
        for &j in &order[k + 1..] {
            if points.point(j)[0] - x > max_lag {
                break;
            }
            let h = points.distance(i, j);
            if h > max_lag {
                continue;
            }
            let bin = ((h / width) as usize).min(BINS - 1);
            let g: f64 = (0..3)
                .map(|a| (values[i][a] - values[j][a]).powi(2))
                .sum::<f64>()
                / 2.0;
            let s = &mut sums[bin];
            s.0 += h;
            s.1 += g;
            s.2 += 1;
        }
    }
    let bins: Vec<LagBin> = sums
        .iter()
        .filter(|s| s.2 >= MIN_PAIRS)
        .take(FIT_BINS)
        .map(|s| LagBin {
            lag: s.0 / s.2 as f64,
            semivariance_mm2: s.1 / s.2 as f64,
            pairs: s.2,
        })
        .collect();
    if bins.len() < 2 {
        return None;
    }
    let n = bins.len() as f64;
    let mean_h = bins.iter().map(|b| b.lag).sum::<f64>() / n;
    let mean_g = bins.iter().map(|b| b.semivariance_mm2).sum::<f64>() / n;
    let sxx: f64 = bins.iter().map(|b| (b.lag - mean_h).powi(2)).sum();
    let sxy: f64 = bins
        .iter()
        .map(|b| (b.lag - mean_h) * (b.semivariance_mm2 - mean_g))
        .sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let (nugget, slope) = if slope > 0.0 {
        let intercept = mean_g - slope * mean_h;
        // A line through zero or below says the low lags are too far apart to show the
        // nugget (the field is still rising steeply there), not that there is no noise.
        if intercept <= 0.0 {
            return None;
        }
        (intercept.min(bins[0].semivariance_mm2), slope)
    } else {
        (mean_g, 0.0)
    };
    Some(NuggetEstimate {
        nugget_mm2: nugget,
        slope_mm2_per_unit: slope,
        spacing,
        bins,
    })
}

/// The noise floor of `values` (residuals, mm, one per sample of `samples`), described
/// by `basis`: nuggets in Cartesian and joint distance, and the best mean they imply.
///
/// # Panics
///
/// When `values` does not have one entry per sample.
pub fn noise_floor(samples: &SampleSet, values: &[[f64; 3]], basis: &str) -> NoiseFloor {
    assert_eq!(values.len(), samples.len());
    let n = values.len().max(1) as f64;
    let mean: [f64; 3] = [0, 1, 2].map(|a| values.iter().map(|v| v[a]).sum::<f64>() / n);
    let total_variance_mm2 = values
        .iter()
        .map(|v| (0..3).map(|a| (v[a] - mean[a]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / n;
    let cartesian_coordinates: Vec<f64> = samples.nominal_mm.iter().flatten().copied().collect();
    let cartesian = estimate_nugget(&cartesian_coordinates, 3, values);
    let joint = samples.joints.as_ref().and_then(|j| {
        let degrees: Vec<f64> = j.rows().flatten().map(|v| v.to_degrees()).collect();
        estimate_nugget(&degrees, j.count(), values)
    });
    let nugget_mm2_cartesian = cartesian.as_ref().map(|e| e.nugget_mm2);
    let nugget_mm2_joint = joint.as_ref().map(|e| e.nugget_mm2);
    let smallest = [nugget_mm2_cartesian, nugget_mm2_joint]
        .into_iter()
        .flatten()
        .reduce(f64::min);
    NoiseFloor {
        basis: basis.to_string(),
        samples: values.len(),
        total_variance_mm2,
        nugget_mm2_cartesian,
        nugget_mm2_joint,
        best_mean_mm: smallest.map(best_mean_mm),
        cartesian,
        joint,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
        let u: f64 = rng.gen_range(f64::EPSILON..1.0);
        let v: f64 = rng.gen::<f64>();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }

    /// A 12 × 12 × 12 lattice (step 10 mm) and a field: a smooth part plus independent
    /// Gaussian noise of per-axis σ (a nugget of 3σ², the semivariance summing the axes).
    fn lattice(sigma: f64, seed: u64) -> (Vec<f64>, Vec<[f64; 3]>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut coordinates = Vec::new();
        let mut values = Vec::new();
        for i in 0..12 {
            for j in 0..12 {
                for k in 0..12 {
                    let p = [i as f64 * 10.0, j as f64 * 10.0, k as f64 * 10.0];
                    coordinates.extend(p);
                    // A field of the UR5 residuals' size (0.1 mm) varying over 0.4 m:
                    // small against the noise between neighbours, as there.
                    let smooth = [
                        0.1 * (p[0] / 400.0).sin(),
                        0.1 * (p[1] / 300.0).cos(),
                        0.1 * ((p[0] + p[2]) / 500.0).sin(),
                    ];
                    values.push(smooth.map(|s| s + sigma * gaussian(&mut rng)));
                }
            }
        }
        (coordinates, values)
    }

    #[test]
    fn recovers_a_known_nugget_under_a_smooth_field() {
        for (sigma, seed) in [(0.03, 1), (0.05, 2), (0.1, 3)] {
            let (coordinates, values) = lattice(sigma, seed);
            let e = estimate_nugget(&coordinates, 3, &values).unwrap();
            let truth = 3.0 * sigma * sigma;
            assert!((e.spacing - 10.0).abs() < 1e-9, "{}", e.spacing);
            assert!(
                (e.nugget_mm2 - truth).abs() < 0.15 * truth,
                "σ {sigma}: nugget {} against {truth} ({:?})",
                e.nugget_mm2,
                e.bins
            );
        }
    }

    #[test]
    fn pure_noise_is_all_nugget_and_the_best_mean_is_maxwells() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let sigma = 0.04;
        let coordinates: Vec<f64> = (0..3000).map(|_| rng.gen_range(0.0..500.0)).collect();
        let values: Vec<[f64; 3]> = (0..1000)
            .map(|_| [0; 3].map(|_| sigma * gaussian(&mut rng)))
            .collect();
        let e = estimate_nugget(&coordinates, 3, &values).unwrap();
        let truth = 3.0 * sigma * sigma;
        // Against the variance these 1000 draws actually have (their own spread is ~5 %).
        let drawn = values
            .iter()
            .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            .sum::<f64>()
            / values.len() as f64;
        assert!((drawn - truth).abs() < 0.15 * truth, "{drawn}");
        assert!(
            (e.nugget_mm2 - drawn).abs() < 0.1 * drawn,
            "{e:?} against {drawn}"
        );
        // The mean norm of the noise itself is what best_mean_mm predicts.
        let mean_norm = values
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .sum::<f64>()
            / values.len() as f64;
        assert!((best_mean_mm(drawn) - mean_norm).abs() < 0.03 * mean_norm);
        assert!((best_mean_mm(3.0) - 2.0 * (2.0 / std::f64::consts::PI).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn too_few_pairs_give_no_estimate() {
        let coordinates = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 5.0, 0.0, 0.0];
        assert!(estimate_nugget(&coordinates, 3, &[[0.0; 3]; 3]).is_none());
    }
}
