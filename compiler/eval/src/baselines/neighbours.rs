//! k-nearest-neighbour search shared by the distance-based baselines.
//!
//! [`k_nearest`] scans every sample: a few thousand queries against a few thousand samples
//! are a few million distance computations, well under a second. A tracked path of a
//! million samples makes that 10¹¹ per fold, hours; [`KdTree`] answers the same queries
//! with the same neighbours, in the same order, visiting a few dozen samples each
//! (`k_nearest` stays as its reference, held equal by a test).

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

/// Samples per leaf of a [`KdTree`]: a leaf is scanned whole, a few dozen distances.
const LEAF_SAMPLES: usize = 16;

/// A k-d tree of sample positions: the same neighbours as [`k_nearest`], ties broken by
/// sample index, in `O(log n)` per query instead of `O(n)`.
///
/// Each node splits its samples at the median of its box's longest axis; the tree is
/// implicit in the order of the samples (a node's samples a range of it, its children the
/// halves), so it takes the positions and their indices, nothing more.
#[derive(Debug, Clone)]
pub(super) struct KdTree {
    /// Positions in tree order, mm.
    positions_mm: Vec<[f64; 3]>,
    /// Each tree-ordered position's sample index.
    indices: Vec<u32>,
    /// Per internal node, in the order of a depth-first walk: the split axis and value,
    /// and where the node's right subtree's nodes begin (its left one's follow it).
    splits: Vec<Split>,
}

impl KdTree {
    /// The tree of `positions_mm` (at most `u32::MAX` of them).
    pub(super) fn new(positions_mm: &[[f64; 3]]) -> KdTree {
        let mut order: Vec<u32> = (0..positions_mm.len() as u32).collect();
        let mut splits = Vec::new();
        build(positions_mm, &mut order, &mut splits);
        KdTree {
            positions_mm: order.iter().map(|&i| positions_mm[i as usize]).collect(),
            indices: order,
            splits,
        }
    }

    /// The `k` samples nearest to `query_mm` within `max_distance_squared_mm2` (when
    /// given), nearest first, ties by sample index: [`k_nearest`]'s answer, written into
    /// `out` (cleared first; no allocation once it holds `k`).
    pub(super) fn k_nearest_into(
        &self,
        query_mm: [f64; 3],
        k: usize,
        max_distance_squared_mm2: Option<f64>,
        out: &mut Vec<Neighbour>,
    ) {
        out.clear();
        if k == 0 || self.indices.is_empty() {
            return;
        }
        let mut search = Search {
            tree: self,
            query_mm,
            k,
            limit: max_distance_squared_mm2.unwrap_or(f64::INFINITY),
            best: out,
        };
        search.visit(0, self.indices.len(), 0, [0.0; 3]);
        out.sort_unstable_by(order);
    }
}

/// Neighbours ordered by distance, then sample index.
fn order(a: &Neighbour, b: &Neighbour) -> std::cmp::Ordering {
    a.distance_squared_mm2
        .total_cmp(&b.distance_squared_mm2)
        .then(a.index.cmp(&b.index))
}

/// Builds the subtree of `order` (a range of the positions), appending its splits in
/// depth-first order. `select_nth_unstable_by` is deterministic: the same positions give
/// the same tree.
fn build(positions_mm: &[[f64; 3]], order: &mut [u32], splits: &mut Vec<Split>) {
    if order.len() <= LEAF_SAMPLES {
        return;
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &i in order.iter() {
        let p = positions_mm[i as usize];
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])).then(b.cmp(&a)))
        .expect("three axes");
    let middle = order.len() / 2;
    let coordinate = |i: &u32| positions_mm[*i as usize][axis];
    order.select_nth_unstable_by(middle, |a, b| {
        coordinate(a).total_cmp(&coordinate(b)).then(a.cmp(b))
    });
    let split = coordinate(&order[middle]);
    let node = splits.len();
    splits.push(Split {
        axis: axis as u8,
        value: split,
        right: 0,
    });
    let (left, right) = order.split_at_mut(middle);
    build(positions_mm, left, splits);
    splits[node].right = splits.len() as u32;
    build(positions_mm, right, splits);
}

/// An internal node of a [`KdTree`].
#[derive(Debug, Clone, Copy)]
struct Split {
    axis: u8,
    value: f64,
    /// The index of the right subtree's first node.
    right: u32,
}

/// One query's walk: the best `k` so far in `best`, a max-heap by [`order`].
struct Search<'a, 'b> {
    tree: &'a KdTree,
    query_mm: [f64; 3],
    k: usize,
    limit: f64,
    best: &'b mut Vec<Neighbour>,
}

impl Search<'_, '_> {
    /// The squared distance beyond which a sample cannot enter the best `k`.
    fn bound(&self) -> f64 {
        if self.best.len() < self.k {
            self.limit
        } else {
            self.best[0].distance_squared_mm2.min(self.limit)
        }
    }

    /// Visits the subtree of tree-ordered samples `start..end`, whose internal nodes begin
    /// at `node`, `gap` the query's per-axis distance to the subtree's region (its sum of
    /// squares, summed as [`distance_squared`] sums, is no more than any of its samples'
    /// squared distance).
    fn visit(&mut self, start: usize, end: usize, node: usize, gap: [f64; 3]) {
        if (0..3).map(|a| gap[a].powi(2)).sum::<f64>() > self.bound() {
            return;
        }
        let n = end - start;
        if n <= LEAF_SAMPLES {
            for t in start..end {
                let candidate = Neighbour {
                    index: self.tree.indices[t] as usize,
                    distance_squared_mm2: distance_squared(
                        self.tree.positions_mm[t],
                        self.query_mm,
                    ),
                };
                self.offer(candidate);
            }
            return;
        }
        let Split { axis, value, right } = self.tree.splits[node];
        let axis = usize::from(axis);
        let middle = start + n / 2;
        let (left_node, right_node) = (node + 1, right as usize);
        let offset = self.query_mm[axis] - value;
        let mut far_gap = gap;
        far_gap[axis] = offset.abs();
        // Samples left of the median are at or below the split, those right of it at or
        // above: the near side first, the far side only where it can still hold one of the
        // best.
        if offset < 0.0 {
            self.visit(start, middle, left_node, gap);
            self.visit(middle, end, right_node, far_gap);
        } else {
            self.visit(middle, end, right_node, gap);
            self.visit(start, middle, left_node, far_gap);
        }
    }

    /// Keeps `candidate` if it is among the best `k` so far and within the limit.
    fn offer(&mut self, candidate: Neighbour) {
        if candidate.distance_squared_mm2 > self.limit {
            return;
        }
        let best = &mut *self.best;
        if best.len() < self.k {
            best.push(candidate);
            let last = best.len() - 1;
            sift_up(best, last);
        } else if order(&candidate, &best[0]).is_lt() {
            best[0] = candidate;
            sift_down(best, 0);
        }
    }
}

/// Max-heap by [`order`]: restores the heap above `i`.
fn sift_up(heap: &mut [Neighbour], mut i: usize) {
    while i > 0 {
        let parent = (i - 1) / 2;
        if order(&heap[parent], &heap[i]).is_lt() {
            heap.swap(parent, i);
            i = parent;
        } else {
            break;
        }
    }
}

/// Max-heap by [`order`]: restores the heap below `i`.
fn sift_down(heap: &mut [Neighbour], mut i: usize) {
    loop {
        let (l, r) = (2 * i + 1, 2 * i + 2);
        let mut largest = i;
        if l < heap.len() && order(&heap[largest], &heap[l]).is_lt() {
            largest = l;
        }
        if r < heap.len() && order(&heap[largest], &heap[r]).is_lt() {
            largest = r;
        }
        if largest == i {
            return;
        }
        heap.swap(i, largest);
        i = largest;
    }
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

    /// The tree gives the scan's neighbours, in its order, on clouds with exact ties
    /// (integer coordinates), coincident samples and a path, for every k and radius.
    #[test]
    fn the_tree_finds_the_neighbours_the_scan_finds() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut out = Vec::new();
        for case in 0..6 {
            let n = [0, 1, 17, 200, 1500, 4000][case];
            let positions: Vec<[f64; 3]> = (0..n)
                .map(|i| match case % 3 {
                    0 => [(); 3].map(|_| f64::from(rng.gen_range(-4i32..=4))),
                    1 => [(); 3].map(|_| rng.gen_range(-100.0..100.0)),
                    _ => [0.1 * i as f64, 0.0, (i % 7) as f64],
                })
                .collect();
            let tree = KdTree::new(&positions);
            for _ in 0..200 {
                let query = [(); 3].map(|_| f64::from(rng.gen_range(-5i32..=5)) * 1.5);
                for k in [1, 2, 8, 33, n.max(1), n + 3] {
                    for limit in [None, Some(4.0), Some(0.0)] {
                        tree.k_nearest_into(query, k, limit, &mut out);
                        assert_eq!(out, k_nearest(&positions, query, k, limit), "{case} {k}");
                    }
                }
            }
        }
    }
}
