//! Step 5 of opening a table ([`crate::Table::from_bytes`]): the table's own invariants,
//! checked once after rkyv has proven the archive memory-safe, so that no query can meet
//! an index out of range, a non-finite value or a parameter out of its domain.

use crate::format::{
    self, ArchivedTableData, Header, CONTENT_CONFIG, CONTENT_JOINTS, CONTENT_KNOWN, CONTENT_MODEL,
    CONTENT_ORIENTATION,
};
use crate::method;
use crate::OpenError;

fn corrupt(what: &'static str) -> OpenError {
    OpenError::Corrupt { what }
}

/// The semantic checks of step 5 of [`Table::from_bytes`].
pub(crate) fn validate(header: &Header, a: &ArchivedTableData) -> Result<(), OpenError> {
    header.method.validate().map_err(corrupt)?;
    if header.content_flags & !CONTENT_KNOWN != 0 {
        return Err(corrupt(
            "the content flags name contents this version does not know",
        ));
    }
    let grid = &header.grid;
    let cells = grid
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
        grid,
        header.joint_radius_rad,
        samples_box_mm,
    )
    .map_err(OpenError::Implausible)?;
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
    let k = header.method.max_neighbours as usize;
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
    let radius_squared_mm2 = header.method.radius_mm * header.method.radius_mm;
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
            let list_samples = &a.list_samples[list.clone()];
            if list_samples.iter().any(|&i| i.to_native() as usize >= n) {
                return Err(corrupt(
                    "a candidate list names a sample that does not exist",
                ));
            }
            // A sample listed twice would be selected twice.
            for i in list_samples {
                let i = i.to_native() as usize;
                let (word, bit) = (i / 64, 1u64 << (i % 64));
                if seen[word] & bit != 0 {
                    return Err(corrupt("a candidate list names a sample twice"));
                }
                seen[word] |= bit;
            }
            list_samples
                .iter()
                .for_each(|i| seen[i.to_native() as usize / 64] = 0);
            checked_list = Some(list);
        }
        let centre = centre_range[0].to_native() as usize..centre_range[1].to_native() as usize;
        if centre.len() > k {
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
            if key > radius_squared_mm2 || key.is_nan() {
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
    }
    Ok(())
}
