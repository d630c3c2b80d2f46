//! Trilinear interpolation inside the cubes of an axis-aligned sample lattice, the grid
//! approach of patent CN201110113246.6.
//!
//! The grid method samples the workspace on a lattice of cubes and predicts the error at a
//! target from the eight corners of the cube that encloses it. It needs the samples to
//! *be* a lattice, which the approximation-degree method does not; that requirement is the
//! point of comparison, so this module checks it rather than assuming it:
//!
//! - [`Grid::new`] detects, per axis, a uniform lattice `origin + n · step` (steps may differ
//!   between axes), anchored at the lowest coordinate along each axis, that every sample
//!   lies on within `relative_tolerance · step`, and reports
//!   [`BaselineError::Unsupported`] with the first offending sample otherwise. The lattice may
//!   be partial: nodes may be missing.
//! - [`Grid::predict`] never extrapolates: a query outside the lattice's bounding box, or in
//!   a cube with a missing corner, is reported as [`NotCovered`].

use std::collections::HashMap;

use super::{validate_query, validate_samples, Baseline, BaselineError, NotCovered, PredictError};

/// The largest number of lattice levels accepted along one axis. A million levels at the
/// default tolerance would already make the tolerance comparable to floating-point noise.
const MAX_LEVELS_PER_AXIS: f64 = 1.0e6;

/// Parameters of lattice detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridParams {
    /// How far (as a fraction of the axis step) a sample coordinate may lie from its lattice
    /// level and still count as on it; must be in `(0, 0.01]`. The default `1e-6` accepts
    /// positions printed with a few decimals of mm but rejects any real jitter. The same
    /// fraction bounds how much weight a missing corner may carry before a query is
    /// reported as not covered.
    pub relative_tolerance: f64,
}

impl Default for GridParams {
    /// A relative tolerance of `1e-6` of the step.
    fn default() -> Self {
        Self {
            relative_tolerance: 1e-6,
        }
    }
}

/// One axis of a detected lattice: levels at `origin_mm + n · step_mm` for `n` in
/// `0..levels`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LatticeAxis {
    /// The lowest level along this axis, mm.
    pub origin_mm: f64,
    /// The spacing between consecutive levels, mm.
    pub step_mm: f64,
    /// The number of levels from lowest to highest, including any with no samples.
    pub levels: usize,
}

/// A trilinear interpolator over a (possibly partial) axis-aligned sample lattice.
#[derive(Debug, Clone)]
pub struct Grid {
    axes: [LatticeAxis; 3],
    /// Sample value at each occupied node, keyed by lattice indices along x, y, z. Samples
    /// that share a node (repeated measurements) are averaged.
    node_values: HashMap<[i64; 3], [f64; 3]>,
    params: GridParams,
}

impl Grid {
    /// Detects the lattice formed by the sample nominal positions (mm, base frame) and
    /// builds the interpolator over their values (any unit).
    ///
    /// # Errors
    ///
    /// [`BaselineError::Unsupported`] when the samples do not form an axis-aligned lattice
    /// with at least two levels along every axis, or when no lattice cube has all eight
    /// corners sampled (nothing could ever be predicted); other [`BaselineError`]s for
    /// empty, mismatched or non-finite samples, or an invalid tolerance.
    pub fn new(
        positions_mm: &[[f64; 3]],
        values: &[[f64; 3]],
        params: GridParams,
    ) -> Result<Self, BaselineError> {
        validate_samples(positions_mm, values)?;
        let tol = params.relative_tolerance;
        if !(tol > 0.0 && tol <= 0.01) {
            return Err(BaselineError::InvalidParameter {
                name: "relative_tolerance",
                reason: format!("must be in (0, 0.01], got {tol}"),
            });
        }

        let [x_axis, y_axis, z_axis] = [0, 1, 2].map(|axis| detect_axis(positions_mm, axis, tol));
        let axes = [x_axis?, y_axis?, z_axis?];

        let mut sums: HashMap<[i64; 3], ([f64; 3], u32)> = HashMap::new();
        for (index, (position, value)) in positions_mm.iter().zip(values).enumerate() {
            let mut key = [0i64; 3];
            for axis in 0..3 {
                let a = &axes[axis];
                let u = (position[axis] - a.origin_mm) / a.step_mm;
                let level = u.round();
                let off_mm = (u - level).abs() * a.step_mm;
                if off_mm > tol * a.step_mm {
                    return Err(BaselineError::Unsupported {
                        reason: format!(
                            "the samples do not form an axis-aligned lattice: sample {index} has \
                             {} = {} mm, {off_mm:.3e} mm off the nearest level of a lattice with \
                             step {} mm (tolerance {:.3e} mm)",
                            AXIS_NAMES[axis],
                            position[axis],
                            a.step_mm,
                            tol * a.step_mm
                        ),
                    });
                }
                // `level` is in 0..levels: `detect_axis` spans the axis's min..max.
                key[axis] = level as i64;
            }
            let entry = sums.entry(key).or_insert(([0.0; 3], 0));
            for (s, v) in entry.0.iter_mut().zip(value) {
                *s += v;
            }
            entry.1 += 1;
        }
        let node_values: HashMap<[i64; 3], [f64; 3]> = sums
            .into_iter()
            .map(|(key, (sum, count))| (key, sum.map(|s| s / f64::from(count))))
            .collect();

        let any_complete_cube = node_values
            .keys()
            .any(|&base| (1..8).all(|corner| node_values.contains_key(&corner_key(base, corner))));
        if !any_complete_cube {
            return Err(BaselineError::Unsupported {
                reason: format!(
                    "no lattice cube has all eight corners sampled ({} occupied nodes on a \
                     {}×{}×{} lattice), so no query could be interpolated",
                    node_values.len(),
                    axes[0].levels,
                    axes[1].levels,
                    axes[2].levels
                ),
            });
        }

        Ok(Self {
            axes,
            node_values,
            params,
        })
    }

    /// The detected lattice along x, y and z.
    pub fn axes(&self) -> &[LatticeAxis; 3] {
        &self.axes
    }

    /// How many lattice nodes hold a sample.
    pub fn occupied_nodes(&self) -> usize {
        self.node_values.len()
    }

    /// The parameters this interpolator was built with.
    pub fn params(&self) -> &GridParams {
        &self.params
    }

    /// Trilinear interpolation of the corner values of the lattice cube enclosing
    /// `query_position_mm` (mm, base frame).
    ///
    /// A query on a face, edge or node of the lattice only needs the corners that carry
    /// weight: a corner whose trilinear weight is at most `relative_tolerance` may be
    /// missing, and the remaining weights are renormalised. Queries within the tolerance
    /// of the lattice's outer faces count as inside.
    ///
    /// # Errors
    ///
    /// [`PredictError::NonFiniteQuery`]; [`NotCovered::OutsideLattice`] outside the lattice's
    /// bounding box; [`NotCovered::MissingCorner`] when a weighted corner has no sample.
    pub fn predict(&self, query_position_mm: [f64; 3]) -> Result<[f64; 3], PredictError> {
        validate_query(query_position_mm)?;
        let tol = self.params.relative_tolerance;
        let mut base = [0i64; 3];
        let mut fraction = [0.0f64; 3];
        for axis in 0..3 {
            let a = &self.axes[axis];
            let last = (a.levels - 1) as f64;
            let u = (query_position_mm[axis] - a.origin_mm) / a.step_mm;
            if u < -tol || u > last + tol {
                return Err(PredictError::NotCovered(NotCovered::OutsideLattice));
            }
            let u = u.clamp(0.0, last);
            // The cube's lower index; the top face belongs to the last cube.
            let lower = u.floor().min(last - 1.0);
            base[axis] = lower as i64;
            fraction[axis] = u - lower;
        }

        let mut sum = [0.0; 3];
        let mut weight_sum = 0.0;
        for corner in 0..8 {
            let weight: f64 = (0..3)
                .map(|axis| {
                    if corner >> axis & 1 == 1 {
                        fraction[axis]
                    } else {
                        1.0 - fraction[axis]
                    }
                })
                .product();
            let key = corner_key(base, corner);
            match self.node_values.get(&key) {
                Some(value) => {
                    for (s, v) in sum.iter_mut().zip(value) {
                        *s += weight * v;
                    }
                    weight_sum += weight;
                }
                None if weight <= tol => {}
                None => {
                    return Err(PredictError::NotCovered(NotCovered::MissingCorner {
                        corner_index: key,
                    }))
                }
            }
        }
        Ok(sum.map(|s| s / weight_sum))
    }
}

impl Baseline for Grid {
    fn name(&self) -> &'static str {
        "grid"
    }

    fn predict(&self, query_position_mm: [f64; 3]) -> Result<[f64; 3], PredictError> {
        Grid::predict(self, query_position_mm)
    }
}

const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

/// The lattice key of corner `corner` (bit 0: +x, bit 1: +y, bit 2: +z) of the cube whose
/// lowest corner is `base`.
fn corner_key(base: [i64; 3], corner: u32) -> [i64; 3] {
    [0, 1, 2].map(|axis| base[axis] + i64::from(corner >> axis & 1))
}

/// Finds the uniform levels spanned by the samples' coordinates along `axis`.
///
/// The step is first estimated as the smallest gap between distinct sorted coordinates
/// (gaps up to `relative_tolerance` of the axis's range count as the same level), then
/// refined to `range / round(range / estimate)` so that it is accurate to the tolerance over
/// the whole range. Whether every sample actually lies on a level is checked by the caller.
fn detect_axis(
    positions_mm: &[[f64; 3]],
    axis: usize,
    relative_tolerance: f64,
) -> Result<LatticeAxis, BaselineError> {
    let mut coords: Vec<f64> = positions_mm.iter().map(|p| p[axis]).collect();
    coords.sort_unstable_by(f64::total_cmp);
    let (min, max) = (coords[0], coords[coords.len() - 1]);
    let range = max - min;
    if range <= 0.0 {
        return Err(BaselineError::Unsupported {
            reason: format!(
                "all samples share {} = {min} mm; trilinear interpolation needs at least two \
                 lattice levels along every axis",
                AXIS_NAMES[axis]
            ),
        });
    }
    let merge_gap = relative_tolerance * range;
    let smallest_gap = coords
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&gap| gap > merge_gap)
        .fold(f64::INFINITY, f64::min);
    let intervals = (range / smallest_gap).round();
    if intervals > MAX_LEVELS_PER_AXIS {
        return Err(BaselineError::Unsupported {
            reason: format!(
                "the {} coordinates are not on a plausible lattice: their smallest spacing \
                 ({smallest_gap:.3e} mm) would need over {MAX_LEVELS_PER_AXIS:e} levels",
                AXIS_NAMES[axis]
            ),
        });
    }
    Ok(LatticeAxis {
        origin_mm: min,
        step_mm: range / intervals,
        levels: intervals as usize + 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Lattice nodes with x, y, z steps 50, 40 and 30 mm on a 6 × 5 × 4 lattice.
    fn lattice() -> Vec<[f64; 3]> {
        let mut nodes = Vec::new();
        for i in 0..6 {
            for j in 0..5 {
                for k in 0..4 {
                    nodes.push([
                        800.0 + 50.0 * f64::from(i),
                        -200.0 + 40.0 * f64::from(j),
                        600.0 + 30.0 * f64::from(k),
                    ]);
                }
            }
        }
        nodes
    }

    /// A different trilinear function per component, including all cross terms.
    fn trilinear_field(p: [f64; 3]) -> [f64; 3] {
        let [x, y, z] = p;
        [
            0.3 + 1e-3 * x - 2e-3 * y + 5e-4 * z + 1e-6 * x * y - 2e-6 * y * z + 3e-6 * x * z
                - 1e-9 * x * y * z,
            -1.0 + 2e-3 * x + 1e-9 * x * y * z,
            0.05 - 4e-4 * z + 7e-7 * x * z,
        ]
    }

    #[test]
    fn trilinear_is_exact_for_a_trilinear_field() {
        let positions = lattice();
        let values: Vec<[f64; 3]> = positions.iter().map(|&p| trilinear_field(p)).collect();
        let grid = Grid::new(&positions, &values, GridParams::default()).unwrap();
        assert_eq!(
            grid.axes()[1],
            LatticeAxis {
                origin_mm: -200.0,
                step_mm: 40.0,
                levels: 5
            }
        );
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let queries = (0..500).map(|_| {
            [
                rng.gen_range(800.0..=1050.0),
                rng.gen_range(-200.0..=-40.0),
                rng.gen_range(600.0..=690.0),
            ]
        });
        for q in queries.chain(positions.iter().copied()) {
            let got = grid.predict(q).unwrap();
            let want = trilinear_field(q);
            for axis in 0..3 {
                assert!(
                    (got[axis] - want[axis]).abs() <= 1e-9,
                    "{q:?}: {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn a_jittered_cloud_is_unsupported() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let positions: Vec<[f64; 3]> = lattice()
            .into_iter()
            .map(|p| p.map(|c| c + rng.gen_range(-0.05..0.05)))
            .collect();
        let values = vec![[0.0; 3]; positions.len()];
        let err = Grid::new(&positions, &values, GridParams::default()).unwrap_err();
        match err {
            BaselineError::Unsupported { reason } => {
                assert!(reason.contains("lattice"), "{reason}")
            }
            other => panic!("expected Unsupported, got {other:?}"),
        }
    }

    #[test]
    fn a_rotated_lattice_and_a_flat_layer_are_unsupported() {
        let (s, c) = 0.3f64.sin_cos();
        let rotated: Vec<[f64; 3]> = lattice()
            .into_iter()
            .map(|[x, y, z]| [c * x - s * y, s * x + c * y, z])
            .collect();
        let values = vec![[0.0; 3]; rotated.len()];
        assert!(matches!(
            Grid::new(&rotated, &values, GridParams::default()),
            Err(BaselineError::Unsupported { .. })
        ));
        let flat: Vec<[f64; 3]> = lattice().into_iter().map(|[x, y, _]| [x, y, 0.0]).collect();
        assert!(matches!(
            Grid::new(&flat, &values, GridParams::default()),
            Err(BaselineError::Unsupported { .. })
        ));
    }

    #[test]
    fn small_coordinate_noise_within_tolerance_is_accepted() {
        // Positions as a CSV with 1e-6 mm resolution would print them.
        let positions: Vec<[f64; 3]> = lattice()
            .into_iter()
            .enumerate()
            .map(|(i, p)| p.map(|c| c + if i % 2 == 0 { 1e-6 } else { -1e-6 }))
            .collect();
        let values = vec![[1.0; 3]; positions.len()];
        let grid = Grid::new(&positions, &values, GridParams::default()).unwrap();
        assert_eq!(grid.occupied_nodes(), positions.len());
        assert_eq!(grid.axes()[0].levels, 6);
    }

    #[test]
    fn partial_lattice_reports_missing_corners_and_outside_queries() {
        let mut positions = lattice();
        // Remove node (1, 1, 1).
        let removed = [850.0, -160.0, 630.0];
        positions.retain(|p| *p != removed);
        let values: Vec<[f64; 3]> = positions.iter().map(|&p| trilinear_field(p)).collect();
        let grid = Grid::new(&positions, &values, GridParams::default()).unwrap();

        // Inside cube (0, 0, 0), which has the removed node as a corner.
        assert_eq!(
            grid.predict([830.0, -180.0, 610.0]),
            Err(PredictError::NotCovered(NotCovered::MissingCorner {
                corner_index: [1, 1, 1]
            }))
        );
        // Cube (3, 3, 2) is complete.
        let q = [960.0, -70.0, 670.0];
        let got = grid.predict(q).unwrap();
        let want = trilinear_field(q);
        for axis in 0..3 {
            assert!((got[axis] - want[axis]).abs() <= 1e-9);
        }
        // Cube (0, 0, 0) still serves its node (0, 0, 0) and its face x = 800 mm: there the
        // missing corner carries no weight.
        for q in [[800.0, -200.0, 600.0], [800.0, -180.0, 610.0]] {
            let got = grid.predict(q).unwrap();
            let want = trilinear_field(q);
            for axis in 0..3 {
                assert!((got[axis] - want[axis]).abs() <= 1e-9, "{q:?}");
            }
        }
        // Outside the bounding box along z.
        assert_eq!(
            grid.predict([900.0, -100.0, 700.0]),
            Err(PredictError::NotCovered(NotCovered::OutsideLattice))
        );
    }

    #[test]
    fn repeated_measurements_at_a_node_are_averaged() {
        let mut positions = lattice();
        let mut values = vec![[0.0; 3]; positions.len()];
        positions.push(positions[0]);
        values.push([2.0, 4.0, -6.0]);
        let grid = Grid::new(&positions, &values, GridParams::default()).unwrap();
        assert_eq!(grid.predict(positions[0]).unwrap(), [1.0, 2.0, -3.0]);
    }

    #[test]
    fn a_lattice_without_any_complete_cube_is_unsupported() {
        // Two opposite corners of a cube only.
        let positions = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]];
        let values = [[0.0; 3]; 2];
        assert!(matches!(
            Grid::new(&positions, &values, GridParams::default()),
            Err(BaselineError::Unsupported { .. })
        ));
    }
}
