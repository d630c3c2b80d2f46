//! The least-squares problem and its solution: pivoted QR of the scaled Jacobian, then
//! Levenberg–Marquardt on the kept columns, with the covariance of the solution (module
//! docs of [`crate::calibrate`], "Identification", "Uncertainty").

use nalgebra::{DMatrix, DVector};

use adwi_runtime::kinematics::Transform;

use super::model::{Model, State, Walk};
use super::parameters::Parameter;
use super::{CalibrateError, CalibrateOptions};
use adwi_robot::error_model::transform_pose_error;

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
    /// The weighted residual vector and Jacobian, all columns, of a state.
    pub(super) fn linearise(
        &self,
        x: &DVector<f64>,
        state: &State,
    ) -> (DVector<f64>, DMatrix<f64>) {
        let mut jac = DMatrix::zeros(0, 0);
        let r = self.linearise_into(x, state, Some(&mut jac));
        (r, jac)
    }

    /// The weighted residual vector of a state and, when `jacobian` is given, its Jacobian
    /// written over it (every entry; its shape is set first): a fit linearises at every
    /// step, and a fresh Jacobian of tens of thousands of rows was zeroed and faulted in
    /// each time.
    pub(super) fn linearise_into(
        &self,
        x: &DVector<f64>,
        state: &State,
        mut jacobian: Option<&mut DMatrix<f64>>,
    ) -> DVector<f64> {
        let p = self.model.len();
        let rows = self.measurements.len() * self.rows_per_sample;
        let mut r = DVector::zeros(rows);
        if let Some(jac) = jacobian.as_deref_mut() {
            if jac.shape() != (rows, p) {
                *jac = DMatrix::zeros(rows, p);
            }
        }
        for (s, m) in self.measurements.iter().enumerate() {
            // With the Jacobian, the error from the walk it is taken at (the same bits as
            // `error_from`'s, one walk of the arm instead of two).
            let walk = jacobian.is_some().then(|| Walk::of(state, &m.q));
            let e = match &walk {
                Some(walk) => transform_pose_error(&m.nominal_tcp, &walk.tcp),
                None => self.model.error_from(&m.nominal_tcp, state, &m.q),
            };
            let row = s * self.rows_per_sample;
            for a in 0..3 {
                r[row + a] = m.error_mm[a] - e[a];
            }
            if let Some(measured) = m.rotation_error_rad {
                for a in 0..3 {
                    r[row + 3 + a] = self.weight * (measured[a] - e[a + 3]);
                }
            }
            if let (Some(jac), Some(walk)) = (jacobian.as_deref_mut(), &walk) {
                let j = self.model.jacobian_of(x, state, &m.q, walk);
                for a in 0..self.rows_per_sample {
                    let scale = if a < 3 { 1.0 } else { self.weight };
                    for c in 0..p {
                        jac[(row + a, c)] = scale * j[(a, c)];
                    }
                }
            }
        }
        r
    }

    /// RMS of the position residual norms.
    pub(super) fn position_rms(&self, r: &DVector<f64>) -> f64 {
        let n = self.measurements.len();
        let sum: f64 = (0..n)
            .map(|s| r.fixed_rows::<3>(s * self.rows_per_sample).norm_squared())
            .sum();
        (sum / n as f64).sqrt()
    }

    /// Selects the identifiable columns of the nominal Jacobian (scaled by `scales`) other
    /// than `held`, and fits them from `start` (whose held columns are zero).
    ///
    /// `j0_factor` is the nominal Jacobian's R factor (`J₀ = Q R`, [`r_factor`]): the
    /// selection needs only the columns' norms and inner products, which `R` keeps
    /// (`J₀ᵀJ₀ = RᵀR`) in as many rows as there are parameters, not every sample's.
    pub(super) fn solve(
        &self,
        j0_factor: &DMatrix<f64>,
        scales: &[f64],
        held: &[usize],
        start: DVector<f64>,
        options: &CalibrateOptions,
    ) -> Result<Fit, CalibrateError> {
        let p = self.model.len();
        let mut scaled = j0_factor.clone();
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
        let kept_scales: Vec<f64> = kept.iter().map(|&c| scales[c]).collect();
        let n = kept.len();
        let mut x = start;
        let mut state = self.model.state(&x)?;
        let mut jac = DMatrix::zeros(0, 0);
        let mut r = self.linearise_into(&x, &state, Some(&mut jac));
        let mut cost = r.norm_squared();
        let mut mu: f64 = 1e-6;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < options.max_iterations {
            iterations += 1;
            let (factor, projected) = thin_qr(&jac, &kept, &kept_scales, &r);
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
                let candidate_r = self.linearise_into(&candidate_x, &candidate, None);
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
            r = self.linearise_into(&x, &state, Some(&mut jac));
            if converged {
                break;
            }
        }

        // J and its R factor have the same singular values and right singular vectors.
        let (factor, _) = thin_qr(&jac, &kept, &kept_scales, &r);
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

/// The R factor of `J = Q R` ([`thin_qr`]): a square matrix with `J`'s columns' norms
/// and inner products (`JᵀJ = RᵀR`); with `J`'s columns scaled by `S`, `R S` is that of
/// `J S`.
pub(super) fn r_factor(jacobian: &DMatrix<f64>) -> DMatrix<f64> {
    let columns: Vec<usize> = (0..jacobian.ncols()).collect();
    let ones = vec![1.0; columns.len()];
    thin_qr(jacobian, &columns, &ones, &DVector::zeros(jacobian.nrows())).0
}

/// Rows of `J` a step of [`thin_qr`] takes at a time (a multiple of [`LANES`]): with the
/// 66 columns of a six-joint robot with second harmonics 34 KB, within the level-1 and
/// level-2 caches with the 35 KB of `R`.
const QR_CHUNK_ROWS: usize = 64;

/// Interleaved partial sums of [`dot`].
const LANES: usize = 8;

/// The thin QR factorisation `J = Q R` of a tall `J`: `R` (square, upper triangular, of
/// `J`'s column count) and the first rows of `Qᵀ r`, what the least-squares problem
/// `min |J δ − r|` needs of it. `J`'s column `k` is `jacobian`'s column `columns[k]`
/// times `scales[k]`, read as the factorisation goes rather than copied whole.
///
/// Householder reflections applied to `[R; rows]`, [`QR_CHUNK_ROWS`] rows of `J` at a
/// time (QR updated by rows; the reflections' product is one orthogonal `Q`, backward
/// stable as a QR of the whole). Each reflection touches only `R`'s row and the chunk,
/// which stay in cache: on the whole `J` (the UR10's series C with second harmonics:
/// 16,638 × 66, 8.8 MB) each reflection streamed every row from memory. `R`'s diagonal may have either sign.
fn thin_qr(
    jacobian: &DMatrix<f64>,
    columns: &[usize],
    scales: &[f64],
    r: &DVector<f64>,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = columns.len();
    let m = jacobian.nrows();
    let mut factor = DMatrix::<f64>::zeros(n, n);
    let mut projected = DVector::<f64>::zeros(n);
    // The chunk, column by column, and its rows of `r`; the last chunk's rows beyond `J`'s
    // are zero, which no reflection changes and no sum notices.
    let mut chunk = vec![0.0; QR_CHUNK_ROWS * n];
    let mut rhs = [0.0; QR_CHUNK_ROWS];
    let reflect = reflect_chunk_compiled();
    let mut first = 0;
    while first < m {
        let b = QR_CHUNK_ROWS.min(m - first);
        for (k, (&c, &scale)) in columns.iter().zip(scales).enumerate() {
            // Column-major: column c's rows are contiguous.
            let from = &jacobian.as_slice()[c * m + first..c * m + first + b];
            let to = &mut chunk[k * QR_CHUNK_ROWS..(k + 1) * QR_CHUNK_ROWS];
            for (to, &v) in to.iter_mut().zip(from) {
                *to = v * scale;
            }
            to[b..].fill(0.0);
        }
        rhs[..b].copy_from_slice(&r.as_slice()[first..first + b]);
        rhs[b..].fill(0.0);
        reflect(
            factor.as_mut_slice(),
            projected.as_mut_slice(),
            &mut chunk,
            &mut rhs,
        );
        first += b;
    }
    (factor, projected)
}

/// A chunk's reflections ([`reflect_chunk`]), as compiled for the processor.
type ReflectChunk = fn(&mut [f64], &mut [f64], &mut [f64], &mut [f64; QR_CHUNK_ROWS]);

/// [`reflect_chunk`] compiled for the widest vectors this processor has. Without fused
/// multiply-adds the vector versions do the portable version's very operations in wider
/// registers, so every version gives the same bits (`tests`): a calibration does not
/// depend on the processor that made it.
fn reflect_chunk_compiled() -> ReflectChunk {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the processor has AVX-512F (checked just above).
            return |f, p, c, r| unsafe { reflect_chunk_avx512(f, p, c, r) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above).
            return |f, p, c, r| unsafe { reflect_chunk_avx2(f, p, c, r) };
        }
    }
    reflect_chunk
}

/// [`reflect_chunk`] compiled for an instruction set, as `$name`.
macro_rules! reflect_chunk_for {
    ($name:ident, $features:literal, $set:literal) => {
        #[doc = concat!("[`reflect_chunk`] compiled for ", $set, ".")]
        ///
        /// # Safety
        ///
        #[doc = concat!("The processor must have ", $set, ".")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $name(
            factor: &mut [f64],
            projected: &mut [f64],
            chunk: &mut [f64],
            rhs: &mut [f64; QR_CHUNK_ROWS],
        ) {
            reflect_chunk_body(factor, projected, chunk, rhs);
        }
    };
}
reflect_chunk_for!(reflect_chunk_avx2, "avx2", "AVX2");
reflect_chunk_for!(reflect_chunk_avx512, "avx512f", "AVX-512F");

/// Reflects `[R; chunk]` (`R` column-major `n × n`, the chunk column-major with
/// [`QR_CHUNK_ROWS`] rows) so that the chunk's columns are zero, with `[Qᵀr; rhs]` alike.
fn reflect_chunk(
    factor: &mut [f64],
    projected: &mut [f64],
    chunk: &mut [f64],
    rhs: &mut [f64; QR_CHUNK_ROWS],
) {
    reflect_chunk_body(factor, projected, chunk, rhs);
}

#[inline(always)]
fn reflect_chunk_body(
    factor: &mut [f64],
    projected: &mut [f64],
    chunk: &mut [f64],
    rhs: &mut [f64; QR_CHUNK_ROWS],
) {
    let n = projected.len();
    for k in 0..n {
        // The reflection I − τ v vᵀ that zeroes column k of the chunk into R's diagonal
        // entry (LAPACK's dlarfg): v = [1; x / (α − β)] over R's row k and the chunk.
        let (done, rest) = chunk.split_at_mut((k + 1) * QR_CHUNK_ROWS);
        let x: &[f64; QR_CHUNK_ROWS] = done[k * QR_CHUNK_ROWS..].try_into().expect("one column");
        let sigma = dot(x, x);
        if sigma == 0.0 {
            continue;
        }
        let alpha = factor[k * n + k];
        let norm = (alpha * alpha + sigma).sqrt();
        let beta = if alpha > 0.0 { -norm } else { norm };
        let tau = (beta - alpha) / beta;
        let scale = 1.0 / (alpha - beta);
        let reflection = (tau, scale, x);
        for (j, tail) in (k + 1..n).zip(rest.chunks_exact_mut(QR_CHUNK_ROWS)) {
            let tail = tail.try_into().expect("one column");
            reflect_column(reflection, &mut factor[j * n + k], tail);
        }
        reflect_column(reflection, &mut projected[k], rhs);
        factor[k * n + k] = beta;
    }
}

/// Applies the reflection `(τ, 1 / (α − β), x)` of [`reflect_chunk_body`] to one column,
/// `head` its entry in R's row and `tail` its rows in the chunk. A function, not a
/// closure, so that it is compiled with its caller's instruction set.
#[inline(always)]
fn reflect_column(
    (tau, scale, x): (f64, f64, &[f64; QR_CHUNK_ROWS]),
    head: &mut f64,
    tail: &mut [f64; QR_CHUNK_ROWS],
) {
    let w = tau * (*head + scale * dot(tail, x));
    *head -= w;
    let ws = w * scale;
    for (t, v) in tail.iter_mut().zip(x) {
        *t -= ws * v;
    }
}

/// `Σ aᵢ bᵢ` in [`LANES`] interleaved partial sums, added in a fixed order: one sum would
/// wait on each addition before the next (the compiler may not reorder them), and the
/// lanes are one or two vector registers.
#[inline(always)]
fn dot(a: &[f64; QR_CHUNK_ROWS], b: &[f64; QR_CHUNK_ROWS]) -> f64 {
    let mut partial = [0.0; LANES];
    for (x, y) in a.chunks_exact(LANES).zip(b.chunks_exact(LANES)) {
        for lane in 0..LANES {
            partial[lane] += x[lane] * y[lane];
        }
    }
    partial.iter().sum()
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

    /// Each compilation of a chunk's reflections this processor runs gives the portable
    /// one's bits: R and Qᵀr after three chunks, one of them with rows left zero.
    #[test]
    fn every_compilation_of_the_reflections_gives_the_same_bits() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 37;
        let chunks: Vec<(Vec<f64>, [f64; QR_CHUNK_ROWS])> = (0..3)
            .map(|c| {
                let mut chunk: Vec<f64> = (0..QR_CHUNK_ROWS * n)
                    .map(|_| rng.gen_range(-1.0..1.0))
                    .collect();
                let rhs = std::array::from_fn(|i| {
                    if c == 2 && i > 20 {
                        0.0
                    } else {
                        rng.gen_range(-1.0..1.0)
                    }
                });
                if c == 2 {
                    for column in chunk.chunks_exact_mut(QR_CHUNK_ROWS) {
                        column[21..].fill(0.0);
                    }
                }
                (chunk, rhs)
            })
            .collect();
        let run = |reflect: ReflectChunk| {
            let (mut factor, mut projected) = (vec![0.0; n * n], vec![0.0; n]);
            for (chunk, rhs) in &chunks {
                let (mut chunk, mut rhs) = (chunk.clone(), *rhs);
                reflect(&mut factor, &mut projected, &mut chunk, &mut rhs);
            }
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            (bits(&factor), bits(&projected))
        };
        let portable = run(reflect_chunk);
        assert!(portable.0.iter().any(|&b| b != 0));
        assert_eq!(run(reflect_chunk_compiled()), portable);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above).
            assert_eq!(
                run(|f, p, c, r| unsafe { reflect_chunk_avx2(f, p, c, r) }),
                portable
            );
        }
    }

    /// The QR by chunks of rows is a QR of the whole matrix: `R` upper triangular with
    /// `RᵀR = JᵀJ` and `Rᵀ(Qᵀr) = Jᵀr`, whatever the rank; and with full rank it is the
    /// Householder QR of the whole (nalgebra's, the reference) up to the signs of `R`'s
    /// rows, which `Qᵀr` shares. Tall matrices of every remainder of the chunk's rows,
    /// columns taken out of order and scaled, a zero column, fewer rows than a chunk.
    #[test]
    fn the_qr_by_chunks_is_the_householder_qr_of_the_whole() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let cases = [(5, 3), (63, 7), (64, 7), (65, 12), (300, 30), (1001, 50)];
        for (case, &(rows, width)) in cases.iter().enumerate() {
            let mut j = DMatrix::from_fn(rows, width, |_, _| rng.gen_range(-1.0..1.0));
            let full_rank = case % 2 == 0;
            if !full_rank {
                j.column_mut(width / 2).fill(0.0);
            }
            let r = DVector::from_fn(rows, |_, _| rng.gen_range(-1.0..1.0));
            // Every other column from the last, scaled: the solver's kept columns; and the
            // zero one, where there is one.
            let zero = (!full_rank).then_some(width / 2);
            let columns: Vec<usize> = (0..width).rev().step_by(2).chain(zero).collect();
            let scales: Vec<f64> = columns.iter().map(|&c| 0.5 + c as f64).collect();
            let selected =
                DMatrix::from_fn(rows, columns.len(), |i, k| j[(i, columns[k])] * scales[k]);
            let (got_r, got_y) = thin_qr(&j, &columns, &scales, &r);
            let n = columns.len();
            let size = selected.norm() * (selected.norm() + r.norm());
            assert!((0..n).all(|k| (0..k).all(|c| got_r[(k, c)] == 0.0)));
            let gram = got_r.transpose() * &got_r - selected.transpose() * &selected;
            assert!(
                gram.amax() <= 1e-12 * size,
                "{rows}×{n}: RᵀR − JᵀJ {}",
                gram.amax()
            );
            let normal = got_r.transpose() * &got_y - selected.transpose() * &r;
            assert!(
                normal.amax() <= 1e-12 * size,
                "{rows}×{n}: Rᵀy − Jᵀr {}",
                normal.amax()
            );
            if !full_rank || rows < n {
                continue;
            }
            let reference = selected.clone().qr();
            let (want_r, mut want_y) = (reference.r(), r.clone());
            reference.q_tr_mul(&mut want_y);
            for k in 0..n {
                let sign = want_r[(k, k)].signum() * got_r[(k, k)].signum();
                for c in 0..n {
                    let (want, got) = (want_r[(k, c)], sign * got_r[(k, c)]);
                    assert!(
                        (want - got).abs() <= 1e-12 * size,
                        "{rows}×{n} R[{k},{c}]: {want} vs {got}"
                    );
                }
                let (want, got) = (want_y[k], sign * got_y[k]);
                assert!(
                    (want - got).abs() <= 1e-12 * size,
                    "{rows}×{n} y[{k}]: {want} vs {got}"
                );
            }
        }
    }

    /// Pivoting on the R factor keeps and drops the columns pivoting on every row does, in
    /// the same order, with the same independent fractions to rounding: random tall
    /// matrices with exact copies and combinations of other columns (dropped), a column
    /// dependent only to 1e-2 (kept at the tolerance 1e-3), a zero column, and exact
    /// copies of preferred columns (the tie rule).
    #[test]
    fn pivoting_on_the_r_factor_is_pivoting_on_every_row() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for case in 0..60 {
            let rows = [30, 200, 900][case % 3];
            let n = 4 + case % 17;
            let mut a = DMatrix::from_fn(rows, n, |_, _| rng.gen_range(-1.0..1.0));
            // Columns of other columns: exactly redundant, or nearly (kept at 1e-3).
            for _ in 0..(1 + case % 4) {
                let (to, from, other) = (
                    rng.gen_range(0..n),
                    rng.gen_range(0..n),
                    rng.gen_range(0..n),
                );
                if to == from || to == other {
                    continue;
                }
                let mut column = if rng.gen_bool(0.3) {
                    // A multiple: equal to `from` once scaled, a tie.
                    a.column(from) * -3.0
                } else {
                    a.column(from) * rng.gen_range(-2.0..2.0) + a.column(other)
                };
                if rng.gen_bool(0.3) {
                    let apart = DVector::from_fn(rows, |_, _| rng.gen_range(-1e-2..1e-2));
                    column += apart;
                }
                a.set_column(to, &column);
            }
            if case % 5 == 0 {
                a.column_mut(n - 1).fill(0.0);
            }
            // Unit columns, as the identification scales them.
            for c in 0..n {
                let norm = a.column(c).norm();
                if norm > 0.0 {
                    a.column_mut(c).scale_mut(1.0 / norm);
                }
            }
            let preferred: Vec<bool> = (0..n).map(|c| c % 3 == 1).collect();
            let (kept, dropped) = pivot_columns(&a, 1e-3, &preferred);
            let (kept_r, dropped_r) = pivot_columns(&r_factor(&a), 1e-3, &preferred);
            assert_eq!(kept_r, kept, "case {case}: {rows}×{n}");
            let columns = |d: &[(usize, f64)]| d.iter().map(|x| x.0).collect::<Vec<_>>();
            assert_eq!(columns(&dropped_r), columns(&dropped), "case {case}");
            for (x, y) in dropped.iter().zip(&dropped_r) {
                assert!((x.1 - y.1).abs() <= 1e-12, "case {case}: {x:?} vs {y:?}");
            }
        }
    }

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
            let columns: Vec<usize> = (0..n).collect();
            let (factor, projected) = thin_qr(&j, &columns, &vec![1.0; n], &r);
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
