//! Kriging with a nugget — Gaussian-process regression — of a model's residuals, in any
//! distance: Cartesian (nominal positions, mm) or joint space (commanded joint angles, rad).
//!
//! What a calibrated kinematic model leaves is part noise (tracker, repeatability) and part
//! a smooth field it cannot represent (compliance, gear errors, thermal drift). Interpolating
//! the residuals exactly, as kriging without a nugget and the paper's weights do, passes the noise
//! on to every prediction. This predictor separates the two: each residual component `y` is
//! a constant mean plus a zero-mean field with covariance `σ² R(h)` plus independent noise
//! of variance `σ² λ` (the nugget, relative to the sill), and the prediction at `x` is the
//! field's conditional mean,
//!
//! ```text
//! ŷ(x) = ȳ + r(x)ᵀ (R + λ I)⁻¹ (y − ȳ),     r_i(x) = R(|x − x_i|)
//! ```
//!
//! which smooths instead of interpolating. `R` is the Matérn 5/2 correlation,
//! `R(h) = (1 + √5 h/ℓ + 5h²/(3ℓ²)) exp(−√5 h/ℓ)`: twice differentiable, the usual
//! choice for physical fields that are smooth but not analytic.
//!
//! # Choosing ℓ and λ by evidence
//!
//! The length scale `ℓ` and the relative nugget `λ` are chosen from the training samples
//! alone, by maximising the marginal likelihood of the residuals over a fixed grid
//! ([`LENGTH_SCALES`] times the median nearest-neighbour distance, [`NUGGETS`]), searched
//! by a climb (below) rather than point by point. For a given
//! `(ℓ, λ)` the sill of each component has a closed-form maximum, `σ̂² = yᵀA⁻¹y / n` with
//! `A = R + λI`, so the profiled log-likelihood summed over components is
//! `−(n/2) log σ̂² − ½ log|A|` (constants dropped). Each component (x, y, z, and the
//! orientation's when given) gets its own `(ℓ, λ)`: gravity bends z, not x, so they need not
//! share smoothness. The grid search is deterministic and needs no optimiser.
//!
//! The nuggets of a length scale (and of a modulation, below) share its correlation
//! matrix, so it is reduced once to tridiagonal form, `R = Q T Qᵀ` (Householder, `Q`
//! orthogonal; 4/3 n³ flops against n³/3 for a Cholesky factorisation), and the values
//! with it, `z = Qᵀy`: then `|A| = |T + λI|` and `yᵀA⁻¹y = zᵀ(T + λI)⁻¹z` cost O(n) per
//! nugget, and the ten nuggets about 2.5 times less than ten factorisations. These scores
//! are a screen: they agree with the Cholesky ones to about 1e-13, and the grid points
//! within `SCREEN_MARGIN` of a component's best (in practice the best alone) are scored
//! again by Cholesky, which decides, so the choice and the likelihood it reports are those
//! of one Cholesky factorisation per grid point. The reduction is blocked, in panels of
//! 32 columns, with fused multiply-adds ([`crate::householder`]): about 1.5 times faster
//! than the unblocked one on 900 samples, the same bits on every processor with FMA, and
//! only the screen's last bits differ from the unblocked one's, so the choices are the
//! same; its product with the trailing block is written in AVX2 and in AVX-512 intrinsics
//! on cache-line-aligned columns, the same bits again. The fit at the choice reuses the
//! factorisation that scored it.
//!
//! A reduction reads the covariance's lower triangle alone, so the search fills only that
//! ([`lower_covariance`]). Its correlations, and those a table's node sums over every
//! sample ([`kernel_terms`]), are computed four at a time in AVX2 lanes with the
//! exponential of the platform's library reproduced to the bit ([`crate::matern`]): the
//! exponentials were a fifth of a build's processor time, and the tables are unchanged.
//!
//! # The climb
//!
//! A reduction per setting (vertical scale × length scale × modulation, 260 of them with
//! the turning part) was three quarters of a build's processor time. The likelihood over
//! the settings is smooth, with ridges along which a longer length scale trades against a
//! larger vertical scale or modulation, so the search climbs instead: it starts at
//! [`START_LENGTHS`] × [`START_MODULATIONS`] at the isotropic vertical scale, and while
//! some component's best setting (its best over the nuggets, the first in grid order on
//! ties) has a neighbour not yet reduced, it reduces those neighbours: a step of one grid
//! point along any axis, or along both of the (vertical, length) or the (length,
//! modulation) plane's diagonals, which follow those ridges ([`CLIMB_STEPS`]). Each
//! component's choice is so a best among its neighbours, found on the UR5, UR10 and
//! KR150-2 sample sets (and the UR5's folds) at the exhaustive grid's very point with a
//! quarter to a half of its reductions (the UR5's 1,000 samples with the turning part:
//! 64 of 260; the UR10's series A: 83); `tests` hold it to the grid's likelihood on random
//! fields. Each step's settings are reduced in parallel and the steps follow from
//! the scores alone, so nothing depends on the thread count. A component none of whose
//! reduced settings is positive definite has every setting reduced, as before.
//!
//! # Height against breadth
//!
//! Cartesian inputs (positions in mm, base frame, z vertical: [`ResidualGp::fit_cartesian`],
//! [`ResidualGp::fit_turning`]) measure distance with the vertical difference scaled by a
//! factor `s` ([`VERTICAL_SCALES`], chosen per component with `ℓ` and `λ`), so that the
//! field may be smoother along the height than across it (`s < 1`) or rougher (`s > 1`).
//! Gravity sets the vertical apart: what it leaves of a robot's error changes with reach
//! more than with height. On the UR5's residuals the likelihood takes `s = 0.5` for x,
//! `0.25` for y and `2` for z, and the served tool-axis field's 10-fold cross-validation
//! moves from 0.0759 to 0.0730 mm mean (docs/evaluation.md, "Height against breadth"). It
//! is still a field of position, so a table serves it at no cost to a query.
//!
//! # A part that turns with the tool
//!
//! A residual may depend on the tool's orientation as well as on where it is: a tool offset
//! slightly off, a reflector seen from another side, a wrist error the model does not hold.
//! With a unit vector `a_i` per sample (the nominal tool's approach axis, say) the
//! covariance becomes
//!
//! ```text
//! σ² R(h) (1 + w ⟨a, a'⟩)
//! ```
//!
//! the field of position times a part linear in the axis, `w` its weight relative to the
//! position part ([`MODULATIONS`], `w = 0` is the Cartesian kriging above). It is chosen with
//! `ℓ` and `λ` by the same likelihood. The prediction is then linear in the query's axis,
//!
//! ```text
//! ŷ(x, a) = f(x) + a_x h_x(x) + a_y h_y(x) + a_z h_z(x),
//! f(x) = ȳ + Σ_i s_i R(|x − x_i|),   h(x) = w Σ_i s_i R(|x − x_i|) a_i,   s = (K + λI)⁻¹ (y − ȳ)
//! ```
//!
//! so `f` and `h` can be tabulated over positions and combined with the axis at query time,
//! in constant time ([`ResidualGp::predict_terms`]).

#[cfg(test)]
use nalgebra::DVector;
use nalgebra::{Cholesky, DMatrix, Dyn};
use rayon::prelude::*;

/// Length scales tried, in multiples of the median nearest-neighbour distance of the
/// inputs: from below the sample spacing (a rough field) to far beyond it (a smooth trend).
pub const LENGTH_SCALES: [f64; 13] = [
    0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0, 11.0, 16.0, 22.0, 32.0,
];

/// Nuggets tried, as a fraction of the sill: from near-exact interpolation to a field
/// mostly noise.
pub const NUGGETS: [f64; 10] = [0.003, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0];

/// Weights of the part that turns with a unit vector, relative to the position part, tried
/// when the fit is given one per sample ([`ResidualGp::fit_turning`]): none, comparable, or
/// dominant.
pub const MODULATIONS: [f64; 5] = [0.0, 0.3, 1.0, 3.0, 10.0];

/// Factors on the vertical (third, z) coordinate tried for Cartesian inputs
/// ([`ResidualGp::fit_cartesian`], [`ResidualGp::fit_turning`]): the vertical length scale
/// is `ℓ / s`. A robot's errors need not vary as fast with height as across it (gravity
/// acts along z); 1 is the isotropic field, and the likelihood chooses.
pub const VERTICAL_SCALES: [f64; 4] = [0.25, 0.5, 1.0, 2.0];

/// The length scales (indices into [`LENGTH_SCALES`]: 1, 4 and 16 spacings) the climb
/// starts from, a coarse cover of the grid's range (module docs).
pub const START_LENGTHS: [usize; 3] = [2, 6, 10];

/// The modulations (indices into [`MODULATIONS`]: none and comparable) the climb starts
/// from when the field turns.
pub const START_MODULATIONS: [usize; 2] = [0, 2];

/// The climb's steps in grid coordinates `(vertical, length, modulation)`: one grid point
/// along an axis, or along a diagonal of the (vertical, length) or (length, modulation)
/// plane, where the likelihood's ridges lie.
const CLIMB_STEPS: [[isize; 3]; 14] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
    [-1, -1, 0],
    [-1, 1, 0],
    [1, -1, 0],
    [1, 1, 0],
    [0, -1, -1],
    [0, -1, 1],
    [0, 1, -1],
    [0, 1, 1],
];

/// How far below a component's best screened score (relative to `n + |best|`, the scale of
/// a sum of `n` terms) a grid point is scored again by Cholesky. The screen agrees with
/// Cholesky to about 1e-13 of that (the nugget keeps every system well conditioned); the
/// margin is millions of times wider, so the Cholesky scores decide between any points the
/// rounding of either could reorder.
const SCREEN_MARGIN: f64 = 1e-6;

/// A Cholesky factorisation of a search's system.
type Factor = Cholesky<f64, Dyn>;

/// The most exact scorings whose factorisations a search keeps for its fit
/// ([`ResidualGp::fit_turning`]): one per component of position and orientation, and as
/// many again for near-ties.
const KEPT_FACTORS: usize = 2 * GivenChoices::MAX;

/// Why a residual field could not be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpError {
    /// Fewer samples than the fit needs.
    #[error("kriging with a nugget needs at least 3 samples, got {0}")]
    TooFewSamples(usize),
    /// Inputs or values of unequal length or dimension, or not finite.
    #[error("the kriging inputs are malformed: {0}")]
    Malformed(&'static str),
    /// No grid point gave a positive-definite system (all inputs coincide).
    #[error("no length scale gives a solvable kriging system (do all samples coincide?)")]
    Singular,
}

/// The chosen hyperparameters of one group of components.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpChoice {
    /// Length scale ℓ, in the inputs' unit (mm or rad); horizontal for Cartesian inputs.
    pub length_scale: f64,
    /// Factor `s` on the vertical coordinate ([`VERTICAL_SCALES`]; 1 for inputs that are
    /// not Cartesian): the vertical length scale is `ℓ / s`.
    pub vertical_scale: f64,
    /// Nugget relative to the sill, λ.
    pub relative_nugget: f64,
    /// Weight `w` of the part that turns with the samples' unit vectors (0 without them).
    pub modulation: f64,
    /// The profiled log-likelihood it reached (constants dropped).
    pub log_likelihood: f64,
}

/// Hyperparameters given to a fit instead of searched for, one choice per value component
/// (position, then orientation: at most [`GivenChoices::MAX`]): a build's served-field
/// choice searches them once on all its training samples, and its cross-validation folds
/// reuse them. A value (`Copy`), so that build plans can carry it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GivenChoices {
    len: usize,
    choices: [GpChoice; GivenChoices::MAX],
}

impl GivenChoices {
    /// The most components: three of position, three of orientation.
    pub const MAX: usize = 6;

    /// `choices`, or `None` for none or more than [`GivenChoices::MAX`].
    pub fn new(choices: &[GpChoice]) -> Option<GivenChoices> {
        if choices.is_empty() || choices.len() > Self::MAX {
            return None;
        }
        let mut out = GivenChoices {
            len: choices.len(),
            choices: [choices[0]; Self::MAX],
        };
        out.choices[..choices.len()].copy_from_slice(choices);
        Some(out)
    }

    /// The choices, one per component.
    pub fn as_slice(&self) -> &[GpChoice] {
        &self.choices[..self.len]
    }
}

/// A fitted residual field: the predictor of the module docs for each value component.
#[derive(Debug, Clone)]
pub struct ResidualGp {
    inputs: Vec<Vec<f64>>,
    /// Each sample's unit vector, when the field turns with one.
    axes: Option<Vec<[f64; 3]>>,
    components: Vec<Component>,
}

/// One value component's fit.
#[derive(Debug, Clone)]
struct Component {
    choice: GpChoice,
    mean: f64,
    /// `(K + λI)⁻¹ (y − ȳ)`, `K = R` or `R ∘ (1 + w A)`.
    weights: Vec<f64>,
}

/// Matérn 5/2 correlation at distance `h` for length scale `l` (the scalar definition,
/// beside its lanes in [`crate::matern`]).
pub use crate::matern::matern52;

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// [`distance`] with the third coordinate scaled by `vertical` (exactly [`distance`] at 1).
pub(crate) fn scaled_distance(a: &[f64], b: &[f64], vertical: f64) -> f64 {
    if vertical == 1.0 {
        return distance(a, b);
    }
    let dz = vertical * (a[2] - b[2]);
    ((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + dz * dz).sqrt()
}

impl ResidualGp {
    /// Fits the field to `values[i]` (one row of components per input) at `inputs[i]`,
    /// each component with its own `(ℓ, λ)`.
    ///
    /// # Errors
    ///
    /// [`GpError`] for fewer than 3 samples, malformed rows or coincident inputs.
    pub fn fit(inputs: &[Vec<f64>], values: &[Vec<f64>]) -> Result<ResidualGp, GpError> {
        Self::fit_with(inputs, None, &[1.0], values)
    }

    /// Fits the field to values at three-dimensional Cartesian `inputs` (mm, z vertical),
    /// as [`ResidualGp::fit`], the vertical scale `s` chosen among [`VERTICAL_SCALES`] with
    /// `ℓ` and `λ`, per component.
    ///
    /// # Errors
    ///
    /// As [`ResidualGp::fit`]; [`GpError::Malformed`] also for inputs not three-dimensional.
    pub fn fit_cartesian(inputs: &[Vec<f64>], values: &[Vec<f64>]) -> Result<ResidualGp, GpError> {
        check_cartesian(inputs, None)?;
        Self::fit_with(inputs, None, &VERTICAL_SCALES, values)
    }

    /// Fits the field at three-dimensional Cartesian `inputs` with a part that turns with
    /// `axes[i]`, a unit vector per sample (module docs): `w` is chosen among
    /// [`MODULATIONS`] with `ℓ`, `λ` and `s` ([`ResidualGp::fit_cartesian`]), per component.
    ///
    /// # Errors
    ///
    /// As [`ResidualGp::fit_cartesian`]; [`GpError::Malformed`] also for axes not one per
    /// input, not finite, or not of unit length (to 1e-6).
    pub fn fit_turning(
        inputs: &[Vec<f64>],
        axes: &[[f64; 3]],
        values: &[Vec<f64>],
    ) -> Result<ResidualGp, GpError> {
        check_cartesian(inputs, Some(axes))?;
        Self::fit_with(inputs, Some(axes), &VERTICAL_SCALES, values)
    }

    /// The search over `vertical_scales` × [`LENGTH_SCALES`] × the modulations ×
    /// [`NUGGETS`], in that order (nuggets innermost), by the climb of the module docs, then
    /// the fit at each component's choice.
    fn fit_with(
        inputs: &[Vec<f64>],
        axes: Option<&[[f64; 3]]>,
        vertical_scales: &[f64],
        values: &[Vec<f64>],
    ) -> Result<ResidualGp, GpError> {
        let width = check_rows(inputs, values)?;
        let n = inputs.len();
        // Length scales are in units of the inputs' own spacing, whatever the vertical scale.
        let spacing = median_nearest_distance(&DMatrix::from_fn(n, n, |i, j| {
            distance(&inputs[i], &inputs[j])
        }));
        if spacing <= 0.0 {
            return Err(GpError::Singular);
        }
        let distances: Vec<DMatrix<f64>> = vertical_scales
            .iter()
            .map(|&s| DMatrix::from_fn(n, n, |i, j| scaled_distance(&inputs[i], &inputs[j], s)))
            .collect();
        let (means, centred) = centred_values(values);
        let gram = axes.map(gram_matrix);
        let modulations: &[f64] = if gram.is_some() { &MODULATIONS } else { &[0.0] };
        let grid = Grid {
            dims: [
                vertical_scales.len(),
                LENGTH_SCALES.len(),
                modulations.len(),
            ],
        };
        // Setting `i` is (index into `vertical_scales`, ℓ, w); candidate `i` (nuggets
        // innermost) has the covariance of setting `i / NUGGETS.len()`.
        let setting = |i: usize| {
            let [v, l, w] = grid.coordinates(i);
            (v, LENGTH_SCALES[l] * spacing, modulations[w])
        };
        let candidate = |i: usize| {
            let (v, l, w) = setting(i / NUGGETS.len());
            (v, l, NUGGETS[i % NUGGETS.len()], w)
        };
        let varies: Vec<bool> = (0..width)
            .map(|c| centred.column(c).iter().any(|&v| v != 0.0))
            .collect();
        // The climb: each step's settings reduced in parallel, each reduction sequential,
        // the next step chosen from the scores alone, so nothing depends on the thread count.
        let mut screened: Vec<Option<Vec<Option<Vec<f64>>>>> = vec![None; grid.len()];
        let mut step = grid.start(vertical_scales);
        while !step.is_empty() {
            let scores: Vec<Vec<Option<Vec<f64>>>> = step
                .par_iter()
                .map(|&i| {
                    let (v, l, w) = setting(i);
                    let k = lower_covariance(&distances[v], gram.as_ref(), l, w);
                    Tridiagonal::new(k, &centred).log_likelihoods(&NUGGETS)
                })
                .collect();
            for (&i, scores) in step.iter().zip(scores) {
                screened[i] = Some(scores);
            }
            step = grid.next_step(&screened, &varies);
        }
        // Per candidate: `None` where its setting was not reduced, `Some(None)` where the
        // screen found it not positive definite.
        let screened: Vec<Option<Option<Vec<f64>>>> = screened
            .into_iter()
            .flat_map(|scores| match scores {
                Some(scores) => scores.into_iter().map(Some).collect(),
                None => vec![None; NUGGETS.len()],
            })
            .collect();
        // Scored exactly, by Cholesky: every candidate reduced that the screen finds within
        // SCREEN_MARGIN of a component's best, and every one it finds not positive
        // definite. The first best in grid order by the exact scores is then the first
        // best over the candidates reduced.
        let factored = |i: usize| {
            let (v, l, lambda, w) = candidate(i);
            factored_log_likelihoods(system(&distances[v], gram.as_ref(), l, lambda, w), &centred)
        };
        let exact = |i: usize| factored(i).map(|(scores, _)| scores);
        let thresholds: Vec<f64> = (0..width)
            .map(|c| {
                let best = screened
                    .iter()
                    .flatten()
                    .flatten()
                    .map(|s| s[c])
                    .fold(f64::NEG_INFINITY, f64::max);
                best - SCREEN_MARGIN * (n as f64 + best.abs())
            })
            .collect();
        let rescored: Vec<usize> = (0..screened.len())
            .filter(|&i| match &screened[i] {
                None => false,
                Some(None) => true,
                Some(Some(s)) => (0..width).any(|c| varies[c] && s[c] >= thresholds[c]),
            })
            .collect();
        // The factorisations of the few rescored are kept for the fit at the choice (the
        // same system, so the same factor): one factorisation fewer per distinct choice.
        // Beyond a few (near-ties), only the scores, so that memory stays a few matrices.
        let keep = rescored.len() <= KEPT_FACTORS;
        let mut exact_scores: Vec<Option<Option<Vec<f64>>>> = vec![None; screened.len()];
        let mut factors: Vec<(usize, Factor)> = Vec::new();
        let results: Vec<Option<(Vec<f64>, Option<Factor>)>> = rescored
            .par_iter()
            .map(|&i| factored(i).map(|(scores, factor)| (scores, keep.then_some(factor))))
            .collect();
        for (&i, result) in rescored.iter().zip(results) {
            exact_scores[i] = Some(result.map(|(scores, factor)| {
                factors.extend(factor.map(|f| (i, f)));
                scores
            }));
        }
        let mut chosen = Vec::with_capacity(width);
        for c in 0..width {
            let mut best: Option<(usize, f64)> = None;
            if varies[c] {
                for (i, score) in exact_scores.iter().enumerate() {
                    let Some(Some(s)) = score else {
                        continue;
                    };
                    if best.is_none_or(|(_, b)| s[c] > b) {
                        best = Some((i, s[c]));
                    }
                }
            } else {
                // A component with no variation scores 0 wherever the system is positive
                // definite: the first such grid point is its choice, scored exactly here
                // if the screen did not.
                for (i, score) in exact_scores.iter_mut().enumerate() {
                    if let Some(s) = score.get_or_insert_with(|| exact(i)) {
                        best = Some((i, s[c]));
                        break;
                    }
                }
            }
            chosen.push(best.ok_or(GpError::Singular)?);
        }
        let choices: Vec<GpChoice> = chosen
            .iter()
            .map(|&(i, log_likelihood)| {
                let (v, length_scale, relative_nugget, modulation) = candidate(i);
                GpChoice {
                    length_scale,
                    vertical_scale: vertical_scales[v],
                    relative_nugget,
                    modulation,
                    log_likelihood,
                }
            })
            .collect();
        let known: Vec<([u64; 4], Factor)> = factors
            .into_iter()
            .filter(|(i, _)| chosen.iter().any(|(c, _)| c == i))
            .map(|(i, factor)| {
                let (v, l, lambda, w) = candidate(i);
                ([l, vertical_scales[v], lambda, w].map(f64::to_bits), factor)
            })
            .collect();
        Self::solve(inputs, axes, &means, &centred, choices, known)
    }

    /// The dense fit at given hyperparameters, one per value component (no search): what
    /// [`ResidualGp::fit_turning`] (with `axes`) or [`ResidualGp::fit_cartesian`] would
    /// predict had they chosen `choices`. The reference a local fit
    /// ([`crate::local_kriging`]) is held to.
    ///
    /// # Errors
    ///
    /// As [`ResidualGp::fit_turning`]; [`GpError::Malformed`] also for a choice per
    /// component not given or not positive, and [`GpError::Singular`] for a system not
    /// positive definite.
    pub fn with_choices(
        inputs: &[Vec<f64>],
        axes: Option<&[[f64; 3]]>,
        values: &[Vec<f64>],
        choices: &[GpChoice],
    ) -> Result<ResidualGp, GpError> {
        let width = check_rows(inputs, values)?;
        check_cartesian(inputs, axes)?;
        check_choices(choices, width, axes.is_some())?;
        let (means, centred) = centred_values(values);
        Self::solve(inputs, axes, &means, &centred, choices.to_vec(), Vec::new())
    }

    /// The fit at each component's choice: `(K + λI)⁻¹ (y − ȳ)` by Cholesky, one
    /// factorisation per distinct choice, unless `known` has it (keyed by [`GpChoice`]'s
    /// length scale, vertical scale, nugget and modulation, to the bit: a factor of that
    /// very system).
    fn solve(
        inputs: &[Vec<f64>],
        axes: Option<&[[f64; 3]]>,
        means: &[f64],
        centred: &DMatrix<f64>,
        choices: Vec<GpChoice>,
        mut known: Vec<([u64; 4], Factor)>,
    ) -> Result<ResidualGp, GpError> {
        let n = inputs.len();
        let key = |c: &GpChoice| {
            [
                c.length_scale,
                c.vertical_scale,
                c.relative_nugget,
                c.modulation,
            ]
            .map(f64::to_bits)
        };
        let mut points: Vec<[u64; 4]> = choices.iter().map(key).collect();
        points.sort_unstable();
        points.dedup();
        let gram = axes.map(gram_matrix);
        let given: Vec<Option<Factor>> = points
            .iter()
            .map(|p| {
                let at = known.iter().position(|(k, _)| k == p)?;
                Some(known.swap_remove(at).1)
            })
            .collect();
        let factors: Vec<_> = points
            .par_iter()
            .zip(given)
            .map(|(p, given)| {
                if given.is_some() {
                    return given;
                }
                let [l, vertical, lambda, w] = p.map(f64::from_bits);
                let distances = DMatrix::from_fn(n, n, |i, j| {
                    scaled_distance(&inputs[i], &inputs[j], vertical)
                });
                crate::cholesky::cholesky(system(&distances, gram.as_ref(), l, lambda, w))
            })
            .collect();
        let mut components = Vec::with_capacity(choices.len());
        for (c, (&mean, choice)) in means.iter().zip(choices).enumerate() {
            let factor = factors[points.binary_search(&key(&choice)).expect("a chosen point")]
                .as_ref()
                .ok_or(GpError::Singular)?;
            let weights = factor.solve(&centred.column(c).into_owned());
            components.push(Component {
                choice,
                mean,
                weights: weights.iter().copied().collect(),
            });
        }
        Ok(ResidualGp {
            inputs: inputs.to_vec(),
            axes: axes.map(<[_]>::to_vec),
            components,
        })
    }

    /// Whether the field turns with an axis ([`ResidualGp::fit_turning`]).
    pub fn turns(&self) -> bool {
        self.axes.is_some()
    }

    /// The chosen `(ℓ, λ)` of each component.
    pub fn choices(&self) -> Vec<GpChoice> {
        self.components.iter().map(|c| c.choice).collect()
    }

    /// The predicted components at `x`, for a field fitted without axes ([`ResidualGp::fit`]);
    /// `None` when `x` has the wrong dimension or is not finite, or the field turns with an
    /// axis (its prediction needs one: [`ResidualGp::predict_at`]).
    pub fn predict(&self, x: &[f64]) -> Option<Vec<f64>> {
        if self.turns() {
            return None;
        }
        Some(self.predict_terms(x)?.iter().map(|t| t[0]).collect())
    }

    /// The predicted components at `x` for a tool whose axis is `axis`
    /// (`f + axis · h`, module docs); `None` when `x` or `axis` is malformed, or the field
    /// does not turn.
    pub fn predict_at(&self, x: &[f64], axis: [f64; 3]) -> Option<Vec<f64>> {
        if !self.turns() || !axis.iter().all(|v| v.is_finite()) {
            return None;
        }
        let terms = self.predict_terms(x)?;
        Some(
            terms
                .iter()
                .map(|[f, hx, hy, hz]| f + axis[0] * hx + axis[1] * hy + axis[2] * hz)
                .collect(),
        )
    }

    /// Per component, the terms `[f, h_x, h_y, h_z]` at `x` (module docs; `h = 0` for a field
    /// that does not turn): what a table's node holds. `None` when `x` has the wrong
    /// dimension or is not finite.
    pub fn predict_terms(&self, x: &[f64]) -> Option<Vec<[f64; 4]>> {
        if x.len() != self.inputs[0].len() || x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        Some(
            self.components
                .iter()
                .map(|c| {
                    kernel_terms(
                        &c.choice,
                        c.mean,
                        self.inputs.iter().map(Vec::as_slice),
                        self.axes.as_deref(),
                        &c.weights,
                        x,
                    )
                })
                .collect(),
        )
    }
}

/// The settings of a search, `(vertical, length, modulation)` in grid coordinates,
/// numbered in grid order (vertical outermost, modulation innermost).
struct Grid {
    dims: [usize; 3],
}

impl Grid {
    fn len(&self) -> usize {
        self.dims.iter().product()
    }

    fn coordinates(&self, i: usize) -> [usize; 3] {
        let [_, lengths, modulations] = self.dims;
        [
            i / (lengths * modulations),
            i / modulations % lengths,
            i % modulations,
        ]
    }

    fn index(&self, [v, l, w]: [usize; 3]) -> usize {
        (v * self.dims[1] + l) * self.dims[2] + w
    }

    /// Where the climb starts: [`START_LENGTHS`] × [`START_MODULATIONS`] (those the grid
    /// has) at the vertical scale 1, or the middle one.
    fn start(&self, vertical_scales: &[f64]) -> Vec<usize> {
        let v = (vertical_scales.iter())
            .position(|&s| s == 1.0)
            .unwrap_or(vertical_scales.len() / 2);
        let mut out: Vec<usize> = START_LENGTHS
            .iter()
            .flat_map(|&l| {
                (START_MODULATIONS.iter())
                    .filter(|&&w| w < self.dims[2])
                    .map(move |&w| [v, l.min(self.dims[1] - 1), w])
            })
            .map(|c| self.index(c))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The climb's next step: the settings not yet reduced among the [`CLIMB_STEPS`] of
    /// each varying component's best reduced setting, in grid order; every setting not
    /// reduced for a varying component none of whose reduced settings scores.
    fn next_step(&self, screened: &[Option<Vec<Option<Vec<f64>>>>], varies: &[bool]) -> Vec<usize> {
        let mut out = Vec::new();
        for (c, _) in varies.iter().enumerate().filter(|(_, &v)| v) {
            let mut best: Option<(usize, f64)> = None;
            for (i, scores) in screened.iter().enumerate() {
                for s in scores.iter().flatten().flatten() {
                    if best.is_none_or(|(_, b)| s[c] > b) {
                        best = Some((i, s[c]));
                    }
                }
            }
            match best {
                None => out.extend((0..self.len()).filter(|&i| screened[i].is_none())),
                Some((i, _)) => {
                    let at = self.coordinates(i);
                    for step in CLIMB_STEPS {
                        let mut next = [0; 3];
                        let inside = (0..3).all(|k| {
                            let x = at[k].checked_add_signed(step[k]);
                            next[k] = x.unwrap_or(0);
                            x.is_some_and(|x| x < self.dims[k])
                        });
                        if inside && screened[self.index(next)].is_none() {
                            out.push(self.index(next));
                        }
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// Checks a fit's rows: at least 3 samples, inputs of one non-zero dimension, values of one
/// non-zero width, one row per input, everything finite. Returns the width.
pub(crate) fn check_rows(inputs: &[Vec<f64>], values: &[Vec<f64>]) -> Result<usize, GpError> {
    let n = inputs.len();
    if n < 3 {
        return Err(GpError::TooFewSamples(n));
    }
    let dim = inputs[0].len();
    let width = values.first().map_or(0, Vec::len);
    if values.len() != n
        || dim == 0
        || width == 0
        || inputs.iter().any(|x| x.len() != dim)
        || values.iter().any(|v| v.len() != width)
    {
        return Err(GpError::Malformed("rows of unequal or zero length"));
    }
    if inputs
        .iter()
        .chain(values)
        .flatten()
        .any(|v| !v.is_finite())
    {
        return Err(GpError::Malformed("a value is not finite"));
    }
    Ok(width)
}

/// Checks the inputs of a Cartesian fit (three-dimensional) and, when given, its axes (one
/// unit vector per input, to 1e-6).
pub(crate) fn check_cartesian(
    inputs: &[Vec<f64>],
    axes: Option<&[[f64; 3]]>,
) -> Result<(), GpError> {
    if let Some(axes) = axes {
        // Written so that a NaN fails the test.
        let unit =
            |a: &[f64; 3]| ((a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt() - 1.0).abs() < 1e-6;
        if axes.len() != inputs.len() || !axes.iter().all(unit) {
            return Err(GpError::Malformed(
                "the axes are not one unit vector per input",
            ));
        }
    }
    if inputs.iter().any(|x| x.len() != 3) {
        return Err(GpError::Malformed(
            "Cartesian inputs are not three-dimensional",
        ));
    }
    Ok(())
}

/// Checks given hyperparameters: one per component, positive and finite (a modulation
/// non-negative, and 0 without axes).
pub(crate) fn check_choices(choices: &[GpChoice], width: usize, axes: bool) -> Result<(), GpError> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let good = |c: &GpChoice| {
        positive(c.length_scale)
            && positive(c.vertical_scale)
            && positive(c.relative_nugget)
            && c.modulation.is_finite()
            && c.modulation >= 0.0
            && (axes || c.modulation == 0.0)
    };
    if choices.len() != width || !choices.iter().all(good) {
        return Err(GpError::Malformed(
            "the hyperparameters are not one valid choice per component",
        ));
    }
    Ok(())
}

/// The terms `[f, h_x, h_y, h_z]` of one component at `x` (module docs) from kriging
/// `weights` on `inputs` (and their `axes` when the field turns): the one sum both the dense
/// fit and the local one ([`crate::local_kriging`]) evaluate.
pub(crate) fn kernel_terms<'a>(
    choice: &GpChoice,
    mean: f64,
    inputs: impl Iterator<Item = &'a [f64]>,
    axes: Option<&[[f64; 3]]>,
    weights: &[f64],
    x: &[f64],
) -> [f64; 4] {
    let (l, vertical) = (choice.length_scale, choice.vertical_scale);
    let mut terms = [mean, 0.0, 0.0, 0.0];
    // The correlations a chunk at a time ([`crate::matern::matern52_many`]), summed in the
    // samples' order.
    let (mut distances, mut correlations) = ([0.0; TERM_CHUNK], [0.0; TERM_CHUNK]);
    let mut samples = inputs.zip(weights).enumerate();
    loop {
        let mut chunk = [(0, 0.0); TERM_CHUNK];
        let mut count = 0;
        if x.len() == 3 {
            // The coordinates' differences here, their distances in lanes: as
            // [`scaled_distance`] has them (a vertical scale of 1 multiplies exactly).
            let mut offsets = [[0.0; TERM_CHUNK]; 3];
            for (i, (input, &s)) in samples.by_ref().take(TERM_CHUNK) {
                offsets[0][count] = input[0] - x[0];
                offsets[1][count] = input[1] - x[1];
                offsets[2][count] = vertical * (input[2] - x[2]);
                chunk[count] = (i, s);
                count += 1;
            }
            let [dx, dy, dz] = &offsets;
            crate::matern::distances_3d(
                &dx[..count],
                &dy[..count],
                &dz[..count],
                &mut distances[..count],
            );
        } else {
            for (i, (input, &s)) in samples.by_ref().take(TERM_CHUNK) {
                distances[count] = scaled_distance(input, x, vertical);
                chunk[count] = (i, s);
                count += 1;
            }
        }
        crate::matern::matern52_many(&distances[..count], l, &mut correlations[..count]);
        for (&(i, s), &correlation) in chunk[..count].iter().zip(&correlations) {
            let r = correlation * s;
            terms[0] += r;
            if let Some(axes) = axes {
                for k in 0..3 {
                    terms[1 + k] += choice.modulation * r * axes[i][k];
                }
            }
        }
        if count < TERM_CHUNK {
            return terms;
        }
    }
}

/// Samples whose correlations [`kernel_terms`] computes at once.
const TERM_CHUNK: usize = 64;

/// The covariance of the module docs between two samples at scaled distance `h` whose axes
/// have inner product `gram` (ignored at `w = 0`): `R(h) (1 + w gram)`. The entry by entry
/// reference the matrices' fills ([`lower_covariance`], [`cartesian_system`]) are held to.
#[cfg(test)]
fn covariance_entry(h: f64, l: f64, w: f64, gram: f64) -> f64 {
    let r = matern52(h, l);
    if w != 0.0 {
        r * (1.0 + w * gram)
    } else {
        r
    }
}

/// Each component's mean over the samples, and the values less it (samples × components).
fn centred_values(values: &[Vec<f64>]) -> (Vec<f64>, DMatrix<f64>) {
    let (n, width) = (values.len(), values[0].len());
    let means: Vec<f64> = (0..width)
        .map(|c| values.iter().map(|v| v[c]).sum::<f64>() / n as f64)
        .collect();
    let centred = DMatrix::from_fn(n, width, |i, c| values[i][c] - means[c]);
    (means, centred)
}

/// The axes' Gram matrix `⟨a_i, a_j⟩`, for a field that turns with them.
fn gram_matrix(a: &[[f64; 3]]) -> DMatrix<f64> {
    let n = a.len();
    DMatrix::from_fn(n, n, |i, j| {
        a[i][0] * a[j][0] + a[i][1] * a[j][1] + a[i][2] * a[j][2]
    })
}

/// `K + λI` for length scale `l`: `K = R`, or `R ∘ (1 + w G)` with `G` the axes' Gram matrix.
fn system(
    distances: &DMatrix<f64>,
    gram: Option<&DMatrix<f64>>,
    l: f64,
    lambda: f64,
    w: f64,
) -> DMatrix<f64> {
    with_nugget(covariance(distances, gram, l, w), lambda)
}

/// `k + λ I`: [`system`] of the covariance `k`.
fn with_nugget(mut k: DMatrix<f64>, lambda: f64) -> DMatrix<f64> {
    for i in 0..k.nrows() {
        k[(i, i)] += lambda;
    }
    k
}

/// `K` of [`system`], without the nugget: [`lower_covariance`] mirrored (the distances and
/// the Gram matrix are symmetric to the bit, so this is the matrix entry by entry, at half
/// the exponentials).
fn covariance(
    distances: &DMatrix<f64>,
    gram: Option<&DMatrix<f64>>,
    l: f64,
    w: f64,
) -> DMatrix<f64> {
    let mut k = lower_covariance(distances, gram, l, w);
    k.fill_upper_triangle_with_lower_triangle();
    k
}

/// The lower triangle of [`covariance`] (diagonal included; zeros above it), all that a
/// reduction ([`Tridiagonal::new`]) reads: column by column, the correlations at once
/// ([`crate::matern::matern52_many`]), then `R (1 + w G)` entry by entry as
/// [`covariance_entry`] has it.
fn lower_covariance(
    distances: &DMatrix<f64>,
    gram: Option<&DMatrix<f64>>,
    l: f64,
    w: f64,
) -> DMatrix<f64> {
    let n = distances.nrows();
    let mut k = DMatrix::zeros(n, n);
    for j in 0..n {
        let column = j * n + j..(j + 1) * n;
        let below = &mut k.as_mut_slice()[column.clone()];
        crate::matern::matern52_many(&distances.as_slice()[column.clone()], l, below);
        if let Some(g) = gram.filter(|_| w != 0.0) {
            for (entry, &g) in below.iter_mut().zip(&g.as_slice()[column]) {
                *entry *= 1.0 + w * g;
            }
        }
    }
    k
}

/// `K + λI` over three-dimensional `points` (Cartesian, mm: the vertical difference scaled
/// by `vertical`), turning with `axes` (one per point) when given: [`covariance_entry`] at
/// [`scaled_distance`] for every entry, the nugget added on the diagonal (and `+ 0.0`
/// elsewhere), to the bit; the lower triangle's distances and correlations in lanes
/// ([`crate::matern`]), then mirrored (both are symmetric to the bit). A local system of
/// [`crate::local_kriging`].
pub(crate) fn cartesian_system(
    points: &[&[f64]],
    axes: Option<&[[f64; 3]]>,
    (l, vertical, lambda, w): (f64, f64, f64, f64),
) -> DMatrix<f64> {
    let k = points.len();
    let mut a = DMatrix::zeros(k, k);
    let (mut dx, mut dy, mut dz, mut h) = (vec![0.0; k], vec![0.0; k], vec![0.0; k], vec![0.0; k]);
    for j in 0..k {
        let m = k - j;
        for (t, p) in points[j..].iter().enumerate() {
            dx[t] = p[0] - points[j][0];
            dy[t] = p[1] - points[j][1];
            dz[t] = vertical * (p[2] - points[j][2]);
        }
        crate::matern::distances_3d(&dx[..m], &dy[..m], &dz[..m], &mut h[..m]);
        let column = &mut a.as_mut_slice()[j * k + j..(j + 1) * k];
        crate::matern::matern52_many(&h[..m], l, column);
        for (i, entry) in (j..k).zip(column.iter_mut()) {
            if w != 0.0 {
                let g = axes.map_or(0.0, |a| {
                    a[i][0] * a[j][0] + a[i][1] * a[j][1] + a[i][2] * a[j][2]
                });
                *entry *= 1.0 + w * g;
            }
            *entry += if i == j { lambda } else { 0.0 };
        }
    }
    a.fill_upper_triangle_with_lower_triangle();
    a
}

/// Per component, the profiled log-likelihood of the module docs for the system `a`;
/// `None` when it is not positive definite in floating point. A component with no
/// variation scores 0 at every grid point: it carries no evidence about the
/// hyperparameters.
#[cfg(test)]
fn log_likelihoods(a: DMatrix<f64>, centred: &DMatrix<f64>) -> Option<Vec<f64>> {
    factored_log_likelihoods(a, centred).map(|(scores, _)| scores)
}

/// [`log_likelihoods`], with the Cholesky factor of `a` that gave them.
fn factored_log_likelihoods(a: DMatrix<f64>, centred: &DMatrix<f64>) -> Option<(Vec<f64>, Factor)> {
    let n = a.nrows() as f64;
    let chol = crate::cholesky::cholesky(a)?;
    let log_det: f64 = 2.0
        * chol
            .l_dirty()
            .diagonal()
            .iter()
            .map(|d| d.ln())
            .sum::<f64>();
    let solved = chol.solve(centred);
    let scores: Vec<f64> = (0..centred.ncols())
        .map(|c| profiled(n, centred.column(c).dot(&solved.column(c)), log_det))
        .collect();
    scores
        .iter()
        .all(|s| s.is_finite())
        .then_some((scores, chol))
}

/// `−(n/2) log(q/n) − ½ log|A|`, or 0 for a component with no variation (`q = yᵀA⁻¹y ≤ 0`).
fn profiled(n: f64, quadratic: f64, log_det: f64) -> f64 {
    if quadratic > 0.0 {
        -0.5 * n * (quadratic / n).ln() - 0.5 * log_det
    } else {
        0.0
    }
}

/// A covariance `K = Q T Qᵀ` reduced to symmetric tridiagonal form `T` (Householder, `Q`
/// orthogonal), with the centred values carried along, `z = Qᵀ y`: then
/// `|K + λI| = |T + λI|` and `yᵀ(K + λI)⁻¹y = zᵀ(T + λI)⁻¹z` for every nugget `λ`.
struct Tridiagonal {
    diagonal: Vec<f64>,
    /// `T[(i + 1, i)]`, signed.
    off_diagonal: Vec<f64>,
    /// Per component, `z`.
    values: Vec<Vec<f64>>,
}

impl Tridiagonal {
    /// Reduces `k` (symmetric; only its lower triangle is read) and transforms the columns
    /// of `centred`, about 4/3 n³ flops: by the blocked reduction with fused multiply-adds
    /// ([`crate::householder`], the same bits on any processor that has them), or, on an
    /// x86-64 processor without FMA, where those would be library calls, by
    /// [`Tridiagonal::reduce`] (whose screen differs from the blocked one's in the last
    /// bits; the choice is the Cholesky scores', module docs).
    ///
    /// [`Tridiagonal::reduce`] on x86-64 with AVX is the same code compiled for it and
    /// chosen at run time: its loops are elementwise or sum in four fixed interleaved sums
    /// ([`dot`]), so four lanes give the two lanes' bits.
    fn new(k: DMatrix<f64>, centred: &DMatrix<f64>) -> Tridiagonal {
        if crate::householder::fused_in_hardware() {
            return Tridiagonal::blocked(k, centred, crate::householder::tridiagonalise);
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the processor has AVX (checked just above).
            return unsafe { Tridiagonal::new_avx(k, centred) };
        }
        Tridiagonal::reduce(k, centred)
    }

    /// [`Tridiagonal::reduce`] compiled for AVX (without FMA, which would round otherwise).
    ///
    /// # Safety
    ///
    /// The processor must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn new_avx(k: DMatrix<f64>, centred: &DMatrix<f64>) -> Tridiagonal {
        Tridiagonal::reduce(k, centred)
    }

    /// The blocked reduction `reduce` ([`crate::householder::tridiagonalise`] or its
    /// portable compilation) of `k`, carrying the columns of `centred`.
    fn blocked(
        k: DMatrix<f64>,
        centred: &DMatrix<f64>,
        reduce: crate::householder::Reduction,
    ) -> Tridiagonal {
        let n = k.nrows();
        let mut values: Vec<Vec<f64>> = centred
            .column_iter()
            .map(|c| c.iter().copied().collect())
            .collect();
        let (diagonal, off_diagonal) = reduce(k.as_slice(), n, &mut values);
        Tridiagonal {
            diagonal,
            off_diagonal,
            values,
        }
    }

    /// The unblocked reduction: `n − 2` Householder reflections, each applied to the
    /// trailing block as a rank-2 update in the same pass over it as the next reflection's
    /// product with it (LAPACK's `dsytd2`, fused). The reference the blocked one is held to
    /// (`tests`), and the reduction on x86-64 processors without FMA.
    #[inline(always)]
    fn reduce(mut k: DMatrix<f64>, centred: &DMatrix<f64>) -> Tridiagonal {
        let n = k.nrows();
        let a = k.as_mut_slice();
        let mut values: Vec<Vec<f64>> = centred
            .column_iter()
            .map(|c| c.iter().copied().collect())
            .collect();
        let mut off_diagonal = vec![0.0; n.saturating_sub(1)];
        // The previous reflection `I − τ v vᵀ` and its rank-2 update `−v wᵀ − w vᵀ` of the
        // trailing block (still to apply); `u` the current reflection, `p` its product.
        let (mut v, mut w, mut u, mut p) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut tau_previous = 0.0;
        for k in 0..n.saturating_sub(1) {
            let column = &mut a[k * n..(k + 1) * n];
            if tau_previous != 0.0 {
                rank_two_update(&mut column[k..], &v[k..], &w[k..], v[k], w[k]);
            }
            // The reflection taking column k below the subdiagonal to zero.
            let (tau, beta) = reflection(&mut column[k + 1..]);
            off_diagonal[k] = beta;
            u[k + 1] = 1.0;
            u[k + 2..].copy_from_slice(&column[k + 2..]);
            p[k + 1..].fill(0.0);
            for j in k + 1..n {
                let column = &mut a[j * n..(j + 1) * n];
                if tau_previous != 0.0 {
                    rank_two_update(&mut column[j..], &v[j..], &w[j..], v[j], w[j]);
                }
                if tau != 0.0 {
                    // p += B u over the lower triangle: column j below the diagonal
                    // serves row j (a dot product) and rows below it (an axpy).
                    let uj = u[j];
                    for (pi, aij) in p[j + 1..].iter_mut().zip(&column[j + 1..]) {
                        *pi += aij * uj;
                    }
                    p[j] += column[j] * uj + dot(&column[j + 1..], &u[j + 1..]);
                }
            }
            if tau != 0.0 {
                for y in &mut values {
                    let s = tau * dot(&u[k + 1..], &y[k + 1..]);
                    for (yi, ui) in y[k + 1..].iter_mut().zip(&u[k + 1..]) {
                        *yi -= s * ui;
                    }
                }
                // w = τ p − (τ/2)(τ pᵀu) u, so that H B H = B − u wᵀ − w uᵀ.
                p[k + 1..].iter_mut().for_each(|x| *x *= tau);
                let half = 0.5 * tau * dot(&p[k + 1..], &u[k + 1..]);
                for ((wi, pi), ui) in w[k + 1..].iter_mut().zip(&p[k + 1..]).zip(&u[k + 1..]) {
                    *wi = pi - half * ui;
                }
            }
            std::mem::swap(&mut v, &mut u);
            tau_previous = tau;
        }
        Tridiagonal {
            diagonal: (0..n).map(|i| a[i * n + i]).collect(),
            off_diagonal,
            values,
        }
    }

    /// Per nugget, the scores of [`log_likelihoods`] for `K + λI`, from an `LDLᵀ`
    /// factorisation of `T + λI` in O(n): `log|T + λI| = Σ log dᵢ` and
    /// `zᵀ(T + λI)⁻¹z = Σ (L⁻¹z)ᵢ² / dᵢ`. `None` where a pivot `dᵢ` is not positive (the
    /// system is not positive definite) or a score is not finite.
    fn log_likelihoods(&self, nuggets: &[f64]) -> Vec<Option<Vec<f64>>> {
        let n = self.diagonal.len();
        let width = self.values.len();
        nuggets
            .iter()
            .map(|&lambda| {
                let mut log_det = 0.0;
                let mut pivot = 1.0;
                let mut last = 0.0;
                let mut forward = vec![0.0; width];
                let mut quadratic = vec![0.0; width];
                for i in 0..n {
                    let l = if i == 0 {
                        0.0
                    } else {
                        self.off_diagonal[i - 1] / pivot
                    };
                    pivot = self.diagonal[i] + lambda - l * last;
                    if pivot.is_nan() || pivot <= 0.0 {
                        return None;
                    }
                    if i + 1 < n {
                        last = self.off_diagonal[i];
                    }
                    log_det += pivot.ln();
                    for c in 0..width {
                        forward[c] = self.values[c][i] - l * forward[c];
                        quadratic[c] += forward[c] * forward[c] / pivot;
                    }
                }
                let scores: Vec<f64> = quadratic
                    .iter()
                    .map(|&q| profiled(n as f64, q, log_det))
                    .collect();
                scores.iter().all(|s| s.is_finite()).then_some(scores)
            })
            .collect()
    }
}

/// The Householder reflection `I − τ v vᵀ` (`v₀ = 1`) taking `x` to `β e₀`: returns
/// `(τ, β)` and leaves `v` below `x[0]`; `τ = 0` when `x` is already there.
fn reflection(x: &mut [f64]) -> (f64, f64) {
    let alpha = x[0];
    let norm = dot(&x[1..], &x[1..]).sqrt();
    if norm == 0.0 {
        return (0.0, alpha);
    }
    let beta = -alpha.signum() * alpha.hypot(norm);
    let scale = 1.0 / (alpha - beta);
    x[1..].iter_mut().for_each(|v| *v *= scale);
    ((beta - alpha) / beta, beta)
}

/// `column −= v w_j + w v_j`, one column of a symmetric rank-2 update.
#[inline(always)]
fn rank_two_update(column: &mut [f64], v: &[f64], w: &[f64], vj: f64, wj: f64) {
    for ((a, vi), wi) in column.iter_mut().zip(v).zip(w) {
        *a -= vi * wj + wi * vj;
    }
}

/// A dot product in four interleaved sums (they vectorise).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0; 4];
    let (chunks_a, chunks_b) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = chunks_a
        .remainder()
        .iter()
        .zip(chunks_b.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in chunks_a.zip(chunks_b) {
        for t in 0..4 {
            sums[t] += x[t] * y[t];
        }
    }
    (sums[0] + sums[2]) + (sums[1] + sums[3]) + tail
}

/// The median over inputs of the distance to the nearest other input.
fn median_nearest_distance(distances: &DMatrix<f64>) -> f64 {
    let n = distances.nrows();
    let mut nearest: Vec<f64> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j != i)
                .map(|j| distances[(i, j)])
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    nearest.sort_by(f64::total_cmp);
    nearest[n / 2]
}

/// A slow, obvious reference of [`ResidualGp::predict`] for a given `(ℓ, λ)`: builds the
/// system densely and solves it by LU, for tests.
#[cfg(test)]
fn reference_predict(inputs: &[Vec<f64>], values: &[f64], l: f64, lambda: f64, x: &[f64]) -> f64 {
    reference_predict_turning(inputs, None, values, (l, 1.0, lambda, 0.0), x, [0.0; 3])
}

/// The same with axes and a vertical scale `s`: the covariance `R(h) (1 + w ⟨a, a'⟩)`
/// written out per entry, `h` with the third coordinate's difference times `s`, the query's
/// axis in the cross-covariances.
#[cfg(test)]
fn reference_predict_turning(
    inputs: &[Vec<f64>],
    axes: Option<&[[f64; 3]]>,
    values: &[f64],
    (l, s, lambda, w): (f64, f64, f64, f64),
    x: &[f64],
    axis: [f64; 3],
) -> f64 {
    let squeezed = |p: &[f64]| -> Vec<f64> {
        let mut p = p.to_vec();
        if s != 1.0 {
            p[2] *= s;
        }
        p
    };
    let inputs: Vec<Vec<f64>> = inputs.iter().map(|p| squeezed(p)).collect();
    let x = &squeezed(x);
    let n = inputs.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let turn = |i: usize, b: [f64; 3]| axes.map_or(1.0, |a| 1.0 + w * dot(a[i], b));
    let a = DMatrix::from_fn(n, n, |i, j| {
        let aj = axes.map_or([0.0; 3], |a| a[j]);
        matern52(distance(&inputs[i], &inputs[j]), l) * turn(i, aj)
            + if i == j { lambda } else { 0.0 }
    });
    let y = DVector::from_iterator(n, values.iter().map(|v| v - mean));
    let s = a.lu().solve(&y).expect("invertible");
    let r = DVector::from_fn(n, |i, _| {
        matern52(distance(&inputs[i], x), l) * turn(i, axis)
    });
    mean + r.dot(&s)
}

/// The choices of [`ResidualGp::fit_turning`] (or of [`ResidualGp::fit`] or
/// [`ResidualGp::fit_cartesian`] without axes, as `vertical_scales` says) by the obvious
/// search: every grid point scored by Cholesky, the first best in grid order.
#[cfg(test)]
fn reference_choices(
    inputs: &[Vec<f64>],
    axes: Option<&[[f64; 3]]>,
    vertical_scales: &[f64],
    values: &[Vec<f64>],
) -> Vec<GpChoice> {
    let n = inputs.len();
    let width = values[0].len();
    let spacing = median_nearest_distance(&DMatrix::from_fn(n, n, |i, j| {
        distance(&inputs[i], &inputs[j])
    }));
    let (_, centred) = centred_values(values);
    let gram = axes.map(gram_matrix);
    let modulations: &[f64] = if axes.is_some() { &MODULATIONS } else { &[0.0] };
    let mut best: Vec<Option<GpChoice>> = vec![None; width];
    for &vertical in vertical_scales {
        let distances = DMatrix::from_fn(n, n, |i, j| {
            let (a, b) = (&inputs[i], &inputs[j]);
            let d: Vec<f64> = (0..a.len()).map(|k| a[k] - b[k]).collect();
            let dz = if d.len() == 3 { vertical * d[2] } else { 0.0 };
            let rest: f64 = d
                .iter()
                .take(if d.len() == 3 { 2 } else { d.len() })
                .map(|v| v * v)
                .sum();
            (rest + dz * dz).sqrt()
        });
        for &l in &LENGTH_SCALES {
            for &w in modulations {
                // The nuggets share the covariance: [`system`] of each is this plus λ I.
                let k = covariance(&distances, gram.as_ref(), l * spacing, w);
                for &lambda in &NUGGETS {
                    let a = with_nugget(k.clone(), lambda);
                    let Some(scores) = log_likelihoods(a, &centred) else {
                        continue;
                    };
                    for (b, &s) in best.iter_mut().zip(&scores) {
                        if b.is_none_or(|b| s > b.log_likelihood) {
                            *b = Some(GpChoice {
                                length_scale: l * spacing,
                                vertical_scale: vertical,
                                relative_nugget: lambda,
                                modulation: w,
                                log_likelihood: s,
                            });
                        }
                    }
                }
            }
        }
    }
    best.into_iter()
        .map(|b| b.expect("a solvable grid point"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn cloud(n: usize, dim: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| (0..dim).map(|_| rng.gen_range(-1.0..1.0)).collect())
            .collect()
    }

    #[test]
    fn prediction_equals_the_dense_reference_at_the_chosen_hyperparameters() {
        let inputs = cloud(60, 4, 1);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let values: Vec<Vec<f64>> = inputs
            .iter()
            .map(|x| {
                let a = (2.0 * x[0]).sin() + x[1] * x[2];
                let b = x[3] * x[3] - 0.3 * x[0];
                vec![a + 0.05 * rng.gen_range(-1.0..1.0), b]
            })
            .collect();
        let gp = ResidualGp::fit(&inputs, &values).unwrap();
        let choices = gp.choices();
        for x in cloud(20, 4, 3) {
            let got = gp.predict(&x).unwrap();
            for (c, choice) in choices.iter().enumerate() {
                let column: Vec<f64> = values.iter().map(|v| v[c]).collect();
                let want = reference_predict(
                    &inputs,
                    &column,
                    choice.length_scale,
                    choice.relative_nugget,
                    &x,
                );
                assert!((got[c] - want).abs() < 1e-9, "{} vs {want}", got[c]);
            }
        }
    }

    #[test]
    fn smooths_noise_that_exact_interpolation_would_keep() {
        // A smooth field plus independent noise: the fitted nugget is large enough that
        // predictions at held-out points beat the noisy samples' own error.
        let inputs = cloud(300, 2, 4);
        let field = |x: &[f64]| (1.5 * x[0]).sin() + 0.5 * x[1];
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let noise = 0.2;
        let values: Vec<Vec<f64>> = inputs
            .iter()
            .map(|x| vec![field(x) + noise * rng.gen_range(-1.0..1.0)])
            .collect();
        let gp = ResidualGp::fit(&inputs, &values).unwrap();
        assert!(
            gp.choices()[0].relative_nugget >= 0.01,
            "{:?}",
            gp.choices()
        );
        let held = cloud(200, 2, 6);
        let rms = (held
            .iter()
            .map(|x| (gp.predict(x).unwrap()[0] - field(x)).powi(2))
            .sum::<f64>()
            / held.len() as f64)
            .sqrt();
        // The noise's own RMS is 0.2/√3 ≈ 0.115.
        assert!(rms < 0.05, "held-out RMS {rms}");
    }

    fn unit_axes(n: usize, seed: u64) -> Vec<[f64; 3]> {
        cloud(n, 3, seed)
            .iter()
            .map(|v| {
                let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
                [v[0] / norm, v[1] / norm, v[2] / norm]
            })
            .collect()
    }

    /// The search's fit reuses the factorisation that scored its choice: its weights are,
    /// to the bit, those of a fit given the same choices and factorising afresh
    /// ([`ResidualGp::with_choices`]), for fields that turn and fields that do not, with
    /// components that choose alike and apart, and one that does not vary.
    #[test]
    fn a_search_fits_as_its_choices_factorised_afresh() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for case in 0..6u64 {
            let n = 40 + 13 * case as usize;
            let inputs = cloud(n, 3, 200 + case);
            let axes = unit_axes(n, 300 + case);
            let values: Vec<Vec<f64>> = (0..n)
                .map(|i| {
                    let x = &inputs[i];
                    let noise = 0.05 * rng.gen_range(-1.0..1.0);
                    vec![
                        (1.3 * x[1]).sin() + noise + 0.3 * axes[i][0],
                        (0.4 * x[0]).cos() * (2.0 * x[2]).sin() + noise,
                        if case == 2 { 0.5 } else { x[0] * x[2] + noise },
                    ]
                })
                .collect();
            for turning in [false, true] {
                let (gp, given) = if turning {
                    let gp = ResidualGp::fit_turning(&inputs, &axes, &values).unwrap();
                    let choices = gp.choices();
                    let given =
                        ResidualGp::with_choices(&inputs, Some(&axes), &values, &choices).unwrap();
                    (gp, given)
                } else {
                    let gp = ResidualGp::fit_cartesian(&inputs, &values).unwrap();
                    let choices = gp.choices();
                    (
                        gp,
                        ResidualGp::with_choices(&inputs, None, &values, &choices).unwrap(),
                    )
                };
                assert_eq!(gp.choices(), given.choices(), "case {case}");
                for (got, want) in gp.components.iter().zip(&given.components) {
                    assert_eq!(got.mean.to_bits(), want.mean.to_bits(), "case {case}");
                    let bits = |w: &[f64]| w.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&got.weights), bits(&want.weights), "case {case}");
                }
            }
        }
    }

    #[test]
    fn a_turning_field_equals_its_dense_reference_and_is_linear_in_the_axis() {
        // A field with a part proportional to the axis, as an offset tool gives.
        let inputs = cloud(80, 3, 11);
        let axes = unit_axes(80, 12);
        let offset = |x: &[f64]| [0.3 + 0.2 * x[0], -0.1, 0.4 * x[2]];
        let field = |x: &[f64], a: [f64; 3]| {
            let o = offset(x);
            (1.3 * x[1]).sin() + o[0] * a[0] + o[1] * a[1] + o[2] * a[2]
        };
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let values: Vec<Vec<f64>> = (0..80)
            .map(|i| vec![field(&inputs[i], axes[i]) + 0.01 * rng.gen_range(-1.0..1.0)])
            .collect();
        let gp = ResidualGp::fit_turning(&inputs, &axes, &values).unwrap();
        let choice = gp.choices()[0];
        assert!(choice.modulation > 0.0, "{choice:?}");
        let column: Vec<f64> = values.iter().map(|v| v[0]).collect();
        let plain = ResidualGp::fit(&inputs, &values).unwrap();
        let (mut turning_sq, mut plain_sq) = (0.0, 0.0);
        for (x, axis) in cloud(30, 3, 14).iter().zip(unit_axes(30, 15)) {
            let got = gp.predict_at(x, axis).unwrap()[0];
            let want = reference_predict_turning(
                &inputs,
                Some(&axes),
                &column,
                (
                    choice.length_scale,
                    choice.vertical_scale,
                    choice.relative_nugget,
                    choice.modulation,
                ),
                x,
                axis,
            );
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
            let t = gp.predict_terms(x).unwrap()[0];
            let linear = t[0] + axis[0] * t[1] + axis[1] * t[2] + axis[2] * t[3];
            assert!((linear - got).abs() < 1e-12);
            turning_sq += (got - field(x, axis)).powi(2);
            plain_sq += (plain.predict(x).unwrap()[0] - field(x, axis)).powi(2);
        }
        // The part that turns is beyond a field of position alone.
        assert!(turning_sq < 0.2 * plain_sq, "{turning_sq} vs {plain_sq}");
        assert!(gp.predict(&[0.0; 3]).is_none());
        assert!(plain.predict_at(&[0.0; 3], [0.0, 0.0, 1.0]).is_none());
        assert!(matches!(
            ResidualGp::fit_turning(&inputs, &axes[1..], &values),
            Err(GpError::Malformed(_))
        ));
        let mut long = axes.clone();
        long[3] = [1.0, 1.0, 0.0];
        assert!(matches!(
            ResidualGp::fit_turning(&inputs, &long, &values),
            Err(GpError::Malformed(_))
        ));
    }

    /// Whether two scores agree to 1e-9 of their scale, `n + |score|` (a sum of `n` terms).
    fn agree(got: &Option<Vec<f64>>, want: &Option<Vec<f64>>, n: usize) -> bool {
        match (got, want) {
            (None, None) => true,
            (Some(g), Some(w)) => g
                .iter()
                .zip(w)
                .all(|(g, w)| (g - w).abs() <= 1e-9 * (n as f64 + w.abs())),
            _ => false,
        }
    }

    /// A random cloud's distances, axes' Gram matrix and centred values (one component
    /// smooth, one rough).
    fn scoring_case(n: usize, dim: usize, seed: u64) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
        let inputs = cloud(n, dim, seed);
        let axes = unit_axes(n, seed + 1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 2);
        let distances = DMatrix::from_fn(n, n, |i, j| distance(&inputs[i], &inputs[j]));
        let gram = DMatrix::from_fn(n, n, |i, j| {
            axes[i][0] * axes[j][0] + axes[i][1] * axes[j][1] + axes[i][2] * axes[j][2]
        });
        let mut centred = DMatrix::from_fn(n, 2, |i, c| {
            let x = &inputs[i];
            if c == 0 {
                (2.0 * x[0]).sin() + x[1] + 0.1 * axes[i][2]
            } else {
                rng.gen_range(-1.0..1.0)
            }
        });
        for mut column in centred.column_iter_mut() {
            let mean = column.mean();
            column.add_scalar_mut(-mean);
        }
        (distances, gram, centred)
    }

    /// The covariance mirrored from its lower triangle is, to the bit, every entry computed
    /// on its own (the matrix the search reduced before), with and without the turning part
    /// and the vertical scale.
    #[test]
    fn the_mirrored_covariance_is_every_entry_to_the_bit() {
        let inputs = cloud(57, 3, 41);
        let axes = unit_axes(57, 42);
        let gram = gram_matrix(&axes);
        for vertical in [1.0, 0.25, 2.0] {
            let distances = DMatrix::from_fn(57, 57, |i, j| {
                scaled_distance(&inputs[i], &inputs[j], vertical)
            });
            for (l, w) in [(0.3, 0.0), (1.7, 0.3), (0.05, 10.0)] {
                let got = covariance(&distances, Some(&gram), l, w);
                let want = DMatrix::from_fn(57, 57, |i, j| {
                    covariance_entry(distances[(i, j)], l, w, gram[(i, j)])
                });
                let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&want), "s {vertical}, ℓ {l}, w {w}");
            }
        }
    }

    /// The search reduces the covariance's lower triangle alone ([`lower_covariance`]):
    /// it is the full matrix's, and the reductions (blocked, and the unblocked reference)
    /// read nothing above the diagonal, so they give the full matrix's bits.
    #[test]
    fn the_reductions_read_the_lower_triangle_alone() {
        for (seed, n) in [(1, 5), (2, 40), (3, 97), (4, 150)] {
            let (distances, gram, centred) = scoring_case(n, 3, 500 + seed);
            let spacing = median_nearest_distance(&distances);
            for w in [0.0, 0.3] {
                let full = covariance(&distances, Some(&gram), 2.0 * spacing, w);
                let lower = lower_covariance(&distances, Some(&gram), 2.0 * spacing, w);
                for j in 0..n {
                    for i in 0..n {
                        let want = if i >= j { full[(i, j)].to_bits() } else { 0 };
                        assert_eq!(lower[(i, j)].to_bits(), want, "n {n}, ({i}, {j})");
                    }
                }
                // Above the diagonal, something a reading would notice.
                let mut marked = lower.clone();
                for j in 1..n {
                    for i in 0..j {
                        marked[(i, j)] = f64::NAN;
                    }
                }
                assert_eq!(
                    reduction_bits(&Tridiagonal::new(marked.clone(), &centred)),
                    reduction_bits(&Tridiagonal::new(full.clone(), &centred)),
                    "n {n}, w {w}"
                );
                assert_eq!(
                    reduction_bits(&Tridiagonal::reduce(marked, &centred)),
                    reduction_bits(&Tridiagonal::reduce(full, &centred)),
                    "n {n}, w {w}"
                );
            }
        }
    }

    /// Property: [`cartesian_system`] (the lower triangle in lanes, mirrored) is the
    /// obvious matrix of [`covariance_entry`] at every entry plus the nugget, to the bit:
    /// sizes below, at and beyond the lanes, with and without a vertical scale and axes.
    #[test]
    fn the_cartesian_system_is_every_entry_to_the_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(44);
        for case in 0..60u64 {
            let k = [1, 2, 5, 8, 33, 128][case as usize % 6];
            let points = cloud(k, 3, 5000 + case);
            let axes = unit_axes(k, 6000 + case);
            let local: Vec<&[f64]> = points.iter().map(Vec::as_slice).collect();
            let vertical = [1.0, 0.25, 2.0][case as usize % 3];
            let w = [0.0, 0.3, 10.0][case as usize / 3 % 3];
            let (l, lambda) = (rng.gen_range(0.05..3.0), rng.gen_range(0.001..2.0));
            let axes = (case % 2 == 0).then_some(&axes[..]);
            let got = cartesian_system(&local, axes, (l, vertical, lambda, w));
            let gram = |i: usize, j: usize| {
                axes.map_or(0.0, |a| {
                    a[i][0] * a[j][0] + a[i][1] * a[j][1] + a[i][2] * a[j][2]
                })
            };
            let want = DMatrix::from_fn(k, k, |i, j| {
                covariance_entry(
                    scaled_distance(local[i], local[j], vertical),
                    l,
                    w,
                    gram(i, j),
                ) + if i == j { lambda } else { 0.0 }
            });
            let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "case {case}, k {k}");
        }
    }

    /// Property: [`kernel_terms`] (distances and correlations in lanes, a chunk at a time)
    /// gives the bits of the obvious sum, sample after sample, of the scalar
    /// [`matern52`] at [`scaled_distance`]: Cartesian points with and without a vertical
    /// scale and a turning part, two- and six-dimensional inputs, sample counts below, at
    /// and across the chunks, and points on a sample (distance 0).
    #[test]
    fn the_kernel_terms_are_the_obvious_sum_to_the_bit() {
        let reference = |choice: &GpChoice,
                         inputs: &[Vec<f64>],
                         axes: Option<&[[f64; 3]]>,
                         weights: &[f64],
                         x: &[f64]| {
            let mut terms = [0.5, 0.0, 0.0, 0.0];
            for (i, (input, s)) in inputs.iter().zip(weights).enumerate() {
                let r = matern52(
                    scaled_distance(input, x, choice.vertical_scale),
                    choice.length_scale,
                ) * s;
                terms[0] += r;
                if let Some(axes) = axes {
                    for k in 0..3 {
                        terms[1 + k] += choice.modulation * r * axes[i][k];
                    }
                }
            }
            terms
        };
        let mut rng = ChaCha8Rng::seed_from_u64(43);
        for case in 0..120u64 {
            let n = [1, 3, 63, 64, 65, 128, 200][case as usize % 7];
            let dim = [3, 3, 3, 2, 6][case as usize % 5];
            let inputs = cloud(n, dim, 2000 + case);
            let axes = unit_axes(n, 3000 + case);
            let weights: Vec<f64> = (0..n).map(|_| rng.gen_range(-2.0..2.0)).collect();
            let choice = GpChoice {
                length_scale: rng.gen_range(0.05..3.0),
                vertical_scale: if dim == 3 {
                    [1.0, 0.25, 2.0][case as usize % 3]
                } else {
                    1.0
                },
                relative_nugget: 0.1,
                modulation: [0.0, 0.3, 10.0][case as usize % 3],
                log_likelihood: 0.0,
            };
            let axes = (case % 2 == 0).then_some(&axes[..]);
            let on_a_sample = inputs[n / 2].clone();
            for x in [cloud(1, dim, 4000 + case).remove(0), on_a_sample] {
                let got = kernel_terms(
                    &choice,
                    0.5,
                    inputs.iter().map(Vec::as_slice),
                    axes,
                    &weights,
                    &x,
                );
                let want = reference(&choice, &inputs, axes, &weights, &x);
                assert_eq!(
                    got.map(f64::to_bits),
                    want.map(f64::to_bits),
                    "case {case}: {got:?} vs {want:?}"
                );
            }
        }
    }

    /// A reduction's bits: diagonal, subdiagonal, transformed values.
    fn reduction_bits(t: &Tridiagonal) -> Vec<u64> {
        (t.diagonal.iter())
            .chain(&t.off_diagonal)
            .chain(t.values.iter().flatten())
            .map(|v| v.to_bits())
            .collect()
    }

    /// The reduction chosen at run time (the blocked one with FMA where the processor has
    /// it, else the unblocked one with AVX where it has that) gives the portable
    /// compilation's bits, so that a table does not depend on the processor that built it.
    #[test]
    fn the_reduction_is_the_same_to_the_bit_on_any_processor() {
        // Sizes below, at and beyond a panel and the kernels' column and row counts.
        for (seed, n) in [(1, 7), (2, 64), (3, 203), (4, 33), (5, 97)] {
            let (distances, gram, centred) = scoring_case(n, 3, 300 + seed);
            let spacing = median_nearest_distance(&distances);
            let k = covariance(&distances, Some(&gram), 2.0 * spacing, 0.3);
            let chosen = Tridiagonal::new(k.clone(), &centred);
            let portable = if crate::householder::fused_in_hardware() {
                Tridiagonal::blocked(
                    k.clone(),
                    &centred,
                    crate::householder::tridiagonalise_portable,
                )
            } else {
                Tridiagonal::reduce(k.clone(), &centred)
            };
            assert_eq!(
                reduction_bits(&chosen),
                reduction_bits(&portable),
                "n = {n}"
            );
            // Both compilations of the unblocked reference agree too.
            let plain = Tridiagonal::reduce(k.clone(), &centred);
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: the processor has AVX (checked just above).
                let avx = unsafe { Tridiagonal::new_avx(k, &centred) };
                assert_eq!(reduction_bits(&avx), reduction_bits(&plain), "n = {n}");
            }
        }
    }

    /// Property: the blocked reduction's screen equals the unblocked reference's, every
    /// nugget's scores to 1e-9 of their scale, on random clouds of 3 to 150 samples (below,
    /// at and across panels), plain and turning, smooth and rough covariances, and on
    /// matrices with columns already reduced (reflections that are the identity); both
    /// keep the matrix's trace and Frobenius norm to 1e-12.
    #[test]
    fn the_blocked_reduction_equals_the_unblocked_reference() {
        let mut rng = ChaCha8Rng::seed_from_u64(900);
        for case in 0..40u64 {
            let n = if case < 8 {
                [3, 4, 5, 8, 31, 32, 33, 65][case as usize]
            } else {
                rng.gen_range(3..150)
            };
            let (distances, gram, centred) = scoring_case(n, 3, 1000 + case);
            let spacing = median_nearest_distance(&distances);
            let l = LENGTH_SCALES[rng.gen_range(0..LENGTH_SCALES.len())] * spacing;
            let w = MODULATIONS[rng.gen_range(0..MODULATIONS.len())];
            let mut k = covariance(&distances, Some(&gram), l, w);
            if case % 5 == 4 {
                // Block diagonal, with zero rows below some diagonals: τ = 0 there.
                let cut = n / 2;
                for i in 0..n {
                    for j in 0..n {
                        if (i < cut) != (j < cut) || (i != j && (i == 1 || j == 1)) {
                            k[(i, j)] = 0.0;
                        }
                    }
                }
            }
            let blocked = Tridiagonal::new(k.clone(), &centred);
            let reference = Tridiagonal::reduce(k.clone(), &centred);
            // The invariants of an orthogonal similarity: trace and Frobenius norm (the
            // entries themselves are ill-conditioned when K is nearly singular).
            let invariants = |t: &Tridiagonal| {
                let trace: f64 = t.diagonal.iter().sum();
                let squares: f64 = t.diagonal.iter().map(|d| d * d).sum::<f64>()
                    + 2.0 * t.off_diagonal.iter().map(|e| e * e).sum::<f64>();
                [trace, squares]
            };
            let (got, want) = (invariants(&blocked), invariants(&reference));
            let direct = [k.trace(), k.norm_squared()];
            for ((got, want), direct) in got.iter().zip(&want).zip(&direct) {
                assert!(
                    (got - want).abs() <= 1e-12 * direct && (got - direct).abs() <= 1e-12 * direct,
                    "case {case}, n {n}: {got} vs {want} (directly {direct})"
                );
            }
            let (got, want) = (
                blocked.log_likelihoods(&NUGGETS),
                reference.log_likelihoods(&NUGGETS),
            );
            for (lambda, (got, want)) in NUGGETS.iter().zip(got.iter().zip(&want)) {
                assert!(
                    agree(got, want, n),
                    "case {case}, n {n}, λ {lambda}: {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn the_screen_equals_the_cholesky_scores_at_every_grid_point() {
        for seed in 0..6 {
            let n = 20 + 17 * seed as usize;
            let (distances, gram, centred) = scoring_case(n, 2 + seed as usize % 3, 100 + seed);
            let spacing = median_nearest_distance(&distances);
            for &l in &LENGTH_SCALES {
                for &w in &[0.0, 0.3, 10.0] {
                    let k = covariance(&distances, Some(&gram), l * spacing, w);
                    let screened = Tridiagonal::new(k, &centred).log_likelihoods(&NUGGETS);
                    for (&lambda, got) in NUGGETS.iter().zip(&screened) {
                        let a = system(&distances, Some(&gram), l * spacing, lambda, w);
                        let want = log_likelihoods(a, &centred);
                        assert!(want.is_some());
                        assert!(
                            agree(got, &want, n),
                            "seed {seed}, ℓ {l}, w {w}, λ {lambda}: {got:?} vs {want:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_screen_refuses_what_cholesky_refuses() {
        // K shifted so that its least eigenvalue is −0.015: K + λI is not positive
        // definite for the two smallest nuggets and is for the others.
        let (distances, gram, centred) = scoring_case(50, 3, 7);
        let spacing = median_nearest_distance(&distances);
        for w in [0.0, 1.0] {
            let mut k = covariance(&distances, Some(&gram), 2.0 * spacing, w);
            let least = k.clone().symmetric_eigenvalues().min();
            for i in 0..50 {
                k[(i, i)] -= least + 0.015;
            }
            let screened = Tridiagonal::new(k.clone(), &centred).log_likelihoods(&NUGGETS);
            for (&lambda, got) in NUGGETS.iter().zip(&screened) {
                let mut a = k.clone();
                for i in 0..50 {
                    a[(i, i)] += lambda;
                }
                let want = log_likelihoods(a, &centred);
                assert_eq!(want.is_none(), lambda < 0.015, "λ {lambda}");
                assert!(agree(got, &want, 50), "λ {lambda}: {got:?} vs {want:?}");
            }
        }
    }

    /// Inputs, axes and values.
    type Field = (Vec<Vec<f64>>, Vec<[f64; 3]>, Vec<Vec<f64>>);

    /// A random field for the search's property test: `case` picks the cloud, its size
    /// (30 to 110 samples), how rough and how noisy each component is and how much of it
    /// turns with the axes; a third component does not vary and a fourth is rounding only.
    fn random_field(case: u64) -> Field {
        let mut rng = ChaCha8Rng::seed_from_u64(500 + case);
        let n = rng.gen_range(30..110);
        let inputs = cloud(n, 3, 600 + case);
        let axes = unit_axes(n, 700 + case);
        let mut pick = |low: f64, high: f64| rng.gen_range(low.ln()..high.ln()).exp();
        let (f0, f1, fz) = (pick(0.3, 6.0), pick(0.3, 6.0), pick(0.1, 6.0));
        let (noise0, noise1) = (pick(1e-3, 0.5), pick(1e-3, 2.0));
        let turning = pick(1e-3, 1.0);
        let mut noise = ChaCha8Rng::seed_from_u64(800 + case);
        let values = (0..n)
            .map(|i| {
                let x = &inputs[i];
                vec![
                    (f0 * x[0]).sin()
                        + (fz * x[2]).cos()
                        + turning * axes[i][0]
                        + noise0 * noise.gen_range(-1.0..1.0),
                    (f1 * x[1]).sin() * (fz * x[2]).sin()
                        + x[1] * x[2]
                        + noise1 * noise.gen_range(-1.0..1.0),
                    2.5,
                    0.1,
                ]
            })
            .collect();
        (inputs, axes, values)
    }

    /// How far (nats) below the best grid point's log-likelihood the climb's choice may
    /// score: a likelihood ratio of 1.65, which no evidence scale counts as a preference.
    const CLIMB_TOLERANCE: f64 = 0.5;

    #[test]
    fn the_climb_scores_as_the_exhaustive_grid_within_the_tolerance() {
        // Property: on random fields, plain, Cartesian and turning, each component's choice
        // scores at least the best grid point's less CLIMB_TOLERANCE, the obvious search
        // over every grid point (by Cholesky) being the reference; the score it reports is
        // its own point's Cholesky score; at most one in twenty is not the grid's very
        // point; a component that does not vary, or whose centred values are rounding only,
        // gets the reference's choice to the bit.
        let (mut compared, mut misses) = (0, 0);
        for case in 0..60 {
            let (inputs, axes, values) = random_field(case);
            let (_, centred) = centred_values(&values);
            for (axes, vertical_scales) in [
                (None, &[1.0][..]),
                (None, &VERTICAL_SCALES[..]),
                (Some(&axes[..]), &VERTICAL_SCALES[..]),
            ] {
                let got = ResidualGp::fit_with(&inputs, axes, vertical_scales, &values)
                    .unwrap()
                    .choices();
                let want = reference_choices(&inputs, axes, vertical_scales, &values);
                for (c, (got, want)) in got.iter().zip(&want).enumerate() {
                    if c >= 2 {
                        assert_eq!(got, want, "case {case}, component {c}");
                        continue;
                    }
                    let n = inputs.len();
                    let distances = DMatrix::from_fn(n, n, |i, j| {
                        scaled_distance(&inputs[i], &inputs[j], got.vertical_scale)
                    });
                    let a = system(
                        &distances,
                        axes.map(gram_matrix).as_ref(),
                        got.length_scale,
                        got.relative_nugget,
                        got.modulation,
                    );
                    assert_eq!(log_likelihoods(a, &centred).unwrap()[c], got.log_likelihood);
                    assert!(
                        got.log_likelihood >= want.log_likelihood - CLIMB_TOLERANCE,
                        "case {case}, component {c}: {got:?} against the grid's {want:?}"
                    );
                    compared += 1;
                    misses += usize::from(got != want);
                }
            }
        }
        assert!(
            20 * misses <= compared,
            "{misses} of {compared} off the grid's best"
        );
    }

    #[test]
    fn a_field_slower_in_height_gets_a_vertical_scale_and_equals_its_dense_reference() {
        // Varies across x and y three times faster than along z: the likelihood takes a
        // vertical scale below 1, and the prediction is the dense system's with that
        // metric, and closer to the field than the isotropic fit's.
        let inputs = cloud(150, 3, 21);
        let field = |x: &[f64]| (3.0 * x[0]).sin() + (3.0 * x[1]).cos() + (x[2]).sin();
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        let values: Vec<Vec<f64>> = inputs
            .iter()
            .map(|x| vec![field(x) + 0.01 * rng.gen_range(-1.0..1.0)])
            .collect();
        let gp = ResidualGp::fit_cartesian(&inputs, &values).unwrap();
        let choice = gp.choices()[0];
        assert!(choice.vertical_scale < 1.0, "{choice:?}");
        let isotropic = ResidualGp::fit(&inputs, &values).unwrap();
        assert_eq!(isotropic.choices()[0].vertical_scale, 1.0);
        assert!(choice.log_likelihood > isotropic.choices()[0].log_likelihood);
        let column: Vec<f64> = values.iter().map(|v| v[0]).collect();
        let (mut scaled_sq, mut isotropic_sq) = (0.0, 0.0);
        for x in cloud(40, 3, 23) {
            let got = gp.predict(&x).unwrap()[0];
            let want = reference_predict_turning(
                &inputs,
                None,
                &column,
                (
                    choice.length_scale,
                    choice.vertical_scale,
                    choice.relative_nugget,
                    0.0,
                ),
                &x,
                [0.0; 3],
            );
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
            scaled_sq += (got - field(&x)).powi(2);
            isotropic_sq += (isotropic.predict(&x).unwrap()[0] - field(&x)).powi(2);
        }
        assert!(scaled_sq < isotropic_sq, "{scaled_sq} vs {isotropic_sq}");
        assert!(matches!(
            ResidualGp::fit_cartesian(&cloud(10, 2, 24), &vec![vec![1.0]; 10]),
            Err(GpError::Malformed(_))
        ));
    }

    #[test]
    fn refuses_what_it_cannot_fit() {
        let one = vec![vec![0.0, 0.0]; 2];
        assert_eq!(
            ResidualGp::fit(&one, &[vec![1.0], vec![2.0]]).unwrap_err(),
            GpError::TooFewSamples(2)
        );
        let same = vec![vec![1.0, 1.0]; 5];
        let v = vec![vec![1.0]; 5];
        assert_eq!(ResidualGp::fit(&same, &v).unwrap_err(), GpError::Singular);
        let inputs = cloud(5, 2, 7);
        let mut bad = vec![vec![1.0]; 5];
        bad[2][0] = f64::NAN;
        assert!(matches!(
            ResidualGp::fit(&inputs, &bad),
            Err(GpError::Malformed(_))
        ));
        let gp = ResidualGp::fit(&inputs, &vec![vec![1.0]; 5]).unwrap();
        assert!(gp.predict(&[0.0]).is_none());
        assert!(gp.predict(&[0.0, f64::NAN]).is_none());
    }
}
