//! The least-squares problem and its solution: pivoted QR of the scaled Jacobian, then
//! Levenberg–Marquardt on the kept columns, with the covariance of the solution (module
//! docs of [`crate::calibrate`], "Identification", "Uncertainty").

use nalgebra::{DMatrix, DVector};

use super::model::{Model, State};
use super::parameters::Parameter;
use super::{CalibrateError, CalibrateOptions};

/// The measurements of one sample.
pub(super) struct Measurement {
    pub(super) q: Vec<f64>,
    pub(super) error_mm: [f64; 3],
    pub(super) rotation_error_rad: Option<[f64; 3]>,
}

/// The least-squares problem: the model and the measurements.
pub(super) struct Problem {
    pub(super) model: Model,
    pub(super) measurements: Vec<Measurement>,
    pub(super) rows_per_sample: usize,
    pub(super) weight: f64,
}

/// One solution of [`Problem::solve`].
pub(super) struct Fit {
    pub(super) x: DVector<f64>,
    pub(super) state: State,
    pub(super) r: DVector<f64>,
    pub(super) kept: Vec<usize>,
    pub(super) dropped: Vec<(usize, f64)>,
    /// Per dropped column, the kept column most like it.
    pub(super) resembles: Vec<Option<usize>>,
    pub(super) condition_number: f64,
    pub(super) residual_sigma_mm: f64,
    /// `(JᵀJ)⁻¹` of the kept parameters (unscaled, kept order), times σ².
    pub(super) covariance: DMatrix<f64>,
    pub(super) iterations: u32,
    pub(super) converged: bool,
}

impl Problem {
    /// The weighted residual vector and (when asked) Jacobian, all columns, of a state.
    pub(super) fn linearise(
        &self,
        x: &DVector<f64>,
        state: &State,
        with_jacobian: bool,
    ) -> (DVector<f64>, DMatrix<f64>) {
        let p = self.model.len();
        let rows = self.measurements.len() * self.rows_per_sample;
        let mut r = DVector::zeros(rows);
        let mut jac = if with_jacobian {
            DMatrix::zeros(rows, p)
        } else {
            DMatrix::zeros(0, 0)
        };
        for (s, m) in self.measurements.iter().enumerate() {
            let e = self.model.error(state, &m.q);
            let row = s * self.rows_per_sample;
            for a in 0..3 {
                r[row + a] = m.error_mm[a] - e[a];
            }
            if let Some(measured) = m.rotation_error_rad {
                for a in 0..3 {
                    r[row + 3 + a] = self.weight * (measured[a] - e[a + 3]);
                }
            }
            if with_jacobian {
                let j = self.model.jacobian(x, state, &m.q);
                for a in 0..self.rows_per_sample {
                    let scale = if a < 3 { 1.0 } else { self.weight };
                    for c in 0..p {
                        jac[(row + a, c)] = scale * j[(a, c)];
                    }
                }
            }
        }
        (r, jac)
    }

    /// RMS of the position residual norms.
    pub(super) fn position_rms(&self, r: &DVector<f64>) -> f64 {
        let n = self.measurements.len();
        let sum: f64 = (0..n)
            .map(|s| r.fixed_rows::<3>(s * self.rows_per_sample).norm_squared())
            .sum();
        (sum / n as f64).sqrt()
    }

    /// Selects the identifiable columns of the nominal Jacobian `j0` (scaled by `scales`)
    /// other than `held`, and fits them from `start` (whose held columns are zero).
    pub(super) fn solve(
        &self,
        j0: &DMatrix<f64>,
        scales: &[f64],
        held: &[usize],
        start: DVector<f64>,
        options: &CalibrateOptions,
    ) -> Result<Fit, CalibrateError> {
        let p = self.model.len();
        let mut scaled = j0.clone();
        for (c, s) in scales.iter().enumerate() {
            let s = if held.contains(&c) { 0.0 } else { *s };
            scaled.column_mut(c).scale_mut(s);
        }
        // Of exactly redundant columns the tool's or the base's is kept (module docs).
        let preferred: Vec<bool> = self
            .model
            .parameters
            .iter()
            .map(|p| {
                matches!(
                    p,
                    Parameter::ToolTranslation(_)
                        | Parameter::ToolRotation(_)
                        | Parameter::BaseTranslation(_)
                        | Parameter::BaseRotation(_)
                )
            })
            .collect();
        let (kept, mut dropped) = pivot_columns(&scaled, options.rank_tolerance, &preferred);
        dropped.retain(|(c, _)| !held.contains(c));
        // The kept column most like each dropped one (largest |cosine| of the unit columns).
        let resembles: Vec<Option<usize>> = dropped
            .iter()
            .map(|&(c, _)| {
                kept.iter()
                    .map(|&k| (k, scaled.column(c).dot(&scaled.column(k)).abs()))
                    .filter(|&(_, cosine)| cosine > 0.0)
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(k, _)| k)
            })
            .collect();
        if kept.is_empty() {
            return Err(CalibrateError::NothingIdentifiable);
        }
        let rows = self.measurements.len() * self.rows_per_sample;
        if rows < 2 * kept.len() {
            return Err(CalibrateError::TooFewMeasurements {
                measurements: rows,
                parameters: kept.len(),
            });
        }

        // Levenberg–Marquardt in the scaled, kept coordinates: solve
        // [J; √μ·I] δ = [r; 0] by SVD, accept the step if the cost falls.
        let reduced = |jac: &DMatrix<f64>| {
            DMatrix::from_fn(rows, kept.len(), |i, k| jac[(i, kept[k])] * scales[kept[k]])
        };
        let mut x = start;
        let mut state = self.model.state(&x)?;
        let (mut r, mut jac) = self.linearise(&x, &state, true);
        let mut cost = r.norm_squared();
        let mut mu: f64 = 1e-6;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < options.max_iterations {
            iterations += 1;
            let jk = reduced(&jac);
            let mut accepted = false;
            for _ in 0..30 {
                let mut augmented = DMatrix::zeros(rows + kept.len(), kept.len());
                augmented.rows_mut(0, rows).copy_from(&jk);
                for k in 0..kept.len() {
                    augmented[(rows + k, k)] = mu.sqrt();
                }
                let mut rhs = DVector::zeros(rows + kept.len());
                rhs.rows_mut(0, rows).copy_from(&r);
                let step = augmented
                    .svd(true, true)
                    .solve(&rhs, 0.0)
                    .expect("SVD with both factors computed");
                let mut dx = DVector::zeros(p);
                for (k, &c) in kept.iter().enumerate() {
                    dx[c] = step[k] * scales[c];
                }
                let candidate_x = self.model.step(&x, &dx);
                // A step so large that the model stops being a robot is refused like one
                // that raises the cost.
                let Ok(candidate) = self.model.state(&candidate_x) else {
                    mu *= 10.0;
                    continue;
                };
                let (candidate_r, _) = self.linearise(&candidate_x, &candidate, false);
                let candidate_cost = candidate_r.norm_squared();
                if candidate_cost.is_finite() && candidate_cost <= cost {
                    let decrease = cost - candidate_cost;
                    x = candidate_x;
                    state = candidate;
                    mu = (mu / 10.0).max(1e-15);
                    accepted = true;
                    if decrease <= options.relative_cost_tolerance * cost || candidate_cost == 0.0 {
                        converged = true;
                    }
                    cost = candidate_cost;
                    break;
                }
                mu *= 10.0;
            }
            if !accepted {
                // No step lowers the cost any more: a minimum to working precision.
                converged = true;
            }
            let (next_r, next_jac) = self.linearise(&x, &state, true);
            r = next_r;
            jac = next_jac;
            if converged {
                break;
            }
        }

        let jk = reduced(&jac);
        let svd = jk.svd(false, true);
        let singular = &svd.singular_values;
        let condition_number = singular.max() / singular.min();
        let residual_sigma_mm = (r.norm_squared() / (rows - kept.len()) as f64).sqrt();
        // σ² (JᵀJ)⁻¹ of the unscaled parameters: with J_s = J·S = U Σ Vᵀ,
        // (JᵀJ)⁻¹ = S V Σ⁻² Vᵀ S.
        let n = kept.len();
        let mut covariance = DMatrix::zeros(n, n);
        if let Some(v_t) = &svd.v_t {
            for k in 0..n {
                for l in k..n {
                    let m: f64 = (0..singular.len())
                        .map(|i| v_t[(i, k)] * v_t[(i, l)] / singular[i].powi(2))
                        .sum();
                    let value = residual_sigma_mm.powi(2) * m * scales[kept[k]] * scales[kept[l]];
                    covariance[(k, l)] = value;
                    covariance[(l, k)] = value;
                }
            }
        }
        Ok(Fit {
            x,
            state,
            r,
            kept,
            dropped,
            resembles,
            condition_number,
            residual_sigma_mm,
            covariance,
            iterations,
            converged,
        })
    }
}

/// QR with column pivoting by modified Gram–Schmidt: returns the kept columns in pivot
/// order, and the dropped ones with their independent fraction (relative to the first
/// pivot), in column order. Selection stops at the first pivot below `tolerance`; of
/// columns whose independent parts are equal (to 1e-9), a `preferred` one is kept, else the
/// first.
pub(super) fn pivot_columns(
    a: &DMatrix<f64>,
    tolerance: f64,
    preferred: &[bool],
) -> (Vec<usize>, Vec<(usize, f64)>) {
    let mut residual = a.clone();
    let mut kept = Vec::new();
    let mut remaining: Vec<usize> = (0..a.ncols()).collect();
    let mut first = None;
    while !remaining.is_empty() {
        let norms: Vec<f64> = remaining
            .iter()
            .map(|&c| residual.column(c).norm())
            .collect();
        let largest = norms.iter().copied().fold(-1.0, f64::max);
        let tied = |i: &usize| norms[*i] >= largest * (1.0 - 1e-9);
        let position = (0..remaining.len())
            .filter(tied)
            .find(|&i| preferred[remaining[i]])
            .or_else(|| (0..remaining.len()).find(tied))
            .expect("the largest is among the remaining");
        let norm = norms[position];
        let first_norm = *first.get_or_insert(norm);
        if first_norm <= 0.0 || norm < tolerance * first_norm {
            break;
        }
        let pivot = remaining.remove(position);
        let q = residual.column(pivot) / norm;
        for &c in &remaining {
            // Twice, so the projection stays orthogonal to working precision.
            for _ in 0..2 {
                let dot = q.dot(&residual.column(c));
                let mut col = residual.column_mut(c);
                col.axpy(-dot, &q, 1.0);
            }
        }
        kept.push(pivot);
    }
    let first_norm = first.unwrap_or(1.0_f64).max(f64::MIN_POSITIVE);
    let mut dropped: Vec<(usize, f64)> = remaining
        .into_iter()
        .map(|c| (c, residual.column(c).norm() / first_norm))
        .collect();
    dropped.sort_by_key(|&(c, _)| c);
    (kept, dropped)
}
