//! Kriging with a nugget ([`crate::nugget_kriging`]) at any number of samples: the
//! hyperparameters chosen on a subsample, each node predicted from the samples near it.
//!
//! The dense fit solves one system over all `n` samples: O(n³) time and O(n²) memory per
//! grid point of its likelihood search, a minute at 2,000 samples and out of memory at
//! 30,000. Neither the choice of the hyperparameters nor a prediction needs all of them:
//!
//! - **Hyperparameters from a subsample.** The length scale (mm), the vertical scale, the
//!   nugget relative to the sill and the turning weight are properties of the field and of
//!   the noise, not of the sample count: the likelihood of [`SUBSAMPLE`] samples, evenly
//!   strided through the file's order, chooses them as well as that of all (a stride of a
//!   tracker's path is a sparser path over the same volume). The subsample depends on the
//!   data alone, so the build stays byte-identical.
//! - **Predictions from neighbours.** With the Matérn 5/2 correlation and a nugget, the
//!   weight of a sample decays with its distance and is screened by nearer ones: the
//!   kriging of a point from its [`NEIGHBOURS`] nearest samples differs from the dense one
//!   by about the noise it removes (`tests`: 1,200 noisy samples of a smooth field in a
//!   1 m cube, hyperparameters from 300, nodes 50 mm apart: at most 1.8 standard
//!   deviations of the noise, 0.1 on average, and as close to the noise-free field to
//!   0.04 of one). The constant mean is the mean over all samples, as in the dense fit.
//! - **One system per block of nodes.** Nodes are taken in blocks of up to
//!   [`MAX_BLOCK_NODES`]³, small enough that the block's half-diagonal is at most half the
//!   typical distance to the `NEIGHBOURS`-th nearest sample; the samples nearest the
//!   block's centre are then around each of its nodes, and one factorisation serves them
//!   all. Neighbouring nodes of two blocks are predicted from two sample sets, so their
//!   values can differ by more than the dense field's: in the same test by at most 1.6
//!   standard deviations of the noise beyond the dense field's own difference (the noise
//!   spans ±1.7 of them). The table blends the nodes trilinearly, so the served field is
//!   continuous whatever the node values are.
//!
//! Time is O(n log n) for the k-d tree, plus O(nodes · NEIGHBOURS) and O(blocks ·
//! NEIGHBOURS³) for the predictions, plus the subsample's dense search (fixed); memory is
//! O(n), never an `n × n` matrix. Blocks are computed in parallel and assembled in order:
//! nothing depends on the thread count.
//!
//! Up to [`SUBSAMPLE`] samples the dense fit is used as it is ([`KrigingField::Dense`]).

use std::num::NonZero;
use std::sync::Mutex;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::nugget_kriging::{
    cartesian_system, check_cartesian, check_choices, check_rows, kernel_terms, scaled_distance,
    GpChoice, GpError, ResidualGp,
};

/// Samples whose likelihood chooses the hyperparameters; up to this many samples the fit
/// is the dense one, its hyperparameters chosen on the very samples it fits. The search
/// costs a reduction, cubic in its samples, per setting its climb visits (of 13 length
/// scales × 4 vertical scales, × 5 weights of the turning part; [`crate::nugget_kriging`]):
/// on the UR5's thousand, 64 of the 260 with the turning part, and the shipped UR5 (1,000)
/// and KR150-2 (729) sample sets are fitted densely. A search on 500 strided samples costs an eighth, but on the UR5 its choice
/// cross-validates worse on the training samples (5-fold 0.0738 against 0.0732 mm, 10-fold
/// 0.0736 against 0.0733; docs/evaluation.md, "At any size").
pub const SUBSAMPLE: usize = 1000;

/// Samples in each local system: enough that what the samples beyond them would add stays
/// within the noise for the length scales the likelihood chooses (64 left half as much
/// again, tests), few enough that a factorisation costs well under a millisecond.
pub const NEIGHBOURS: usize = 128;

/// The most nodes along each axis of a block sharing one local system.
pub const MAX_BLOCK_NODES: usize = 4;

/// How a field is fitted beyond [`SUBSAMPLE`] samples (the defaults are the constants;
/// tests use smaller ones).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LocalSettings {
    /// The largest sample count fitted densely, and the size of the evenly strided
    /// subsample a local fit's hyperparameters are searched on.
    pub subsample: usize,
    /// Samples per local system.
    pub neighbours: usize,
}

impl Default for LocalSettings {
    fn default() -> Self {
        LocalSettings {
            subsample: SUBSAMPLE,
            neighbours: NEIGHBOURS,
        }
    }
}

/// The hyperparameters a fit chooses by likelihood ([`KrigingField::fit`]): on all
/// samples up to `settings.subsample`, else on an evenly strided subsample of that many,
/// without predicting anything.
///
/// The process remembers its last [`REMEMBERED_SEARCHES`] searches by the samples searched,
/// to the bit: an evaluation builds two tables on each fold's samples (`paper` and
/// `paper-trilinear`, `hybrid` and `hybrid-trilinear`), and the second is given the first's
/// choice, which is what its own search would find.
///
/// # Errors
///
/// As [`ResidualGp::fit_turning`].
pub fn search_choices(
    inputs: &[Vec<f64>],
    axes: Option<&[[f64; 3]]>,
    values: &[Vec<f64>],
    settings: LocalSettings,
) -> Result<Vec<GpChoice>, GpError> {
    check_rows(inputs, values)?;
    check_cartesian(inputs, axes)?;
    let n = inputs.len();
    let m = settings.subsample.max(3);
    if n <= m {
        return remembered_search(&SEARCHES, inputs, axes, values);
    }
    // Evenly strided: sample ⌊i n / m⌋ for i < m (n > m, so all distinct).
    let picked: Vec<usize> = (0..m)
        .map(|i| (i as u128 * n as u128 / m as u128) as usize)
        .collect();
    let pick =
        |rows: &[Vec<f64>]| -> Vec<Vec<f64>> { picked.iter().map(|&i| rows[i].clone()).collect() };
    let picked_axes: Option<Vec<[f64; 3]>> = axes.map(|a| picked.iter().map(|&i| a[i]).collect());
    remembered_search(
        &SEARCHES,
        &pick(inputs),
        picked_axes.as_deref(),
        &pick(values),
    )
}

/// How many searches [`search_choices`] remembers: an evaluation's folds run side by side,
/// each building its tables one after the other.
pub const REMEMBERED_SEARCHES: usize = 8;

/// A search remembered: everything it depended on, to the bit ([`search_key`]), and its
/// choices.
type Remembered = (Vec<u64>, Vec<GpChoice>);

/// The searches remembered, the least recently used first.
static SEARCHES: Mutex<Vec<Remembered>> = Mutex::new(Vec::new());

/// The dense search's choices on these very samples, remembered in `store` (at most
/// [`REMEMBERED_SEARCHES`]) or searched and then remembered.
fn remembered_search(
    store: &Mutex<Vec<Remembered>>,
    inputs: &[Vec<f64>],
    axes: Option<&[[f64; 3]]>,
    values: &[Vec<f64>],
) -> Result<Vec<GpChoice>, GpError> {
    let key = search_key(inputs, axes, values);
    let recall = |searches: &mut Vec<Remembered>| {
        let found = searches.iter().position(|(k, _)| *k == key)?;
        let entry = searches.remove(found);
        let choices = entry.1.clone();
        searches.push(entry);
        Some(choices)
    };
    // Entries are pushed whole, so a thread that panicked holding the lock left none
    // half-written.
    let lock = || {
        store
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    };
    if let Some(choices) = recall(&mut lock()) {
        return Ok(choices);
    }
    let choices = fit_dense(inputs, axes, values)?.choices();
    let mut searches = lock();
    // Another thread may have searched the same samples meanwhile: remembered once.
    if recall(&mut searches).is_none() {
        if searches.len() >= REMEMBERED_SEARCHES {
            searches.remove(0);
        }
        searches.push((key, choices.clone()));
    }
    Ok(choices)
}

/// Everything a dense search depends on, to the bit: the samples' inputs, axes (when
/// given) and values.
fn search_key(inputs: &[Vec<f64>], axes: Option<&[[f64; 3]]>, values: &[Vec<f64>]) -> Vec<u64> {
    let mut key = vec![
        inputs.len() as u64,
        inputs[0].len() as u64,
        values[0].len() as u64,
        u64::from(axes.is_some()),
    ];
    key.extend(
        (inputs.iter().flatten())
            .chain(axes.into_iter().flatten().flatten())
            .chain(values.iter().flatten())
            .map(|v| v.to_bits()),
    );
    key
}

/// The dense fit with its likelihood search: turning with `axes` when given.
fn fit_dense(
    inputs: &[Vec<f64>],
    axes: Option<&[[f64; 3]]>,
    values: &[Vec<f64>],
) -> Result<ResidualGp, GpError> {
    match axes {
        Some(axes) => ResidualGp::fit_turning(inputs, axes, values),
        None => ResidualGp::fit_cartesian(inputs, values),
    }
}

/// A kriging field over Cartesian positions (mm, z vertical), dense or local (module docs).
#[derive(Debug)]
pub enum KrigingField {
    /// All samples in one system (at most [`LocalSettings::subsample`] of them).
    Dense(ResidualGp),
    /// Hyperparameters from a subsample, predictions from neighbours.
    Local(Box<LocalGp>),
}

impl KrigingField {
    /// Fits the field to `values` (one row of components per sample) at three-dimensional
    /// `inputs`, turning with `axes` (one unit vector per sample) when given: densely up to
    /// `settings.subsample` samples ([`ResidualGp::fit_turning`],
    /// [`ResidualGp::fit_cartesian`]), else locally.
    ///
    /// # Errors
    ///
    /// As [`ResidualGp::fit_turning`].
    pub fn fit(
        inputs: &[Vec<f64>],
        axes: Option<&[[f64; 3]]>,
        values: &[Vec<f64>],
        settings: LocalSettings,
    ) -> Result<KrigingField, GpError> {
        check_rows(inputs, values)?;
        check_cartesian(inputs, axes)?;
        if inputs.len() <= settings.subsample.max(3) {
            return fit_dense(inputs, axes, values).map(KrigingField::Dense);
        }
        let choices = search_choices(inputs, axes, values, settings)?;
        LocalGp::with_choices(inputs, axes, values, &choices, settings.neighbours)
            .map(|fit| KrigingField::Local(Box::new(fit)))
    }

    /// The field at given hyperparameters (no search): dense up to `settings.subsample`
    /// samples ([`ResidualGp::with_choices`]), else local ([`LocalGp::with_choices`]).
    ///
    /// # Errors
    ///
    /// As [`ResidualGp::with_choices`].
    pub fn with_choices(
        inputs: &[Vec<f64>],
        axes: Option<&[[f64; 3]]>,
        values: &[Vec<f64>],
        choices: &[GpChoice],
        settings: LocalSettings,
    ) -> Result<KrigingField, GpError> {
        if inputs.len() <= settings.subsample.max(3) {
            return ResidualGp::with_choices(inputs, axes, values, choices)
                .map(KrigingField::Dense);
        }
        LocalGp::with_choices(inputs, axes, values, choices, settings.neighbours)
            .map(|fit| KrigingField::Local(Box::new(fit)))
    }

    /// Each component's hyperparameters.
    pub fn choices(&self) -> Vec<GpChoice> {
        match self {
            KrigingField::Dense(fit) => fit.choices(),
            KrigingField::Local(fit) => fit.choices.clone(),
        }
    }

    /// Whether some component has a part that turns with the axes (a chosen modulation
    /// above 0): without one, every `h` term is 0 and a node needs `f` alone.
    pub fn turns(&self) -> bool {
        self.choices().iter().any(|c| c.modulation != 0.0)
    }

    /// The terms `[f, h_x, h_y, h_z]` per component ([`ResidualGp::predict_terms`]) at the
    /// nodes of a lattice `dims` nodes wide (x fastest, node `i + dims[0] (j + dims[1] k)`
    /// at `position([i, j, k])`, `cell_mm` apart), for every node `wanted` and `computed`,
    /// passed through `map`; `None` for the others. Dense: each node on its own; local: by
    /// blocks (module docs) of the nodes `wanted`, so that a node's terms do not depend on
    /// which others are `computed`.
    ///
    /// # Errors
    ///
    /// [`GpError::Malformed`] for a position not finite, [`GpError::Singular`] for a local
    /// system not positive definite.
    pub fn lattice_terms<T: Send>(
        &self,
        dims: [usize; 3],
        cell_mm: f64,
        position: &(dyn Fn([usize; 3]) -> [f64; 3] + Sync),
        wanted: &(dyn Fn(usize) -> bool + Sync),
        computed: &(dyn Fn(usize) -> bool + Sync),
        map: &(dyn Fn(&[[f64; 4]]) -> T + Sync),
    ) -> Result<Vec<Option<T>>, GpError> {
        let [nx, ny, nz] = dims;
        let coords = |node: usize| [node % nx, node / nx % ny, node / (nx * ny)];
        let nodes = nx * ny * nz;
        let fit = match self {
            KrigingField::Dense(fit) => {
                return (0..nodes)
                    .into_par_iter()
                    .map(|node| {
                        if !(wanted(node) && computed(node)) {
                            return Ok(None);
                        }
                        let terms = fit
                            .predict_terms(&position(coords(node)))
                            .ok_or(GpError::Malformed("a node position is not finite"))?;
                        Ok(Some(map(&terms)))
                    })
                    .collect();
            }
            KrigingField::Local(fit) => fit,
        };
        let b = fit.block_nodes(cell_mm);
        let blocks = [nx, ny, nz].map(|d| d.div_ceil(b));
        let per_block: Vec<Vec<(usize, T)>> = (0..blocks[0] * blocks[1] * blocks[2])
            .into_par_iter()
            .map(|block| {
                let corner = [
                    block % blocks[0] * b,
                    block / blocks[0] % blocks[1] * b,
                    block / (blocks[0] * blocks[1]) * b,
                ];
                let mut members = Vec::new();
                for k in corner[2]..(corner[2] + b).min(nz) {
                    for j in corner[1]..(corner[1] + b).min(ny) {
                        for i in corner[0]..(corner[0] + b).min(nx) {
                            let node = i + nx * (j + ny * k);
                            if wanted(node) {
                                members.push((node, position([i, j, k])));
                            }
                        }
                    }
                }
                if !members.iter().any(|m| computed(m.0)) {
                    return Ok(Vec::new());
                }
                let points: Vec<[f64; 3]> = members.iter().map(|m| m.1).collect();
                let centre = bounding_centre(&points)?;
                members.retain(|m| computed(m.0));
                let points: Vec<[f64; 3]> = members.iter().map(|m| m.1).collect();
                let terms = fit.block_terms(centre, &points)?;
                let width = fit.choices.len();
                Ok(members
                    .iter()
                    .zip(terms.chunks_exact(width))
                    .map(|(m, t)| (m.0, map(t)))
                    .collect())
            })
            .collect::<Result<_, GpError>>()?;
        let mut out: Vec<Option<T>> = (0..nodes).map(|_| None).collect();
        for (node, value) in per_block.into_iter().flatten() {
            out[node] = Some(value);
        }
        Ok(out)
    }
}

/// Kriging from neighbours at given hyperparameters (module docs).
pub struct LocalGp {
    inputs: Vec<[f64; 3]>,
    axes: Option<Vec<[f64; 3]>>,
    /// Sample after sample, each component less its mean.
    centred: Vec<f64>,
    means: Vec<f64>,
    choices: Vec<GpChoice>,
    tree: ImmutableKdTree<f64, 3>,
    neighbours: usize,
    /// The median over a strided subset of the samples of the distance to their
    /// `neighbours`-th nearest sample, mm: how far a local system reaches.
    reach_mm: f64,
}

impl std::fmt::Debug for LocalGp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LocalGp")
            .field("samples", &self.inputs.len())
            .field("choices", &self.choices)
            .field("neighbours", &self.neighbours)
            .field("reach_mm", &self.reach_mm)
            .finish_non_exhaustive()
    }
}

impl LocalGp {
    /// The local field of `values` at `inputs` (turning with `axes` when given) with each
    /// component's hyperparameters given, `neighbours` samples per system.
    ///
    /// # Errors
    ///
    /// As [`ResidualGp::with_choices`].
    pub fn with_choices(
        inputs: &[Vec<f64>],
        axes: Option<&[[f64; 3]]>,
        values: &[Vec<f64>],
        choices: &[GpChoice],
        neighbours: usize,
    ) -> Result<LocalGp, GpError> {
        let width = check_rows(inputs, values)?;
        check_cartesian(inputs, axes)?;
        check_choices(choices, width, axes.is_some())?;
        let n = inputs.len();
        let means: Vec<f64> = (0..width)
            .map(|c| values.iter().map(|v| v[c]).sum::<f64>() / n as f64)
            .collect();
        let centred = values
            .iter()
            .flat_map(|v| v.iter().zip(&means).map(|(v, m)| v - m))
            .collect();
        let inputs: Vec<[f64; 3]> = inputs.iter().map(|x| [x[0], x[1], x[2]]).collect();
        let tree = ImmutableKdTree::new_from_slice(&inputs);
        let mut fit = LocalGp {
            inputs,
            axes: axes.map(<[_]>::to_vec),
            centred,
            means,
            choices: choices.to_vec(),
            tree,
            neighbours: neighbours.clamp(1, n),
            reach_mm: 0.0,
        };
        let stride = n.div_ceil(SUBSAMPLE);
        let mut reach: Vec<f64> = (0..n)
            .step_by(stride)
            .map(|i| {
                let near = fit.nearest(fit.inputs[i]);
                let last = near[near.len() - 1];
                scaled_distance(&fit.inputs[i], &fit.inputs[last], 1.0)
            })
            .collect();
        reach.sort_by(f64::total_cmp);
        fit.reach_mm = reach[reach.len() / 2];
        Ok(fit)
    }

    /// Nodes along each axis of a block, for nodes `cell_mm` apart: the most (up to
    /// [`MAX_BLOCK_NODES`]) whose block's half-diagonal, `(b − 1) √3 cell / 2`, is at most
    /// half the reach of a local system.
    fn block_nodes(&self, cell_mm: f64) -> usize {
        let spans = self.reach_mm / (3f64.sqrt() * cell_mm);
        if spans.is_finite() {
            (1 + spans.max(0.0) as usize).min(MAX_BLOCK_NODES)
        } else {
            1
        }
    }

    /// The `neighbours` samples nearest `at`, by distance then index.
    fn nearest(&self, at: [f64; 3]) -> Vec<usize> {
        let k = NonZero::new(self.neighbours).unwrap_or(NonZero::<usize>::MIN);
        let mut near = self.tree.nearest_n::<SquaredEuclidean>(&at, k);
        near.sort_by(|a, b| a.distance.total_cmp(&b.distance).then(a.item.cmp(&b.item)));
        near.into_iter().map(|n| n.item as usize).collect()
    }

    /// The terms of every component at each of `points` (point after point, component
    /// after component), from one local system per distinct choice on the samples nearest
    /// `centre` (the centre of the block's bounding box, [`bounding_centre`]).
    fn block_terms(&self, centre: [f64; 3], points: &[[f64; 3]]) -> Result<Vec<[f64; 4]>, GpError> {
        let width = self.choices.len();
        let near = self.nearest(centre);
        let k = near.len();
        let local: Vec<&[f64]> = near.iter().map(|&i| &self.inputs[i][..]).collect();
        let local_axes: Option<Vec<[f64; 3]>> = self
            .axes
            .as_ref()
            .map(|a| near.iter().map(|&i| a[i]).collect());
        let mut out = vec![[0.0; 4]; points.len() * width];
        let mut done = vec![false; width];
        for c in 0..width {
            if done[c] {
                continue;
            }
            let choice = self.choices[c];
            // The components sharing this choice share the factorisation.
            let same = |d: &GpChoice| {
                (
                    d.length_scale,
                    d.vertical_scale,
                    d.relative_nugget,
                    d.modulation,
                ) == (
                    choice.length_scale,
                    choice.vertical_scale,
                    choice.relative_nugget,
                    choice.modulation,
                )
            };
            let group: Vec<usize> = (c..width).filter(|&d| same(&self.choices[d])).collect();
            let (l, vertical, lambda, w) = (
                choice.length_scale,
                choice.vertical_scale,
                choice.relative_nugget,
                choice.modulation,
            );
            let system = cartesian_system(&local, local_axes.as_deref(), (l, vertical, lambda, w));
            let factor = crate::cholesky::cholesky(system).ok_or(GpError::Singular)?;
            let rhs = DMatrix::from_fn(k, group.len(), |i, g| {
                self.centred[near[i] * width + group[g]]
            });
            let weights = factor.solve(&rhs);
            for (g, &d) in group.iter().enumerate() {
                let column: Vec<f64> = weights.column(g).iter().copied().collect();
                for (p, point) in points.iter().enumerate() {
                    out[p * width + d] = kernel_terms(
                        &self.choices[d],
                        self.means[d],
                        local.iter().copied(),
                        local_axes.as_deref(),
                        &column,
                        point,
                    );
                }
                done[d] = true;
            }
        }
        Ok(out)
    }
}

/// The centre of `points`' bounding box; [`GpError::Malformed`] for a point not finite.
fn bounding_centre(points: &[[f64; 3]]) -> Result<[f64; 3], GpError> {
    if points.iter().flatten().any(|v| !v.is_finite()) {
        return Err(GpError::Malformed("a node position is not finite"));
    }
    let (lo, hi) = points.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                [0, 1, 2].map(|a| lo[a].min(p[a])),
                [0, 1, 2].map(|a| hi[a].max(p[a])),
            )
        },
    );
    Ok([0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a])))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The noise of [`case`]: uniform in ±`NOISE`, standard deviation `NOISE / √3`.
    const NOISE: f64 = 0.02;

    /// Inputs, axes and values.
    type Case = (Vec<Vec<f64>>, Vec<[f64; 3]>, Vec<Vec<f64>>);

    #[test]
    fn a_search_on_the_same_samples_is_recalled_and_another_searched() {
        let store = Mutex::new(Vec::new());
        let (inputs, axes, values) = case(60, 31);
        let searched = fit_dense(&inputs, Some(&axes), &values).unwrap().choices();
        let first = remembered_search(&store, &inputs, Some(&axes), &values).unwrap();
        assert_eq!(first, searched);
        // What is remembered is what the samples get back, without a search: a marked
        // entry under their key comes back as it is.
        let mut marked = searched.clone();
        marked[0].log_likelihood = 1234.5;
        store.lock().unwrap()[0].1 = marked.clone();
        let again = remembered_search(&store, &inputs, Some(&axes), &values).unwrap();
        assert_eq!(again, marked);
        // One value one unit in the last place off, or the same samples without axes, are
        // other samples: searched, and remembered beside.
        let mut nudged = values.clone();
        nudged[17][1] = f64::from_bits(nudged[17][1].to_bits() + 1);
        let other = remembered_search(&store, &inputs, Some(&axes), &nudged).unwrap();
        assert_eq!(
            other,
            fit_dense(&inputs, Some(&axes), &nudged).unwrap().choices()
        );
        let plain = remembered_search(&store, &inputs, None, &values).unwrap();
        assert_eq!(plain, fit_dense(&inputs, None, &values).unwrap().choices());
        assert_eq!(store.lock().unwrap().len(), 3);
        // The least recently used is forgotten first.
        for seed in 0..REMEMBERED_SEARCHES as u64 {
            let (inputs, _, values) = case(12, 40 + seed);
            remembered_search(&store, &inputs, None, &values).unwrap();
        }
        let kept = store.lock().unwrap();
        assert_eq!(kept.len(), REMEMBERED_SEARCHES);
        assert!(kept
            .iter()
            .all(|(k, _)| *k != search_key(&inputs, Some(&axes), &values)));
    }

    /// `n` samples in a 1 m cube (mm) with a smooth field plus noise, two components, and
    /// each sample's unit axis; the field's first component turns with the axis.
    fn case(n: usize, seed: u64) -> Case {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut inputs = Vec::new();
        let mut axes = Vec::new();
        let mut values = Vec::new();
        for _ in 0..n {
            let x: Vec<f64> = (0..3).map(|_| rng.gen_range(0.0..1000.0)).collect();
            let v: [f64; 3] = [0, 1, 2].map(|_| rng.gen_range(-1.0..1.0));
            let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
            let a = v.map(|c| c / norm);
            let smooth = 0.3 * (x[0] / 300.0).sin() + 0.2 * (x[1] / 200.0).cos() * (x[2] / 400.0);
            let noise = |rng: &mut ChaCha8Rng| NOISE * rng.gen_range(-1.0..1.0);
            values.push(vec![
                smooth + 0.05 * a[2] + noise(&mut rng),
                0.1 * (x[2] / 250.0).sin() + noise(&mut rng),
            ]);
            inputs.push(x);
            axes.push(a);
        }
        (inputs, axes, values)
    }

    /// Every node of a lattice of 50 mm over the cube, terms per component, flattened.
    fn lattice(field: &KrigingField, width: usize) -> Vec<[f64; 4]> {
        let position = |[i, j, k]: [usize; 3]| [i, j, k].map(|v| 50.0 * v as f64);
        field
            .lattice_terms([21; 3], 50.0, &position, &|_| true, &|_| true, &|t| {
                t.to_vec()
            })
            .unwrap()
            .into_iter()
            .flat_map(|t| {
                let t = t.unwrap();
                assert_eq!(t.len(), width);
                t
            })
            .collect()
    }

    /// Over the lattice of [`lattice`]: the largest difference between the terms of two
    /// neighbouring nodes (along any axis) of `a` beyond that of `b`, and the largest and
    /// mean difference between `a` and `b`.
    fn jumps_and_gaps(a: &[[f64; 4]], b: &[[f64; 4]], width: usize) -> (f64, f64, f64) {
        let at = |i: usize, j: usize, k: usize, c: usize| (i + 21 * (j + 21 * k)) * width + c;
        let (mut jump, mut gap, mut sum) = (0.0f64, 0.0f64, 0.0);
        for (x, y) in a.iter().zip(b) {
            for t in 0..4 {
                gap = gap.max((x[t] - y[t]).abs());
                sum += (x[t] - y[t]).abs();
            }
        }
        for k in 0..21 {
            for j in 0..21 {
                for i in 0..21 {
                    for c in 0..width {
                        let here = at(i, j, k, c);
                        for [di, dj, dk] in [[1, 0, 0], [0, 1, 0], [0, 0, 1]] {
                            if i + di > 20 || j + dj > 20 || k + dk > 20 {
                                continue;
                            }
                            let next = at(i + di, j + dj, k + dk, c);
                            for t in 0..4 {
                                let excess =
                                    ((a[next][t] - a[here][t]) - (b[next][t] - b[here][t])).abs();
                                jump = jump.max(excess);
                            }
                        }
                    }
                }
            }
        }
        (jump, gap, sum / (4 * a.len()) as f64)
    }

    /// The RMS over the lattice's inner nodes of the second component's `f` against the
    /// noise-free field.
    fn truth_rms(t: &[[f64; 4]]) -> f64 {
        let mut sum = 0.0;
        let mut count = 0;
        for node in 0..21 * 21 * 21 {
            let ijk = [node % 21, node / 21 % 21, node / 441];
            if ijk.iter().all(|&v| v > 0 && v < 20) {
                let z = 50.0 * ijk[2] as f64;
                sum += (t[2 * node + 1][0] - 0.1 * (z / 250.0).sin()).powi(2);
                count += 1;
            }
        }
        (sum / count as f64).sqrt()
    }

    #[test]
    fn local_kriging_is_the_dense_fit_within_a_fraction_of_the_noise() {
        let (inputs, axes, values) = case(1200, 1);
        let sd = NOISE / 3f64.sqrt();
        for axes in [None, Some(axes.as_slice())] {
            let settings = LocalSettings {
                subsample: 300,
                neighbours: NEIGHBOURS,
            };
            let local = KrigingField::fit(&inputs, axes, &values, settings).unwrap();
            let KrigingField::Local(fit) = &local else {
                panic!("1200 samples above a subsample of 300 are fitted locally");
            };
            // Blocks of several nodes: the test covers the seams between them.
            assert!(fit.block_nodes(50.0) > 1, "{fit:?}");
            let choices = local.choices();
            assert_eq!(choices[0].modulation != 0.0, axes.is_some(), "{choices:?}");
            let dense = KrigingField::Dense(
                ResidualGp::with_choices(&inputs, axes, &values, &choices).unwrap(),
            );
            let (local, dense) = (lattice(&local, 2), lattice(&dense, 2));
            let (jump, gap, mean_gap) = jumps_and_gaps(&local, &dense, 2);
            assert!(gap < 2.0 * sd, "local − dense up to {gap} (noise sd {sd})");
            assert!(mean_gap < 0.2 * sd, "local − dense {mean_gap} on average");
            assert!(
                jump < 2.0 * sd,
                "node-to-node jumps beyond the dense fit's up to {jump}"
            );
            // Against the noise-free field, away from the cube's faces: both well below the
            // noise, the local fit within a tenth of the noise of the dense one.
            let (local_rms, dense_rms) = (truth_rms(&local), truth_rms(&dense));
            assert!(
                local_rms < dense_rms + 0.1 * sd && local_rms < 0.5 * sd,
                "{local_rms} vs {dense_rms}"
            );
        }
    }

    #[test]
    fn the_local_fit_is_the_same_at_any_thread_count() {
        let (inputs, axes, values) = case(1500, 2);
        let settings = LocalSettings {
            subsample: 200,
            neighbours: NEIGHBOURS,
        };
        let fit = KrigingField::fit(&inputs, Some(&axes), &values, settings).unwrap();
        let bits = |threads: usize| -> Vec<u64> {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| lattice(&fit, 2))
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect()
        };
        assert_eq!(bits(1), bits(4));
        let again = KrigingField::fit(&inputs, Some(&axes), &values, settings).unwrap();
        assert_eq!(again.choices(), fit.choices());
    }

    #[test]
    fn nodes_computed_alone_hold_what_they_hold_among_all() {
        // A block's system does not depend on which of its nodes are computed.
        let (inputs, axes, values) = case(1500, 4);
        let settings = LocalSettings {
            subsample: 200,
            neighbours: NEIGHBOURS,
        };
        let fit = KrigingField::fit(&inputs, Some(&axes), &values, settings).unwrap();
        let position = |[i, j, k]: [usize; 3]| [i, j, k].map(|v| 50.0 * v as f64);
        let wanted = |n: usize| !n.is_multiple_of(5);
        let terms = |computed: &(dyn Fn(usize) -> bool + Sync)| {
            fit.lattice_terms([21; 3], 50.0, &position, &wanted, computed, &|t| {
                t.iter()
                    .flatten()
                    .map(|v| v.to_bits())
                    .collect::<Vec<u64>>()
            })
            .unwrap()
        };
        let (all, some) = (terms(&|_| true), terms(&|n| n % 7 == 3));
        for (n, (a, s)) in all.iter().zip(&some).enumerate() {
            assert_eq!(a.is_some(), wanted(n));
            if n % 7 == 3 {
                assert_eq!(a, s, "node {n}");
            } else {
                assert!(s.is_none());
            }
        }
    }

    #[test]
    fn up_to_the_subsample_the_fit_is_the_dense_one() {
        let (inputs, axes, values) = case(150, 3);
        let settings = LocalSettings {
            subsample: 150,
            neighbours: 16,
        };
        let fit = KrigingField::fit(&inputs, Some(&axes), &values, settings).unwrap();
        let KrigingField::Dense(dense) = &fit else {
            panic!("150 samples are fitted densely");
        };
        let reference = ResidualGp::fit_turning(&inputs, &axes, &values).unwrap();
        assert_eq!(dense.choices(), reference.choices());
        let x = [500.0, 400.0, 300.0];
        assert_eq!(dense.predict_terms(&x), reference.predict_terms(&x));
    }

    #[test]
    fn degenerate_clouds_are_fitted_or_refused_without_panicking() {
        // Samples on a plane, many of them coincident, as a tracker's passes give.
        let mut inputs = Vec::new();
        let mut values = Vec::new();
        for i in 0..600 {
            let x = f64::from(i % 20) * 5.0;
            inputs.push(vec![x, f64::from(i / 60) * 5.0, 0.0]);
            values.push(vec![(x / 30.0).sin() + 0.01 * f64::from(i % 7)]);
        }
        let settings = LocalSettings {
            subsample: 100,
            neighbours: 64,
        };
        let fit = KrigingField::fit(&inputs, None, &values, settings).unwrap();
        let position = |[i, j, k]: [usize; 3]| [5.0 * i as f64, 5.0 * j as f64, k as f64];
        let terms = fit
            .lattice_terms(
                [21, 10, 2],
                5.0,
                &position,
                &|n| n % 3 != 0,
                &|_| true,
                &|t| t[0][0],
            )
            .unwrap();
        assert!(terms
            .iter()
            .enumerate()
            .all(|(n, t)| t.is_some_and(f64::is_finite) == (n % 3 != 0)));
        // All at one point: no length scale applies.
        let same = vec![vec![1.0, 2.0, 3.0]; 400];
        assert_eq!(
            KrigingField::fit(&same, None, &values[..400], settings).unwrap_err(),
            GpError::Singular
        );
        let mut bad = values.clone();
        bad[450][0] = f64::NAN;
        assert!(matches!(
            KrigingField::fit(&inputs, None, &bad, settings),
            Err(GpError::Malformed(_))
        ));
        let position = |_: [usize; 3]| [f64::NAN; 3];
        assert!(matches!(
            fit.lattice_terms([2, 2, 2], 5.0, &position, &|_| true, &|_| true, &|t| t[0]
                [0]),
            Err(GpError::Malformed(_))
        ));
    }
}
