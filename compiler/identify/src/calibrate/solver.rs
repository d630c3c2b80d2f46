//! The least-squares problem and its solution: pivoted QR of the scaled Jacobian, then
//! Levenberg–Marquardt on the kept columns, with the covariance of the solution (module
//! docs of [`crate::calibrate`], "Identification", "Uncertainty").

use nalgebra::{DMatrix, DVector};

use adwi_runtime::kinematics::Transform;

use super::model::{Model, State};
use super::parameters::Parameter;
use super::{CalibrateError, CalibrateOptions};

/// The measurements of one sample.
pub(super) struct Measurement {
    pub(super) q: Vec<f64>,
    pub(super) error_mm: [f64; 3],
    pub(super) rotation_error_rad: Option<[f64; 3]>,
    /// The nominal robot's TCP at `q`, base frame: what every state's pose is compared
    /// with, the same at every step of the fit, so computed once.
    pub(super) nominal_tcp: Transform,
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
            let e = self.model.error_from(&m.nominal_tcp, state, &m.q);
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
        // [J; √μ·I] δ = [r; 0] by SVD, accept the step if the cost falls. With the thin
        // QR factorisation J = Q R, made once per iteration, that is the small system
        // [R; √μ·I] δ = [Qᵀr; 0] (the rows Q leaves out are orthogonal to every step),
        // so that each μ tried costs an SVD of 2p × p rather than of every sample's rows.
        let reduced = |jac: &DMatrix<f64>| {
            DMatrix::from_fn(rows, kept.len(), |i, k| jac[(i, kept[k])] * scales[kept[k]])
        };
        let n = kept.len();
        let mut x = start;
        let mut state = self.model.state(&x)?;
        let (mut r, mut jac) = self.linearise(&x, &state, true);
        let mut cost = r.norm_squared();
        let mut mu: f64 = 1e-6;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < options.max_iterations {
            iterations += 1;
            let (factor, projected) = thin_qr(reduced(&jac), &r);
            let mut accepted = false;
            for _ in 0..30 {
                let step = damped_step(&factor, &projected, mu);
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

        // J and its R factor have the same singular values and right singular vectors.
        let (factor, _) = thin_qr(reduced(&jac), &r);
        let svd = factor.svd(false, true);
        let singular = &svd.singular_values;
        let condition_number = singular.max() / singular.min();
        let residual_sigma_mm = (r.norm_squared() / (rows - kept.len()) as f64).sqrt();
        // σ² (JᵀJ)⁻¹ of the unscaled parameters: with J_s = J·S = U Σ Vᵀ,
        // (JᵀJ)⁻¹ = S V Σ⁻² Vᵀ S.
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

/// The thin QR factorisation `J = Q R` of a tall `J` (Householder): `R` (square, of `J`'s
/// column count) and `Qᵀ r`.
fn thin_qr(jacobian: DMatrix<f64>, r: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
    let n = jacobian.ncols();
    let qr = jacobian.qr();
    let mut projected = r.clone();
    qr.q_tr_mul(&mut projected);
    (qr.r(), projected.rows(0, n).into_owned())
}

/// The Levenberg–Marquardt step `δ` minimising `|R δ − Qᵀr|² + μ |δ|²` ([`thin_qr`]'s
/// factors), by SVD of `[R; √μ·I]`.
fn damped_step(factor: &DMatrix<f64>, projected: &DVector<f64>, mu: f64) -> DVector<f64> {
    let n = factor.ncols();
    let mut augmented = DMatrix::zeros(2 * n, n);
    augmented.rows_mut(0, n).copy_from(factor);
    for k in 0..n {
        augmented[(n + k, k)] = mu.sqrt();
    }
    let mut rhs = DVector::zeros(2 * n);
    rhs.rows_mut(0, n).copy_from(projected);
    augmented
        .svd(true, true)
        .solve(&rhs, 0.0)
        .expect("SVD with both factors computed")
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_damped_step_from_the_r_factor_is_that_of_all_the_rows() {
        // The reference: [J; √μ·I] δ = [r; 0] solved by SVD of every row, as written.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (rows, n) in [(40, 5), (300, 12), (1200, 30)] {
            let mut j = DMatrix::from_fn(rows, n, |_, _| rng.gen_range(-1.0..1.0));
            // Two columns nearly dependent, as far as the kept ones may be (pivot_columns
            // drops those more so).
            let apart = DVector::from_fn(rows, |_, _| rng.gen_range(-1e-3..1e-3));
            let nearly = j.column(0) + apart;
            j.set_column(2, &nearly);
            let r = DVector::from_fn(rows, |_, _| rng.gen_range(-1.0..1.0));
            let (factor, projected) = thin_qr(j.clone(), &r);
            for mu in [1e-15f64, 1e-6, 1.0, 1e3] {
                let mut augmented = DMatrix::zeros(rows + n, n);
                augmented.rows_mut(0, rows).copy_from(&j);
                for k in 0..n {
                    augmented[(rows + k, k)] = mu.sqrt();
                }
                let mut rhs = DVector::zeros(rows + n);
                rhs.rows_mut(0, rows).copy_from(&r);
                let want = augmented.svd(true, true).solve(&rhs, 0.0).unwrap();
                let got = damped_step(&factor, &projected, mu);
                assert!(
                    (&got - &want).norm() <= 1e-9 * want.norm(),
                    "{rows}×{n}, μ {mu}: {} vs {}",
                    got.norm(),
                    want.norm()
                );
            }
            let all = j.clone().svd(false, true);
            let small = factor.svd(false, true);
            for (a, b) in all.singular_values.iter().zip(small.singular_values.iter()) {
                assert!(
                    (a - b).abs() <= 1e-12 * all.singular_values.max(),
                    "{a} vs {b}"
                );
            }
        }
    }
}
