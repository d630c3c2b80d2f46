//! Assembling a table: the candidate lists encoded into cell records (inline, or in the
//! overflow array), the served field's nodes, the samples and the model, into the
//! version-2 payload and its header; the table is opened once as the runtime will before
//! its bytes are returned.

use adwi_runtime::format::{
    self, v2, Header, CONTENT_CONFIG, CONTENT_JOINTS, CONTENT_MODEL, CONTENT_ORIENTATION,
};
use adwi_runtime::method;
use adwi_runtime::model::PreparedModel;

use super::candidates::candidate_lists;
use super::nodes::{node_cells, serving_nodes, NodeField, NodeValues};
use super::{BuildError, BuildReport, Plan, Queried, ServedField};
use adwi_samples::SampleSet;

/// Compiles `samples` into table bytes as `plan` (from [`super::plan()`] over the same samples, or
/// the measured ones of a hybrid table) says. With a kinematic `model`, `samples` hold the
/// residuals the model leaves and `source_hash` identifies the measured samples they were
/// derived from ([`crate::hybrid`] builds hybrid tables through this).
///
/// # Errors
///
/// An implausible model, an encoding failure.
pub fn compile_plan(
    samples: &SampleSet,
    plan: &Plan,
    model: Option<&PreparedModel>,
    source_hash: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    compile_plan_serving(
        samples,
        plan,
        model,
        source_hash,
        Queried::Anywhere,
        progress,
    )
}

/// [`compile_plan`] computing only what a table `queried` there needs. Samples the plan merges
/// ([`Plan::merge`]) are merged first: both tiers answer from the voxel averages.
///
/// # Errors
///
/// As [`compile_plan`].
pub fn compile_plan_serving(
    samples: &SampleSet,
    plan: &Plan,
    model: Option<&PreparedModel>,
    source_hash: u64,
    queried: Queried<'_>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<u8>, BuildReport), BuildError> {
    let compiled = compile_plan_values(samples, plan, model, source_hash, queried, progress)?;
    Ok((compiled.bytes, compiled.report))
}

/// A table compiled in memory: the bytes of its file, and the header and payload they
/// encode, kept as values so that a later stage (the posture term, [`crate::posture`])
/// extends the table without decoding its own output.
pub(crate) struct Compiled {
    /// The table file's bytes, opened once as the runtime will when `opened`.
    pub bytes: Vec<u8>,
    /// Whether the build opens its tables to check them ([`Queried::opened_by_build`]).
    pub opened: bool,
    /// The header the bytes begin with (its payload length and checksum as written).
    pub header: Header,
    /// The version-2 payload (the base of a version-5 one with joint-space terms).
    pub data: v2::TableData,
    /// The joint count the header records.
    pub joint_count: usize,
    /// The build's figures.
    pub report: BuildReport,
}

/// [`compile_plan_serving`], the table's values kept beside its bytes.
pub(crate) fn compile_plan_values(
    samples: &SampleSet,
    plan: &Plan,
    model: Option<&PreparedModel>,
    source_hash: u64,
    queried: Queried<'_>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Compiled, BuildError> {
    let merged;
    let samples = match plan.merge {
        Some(m) => {
            merged = super::merge::merge(samples, m.voxel_mm);
            &merged
        }
        None => samples,
    };
    let joint_count = checked_joint_count(samples, plan, model)?;
    let mut report = BuildReport {
        plan: *plan,
        cells_covered: 0,
        distinct_lists: 0,
        list_entries: 0,
        max_list_len: 0,
        mean_list_len: 0.0,
        table_bytes: 0,
        served_cells: 0,
        node_sets: 0,
        served_kriging: Vec::new(),
        posture: None,
        residual_joint_range_rad: match model {
            Some(m) => m.joint_terms().range_rad[..joint_count].to_vec(),
            None => Vec::new(),
        },
    };
    let joint_screen = plan.joint_radius_rad > 0.0;
    let records = samples.records();
    let kriging = !joint_screen && plan.served_field != ServedField::Method;
    let (nodes, cells) = computed(&plan.grid, queried, kriging);
    let lists = candidate_lists(
        &records,
        &plan.params,
        joint_screen,
        &plan.grid,
        cells.as_deref(),
        progress,
    );
    let mut data = exact_tier(samples, &records, &lists, model, joint_screen, &mut report);
    // The served tier: the exact method at every node, one set per target configuration
    // (none with a joint screen: its admissible samples depend on the joint values).
    if !joint_screen {
        served_tier(
            samples,
            &records,
            &lists,
            plan,
            model,
            nodes.as_deref(),
            &mut data,
            &mut report,
        )?;
    }
    drop((lists, records));
    let header = header(
        samples,
        plan,
        model,
        source_hash,
        joint_count,
        &data,
        &report,
    );
    let opened = queried.opened_by_build();
    let (bytes, data) = encode(header, data, model, joint_count, opened)?;
    report.table_bytes = bytes.len();
    Ok(Compiled {
        bytes,
        opened,
        header,
        data,
        joint_count,
        report,
    })
}

/// What a table `queried` there computes: a flag per node of a set ([`serving_nodes`])
/// and per cell (its candidate list), or `None` for all. A cell's list is computed where a
/// position of either tier lies (a table without a served tier answers its served queries
/// from it) and where a computed node of the method's field is a corner (its value is
/// computed from one of them). A kriging field computing some nodes needs every list: a
/// local kriging fits a block of nodes around the centre of those the samples reach,
/// computed or not, and whether a node is reached is read from its cells' lists.
fn computed(
    grid: &format::Grid,
    queried: Queried<'_>,
    kriging: bool,
) -> (Option<Vec<bool>>, Option<Vec<bool>>) {
    let Queried::At { served, exact } = queried else {
        return (None, None);
    };
    let nodes = serving_nodes(grid, served);
    if kriging && nodes.iter().any(|&n| n) {
        return (Some(nodes), None);
    }
    let mut cells = vec![false; grid.cell_count().unwrap_or(0)];
    for p in served.iter().chain(exact) {
        if let Some(cell) = grid.cell_of(*p) {
            cells[cell] = true;
        }
    }
    for (node, _) in nodes.iter().enumerate().filter(|(_, &n)| n) {
        for cell in node_cells(grid, node) {
            cells[cell] = true;
        }
    }
    (Some(nodes), Some(cells))
}

/// The checks a model and the samples' joint values must pass before any work: a model's
/// chains plausible, its joint count the samples', a posture term only with a model. The
/// joint count the header records (the samples', else the model's, else 0).
fn checked_joint_count(
    samples: &SampleSet,
    plan: &Plan,
    model: Option<&PreparedModel>,
) -> Result<usize, BuildError> {
    if model.is_none() && plan.posture != crate::posture::Posture::Off {
        return Err(BuildError::PostureWithoutModel);
    }
    if let Some(model) = model {
        for chain in [model.nominal(), model.calibrated()] {
            format::check_chain_plausible(chain)?;
        }
    }
    match (&samples.joints, model) {
        (Some(j), Some(m)) if j.count() != m.joint_count() => Err(BuildError::JointCount {
            model: m.joint_count(),
            samples: j.count(),
        }),
        (Some(j), _) => Ok(j.count()),
        (None, Some(m)) => Ok(m.joint_count()),
        (None, None) => Ok(0),
    }
}

/// The exact tier's part of the payload: the samples, their errors, the candidate lists in
/// their cell records (narrow or wide by the sample count) and the model; the lists'
/// figures go to `report`.
fn exact_tier(
    samples: &SampleSet,
    records: &[format::SampleRecord],
    lists: &[Vec<u32>],
    model: Option<&PreparedModel>,
    joint_screen: bool,
    report: &mut BuildReport,
) -> v2::TableData {
    let mut data = v2::TableData {
        samples: records
            .iter()
            .map(|r| v2::QuerySample {
                actual_mm: r.actual_mm,
                norm_mm: method::norm_mm(r.actual_mm),
            })
            .collect(),
        errors_mm: samples.error_mm.clone(),
        orientation_errors_rad: samples.rotation_error_rad.clone().unwrap_or_default(),
        configs: samples.config.clone().unwrap_or_default(),
        joints_rad: match (&samples.joints, joint_screen) {
            (Some(j), true) => j.as_flat().to_vec(),
            _ => Vec::new(),
        },
        model: model.map(|m| v2::ModelRecord {
            nominal: v2::ChainRecord::from_chain(m.nominal()),
            calibrated: v2::ChainRecord::from_chain(m.calibrated()),
        }),
        ..v2::TableData::default()
    };
    let narrow = records.len() <= v2::NARROW_SAMPLES;
    // Sized before: grown by doubling, a fine grid's records were copied and their pages
    // touched afresh several times over.
    if narrow {
        data.cells.reserve_exact(lists.len());
    } else {
        data.cells_wide.reserve_exact(lists.len());
    }
    // Counted for the report only: a fast hash, since a fine grid has a million lists.
    let mut distinct = rustc_hash::FxHashSet::default();
    for list in lists {
        if narrow {
            data.cells.push(narrow_record(list, &mut data.overflow));
        } else {
            data.cells_wide.push(wide_record(list, &mut data.overflow));
        }
        if !list.is_empty() {
            report.cells_covered += 1;
            report.max_list_len = report.max_list_len.max(list.len());
            report.mean_list_len += list.len() as f64;
            report.list_entries += list.len();
            distinct.insert(list.as_slice());
        }
    }
    report.mean_list_len /= report.cells_covered.max(1) as f64;
    report.distinct_lists = distinct.len();
    data
}

/// The served tier's nodes into `data` (those flagged in `nodes`, all without), and their figures and
/// the field written into `report`.
#[allow(clippy::too_many_arguments)]
fn served_tier(
    samples: &SampleSet,
    records: &[format::SampleRecord],
    lists: &[Vec<u32>],
    plan: &Plan,
    model: Option<&PreparedModel>,
    nodes: Option<&[bool]>,
    data: &mut v2::TableData,
    report: &mut BuildReport,
) -> Result<(), BuildError> {
    let field = NodeField::new(plan.served_field, plan.kriging_choices, samples, model)?;
    let served = NodeValues::compute(
        records,
        &plan.params,
        &plan.grid,
        lists,
        samples,
        &field,
        nodes,
    )?;
    report.node_sets = served.sets.len();
    report.served_cells = served.served_cells(&plan.grid);
    report.served_kriging = served.kriging_choices;
    // The kind written: a kriging turns with the tool only where the likelihood says.
    report.plan.served_field = served.served_field;
    data.node_sets = served.sets;
    data.node_errors_mm = served.position_mm;
    if samples.rotation_error_rad.is_some() {
        data.node_orientation_errors_rad = served.orientation_rad;
    }
    Ok(())
}

/// The table's header: what the samples carry, the plan's parameters and grid, the served
/// field written, the evidence, and the merge.
fn header(
    samples: &SampleSet,
    plan: &Plan,
    model: Option<&PreparedModel>,
    source_hash: u64,
    joint_count: usize,
    data: &v2::TableData,
    report: &BuildReport,
) -> Header {
    let joint_screen = plan.joint_radius_rad > 0.0;
    let mut content = 0;
    if samples.rotation_error_rad.is_some() {
        content |= CONTENT_ORIENTATION;
    }
    if samples.config.is_some() {
        content |= CONTENT_CONFIG;
    }
    if joint_screen {
        content |= CONTENT_JOINTS;
    }
    if data.model.is_some() {
        content |= CONTENT_MODEL;
    }
    Header {
        version: format::FORMAT_VERSION,
        rkyv_flags: format::RKYV_FLAGS,
        content_flags: content,
        payload_len: 0,
        payload_checksum: 0,
        source_hash,
        method: plan.params,
        grid: plan.grid,
        sample_count: samples.len() as u32,
        joint_radius_rad: plan.joint_radius_rad,
        joint_count: if joint_screen || model.is_some() {
            joint_count as u32
        } else {
            0
        },
        node_set_count: data.node_sets.len() as u32,
        tuning: plan.tuning,
        served_field: if data.node_sets.is_empty() {
            ServedField::Method
        } else {
            report.plan.served_field
        },
        evidence: evidence(samples, model, plan.point_in_flange),
        merge_voxel_mm: plan.merge.map(|m| m.voxel_mm),
    }
}

/// The table's bytes: a version-6 payload for a hybrid table (its model's joint record),
/// else the version-2 one (version 4 when the header records evidence or a merge); opened
/// once as the runtime will when `open` ([`Queried::opened_by_build`]), so that a table the
/// runtime refuses is never written.
fn encode(
    header: Header,
    data: v2::TableData,
    model: Option<&PreparedModel>,
    joint_count: usize,
    open: bool,
) -> Result<(Vec<u8>, v2::TableData), BuildError> {
    let (bytes, data) = match model {
        Some(m) => {
            let data = format::v5::TableData {
                base: data,
                joint_terms: joint_terms_record(m, joint_count),
                ..format::v5::TableData::default()
            };
            (format::encode_v6(header, &data, false), data.base)
        }
        None => (format::encode(header, &data), data),
    };
    let bytes = bytes.map_err(|e| BuildError::Encode(e.to_string()))?;
    if open {
        check_opens(&bytes)?;
    }
    Ok((bytes, data))
}

/// Opens a compiled table's bytes as the runtime will, and refuses them if it would:
/// validated where they are when they start where the archive must (the system
/// allocator's blocks do), rather than copied (a table is tens of megabytes).
///
/// # Errors
///
/// [`BuildError::Unopenable`]: the compiler wrote what the runtime refuses (a bug).
pub(crate) fn check_opens(bytes: &[u8]) -> Result<(), BuildError> {
    if bytes.as_ptr().align_offset(format::PAYLOAD_ALIGN) == 0 {
        adwi_runtime::Table::from_bytes(bytes).map_err(BuildError::Unopenable)?;
    } else {
        adwi_runtime::Table::from_vec(bytes).map_err(BuildError::Unopenable)?;
    }
    Ok(())
}

/// The model's joint record as a version-6 table holds it: its joint-space terms (zero
/// when it has none) and their ranges, the angles the samples span
/// ([`crate::hybrid::bounded_by_samples`]).
pub(crate) fn joint_terms_record(
    model: &PreparedModel,
    joint_count: usize,
) -> format::v5::JointTermsRecord {
    format::v5::JointTermsRecord::from_terms(model.joint_terms(), joint_count)
}

/// What the samples span beyond their positions ([`format::EvidenceRecord`]): the cone of
/// the tool's approach axes, from the model's nominal chain at each sample's joint values
/// (a hybrid table: the axis its queries compare) or else from the samples' own nominal
/// orientations; and where the measured point is on the flange, when known.
fn evidence(
    samples: &SampleSet,
    model: Option<&PreparedModel>,
    point_in_flange: Option<format::PointInFlange>,
) -> format::EvidenceRecord {
    let from_joints = model.and_then(|m| {
        (0..samples.len())
            .map(|i| m.approach_axis(samples.joints_rad(i)?))
            .collect::<Option<Vec<_>>>()
    });
    let axes = from_joints.or_else(|| {
        let rotations = samples.nominal_rotation.as_ref()?;
        Some(
            rotations
                .iter()
                .map(|r| {
                    let m = r.matrix();
                    [m[(0, 2)], m[(1, 2)], m[(2, 2)]]
                })
                .collect(),
        )
    });
    format::EvidenceRecord {
        approach: axes.and_then(format::ApproachCone::of),
        point_in_flange,
    }
}

/// A narrow cell record ([`v2::CellRecord`]): the list inline, or its start in `overflow`.
fn narrow_record(list: &[u32], overflow: &mut Vec<u32>) -> v2::CellRecord {
    let mut record = [0u16; 32];
    record[0] = list.len() as u16;
    if list.len() <= v2::INLINE_CANDIDATES {
        for (slot, &i) in record[1..].iter_mut().zip(list) {
            *slot = i as u16;
        }
    } else {
        let start = overflow.len() as u32;
        record[1] = start as u16;
        record[2] = (start >> 16) as u16;
        overflow.extend_from_slice(list);
    }
    record
}

/// A wide cell record ([`v2::WideCellRecord`]), as [`narrow_record`].
fn wide_record(list: &[u32], overflow: &mut Vec<u32>) -> v2::WideCellRecord {
    let mut record = [0u32; 16];
    record[0] = list.len() as u32;
    if list.len() <= v2::INLINE_CANDIDATES_WIDE {
        record[1..=list.len()].copy_from_slice(list);
    } else {
        record[1] = overflow.len() as u32;
        overflow.extend_from_slice(list);
    }
    record
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::fixtures::samples;
    use crate::build::{plan, BuildOptions};

    #[test]
    fn an_implausible_model_is_refused() {
        use adwi_runtime::chain::Chain;
        use adwi_runtime::kinematics::{MdhJoint, Transform};
        let s = samples("");
        let joint = MdhJoint {
            a_mm: 100.0,
            d_mm: 200.0,
            ..MdhJoint::default()
        };
        let chain = |base: Transform| {
            Chain::from_mdh(base, &[joint; 6], Transform::IDENTITY, None).unwrap()
        };
        let nominal = chain(Transform::IDENTITY);
        let plan = plan(&s, &BuildOptions::default()).unwrap();
        let hash = s.source_hash();
        let sound = PreparedModel::new(nominal, nominal).unwrap();
        compile_plan(&s, &plan, Some(&sound), hash, &|_| {}).unwrap();
        let far = Transform {
            translation_mm: [1e300, 0.0, 0.0],
            ..Transform::IDENTITY
        };
        let model = PreparedModel::new(nominal, chain(far)).unwrap();
        let err = compile_plan(&s, &plan, Some(&model), hash, &|_| {}).unwrap_err();
        assert!(matches!(err, BuildError::Implausible(_)), "{err}");
    }
}
