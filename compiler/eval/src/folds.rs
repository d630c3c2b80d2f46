//! Folds that hold out what use holds out: a region of the workspace, or a whole series.
//!
//! Random folds ([`crate::baselines::k_fold_splits`]) leave every held-out sample among
//! training samples a few millimetres away, so a field that interpolates its neighbours'
//! noise looks better on them than on poses measured elsewhere or on another day. Folds by
//! region ([`block_splits`]) hold out a compact block of nominal positions at a time, and
//! leave-one-series-out folds ([`group_splits`]) a whole measurement series: the figure
//! they give is the one new poses and a new series see.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::baselines::stats::StatsError;
use crate::baselines::Fold;

/// Lloyd iterations of the blocks' k-means: enough for the blocks to settle on any sample
/// cloud, bounded so that the split costs microseconds.
pub const BLOCK_ITERATIONS: usize = 25;

/// Splits samples at `nominal_mm` into `folds` spatial blocks, each one fold: k-means of
/// the positions (k-means++ seeding by ChaCha8 with `seed`, [`BLOCK_ITERATIONS`] Lloyd
/// steps, ties to the lower block), so that a fold is a compact region and its samples are
/// predicted from the other regions alone. Deterministic for a given `seed`.
///
/// # Errors
///
/// [`StatsError::InvalidFolds`] unless `2 <= folds <= samples`, or when the positions do
/// not make `folds` non-empty blocks (fewer distinct positions than folds).
pub fn block_splits(
    nominal_mm: &[[f64; 3]],
    folds: usize,
    seed: u64,
) -> Result<Vec<Fold>, StatsError> {
    let n = nominal_mm.len();
    crate::baselines::stats::check_folds(n, folds)?;
    // Positions too few to make `folds` non-empty blocks.
    let invalid = StatsError::InvalidFolds {
        sample_count: n,
        folds,
    };
    let distance2 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // k-means++: each next centre drawn with probability ∝ the squared distance to the
    // nearest centre so far.
    let mut centres = vec![nominal_mm[(rng.next_u64() % n as u64) as usize]];
    let mut nearest: Vec<f64> = nominal_mm
        .iter()
        .map(|p| distance2(p, &centres[0]))
        .collect();
    while centres.len() < folds {
        let total: f64 = nearest.iter().sum();
        if total <= 0.0 {
            return Err(invalid);
        }
        let draw = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * total;
        let mut acc = 0.0;
        let mut pick = n - 1;
        for (i, d) in nearest.iter().enumerate() {
            acc += d;
            if acc > draw && *d > 0.0 {
                pick = i;
                break;
            }
        }
        let centre = nominal_mm[pick];
        for (d, p) in nearest.iter_mut().zip(nominal_mm) {
            *d = d.min(distance2(p, &centre));
        }
        centres.push(centre);
    }
    let mut block = vec![0usize; n];
    for _ in 0..BLOCK_ITERATIONS {
        for (b, p) in block.iter_mut().zip(nominal_mm) {
            *b = (0..folds)
                .min_by(|&i, &j| distance2(p, &centres[i]).total_cmp(&distance2(p, &centres[j])))
                .expect("at least two blocks");
        }
        let mut sums = vec![[0.0; 3]; folds];
        let mut counts = vec![0usize; folds];
        for (&b, p) in block.iter().zip(nominal_mm) {
            counts[b] += 1;
            (0..3).for_each(|a| sums[b][a] += p[a]);
        }
        for ((c, s), &k) in centres.iter_mut().zip(&sums).zip(&counts) {
            if k > 0 {
                *c = s.map(|v| v / k as f64);
            }
        }
    }
    group_splits(&block)
        .filter(|s| s.len() == folds)
        .ok_or(invalid)
}

/// Leave-one-group-out folds of samples labelled `group` (a series' index, a block's):
/// one fold per group, in ascending order of the label; `None` with fewer than two groups.
pub fn group_splits(group: &[usize]) -> Option<Vec<Fold>> {
    let mut labels: Vec<usize> = group.to_vec();
    labels.sort_unstable();
    labels.dedup();
    if labels.len() < 2 {
        return None;
    }
    Some(
        labels
            .into_iter()
            .map(|label| {
                let (test, train) = (0..group.len()).partition(|&i| group[i] == label);
                Fold { train, test }
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two clouds 1 m apart, 4 points each.
    fn two_clouds() -> Vec<[f64; 3]> {
        let mut points = Vec::new();
        for x0 in [0.0, 1000.0] {
            for (dx, dy) in [(0.0, 0.0), (5.0, 0.0), (0.0, 5.0), (5.0, 5.0)] {
                points.push([x0 + dx, dy, 0.0]);
            }
        }
        points
    }

    #[test]
    fn blocks_hold_out_whole_regions_and_test_every_sample_once() {
        let points = two_clouds();
        let splits = block_splits(&points, 2, 7).unwrap();
        assert_eq!(splits.len(), 2);
        let mut tested: Vec<usize> = splits.iter().flat_map(|f| f.test.clone()).collect();
        tested.sort_unstable();
        assert_eq!(tested, (0..8).collect::<Vec<_>>());
        for fold in &splits {
            // A block is one cloud: its points all lie on one side.
            let side = |i: usize| points[i][0] > 500.0;
            assert!(fold.test.iter().all(|&i| side(i) == side(fold.test[0])));
            assert_eq!(fold.test.len() + fold.train.len(), 8);
        }
    }

    #[test]
    fn blocks_are_the_same_for_a_seed() {
        let points: Vec<[f64; 3]> = (0..200)
            .map(|i| {
                let t = i as f64;
                [(t * 7.3) % 500.0, (t * 3.1) % 400.0, (t * 1.7) % 300.0]
            })
            .collect();
        assert_eq!(
            block_splits(&points, 5, 3).unwrap(),
            block_splits(&points, 5, 3).unwrap()
        );
    }

    #[test]
    fn blocks_refuse_more_folds_than_distinct_positions() {
        let points = vec![[1.0, 2.0, 3.0]; 10];
        assert!(block_splits(&points, 3, 0).is_err());
        assert!(block_splits(&points, 1, 0).is_err());
    }

    #[test]
    fn groups_leave_one_series_out() {
        let splits = group_splits(&[0, 0, 1, 2, 1]).unwrap();
        assert_eq!(splits.len(), 3);
        assert_eq!(splits[1].test, vec![2, 4]);
        assert_eq!(splits[1].train, vec![0, 1, 3]);
        assert!(group_splits(&[4, 4, 4]).is_none());
    }
}
