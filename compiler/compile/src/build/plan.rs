//! Planning a build: its options resolved against its samples into a [`Plan`] — ε, the
//! cell edge and the grid derived where not given — and every check the runtime will make
//! of them, with the table's size estimated, before any work.

use adwi_runtime::format::{self, Grid};
use adwi_runtime::method::MethodParams;

use super::{BuildError, BuildOptions, ServedField, Tuning};
use adwi_samples::SampleSet;

/// The most cells a table may have.
pub const MAX_CELLS: usize = 20_000_000;
/// The default radius ε is this many sample spacings: it covers the 8 corners of a lattice
/// cube (at most √3 spacings away) from any point inside it.
pub const RADIUS_PER_SPACING: f64 = 2.0;
/// The default cell edge is the sample spacing divided by this: cells half a spacing wide
/// keep a cell's candidates within one 64-byte record for lattice-like samples, and put
/// the served field's nodes twice as dense as the samples.
pub const CELLS_PER_SPACING: f64 = 2.0;

/// A build resolved from its options and samples, once: every parameter the table will
/// hold, and what was derived. [`compile_plan`](super::compile_plan) consumes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// The method's parameters, ε resolved.
    pub params: MethodParams,
    /// The cell grid.
    pub grid: Grid,
    /// The joint-space admissibility radius, rad (0 = off).
    pub joint_radius_rad: f64,
    /// Median nearest-neighbour spacing of the nominal positions, mm.
    pub spacing_mm: Option<f64>,
    /// Whether ε was derived from the spacing.
    pub radius_derived: bool,
    /// Whether the cell edge was derived from the spacing.
    pub cell_derived: bool,
    /// The number of samples planned for.
    pub samples: usize,
    /// The cross-validation that chose the options, for the header.
    pub tuning: Option<Tuning>,
    /// What the served tier's nodes hold.
    pub served_field: ServedField,
}

impl Plan {
    /// The number of cells in the grid.
    pub fn cells(&self) -> usize {
        self.grid.cell_count().unwrap_or(0)
    }

    /// At most how many cells can hold candidates ([`max_covered_cells`]).
    pub fn coverable_cells(&self) -> f64 {
        max_covered_cells(self.samples, self.params.radius_mm, self.grid.cell_mm)
            .min(self.cells() as f64)
    }

    /// Whether most of a large grid lies farther than ε from every sample, as it does for
    /// samples along a line or a plane, whose bounding box is mostly empty.
    pub fn is_mostly_empty(&self) -> bool {
        self.cells() > 100_000 && self.cells() as f64 > 10.0 * self.coverable_cells()
    }

    /// The table's estimated size, bytes ([`estimated_table_bytes`]).
    pub fn estimated_table_bytes(&self) -> u128 {
        estimated_table_bytes(
            self.cells() as u128,
            self.samples,
            self.params.radius_mm,
            self.grid.cell_mm,
            self.params.max_neighbours,
        )
    }
}

/// A table's size before it is built, bytes: per cell its 8-byte record and base-weight
/// offset, per cell that can be covered ([`max_covered_cells`]) at most `k` base weights
/// (12 bytes each), and per sample its record.
pub fn estimated_table_bytes(
    cells: u128,
    samples: usize,
    radius_mm: f64,
    cell_mm: f64,
    k: u32,
) -> u128 {
    let covered = (max_covered_cells(samples, radius_mm, cell_mm) as u128).min(cells);
    // Saturating: an absurd grid (a huge --radius, say) must be refused, not overflow.
    cells
        .saturating_mul(12)
        .saturating_add(covered.saturating_mul(12 * u128::from(k)))
        .saturating_add(samples as u128 * 120)
}

/// At most how many cells of edge `cell_mm` can lie within `radius_mm` of one of `samples`
/// points: the cells a ball of that radius, grown by half a cell diagonal, can touch, per
/// sample. A grid far larger than this is mostly empty (samples on a line or a plane).
pub fn max_covered_cells(samples: usize, radius_mm: f64, cell_mm: f64) -> f64 {
    let reach_cells = radius_mm / cell_mm + 3f64.sqrt();
    samples as f64 * 4.0 / 3.0 * std::f64::consts::PI * reach_cells.powi(3)
}

/// `1234567` as `1.2 MB`.
pub fn human_bytes(bytes: u128) -> String {
    let units = ["bytes", "kB", "MB", "GB", "TB", "PB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < units.len() {
        value /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.1} {}", units[unit])
    }
}

/// Resolves a build's options against its samples: derives ε, the cell edge and the grid
/// where not given, and checks everything the runtime will check, before any work.
///
/// # Errors
///
/// Parameters out of range, underivable defaults, a grid too large or implausible.
pub fn plan(samples: &SampleSet, options: &BuildOptions) -> Result<Plan, BuildError> {
    let spacing_mm = samples.spacing_mm();
    let derive = |what| {
        spacing_mm
            .filter(|s| *s > 0.0)
            .ok_or(BuildError::CannotDerive(what))
    };
    let radius_mm = match options.method.radius_mm {
        Some(r) => r,
        None => RADIUS_PER_SPACING * derive("the radius")?,
    };
    let params = options.method.with_radius(radius_mm);
    params.validate().map_err(BuildError::Params)?;
    let joint_radius_rad = options.joint_radius_deg.unwrap_or(0.0).to_radians();
    if !(joint_radius_rad.is_finite() && joint_radius_rad >= 0.0) {
        return Err(BuildError::Params(
            "joint radius must be finite and non-negative",
        ));
    }
    if joint_radius_rad > 0.0 && options.served_field != ServedField::Method {
        return Err(BuildError::KrigingWithoutServedTier);
    }
    if joint_radius_rad > 0.0 && samples.joints.is_none() {
        return Err(BuildError::Params(
            "a joint radius needs samples with joint angles (columns j1..jn)",
        ));
    }
    let cell_mm = match options.cell_mm {
        Some(c) => c,
        None => derive("the cell size")? / CELLS_PER_SPACING,
    };
    if !(cell_mm.is_finite() && cell_mm > 0.0) {
        return Err(BuildError::Params("cell size must be finite and positive"));
    }
    let (lo, hi) = match options.bounds_mm {
        Some(b) => b,
        None => {
            let (lo, hi) = samples
                .nominal_bounds_mm()
                .ok_or(BuildError::CannotDerive("bounds"))?;
            (lo.map(|v| v - radius_mm), hi.map(|v| v + radius_mm))
        }
    };
    if !(0..3).all(|a| lo[a].is_finite() && hi[a].is_finite() && lo[a] < hi[a]) {
        return Err(BuildError::Bounds(format!(
            "{lo:?} to {hi:?}: each minimum must be below its maximum, all finite"
        )));
    }
    // Bounds a kilometre away (a huge --radius widens the default ones) are refused before
    // their cells are counted.
    for v in lo.iter().chain(&hi) {
        format::check_coordinate("a grid bound (mm)", *v)?;
    }
    let dims_f = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / cell_mm).ceil().max(1.0));
    // Saturating: a tiny cell makes each count reach u128::MAX (`as` saturates).
    let cells = dims_f
        .iter()
        .fold(1u128, |product, &d| product.saturating_mul(d as u128));
    if cells > MAX_CELLS as u128 || dims_f.iter().any(|&d| d > u32::MAX as f64) {
        return Err(BuildError::TooManyCells {
            cells,
            cell_mm,
            estimated_bytes: estimated_table_bytes(
                cells,
                samples.len(),
                radius_mm,
                cell_mm,
                params.max_neighbours,
            ),
            max: MAX_CELLS,
        });
    }
    let grid = Grid {
        origin_mm: lo,
        cell_mm,
        dims: dims_f.map(|d| d as u32),
    };
    // The runtime's own plausibility bounds, so that no build ends in a table that does
    // not open (an ε beyond every distance in the workspace, a grid a kilometre away).
    let positions = (0..samples.len()).flat_map(|i| [samples.nominal_mm[i], samples.actual_mm(i)]);
    format::check_plausible(
        &params,
        &grid,
        joint_radius_rad,
        format::bounding_box(positions),
    )?;
    Ok(Plan {
        params,
        grid,
        joint_radius_rad,
        spacing_mm,
        radius_derived: options.method.radius_mm.is_none(),
        cell_derived: options.cell_mm.is_none(),
        samples: samples.len(),
        tuning: options.tuning,
        served_field: options.served_field,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::fixtures::{build, samples};

    #[test]
    fn any_radius_with_the_default_bounds_builds_a_table_that_opens() {
        // The default grid grows with ε, so ε never exceeds its diagonal; `compile` opens
        // what it built.
        let s = samples("");
        for radius_mm in [1.0f64, 200.0, 5e4] {
            let options = BuildOptions {
                method: MethodParams::paper(Some(radius_mm)),
                cell_mm: Some(radius_mm.max(100.0) / 2.0),
                ..BuildOptions::default()
            };
            build(&s, options).unwrap();
        }
    }

    #[test]
    fn what_the_runtime_would_refuse_is_refused_before_building() {
        let s = samples("");
        let small_box = Some(([1000.0; 3], [1200.0; 3]));
        let cases = [
            // ε beyond every distance between the grid and the samples.
            BuildOptions {
                method: MethodParams::paper(Some(1e5)),
                bounds_mm: small_box,
                ..BuildOptions::default()
            },
            // The default grid, ε wide, would reach 1e300 mm from the base.
            BuildOptions {
                method: MethodParams::paper(Some(1e300)),
                cell_mm: Some(1e299),
                ..BuildOptions::default()
            },
            BuildOptions {
                method: MethodParams::paper(Some(1e300)),
                ..BuildOptions::default()
            },
            BuildOptions {
                method: MethodParams::paper(Some(f64::MAX)),
                ..BuildOptions::default()
            },
            BuildOptions {
                bounds_mm: Some(([1000.0; 3], [2e6; 3])),
                cell_mm: Some(1e5),
                ..BuildOptions::default()
            },
            BuildOptions {
                joint_radius_deg: Some(800.0),
                ..BuildOptions::default()
            },
        ];
        for options in cases {
            let err = build(&s, options.clone()).unwrap_err();
            assert!(
                matches!(err, BuildError::Implausible(_)),
                "{options:?}: {err}"
            );
        }
        let far = samples("2e6,0,0,0,0,0,0,0,0,0,0,0\n");
        let options = BuildOptions {
            bounds_mm: small_box,
            ..BuildOptions::default()
        };
        let err = build(&far, options).unwrap_err();
        assert!(err.to_string().contains("sample coordinate"), "{err}");
        // A cell so small that every axis counts more cells than u128 holds.
        let options = BuildOptions {
            cell_mm: Some(1e-300),
            bounds_mm: small_box,
            ..BuildOptions::default()
        };
        let err = build(&s, options).unwrap_err();
        assert!(matches!(err, BuildError::TooManyCells { .. }), "{err}");
    }
}
