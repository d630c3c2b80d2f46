//! Step 5 of opening a table ([`crate::Table::from_bytes`]): the table's own invariants,
//! checked once after rkyv has proven the archive memory-safe, so that no query can meet
//! an index out of range, a non-finite value or a parameter out of its domain.

use crate::chain::MAX_JOINTS;
use crate::format::v1::ArchivedTableData;
use crate::format::{
    self, v2, v3, Header, CONTENT_CONFIG, CONTENT_JOINTS, CONTENT_KNOWN, CONTENT_MODEL,
    CONTENT_ORIENTATION,
};
use crate::method;
use crate::model::PreparedModel;
use crate::OpenError;

fn corrupt(what: &'static str) -> OpenError {
    OpenError::Corrupt { what }
}

/// The semantic checks of step 5 of [`crate::Table::from_bytes`], version 1.
pub(crate) fn validate_v1(header: &Header, a: &ArchivedTableData) -> Result<(), OpenError> {
    header.method.validate().map_err(corrupt)?;
    if header.content_flags & !CONTENT_KNOWN != 0 {
        return Err(corrupt(
            "the content flags name contents this version does not know",
        ));
    }
    let cells = header
        .grid
        .cell_count()
        .filter(|&n| n > 0 && n < u32::MAX as usize)
        .ok_or(corrupt("grid size is zero or too large"))?;
    if a.cells.len() != cells {
        return Err(corrupt("cell count differs from the grid size"));
    }
    let n = a.samples.len();
    if n != header.sample_count as usize || n >= u32::MAX as usize {
        return Err(corrupt("sample count differs from the header"));
    }
    check_samples_v1(header, a)?;
    check_joints_and_model_v1(header, a)?;
    if a.actual_norms_mm.len() != n
        || a.samples
            .iter()
            .zip(a.actual_norms_mm.iter())
            .any(|(s, norm)| {
                method::norm_mm(s.actual_mm.map(|v| v.to_native())) != norm.to_native()
            })
    {
        return Err(corrupt("a sample's stored norm is not |actual|"));
    }
    if a.centre_weights.len() != a.centre_samples.len() {
        return Err(corrupt("base weight arrays differ in length"));
    }
    check_cells_v1(header, a)?;
    Ok(())
}

/// Every sample finite, its actual position nominal + error, without an orientation or
/// configuration the content flags do not name; the parameters plausible for the box of
/// the samples.
fn check_samples_v1(header: &Header, a: &ArchivedTableData) -> Result<(), OpenError> {
    let with_orientation = header.content_flags & CONTENT_ORIENTATION != 0;
    let with_config = header.content_flags & CONTENT_CONFIG != 0;
    for s in a.samples.iter() {
        let nominal = s.nominal_mm.map(|v| v.to_native());
        let error = s.error_mm.map(|v| v.to_native());
        let actual = s.actual_mm.map(|v| v.to_native());
        let rotation = s.rotation_error_rad.map(|v| v.to_native());
        let all = nominal.iter().chain(&error).chain(&actual).chain(&rotation);
        if !all.clone().all(|v| v.is_finite()) {
            return Err(corrupt("a sample value is not finite"));
        }
        if (0..3).any(|i| nominal[i] + error[i] != actual[i]) {
            return Err(corrupt("a sample's actual position is not nominal + error"));
        }
        if !with_orientation && rotation != [0.0; 3] {
            return Err(corrupt(
                "orientation error present in a position-only table",
            ));
        }
        if !with_config && s.config != method::CONFIG_UNKNOWN {
            return Err(corrupt(
                "configuration present in a table without configurations",
            ));
        }
    }
    let positions = a.samples.iter().flat_map(|s| {
        [
            s.nominal_mm.map(|v| v.to_native()),
            s.actual_mm.map(|v| v.to_native()),
        ]
    });
    let samples_box_mm = format::bounding_box(positions);
    format::check_plausible(
        &header.method,
        &header.grid,
        header.joint_radius_rad,
        samples_box_mm,
    )
    .map_err(OpenError::Implausible)?;
    Ok(())
}

/// Joint angles (finite, one set per sample) and a model exactly where the content flags
/// name them; the model's parameters finite and plausible.
fn check_joints_and_model_v1(header: &Header, a: &ArchivedTableData) -> Result<(), OpenError> {
    let n = a.samples.len();
    let with_joints = header.content_flags & CONTENT_JOINTS != 0;
    if header.joint_radius_rad > 0.0 && !with_joints {
        return Err(corrupt("a joint radius without sample joint angles"));
    }
    if a.joints_rad.len() != if with_joints { n } else { 0 } {
        return Err(corrupt("joint angle count differs from the sample count"));
    }
    if !a
        .joints_rad
        .iter()
        .flatten()
        .all(|q| q.to_native().is_finite())
    {
        return Err(corrupt("a joint angle is not finite"));
    }
    let with_model = header.content_flags & CONTENT_MODEL != 0;
    match a.model.as_ref() {
        None if with_model => return Err(corrupt("the content flags promise a model")),
        Some(_) if !with_model => return Err(corrupt("a model the content flags do not name")),
        Some(m) => {
            for p in [&m.nominal, &m.calibrated] {
                let values = p.joints.iter().flatten().chain(&p.tool).chain(&p.base);
                if !values.map(|v| v.to_native()).all(f64::is_finite) {
                    return Err(corrupt("a kinematic parameter is not finite"));
                }
            }
            format::check_model_plausible(&crate::model::native_model(m))
                .map_err(OpenError::Implausible)?;
        }
        None => {}
    }
    Ok(())
}

/// Every cell's candidate list in bounds, naming existing samples once each; its base
/// weights ([`check_base_weights`]).
fn check_cells_v1(header: &Header, a: &ArchivedTableData) -> Result<(), OpenError> {
    let n = a.samples.len();
    let grid = &header.grid;
    let cells = a.cells.len();
    let mut checked_list = None;
    let mut seen = vec![0u64; n.div_ceil(64)];
    let offsets = a.centre_offsets.as_slice();
    if offsets.len() != cells + 1
        || offsets[0].to_native() != 0
        || offsets[cells].to_native() as usize != a.centre_samples.len()
        || offsets
            .windows(2)
            .any(|w| w[0].to_native() > w[1].to_native())
    {
        return Err(corrupt(
            "base weight offsets do not run from 0 to the weight count",
        ));
    }
    // The cell's (ix, iy, iz), x fastest, counted rather than divided out of the index.
    let mut coords = [0usize; 3];
    for (c, centre_range) in a.cells.iter().zip(offsets.windows(2)) {
        let here = coords;
        coords[0] += 1;
        if coords[0] == grid.dims[0] as usize {
            coords[0] = 0;
            coords[1] += 1;
            if coords[1] == grid.dims[1] as usize {
                coords[1] = 0;
                coords[2] += 1;
            }
        }
        let start = c.list_start.to_native() as usize;
        let list = start
            .checked_add(c.list_len.to_native() as usize)
            .filter(|&end| end <= a.list_samples.len())
            .map(|end| start..end)
            .ok_or(corrupt("a cell's candidate list is out of bounds"))?;
        // Cells sharing a list are usually adjacent: check each distinct range once in a row.
        if checked_list.as_ref() != Some(&list) {
            let samples = a.list_samples[list.clone()].iter();
            check_list(&mut seen, n, samples.map(|i| i.to_native() as usize))?;
            checked_list = Some(list);
        }
        let centre = centre_range[0].to_native() as usize..centre_range[1].to_native() as usize;
        check_base_weights(header, a, here, centre)?;
    }
    Ok(())
}

/// Cell `here`'s base weights (`centre`, a range of the weight arrays): at most k, naming
/// existing samples, the nearest within ε of the cell's centre, each in [0, 1], summing
/// to 1.
fn check_base_weights(
    header: &Header,
    a: &ArchivedTableData,
    here: [usize; 3],
    centre: std::ops::Range<usize>,
) -> Result<(), OpenError> {
    let n = a.samples.len();
    let grid = &header.grid;
    if centre.len() > header.method.max_neighbours as usize {
        return Err(corrupt("a cell has more base weights than k"));
    }
    if a.centre_samples[centre.clone()]
        .iter()
        .any(|&i| i.to_native() as usize >= n)
    {
        return Err(corrupt("a base weight names a sample that does not exist"));
    }
    // The base weights were selected at the cell's centre, so their nearest sample is
    // within ε of it (computed as the compiler computes it, so never refused for a
    // table it wrote): a grid edited to another shape or place with the same cell
    // count fails here. One sample a cell keeps the cost of opening low.
    if let Some(nearest) = a.centre_samples[centre.clone()].first() {
        let (lo, hi) = grid.cell_box(here);
        let middle = [0, 1, 2].map(|axis| 0.5 * (lo[axis] + hi[axis]));
        let nearest = a
            .samples
            .get(nearest.to_native() as usize)
            .map_or([0.0; 3], |s| s.actual_mm.map(|v| v.to_native()));
        let key = method::distance_squared_mm2(nearest, middle);
        if key > header.method.radius_mm * header.method.radius_mm || key.is_nan() {
            return Err(corrupt(
                "a cell's nearest base weight is beyond ε of its centre: the grid does not \
                 match its cells",
            ));
        }
    }
    let weights = &a.centre_weights[centre.clone()];
    // Up to 1 + 1e-12: a lone neighbour's ω1 + ω2 may round just above 1.
    if !weights
        .iter()
        .all(|q| (0.0..=1.0 + 1e-12).contains(&q.to_native()))
    {
        return Err(corrupt("a base weight is outside [0, 1]"));
    }
    let sum: f64 = weights.iter().map(|q| q.to_native()).sum();
    if !centre.is_empty() && (sum - 1.0).abs() > 1e-9 {
        return Err(corrupt("a cell's base weights do not sum to 1"));
    }
    Ok(())
}

/// The semantic checks of step 5 of [`crate::Table::from_bytes`], version 2, in order:
/// parameters and flags, counts against the header, the samples (finite, norms as the
/// method computes them, plausible magnitudes), errors, configurations, joint values, the
/// cell records (every candidate a sample, no repeats, long lists in bounds), the node
/// sets (values finite or marked missing), the model (valid chains of the header's joint
/// count). Returns the model, prepared.
pub(crate) fn validate_v2(
    header: &Header,
    a: &v2::ArchivedTableData,
) -> Result<Option<PreparedModel>, OpenError> {
    header.method.validate().map_err(corrupt)?;
    if header.content_flags & !CONTENT_KNOWN != 0 {
        return Err(corrupt(
            "the content flags name contents this version does not know",
        ));
    }
    let flags = header.content_flags;
    let with_orientation = flags & CONTENT_ORIENTATION != 0;
    let with_config = flags & CONTENT_CONFIG != 0;
    let with_joints = flags & CONTENT_JOINTS != 0;
    let with_model = flags & CONTENT_MODEL != 0;
    let grid = &header.grid;
    let cells = grid
        .cell_count()
        .filter(|&n| n > 0 && n < u32::MAX as usize)
        .ok_or(corrupt("grid size is zero or too large"))?;
    let n = a.samples.len();
    if n == 0 || n != header.sample_count as usize || n >= u32::MAX as usize {
        return Err(corrupt("sample count differs from the header"));
    }
    // Samples: finite, norms exactly as the method computes them, plausible magnitudes.
    for s in a.samples.iter() {
        let actual = s.actual_mm.map(|v| v.to_native());
        if !actual.iter().all(|v| v.is_finite()) {
            return Err(corrupt("a sample position is not finite"));
        }
        if method::norm_mm(actual) != s.norm_mm.to_native() {
            return Err(corrupt("a sample's stored norm is not |actual|"));
        }
    }
    let samples_box_mm =
        format::bounding_box(a.samples.iter().map(|s| s.actual_mm.map(|v| v.to_native())));
    format::check_plausible(
        &header.method,
        grid,
        header.joint_radius_rad,
        samples_box_mm,
    )
    .map_err(OpenError::Implausible)?;
    if a.errors_mm.len() != n {
        return Err(corrupt("error count differs from the sample count"));
    }
    if a.orientation_errors_rad.len() != if with_orientation { n } else { 0 } {
        return Err(corrupt(
            "orientation error count differs from the content flags",
        ));
    }
    let finite3 = |v: &rkyv::Archived<[f64; 3]>| v.iter().all(|x| x.to_native().is_finite());
    if !a
        .errors_mm
        .iter()
        .chain(a.orientation_errors_rad.iter())
        .all(finite3)
    {
        return Err(corrupt("a sample error is not finite"));
    }
    if a.configs.len() != if with_config { n } else { 0 }
        || a.configs.contains(&method::CONFIG_UNKNOWN)
    {
        return Err(corrupt("configurations do not match the content flags"));
    }
    // Joint values: a count for hybrid tables and joint screens, values for screens only.
    let joint_count = header.joint_count as usize;
    if (with_model || with_joints) != (joint_count > 0) || joint_count > MAX_JOINTS {
        return Err(corrupt(
            "the joint count does not match the table's contents",
        ));
    }
    if with_joints != (header.joint_radius_rad > 0.0) {
        return Err(corrupt(
            "sample joint values are stored exactly when a joint screen is on",
        ));
    }
    let joint_values = if with_joints { n * joint_count } else { 0 };
    if a.joints_rad.len() != joint_values || !a.joints_rad.iter().all(|q| q.to_native().is_finite())
    {
        return Err(corrupt("joint values do not match the samples"));
    }
    validate_cells(a, cells, n)?;
    validate_cell_reach(header, a)?;
    validate_nodes(header, a, with_orientation, with_config)?;
    // The model: valid chains of the header's joint count, of plausible magnitudes.
    match a.model.as_ref() {
        None if with_model => Err(corrupt("the content flags promise a model")),
        Some(_) if !with_model => Err(corrupt("a model the content flags do not name")),
        None => Ok(None),
        Some(m) => {
            let chain = |c: &v2::ArchivedChainRecord| {
                let chain = c
                    .to_chain()
                    .map_err(|_| corrupt("a stored chain is invalid"))?;
                format::check_chain_plausible(&chain).map_err(OpenError::Implausible)?;
                Ok::<_, OpenError>(chain)
            };
            let (nominal, calibrated) = (chain(&m.nominal)?, chain(&m.calibrated)?);
            if nominal.joint_count() != joint_count || calibrated.joint_count() != joint_count {
                return Err(corrupt("a chain's joint count differs from the header's"));
            }
            Ok(PreparedModel::new(nominal, calibrated))
        }
    }
}

/// A version-3 table's posture term ([`crate::posture`]): parameters positive and finite,
/// one position, residual and joint row per sample, all finite and plausible; a posture
/// grid from the table grid's origin covering its box, one list per cell, each ascending,
/// of existing samples, at most [`v3::MAX_POSTURE_CANDIDATES`] long, every one reaching
/// its cell. (That a list holds *every* sample reaching its cell is the compiler's
/// guarantee, as the exact tier's candidate lists are.)
pub(crate) fn validate_posture(
    header: &Header,
    p: &v3::ArchivedPostureRecord,
) -> Result<(), OpenError> {
    let params = crate::posture::params_of(p);
    let positive = |v: f64, limit: f64| v > 0.0 && v <= limit;
    if !positive(params.radius_mm, format::MAX_COORDINATE_MM)
        || !positive(params.length_rad, 1e3)
        || !positive(params.floor, 1e6)
    {
        return Err(corrupt(
            "a posture parameter is not positive, finite and plausible",
        ));
    }
    let n = header.sample_count as usize;
    let joint_count = header.joint_count as usize;
    if p.positions_mm.len() != n
        || p.residuals_mm.len() != n
        || Some(p.joints_rad.len()) != n.checked_mul(joint_count)
    {
        return Err(corrupt(
            "the posture term's samples differ from the table's",
        ));
    }
    let plausible = |v: &rkyv::Archived<f64>| v.to_native().abs() <= format::MAX_COORDINATE_MM;
    let values = (p.positions_mm.iter().flatten())
        .chain(p.residuals_mm.iter().flatten())
        .chain(p.joints_rad.iter());
    // Written so that NaN fails the test.
    if !values.into_iter().all(plausible) {
        return Err(corrupt(
            "a posture sample value is not finite or implausible",
        ));
    }
    let grid = crate::posture::posture_grid(header, p);
    let table_max = header.grid.max_mm();
    let covers = (0..3).all(|axis| grid.max_mm()[axis] >= table_max[axis]);
    if !(positive(grid.cell_mm, format::MAX_COORDINATE_MM) && covers) {
        return Err(corrupt("the posture grid does not cover the table's grid"));
    }
    let cells = grid
        .cell_count()
        .filter(|&c| c > 0 && c < u32::MAX as usize)
        .ok_or(corrupt("the posture grid's size is zero or too large"))?;
    let offsets = p.cell_offsets.as_slice();
    if offsets.len() != cells + 1
        || offsets[0].to_native() != 0
        || offsets[cells].to_native() as usize != p.cell_samples.len()
    {
        return Err(corrupt(
            "posture list offsets do not run from 0 to the list entries",
        ));
    }
    let reach_mm = params.radius_mm * (1.0 + 1e-9) + 1e-5;
    for (cell, w) in offsets.windows(2).enumerate() {
        let (start, end) = (w[0].to_native() as usize, w[1].to_native() as usize);
        let list = p
            .cell_samples
            .get(start..end)
            .ok_or(corrupt("posture list offsets are not ascending"))?;
        if list.len() > v3::MAX_POSTURE_CANDIDATES {
            return Err(corrupt("a posture list is longer than a query may read"));
        }
        let (lo, hi) = grid.cell_box(grid.cell_coords(cell));
        let mut previous = None;
        for i in list {
            let i = i.to_native() as usize;
            if i >= n || previous.is_some_and(|prev| prev >= i) {
                return Err(corrupt(
                    "a posture list is not ascending or names a sample that does not exist",
                ));
            }
            previous = Some(i);
            let x = p.positions_mm[i].map(|v| v.to_native());
            let outside_mm2: f64 = (0..3)
                .map(|a| (lo[a] - x[a]).max(x[a] - hi[a]).max(0.0).powi(2))
                .sum();
            if outside_mm2 > reach_mm * reach_mm {
                return Err(corrupt(
                    "a posture list names a sample beyond the support of its cell",
                ));
            }
        }
    }
    Ok(())
}

/// Every cell record: one per cell, of the width the sample count calls for; every
/// candidate an existing sample, listed once; unused slots zero; long lists in bounds.
fn validate_cells(a: &v2::ArchivedTableData, cells: usize, n: usize) -> Result<(), OpenError> {
    let narrow = n <= v2::NARROW_SAMPLES;
    let (narrow_len, wide_len) = if narrow { (cells, 0) } else { (0, cells) };
    if a.cells.len() != narrow_len || a.cells_wide.len() != wide_len {
        return Err(corrupt("cell records differ from the grid size"));
    }
    let overflow = a.overflow.as_slice();
    let mut seen = vec![0u64; n.div_ceil(64)];
    let long_list = |start: usize, count: usize| {
        start
            .checked_add(count)
            .and_then(|end| overflow.get(start..end))
            .ok_or(corrupt("a long candidate list is out of bounds"))
    };
    for record in a.cells.iter() {
        let count = record[0].to_native() as usize;
        if count <= v2::INLINE_CANDIDATES {
            if record[count + 1..].iter().any(|s| s.to_native() != 0) {
                return Err(corrupt("a cell record's unused slots are not zero"));
            }
            check_list(
                &mut seen,
                n,
                record[1..=count].iter().map(|i| i.to_native() as usize),
            )?;
        } else {
            let start = record[1].to_native() as usize | (record[2].to_native() as usize) << 16;
            if record[3..].iter().any(|s| s.to_native() != 0) {
                return Err(corrupt("a cell record's unused slots are not zero"));
            }
            check_list(
                &mut seen,
                n,
                long_list(start, count)?
                    .iter()
                    .map(|i| i.to_native() as usize),
            )?;
        }
    }
    for record in a.cells_wide.iter() {
        let count = record[0].to_native() as usize;
        if count <= v2::INLINE_CANDIDATES_WIDE {
            if record[count + 1..].iter().any(|s| s.to_native() != 0) {
                return Err(corrupt("a cell record's unused slots are not zero"));
            }
            check_list(
                &mut seen,
                n,
                record[1..=count].iter().map(|i| i.to_native() as usize),
            )?;
        } else {
            if record[2..].iter().any(|s| s.to_native() != 0) {
                return Err(corrupt("a cell record's unused slots are not zero"));
            }
            let list = long_list(record[1].to_native() as usize, count)?;
            check_list(&mut seen, n, list.iter().map(|i| i.to_native() as usize))?;
        }
    }
    Ok(())
}

/// Checks one candidate list of a table of `n` samples: indices in range and distinct (a
/// sample listed twice would be selected twice), marking each in `seen` (a bit per sample,
/// all clear), then clearing the marks again by a second pass over the list rather than a
/// list of them (no allocation per cell): `seen` is left clear.
/// Generic over the list, so that each of a table's tens of thousands of lists is read
/// without a call per index.
#[inline]
fn check_list(
    seen: &mut [u64],
    n: usize,
    list: impl Iterator<Item = usize> + Clone,
) -> Result<(), OpenError> {
    let mut result = Ok(());
    let mut marked = 0;
    for i in list.clone() {
        if i >= n {
            result = Err(corrupt(
                "a candidate list names a sample that does not exist",
            ));
            break;
        }
        let (word, bit) = (i / 64, 1u64 << (i % 64));
        if seen[word] & bit != 0 {
            result = Err(corrupt("a candidate list names a sample twice"));
            break;
        }
        seen[word] |= bit;
        marked += 1;
    }
    for i in list.take(marked) {
        seen[i / 64] = 0;
    }
    result
}

/// Every cell's first candidate within ε of the cell's box, as the compiler lists them: a
/// grid edited to another shape or place with the same cell count fails here.
fn validate_cell_reach(header: &Header, a: &v2::ArchivedTableData) -> Result<(), OpenError> {
    let grid = &header.grid;
    // The compiler's box margin and distance slack are micrometres and below.
    let reach_mm = header.method.radius_mm * (1.0 + 1e-9) + 1e-5;
    let first = |cell: usize| -> Option<usize> {
        if let Some(r) = a.cells.get(cell) {
            let count = r[0].to_native() as usize;
            if count == 0 {
                return None;
            }
            if count <= v2::INLINE_CANDIDATES {
                return Some(r[1].to_native() as usize);
            }
            let start = r[1].to_native() as usize | (r[2].to_native() as usize) << 16;
            return a.overflow.get(start).map(|i| i.to_native() as usize);
        }
        let r = a.cells_wide.get(cell)?;
        match r[0].to_native() as usize {
            0 => None,
            count if count <= v2::INLINE_CANDIDATES_WIDE => Some(r[1].to_native() as usize),
            _ => a
                .overflow
                .get(r[1].to_native() as usize)
                .map(|i| i.to_native() as usize),
        }
    };
    for cell in 0..a.cells.len().max(a.cells_wide.len()) {
        let Some(sample) = first(cell) else { continue };
        let Some(s) = a.samples.get(sample) else {
            continue;
        };
        let p = s.actual_mm.map(|v| v.to_native());
        let (lo, hi) = grid.cell_box(grid.cell_coords(cell));
        let outside: f64 = (0..3)
            .map(|axis| {
                (lo[axis] - p[axis])
                    .max(p[axis] - hi[axis])
                    .max(0.0)
                    .powi(2)
            })
            .sum();
        if outside > reach_mm * reach_mm || outside.is_nan() {
            return Err(corrupt(
                "a cell's candidate is beyond ε of the cell: the grid does not match its cells",
            ));
        }
    }
    Ok(())
}

/// The served tier's node sets: as many as the header says, none with a joint screen; the
/// first for targets of unknown configuration, the others for distinct configurations the
/// samples carry; each set's nodes in bounds and every block of nodes some set's; every
/// node value finite or the missing mark,
/// a node's vectors ([`format::ServedField::node_stride`] of them) all one or all the
/// other.
fn validate_nodes(
    header: &Header,
    a: &v2::ArchivedTableData,
    with_orientation: bool,
    with_config: bool,
) -> Result<(), OpenError> {
    let sets = a.node_sets.as_slice();
    if sets.len() != header.node_set_count as usize {
        return Err(corrupt("node set count differs from the header"));
    }
    if sets.is_empty() {
        return if a.node_errors_mm.is_empty() && a.node_orientation_errors_rad.is_empty() {
            Ok(())
        } else {
            Err(corrupt("node values without node sets"))
        };
    }
    if header.joint_radius_rad > 0.0 {
        return Err(corrupt("a served tier in a table with a joint screen"));
    }
    // Also refused with the header; checked here too, as the query relies on it.
    let stride = header.served_field.node_stride();
    if stride > 1 && header.content_flags & CONTENT_MODEL == 0 {
        return Err(corrupt(
            "a tool-axis served field without a kinematic model",
        ));
    }
    let [nx, ny, nz] = header.grid.dims.map(|d| d as usize + 1);
    let per_set = nx * ny * nz;
    let values = a.node_errors_mm.len();
    let set_values = per_set
        .checked_mul(stride)
        .ok_or(corrupt("node values do not fill whole node sets"))?;
    if values % set_values != 0
        || a.node_orientation_errors_rad.len() != if with_orientation { values } else { 0 }
    {
        return Err(corrupt("node values do not fill whole node sets"));
    }
    let nodes = values / stride;
    if sets[0].config != method::CONFIG_UNKNOWN {
        return Err(corrupt(
            "the first node set is not for targets of any configuration",
        ));
    }
    for (i, set) in sets.iter().enumerate() {
        let first = set.first_node.to_native() as usize;
        if first % per_set != 0 || first + per_set > nodes {
            return Err(corrupt("a node set is out of bounds"));
        }
        let repeated = sets[..i].iter().any(|other| other.config == set.config);
        if i > 0 && (repeated || !with_config || set.config == method::CONFIG_UNKNOWN) {
            return Err(corrupt("node sets repeat a configuration"));
        }
        if i > 0 && !a.configs.contains(&set.config) {
            return Err(corrupt("a node set serves a configuration no sample has"));
        }
    }
    // The compiler writes a block of nodes only for a set that uses it. A block no set
    // starts at is what a table whose kind was relabelled to a smaller stride shows.
    if (0..nodes / per_set).any(|b| {
        sets.iter()
            .all(|s| s.first_node.to_native() as usize != b * per_set)
    }) {
        return Err(corrupt("node values that no node set uses"));
    }
    // A node is answered or not as a whole: a query reads all of its vectors.
    let whole_nodes = |values: &[rkyv::Archived<[f64; 3]>]| {
        for node in values.chunks_exact(stride) {
            let mut missing = 0;
            for v in node {
                let v = v.map(|x| x.to_native());
                if crate::served::is_missing(&v) {
                    missing += 1;
                } else if !v.iter().all(|x| x.is_finite()) {
                    return Err(corrupt("a node value is neither finite nor marked missing"));
                }
            }
            if missing != 0 && missing != node.len() {
                return Err(corrupt(
                    "a node's vectors are marked missing in part, not all or none",
                ));
            }
        }
        Ok(())
    };
    whole_nodes(a.node_errors_mm.as_slice())?;
    whole_nodes(a.node_orientation_errors_rad.as_slice())
}
