//! The uncertainty of a table's residual field where it has not been measured: the
//! kriging variance of the served field, and how much measuring a candidate would lower it.
//!
//! A kriging served field (`adwi_compile::nugget_kriging`) models each component of
//! the residual as a Matérn 5/2 field of sill `σ²` and length scale `ℓ` (the vertical
//! difference scaled by `s`) plus measurement noise `τ² = λ σ²`. Given the samples `S`,
//! the field's variance at `x` is `v(x) = σ² (1 − r(x)ᵀ (R + λI)⁻¹ r(x))`, largest far
//! from the samples and where they are sparse. Measuring at `x*` lowers it at `x` by
//! `c(x, x*)² / (v(x*) + τ²)`, `c` the field's covariance given the samples: at `x*`
//! itself by `v(x*)² / (v(x*) + τ²)`, its **reducible variance**, which is what a next
//! pose should go after (a variance already below the noise cannot be measured away).
//! Each pose taken conditions the field for the next, a rank-one update per component.
//!
//! `σ²` is the profiled maximum-likelihood sill, `(y − ȳ)ᵀ (R + λI)⁻¹ (y − ȳ) / n`, as the
//! build chooses it; `ℓ`, `s` and `λ` are the build's choices, given.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// The most samples a field's variance is computed from (its cost grows with their cube).
pub const MAX_FIELD_SAMPLES: usize = 4_000;

/// One component's kernel, as the build chose it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kernel {
    /// Horizontal length scale ℓ, mm.
    pub length_scale_mm: f64,
    /// Factor on the vertical difference.
    pub vertical_scale: f64,
    /// Noise relative to the sill, λ.
    pub relative_nugget: f64,
}

/// A table's residual field: where its samples are, what they left, and the kernel of
/// each position component.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldPrior {
    /// The samples' positions, mm, base frame.
    pub positions_mm: Vec<[f64; 3]>,
    /// Their residuals, mm, base frame.
    pub residuals_mm: Vec<[f64; 3]>,
    /// The kernel of x, y and z.
    pub kernels: [Kernel; 3],
}

/// Why a field's variance cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldError {
    /// Too few or too many samples, or rows that do not match.
    #[error("{0}")]
    Samples(String),
    /// A kernel or value that is not finite or not positive.
    #[error("the residual field's {0} is not finite and positive")]
    Kernel(&'static str),
    /// The kriging system is singular.
    #[error("the residual field's kriging system is singular (coincident samples without noise)")]
    Singular,
}

fn matern52(h: f64, l: f64) -> f64 {
    let s = 5f64.sqrt() * h / l;
    (1.0 + s + s * s / 3.0) * (-s).exp()
}

fn correlation(k: &Kernel, a: [f64; 3], b: [f64; 3]) -> f64 {
    let dz = k.vertical_scale * (a[2] - b[2]);
    let h = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + dz * dz).sqrt();
    matern52(h, k.length_scale_mm)
}

/// One component's state over the candidates.
#[derive(Debug, Clone)]
struct Component {
    kernel: Kernel,
    sill_mm2: f64,
    noise_mm2: f64,
    /// `r(x)` for every candidate, `P × n`.
    r: DMatrix<f64>,
    /// `(R + λI)⁻¹ r(x)ᵀ`, `n × P`.
    z: DMatrix<f64>,
    /// The variance at each candidate given the samples and the poses taken, mm².
    variance: Vec<f64>,
    /// Per pose taken, its scaled covariance column `c(·, x*) / √(v(x*) + τ²)`.
    taken: Vec<Vec<f64>>,
}

/// The field's variance at a set of candidates, conditioned on the poses taken.
#[derive(Debug, Clone)]
pub struct FieldVariance {
    candidates: Vec<[f64; 3]>,
    components: Vec<Component>,
}

impl FieldVariance {
    /// The variance at `candidates` (mm, base frame) of `prior`'s field.
    ///
    /// # Errors
    ///
    /// [`FieldError`] for fewer than 3 or more than [`MAX_FIELD_SAMPLES`] samples, a
    /// kernel not finite and positive, a singular system.
    pub fn new(prior: &FieldPrior, candidates: &[[f64; 3]]) -> Result<FieldVariance, FieldError> {
        let n = prior.positions_mm.len();
        if !(3..=MAX_FIELD_SAMPLES).contains(&n) || prior.residuals_mm.len() != n {
            return Err(FieldError::Samples(format!(
                "{n} samples with {} residuals: the field's variance needs 3 to \
                 {MAX_FIELD_SAMPLES}, one residual each",
                prior.residuals_mm.len()
            )));
        }
        let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
        if !(prior.positions_mm.iter().all(finite) && prior.residuals_mm.iter().all(finite)) {
            return Err(FieldError::Samples(
                "a sample's position or residual is not finite".into(),
            ));
        }
        let mut components = Vec::with_capacity(3);
        for (c, kernel) in prior.kernels.iter().enumerate() {
            let positive = |v: f64| v.is_finite() && v > 0.0;
            if !positive(kernel.length_scale_mm) {
                return Err(FieldError::Kernel("length scale"));
            }
            if !positive(kernel.vertical_scale) {
                return Err(FieldError::Kernel("vertical scale"));
            }
            if !positive(kernel.relative_nugget) {
                return Err(FieldError::Kernel("nugget"));
            }
            let a = DMatrix::from_fn(n, n, |i, j| {
                correlation(kernel, prior.positions_mm[i], prior.positions_mm[j])
                    + if i == j { kernel.relative_nugget } else { 0.0 }
            });
            let chol = a.cholesky().ok_or(FieldError::Singular)?;
            let y: Vec<f64> = prior.residuals_mm.iter().map(|v| v[c]).collect();
            let mean = y.iter().sum::<f64>() / n as f64;
            let centred = DVector::from_iterator(n, y.iter().map(|v| v - mean));
            let sill_mm2 = centred.dot(&chol.solve(&centred)) / n as f64;
            if !(sill_mm2.is_finite() && sill_mm2 >= 0.0) {
                return Err(FieldError::Singular);
            }
            let r = DMatrix::from_fn(candidates.len(), n, |i, j| {
                correlation(kernel, candidates[i], prior.positions_mm[j])
            });
            let z = chol.solve(&r.transpose());
            let variance = (0..candidates.len())
                .into_par_iter()
                .map(|i| sill_mm2 * (1.0 - r.row(i).transpose().dot(&z.column(i))).max(0.0))
                .collect();
            components.push(Component {
                kernel: *kernel,
                sill_mm2,
                noise_mm2: kernel.relative_nugget * sill_mm2,
                r,
                z,
                variance,
                taken: Vec::new(),
            });
        }
        Ok(FieldVariance {
            candidates: candidates.to_vec(),
            components,
        })
    }

    /// The field's variance at each candidate, summed over x, y and z, mm².
    pub fn variance_mm2(&self) -> Vec<f64> {
        (0..self.candidates.len())
            .map(|i| self.components.iter().map(|c| c.variance[i]).sum())
            .collect()
    }

    /// How much measuring at each candidate lowers the variance there, summed over the
    /// components: `v² / (v + τ²)` (module docs), mm².
    pub fn reducible_mm2(&self) -> Vec<f64> {
        (0..self.candidates.len())
            .map(|i| {
                self.components
                    .iter()
                    .map(|c| {
                        let v = c.variance[i];
                        let d = v + c.noise_mm2;
                        if d > 0.0 {
                            v * v / d
                        } else {
                            0.0
                        }
                    })
                    .sum()
            })
            .collect()
    }

    /// Conditions the field on a measurement at candidate `index`.
    pub fn take(&mut self, index: usize) {
        let at = self.candidates[index];
        let candidates = &self.candidates;
        for c in &mut self.components {
            let denominator = c.variance[index] + c.noise_mm2;
            if denominator.is_nan() || denominator <= 0.0 {
                continue;
            }
            let z_at = c.z.column(index).into_owned();
            let column: Vec<f64> = (0..candidates.len())
                .into_par_iter()
                .map(|i| {
                    let prior = correlation(&c.kernel, candidates[i], at)
                        - c.r.row(i).transpose().dot(&z_at);
                    let earlier: f64 = c.taken.iter().map(|u| u[i] * u[index]).sum();
                    (c.sill_mm2 * prior - earlier) / denominator.sqrt()
                })
                .collect();
            for (v, u) in c.variance.iter_mut().zip(&column) {
                *v = (*v - u * u).max(0.0);
            }
            c.taken.push(column);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prior(positions: Vec<[f64; 3]>) -> FieldPrior {
        let residuals = positions
            .iter()
            .map(|p| {
                [
                    0.01 * (p[0] / 100.0).sin(),
                    0.02 * (p[1] / 150.0).cos(),
                    0.005 * ((p[0] + p[1]) / 90.0).sin(),
                ]
            })
            .collect();
        FieldPrior {
            positions_mm: positions,
            residuals_mm: residuals,
            kernels: [Kernel {
                length_scale_mm: 200.0,
                vertical_scale: 1.0,
                relative_nugget: 0.05,
            }; 3],
        }
    }

    fn lattice(step: f64, n: usize) -> Vec<[f64; 3]> {
        let mut out = Vec::new();
        for i in 0..n {
            for j in 0..n {
                out.push([i as f64 * step, j as f64 * step, 0.0]);
            }
        }
        out
    }

    /// Far from every sample the variance is the sill's; at a sample it is below the
    /// noise; and a pose taken is the variance computed outright with it as a sample.
    #[test]
    fn the_variance_grows_away_from_the_samples_and_a_pose_taken_is_a_sample() {
        let p = prior(lattice(100.0, 4));
        let candidates = vec![[150.0, 150.0, 0.0], [100.0, 100.0, 0.0], [5000.0, 0.0, 0.0]];
        let mut f = FieldVariance::new(&p, &candidates).unwrap();
        let v = f.variance_mm2();
        let sills: f64 = f.components.iter().map(|c| c.sill_mm2).sum();
        let noise: f64 = f.components.iter().map(|c| c.noise_mm2).sum();
        assert!((v[2] - sills).abs() < 1e-9 * sills, "{} vs {sills}", v[2]);
        assert!(v[1] < noise, "{} vs {noise}", v[1]);
        assert!(v[0] > v[1]);
        // Take the far candidate: the same as a fresh field with it among the samples
        // (its residual does not matter to the variance, only to the sill, held here).
        f.take(2);
        let after = f.variance_mm2();
        let noise_far: f64 = f.components.iter().map(|c| c.noise_mm2).sum();
        // A measurement at a variance of σ² with noise τ² leaves σ² τ² / (σ² + τ²).
        let expected: f64 = f
            .components
            .iter()
            .map(|c| c.sill_mm2 * c.noise_mm2 / (c.sill_mm2 + c.noise_mm2))
            .sum();
        assert!((after[2] - expected).abs() < 1e-9 * expected.max(1e-12));
        assert!(after[2] < noise_far);
        // The others, far from it, hardly move.
        assert!((after[0] - v[0]).abs() < 1e-9 * sills);
        let reducible = f.reducible_mm2();
        assert!(reducible.iter().all(|r| r.is_finite() && *r >= 0.0));
    }

    /// Two poses taken one after the other: the second update accounts for the first
    /// (a second measurement at the same place halves what noise is left, not more).
    #[test]
    fn two_poses_at_one_place_are_two_measurements_of_it() {
        let p = prior(lattice(100.0, 3));
        let candidates = vec![[3000.0, 0.0, 0.0], [3000.0, 0.0, 0.0]];
        let mut f = FieldVariance::new(&p, &candidates).unwrap();
        f.take(0);
        f.take(1);
        let v = f.variance_mm2()[0];
        let expected: f64 = f
            .components
            .iter()
            .map(|c| c.sill_mm2 * c.noise_mm2 / (2.0 * c.sill_mm2 + c.noise_mm2))
            .sum();
        assert!((v - expected).abs() < 1e-9 * expected, "{v} vs {expected}");
    }

    #[test]
    fn bad_fields_are_refused() {
        let mut p = prior(lattice(100.0, 2));
        p.positions_mm.truncate(2);
        p.residuals_mm.truncate(2);
        assert!(matches!(
            FieldVariance::new(&p, &[[0.0; 3]]),
            Err(FieldError::Samples(_))
        ));
        let mut p = prior(lattice(100.0, 2));
        p.kernels[1].length_scale_mm = f64::NAN;
        assert_eq!(
            FieldVariance::new(&p, &[[0.0; 3]]).unwrap_err(),
            FieldError::Kernel("length scale")
        );
    }
}
