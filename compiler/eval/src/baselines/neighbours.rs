//! Brute-force k-nearest-neighbour search shared by the distance-based baselines.
//!
//! An evaluation runs a few thousand queries against a few thousand samples: a linear scan
//! is a few million distance computations per fold, well under a second, and has no
//! failure modes. A spatial index would only pay off for far larger sample databases, so
//! none is built here.

use super::distance_squared;

/// One neighbour of a query: its sample index and squared distance (mm²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Neighbour {
    /// Index of the sample in the baseline's sample arrays.
    pub index: usize,
    /// Squared Euclidean distance from the query, mm².
    pub distance_squared_mm2: f64,
}

/// The `k` samples nearest to `query_mm`, nearest first.
///
/// Only samples with squared distance `<= max_distance_squared_mm2` are considered when it
/// is given. Ties are broken by sample index, so the result is deterministic. Fewer than `k`
/// neighbours are returned when fewer samples qualify.
pub(super) fn k_nearest(
    positions_mm: &[[f64; 3]],
    query_mm: [f64; 3],
    k: usize,
    max_distance_squared_mm2: Option<f64>,
) -> Vec<Neighbour> {
    let limit = max_distance_squared_mm2.unwrap_or(f64::INFINITY);
    let mut candidates: Vec<Neighbour> = positions_mm
        .iter()
        .enumerate()
        .map(|(index, &p)| Neighbour {
            index,
            distance_squared_mm2: distance_squared(p, query_mm),
        })
        .filter(|n| n.distance_squared_mm2 <= limit)
        .collect();
    let order = |a: &Neighbour, b: &Neighbour| {
        a.distance_squared_mm2
            .total_cmp(&b.distance_squared_mm2)
            .then(a.index.cmp(&b.index))
    };
    if k == 0 {
        return Vec::new();
    }
    if candidates.len() > k {
        candidates.select_nth_unstable_by(k - 1, order);
        candidates.truncate(k);
    }
    candidates.sort_unstable_by(order);
    candidates
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn selection_matches_a_full_sort() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        // Coordinates on a coarse integer grid so that exact distance ties occur.
        let positions: Vec<[f64; 3]> = (0..500)
            .map(|_| [(); 3].map(|_| f64::from(rng.gen_range(-5i32..=5))))
            .collect();
        for _ in 0..50 {
            let query = [(); 3].map(|_| f64::from(rng.gen_range(-6i32..=6)));
            let mut all: Vec<(f64, usize)> = positions
                .iter()
                .enumerate()
                .map(|(i, &p)| (distance_squared(p, query), i))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for k in [1, 8, 16, 499, 500, 600] {
                let got = k_nearest(&positions, query, k, None);
                let want: Vec<usize> = all.iter().take(k).map(|x| x.1).collect();
                assert_eq!(got.iter().map(|n| n.index).collect::<Vec<_>>(), want);
            }
            let radius2 = 9.0;
            let got = k_nearest(&positions, query, 1000, Some(radius2));
            let want: Vec<usize> = all.iter().filter(|x| x.0 <= radius2).map(|x| x.1).collect();
            assert_eq!(got.iter().map(|n| n.index).collect::<Vec<_>>(), want);
        }
    }

    #[test]
    fn zero_k_gives_no_neighbours() {
        assert!(k_nearest(&[[0.0; 3]], [0.0; 3], 0, None).is_empty());
    }
}
