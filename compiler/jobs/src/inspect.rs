//! The inspect job: a table's header, parameters, counts and sizes, and one cell in
//! detail (`tablec inspect`).

use std::path::PathBuf;

use adwi_compile::inspect::{CellDetail, Summary};
use adwi_runtime::format::{
    Header, ServedField, CONTENT_CONFIG, CONTENT_JOINTS, CONTENT_MODEL, CONTENT_ORIENTATION,
    HEADER_LEN,
};
use adwi_runtime::posture::PostureParams;
use adwi_runtime::{Table, Target};
use memmap2::Mmap;
use serde::{Deserialize, Serialize, Serializer};

use crate::inputs::open_table;
use crate::JobError;

/// What a table holds: every option of `tablec inspect`.
#[derive(clap::Args, Deserialize, Debug, Clone, Default)]
#[serde(default)]
pub struct InspectArgs {
    /// The table.
    pub table: PathBuf,
    /// Also print the cell holding X Y Z: its candidates, its node values and the exact
    /// method's neighbours and weights at the point.
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_negative_numbers = true)]
    pub cell: Option<Vec<f64>>,
}

/// An inspection checked, its table open, ready to run.
pub struct InspectJob {
    path: PathBuf,
    cell_mm: Option<[f64; 3]>,
    table: Table<Mmap>,
}

/// What a table holds.
#[derive(Debug, Clone, Serialize)]
pub struct Inspected {
    /// The table, as given.
    pub file: PathBuf,
    /// Its size, bytes (header and payload).
    pub size_bytes: u64,
    /// Its header, as stored.
    #[serde(serialize_with = "header")]
    pub header: Header,
    /// What each sample carries (`positions`, `orientations`, `configurations`, `joint
    /// values`, and the kinematic model of a hybrid table).
    pub content: Vec<&'static str>,
    /// The joints of its robot, when it records joint values or a model.
    pub joints: Option<usize>,
    /// A hybrid table's calibrated model: what it answers with joint values.
    pub hybrid: bool,
    /// The calibrated model's gravity compliance, when it has one.
    pub compliance: Option<ComplianceFigures>,
    /// The calibrated model's joint-space terms, each joint that has one.
    pub joint_terms: Vec<JointTerm>,
    /// Per joint the commanded angles the samples span, degrees, when they bound the
    /// residual (format version 6): beyond them it fades, to none 3° past. `None` for a
    /// joint they do not bound (a prismatic one).
    pub residual_joint_range_deg: Option<Vec<Option<[f64; 2]>>>,
    /// The posture term of the served field, when the table has one.
    #[serde(serialize_with = "posture")]
    pub posture: Option<PostureParams>,
    /// Counts, coverage and the size of every section.
    pub summary: Summary,
    /// The cell asked for (`--cell`).
    pub cell: Option<CellAt>,
}

/// A calibrated model's gravity compliance.
#[derive(Debug, Clone, Serialize)]
pub struct ComplianceFigures {
    /// Per joint, µrad/(N·m).
    pub urad_per_nm: Vec<f64>,
    /// The load at the flange, kg.
    pub payload_kg: f64,
    /// Its centre of mass in the tool frame, mm.
    pub payload_com_mm: [f64; 3],
}

/// One joint's joint-space term.
#[derive(Debug, Clone, Serialize)]
pub struct JointTerm {
    /// The joint, from 1.
    pub joint: usize,
    /// The coefficients of sin q, cos q, sin 2q, cos 2q, mrad.
    pub coefficients_mrad: [f64; 4],
    /// The commanded angles the terms were identified from, degrees: beyond them a term is
    /// held.
    pub range_deg: [f64; 2],
}

/// The cell asked for.
#[derive(Debug, Clone, Serialize)]
pub struct CellAt {
    /// The point given, mm.
    pub at_mm: [f64; 3],
    /// The cell holding it; `None` outside the grid.
    pub detail: Option<CellDetail>,
    /// The exact method's neighbours at the point, with their weights (none where it
    /// gives no answer).
    pub neighbours: Vec<NeighbourAt>,
}

/// One neighbour of the exact method at a point.
#[derive(Debug, Clone, Serialize)]
pub struct NeighbourAt {
    /// The sample's index.
    pub sample: u32,
    /// Its distance from the point, mm.
    pub distance_mm: f64,
    /// λ, 1/mm.
    pub lambda_per_mm: f64,
    /// ζ, 1/mm².
    pub zeta_per_mm2: f64,
    /// Its weight q.
    pub weight: f64,
}

impl InspectJob {
    /// Checks the point (three finite coordinates), then opens the table.
    ///
    /// # Errors
    ///
    /// [`JobError::Options`], [`JobError::Table`].
    pub fn new(args: InspectArgs) -> Result<InspectJob, JobError> {
        let cell_mm = match &args.cell {
            None => None,
            Some(p) => match p[..] {
                [x, y, z] if p.iter().all(|v| v.is_finite()) => Some([x, y, z]),
                _ => {
                    return Err(JobError::option(
                        "cell",
                        format!("{p:?}: give three finite coordinates X Y Z, mm"),
                    ))
                }
            },
        };
        let table = open_table(&args.table)?;
        Ok(InspectJob {
            path: args.table,
            cell_mm,
            table,
        })
    }

    /// Reads the table's figures.
    ///
    /// # Errors
    ///
    /// [`JobError::TableChanged`] when its bytes changed after it was validated.
    pub fn run(self) -> Result<Inspected, JobError> {
        let table = &self.table;
        let header = *table.header();
        let summary = adwi_compile::inspect::summary(table).ok_or(JobError::TableChanged)?;
        Ok(Inspected {
            file: self.path.clone(),
            size_bytes: HEADER_LEN as u64 + header.payload_len,
            header,
            content: content(header.content_flags),
            joints: table.joint_count(),
            hybrid: table.is_hybrid(),
            compliance: compliance(table),
            joint_terms: joint_terms(table),
            residual_joint_range_deg: residual_joint_range(table),
            posture: table.posture(),
            summary,
            cell: self.cell_mm.map(|p| cell_at(table, p)),
        })
    }
}

/// What each sample carries, by the header's content flags.
fn content(flags: u32) -> Vec<&'static str> {
    let mut content = vec!["positions"];
    for (flag, name) in [
        (CONTENT_ORIENTATION, "orientations"),
        (CONTENT_CONFIG, "configurations"),
        (CONTENT_JOINTS, "joint values"),
        (
            CONTENT_MODEL,
            "kinematic model: hybrid table, query with joint values",
        ),
    ] {
        if flags & flag != 0 {
            content.push(name);
        }
    }
    content
}

/// The calibrated model's compliance, per joint in µrad/(N·m).
fn compliance(table: &Table<Mmap>) -> Option<ComplianceFigures> {
    let c = table.model().and_then(|m| m.calibrated().compliance)?;
    let n = table.joint_count().unwrap_or(0);
    Some(ComplianceFigures {
        urad_per_nm: c.compliance[..n]
            .iter()
            .map(|v| v / adwi_robot::model::URAD_PER_NM)
            .collect(),
        payload_kg: c.payload_kg,
        payload_com_mm: c.payload_com_mm,
    })
}

/// The joints whose joint-space term is not zero.
fn joint_terms(table: &Table<Mmap>) -> Vec<JointTerm> {
    let Some(terms) = table
        .model()
        .map(|m| m.joint_terms())
        .filter(|t| !t.is_none())
    else {
        return Vec::new();
    };
    let n = table.joint_count().unwrap_or(0);
    terms.coefficients_rad[..n]
        .iter()
        .zip(terms.range_rad)
        .enumerate()
        .filter(|(_, (c, _))| c.iter().any(|&v| v != 0.0))
        .map(|(j, (c, [lo, hi]))| JointTerm {
            joint: j + 1,
            coefficients_mrad: c.map(|v| v * 1e3),
            range_deg: [lo.to_degrees(), hi.to_degrees()],
        })
        .collect()
}

/// The angles the samples span, degrees, where they bound the residual.
fn residual_joint_range(table: &Table<Mmap>) -> Option<Vec<Option<[f64; 2]>>> {
    let model = table.model().filter(|m| m.bounds_residual())?;
    let n = table.joint_count().unwrap_or(0);
    Some(ranges_deg(&model.joint_terms().range_rad[..n]))
}

/// Recorded joint ranges (rad, unbounded for a joint they do not bound) in degrees, `None`
/// where unbounded: what `inspect` and a build's report say.
pub fn ranges_deg(ranges_rad: &[[f64; 2]]) -> Vec<Option<[f64; 2]>> {
    (ranges_rad.iter())
        .map(|&[lo, hi]| {
            (lo.is_finite() && hi.is_finite()).then(|| [lo.to_degrees(), hi.to_degrees()])
        })
        .collect()
}

/// The cell holding `p`, and the exact method's neighbours there.
fn cell_at(table: &Table<Mmap>, p: [f64; 3]) -> CellAt {
    let detail = adwi_compile::inspect::cell(table, p);
    let neighbours = match (&detail, table.explain(&Target::at(p))) {
        (Some(_), Ok(pred)) => pred
            .neighbours
            .as_slice()
            .iter()
            .zip(pred.weights.as_slice())
            .map(|(n, &weight)| NeighbourAt {
                sample: n.sample,
                distance_mm: n.degree.distance_mm,
                lambda_per_mm: n.degree.lambda_per_mm,
                zeta_per_mm2: n.degree.zeta_per_mm2,
                weight,
            })
            .collect(),
        _ => Vec::new(),
    };
    CellAt {
        at_mm: p,
        detail,
        neighbours,
    }
}

/// The header's fields by name; the served field by the name its option takes.
fn header<S: Serializer>(h: &Header, s: S) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Method {
        radius_mm: f64,
        max_neighbours: u32,
        w1: f64,
        w2: f64,
        power: f64,
        lambda_min_per_mm: f64,
        zeta_min_per_mm2: f64,
        consistency_screen: bool,
    }
    #[derive(Serialize)]
    struct Grid {
        origin_mm: [f64; 3],
        cell_mm: f64,
        dims: [u32; 3],
    }
    #[derive(Serialize)]
    struct Tuning {
        folds: u32,
        cv_mean_mm: f64,
        served_cv_mean_mm: Option<f64>,
        posture_cv_mean_mm: Option<f64>,
    }
    #[derive(Serialize)]
    struct Approach {
        axis: [f64; 3],
        spread_rad: f64,
    }
    #[derive(Serialize)]
    struct Evidence {
        approach: Option<Approach>,
        point_in_flange_mm: Option<[f64; 3]>,
    }
    #[derive(Serialize)]
    struct Fields {
        version: u16,
        rkyv_flags: u32,
        content_flags: u32,
        payload_bytes: u64,
        payload_checksum: u64,
        source_hash: u64,
        method: Method,
        grid: Grid,
        sample_count: u32,
        joint_radius_rad: f64,
        joint_count: u32,
        node_set_count: u32,
        tuning: Option<Tuning>,
        served_field: &'static str,
        evidence: Evidence,
        /// Absent for a table holding every measured sample, as before the field was.
        #[serde(skip_serializing_if = "Option::is_none")]
        merge_voxel_mm: Option<f64>,
    }
    let m = h.method;
    Fields {
        version: h.version,
        rkyv_flags: h.rkyv_flags,
        content_flags: h.content_flags,
        payload_bytes: h.payload_len,
        payload_checksum: h.payload_checksum,
        source_hash: h.source_hash,
        method: Method {
            radius_mm: m.radius_mm,
            max_neighbours: m.max_neighbours,
            w1: m.w1,
            w2: m.w2,
            power: m.power,
            lambda_min_per_mm: m.lambda_min_per_mm,
            zeta_min_per_mm2: m.zeta_min_per_mm2,
            consistency_screen: m.consistency_screen,
        },
        grid: Grid {
            origin_mm: h.grid.origin_mm,
            cell_mm: h.grid.cell_mm,
            dims: h.grid.dims,
        },
        sample_count: h.sample_count,
        joint_radius_rad: h.joint_radius_rad,
        joint_count: h.joint_count,
        node_set_count: h.node_set_count,
        tuning: h.tuning.map(|t| Tuning {
            folds: t.folds,
            cv_mean_mm: t.cv_mean_mm,
            served_cv_mean_mm: t.served_cv_mean_mm,
            posture_cv_mean_mm: t.posture_cv_mean_mm,
        }),
        served_field: match h.served_field {
            ServedField::KrigingToolAxis => "kriging",
            other => other.name(),
        },
        evidence: Evidence {
            approach: h.evidence.approach.map(|a| Approach {
                axis: a.axis,
                spread_rad: a.spread_rad,
            }),
            point_in_flange_mm: h.evidence.point_in_flange.map(|p| p.translation_mm),
        },
        merge_voxel_mm: h.merge_voxel_mm,
    }
    .serialize(s)
}

/// A posture term's parameters by name.
fn posture<S: Serializer>(p: &Option<PostureParams>, s: S) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Posture {
        radius_mm: f64,
        length_rad: f64,
        floor: f64,
    }
    p.map(|p| Posture {
        radius_mm: p.radius_mm,
        length_rad: p.length_rad,
        floor: p.floor,
    })
    .serialize(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point that is not three finite coordinates is refused as an option before the
    /// table is read (it does not exist here); a missing table is named.
    #[test]
    fn the_point_is_refused_before_the_table_is_opened() {
        for cell in [vec![1.0, 2.0], vec![f64::NAN, 0.0, 0.0], vec![0.0; 4]] {
            let e = InspectJob::new(InspectArgs {
                table: "/nonexistent/t.tbl".into(),
                cell: Some(cell),
            })
            .err()
            .unwrap();
            assert!(matches!(e, JobError::Options(_)), "{e}");
        }
        let e = InspectJob::new(InspectArgs {
            table: "/nonexistent/t.tbl".into(),
            cell: Some(vec![0.0, 0.0, 0.0]),
        })
        .err()
        .unwrap();
        assert!(matches!(e, JobError::Table { .. }), "{e}");
    }
}
