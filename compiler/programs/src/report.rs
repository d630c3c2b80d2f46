//! What a compensation did to every target, and in sum.

use std::collections::BTreeMap;
use std::fmt::Write;

use adwi_runtime::{Evidence, Residual};

use crate::correct::TargetStatus;

/// One target's line of the report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TargetLine {
    /// Its name, or the instruction writing it inline.
    pub name: String,
    /// 1-based line and column where it is written: in the program, or in its partner
    /// file when `in_partner`.
    pub line: usize,
    /// 1-based column, in bytes.
    pub column: usize,
    /// Whether it is written in the program's partner file (a KRL `.dat`'s `.src`, whose
    /// inline targets and refused motions a `.dat`'s run reports) rather than in the
    /// program: `line` and `column` are then the partner's.
    pub in_partner: bool,
    /// `cartesian` or `joints` (or `incomplete`).
    pub kind: &'static str,
    /// What became of it.
    pub status: TargetStatus,
    /// Why, when it was not corrected (the runtime's status, the joint that jumps).
    pub detail: String,
    /// How far the command's TCP (a joint target's: the table's point) lies from the
    /// target's, mm; for a refused target, the correction that was refused.
    pub correction_mm: Option<f64>,
    /// The rotation between the command's orientation and the target's, degrees.
    pub rotation_deg: Option<f64>,
    /// The largest change of one joint between target and command, degrees (mm for a
    /// prismatic joint), when the postures were solved.
    pub joint_change_deg: Option<f64>,
    /// The table's point at the target, base frame, mm: what the table was asked about.
    pub point_mm: Option<[f64; 3]>,
    /// The table's point at the command, base frame, mm (before the program's rounding).
    pub command_mm: Option<[f64; 3]>,
    /// The command's posture (degrees; mm for prismatic joints), when solved.
    pub command_joints: Option<Vec<f64>>,
    /// Queries the fixed point made.
    pub iterations: u32,
    /// `|command + error(command) − target|` at the command, mm.
    pub residual_mm: Option<f64>,
    /// How much of a hybrid table's residual field the correction held (`full` for a
    /// position-only table), when a command was computed.
    #[serde(serialize_with = "named_residual")]
    pub residual: Option<Residual>,
    /// Where the correction lies beyond the table's evidence, when a command was computed
    /// (a hybrid table's model answering at an orientation its samples never had).
    #[serde(serialize_with = "named_evidence")]
    pub evidence: Option<Evidence>,
}

/// The report: a line per target, in the order the program writes them.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Report {
    /// Per target.
    pub targets: Vec<TargetLine>,
    /// The xxh3-64 hash of the compensated program the report is about, so that a report
    /// and a program from different runs are never taken for a pair.
    pub program_xxh3: Option<u64>,
}

/// The report in figures.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Targets in the program.
    pub total: usize,
    /// Targets corrected.
    pub corrected: usize,
    /// Targets left unchanged, by status.
    pub not_corrected: BTreeMap<&'static str, usize>,
    /// Targets corrected by a hybrid table's model with a faded residual.
    pub faded: usize,
    /// Targets corrected by a hybrid table's model alone.
    pub model_only: usize,
    /// Targets corrected beyond the table's evidence (by a hybrid table's model, or with
    /// `beyond_evidence`).
    pub beyond_evidence: usize,
    /// The largest correction made (mm), and the target it was made to.
    pub largest: Option<(f64, String)>,
}

impl Report {
    /// The counts and the largest correction.
    pub fn summary(&self) -> Summary {
        let mut summary = Summary::default();
        for t in &self.targets {
            summary.add(t);
        }
        summary
    }

    /// The first target not corrected, if any.
    pub fn first_not_corrected(&self) -> Option<&TargetLine> {
        self.targets.iter().find(|t| !t.status.corrected())
    }

    /// The report as CSV: one header, one row per target; the last column,
    /// `program_xxh3`, the compensated program's hash as 16 hex digits (empty when there is
    /// none).
    pub fn to_csv(&self) -> String {
        let mut rows = CsvRows::with_capacity(self.targets.len());
        for t in &self.targets {
            rows.push(t);
        }
        rows.finish(self.program_xxh3)
    }
}

impl Summary {
    /// Counts one more target: a report's summary is its targets added in order, so that
    /// a run that keeps no line still gives the same figures.
    pub fn add(&mut self, t: &TargetLine) {
        self.total += 1;
        if !t.status.corrected() {
            *self.not_corrected.entry(t.status.as_str()).or_default() += 1;
            return;
        }
        self.corrected += 1;
        if let Some(c) = t.correction_mm {
            // The first of equal corrections is the largest.
            if self.largest.as_ref().is_none_or(|(l, _)| c > *l) {
                self.largest = Some((c, t.place()));
            }
        }
        match t.residual {
            Some(Residual::Faded) => self.faded += 1,
            Some(Residual::ModelOnly) => self.model_only += 1,
            _ => {}
        }
        if t.evidence.is_some_and(|e| !e.is_within()) {
            self.beyond_evidence += 1;
        }
    }
}

/// The report's CSV written a row at a time, as the targets are corrected: the compensated
/// program's hash, which ends every row, is known only at the end, so each row is written
/// with a placeholder of the hash's width and the placeholders are filled in by
/// [`CsvRows::finish`]; a long program's report is held as its text alone, some 200 bytes
/// a target, never as its lines as well.
#[derive(Clone, Debug)]
pub struct CsvRows {
    text: String,
    /// Where each row's hash placeholder starts.
    hashes: Vec<usize>,
}

/// The hash's placeholder: as wide as the hash's 16 hex digits.
const HASH_PLACEHOLDER: &str = "################";

impl CsvRows {
    /// The header, with room reserved for `rows` rows.
    pub fn with_capacity(rows: usize) -> CsvRows {
        // About two hundred bytes a row: reserved once, not doubled as the rows come.
        let mut text = String::with_capacity(256 + 224 * rows);
        text.push_str(
            "name,line,column,kind,status,detail,correction_mm,rotation_deg,joint_change_deg,\
             iterations,residual_mm,point_x,point_y,point_z,command_x,command_y,command_z,\
             residual,evidence,program_xxh3\n",
        );
        CsvRows {
            text,
            hashes: Vec::with_capacity(rows),
        }
    }

    /// One target's row.
    pub fn push(&mut self, t: &TargetLine) {
        let opt = |v: Option<f64>, d: usize| v.map_or(String::new(), |v| format!("{v:.d$}"));
        let xyz = |v: Option<[f64; 3]>| {
            v.map_or(",,".to_string(), |p| {
                format!("{:.9},{:.9},{:.9}", p[0], p[1], p[2])
            })
        };
        let _ = write!(
            self.text,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},",
            csv_field(&t.name),
            // A place in the program only: a target written in the partner has none there
            // (its detail names where it is written).
            Blank((!t.in_partner).then_some(t.line)),
            Blank((!t.in_partner).then_some(t.column)),
            t.kind,
            t.status.as_str(),
            csv_field(&t.detail),
            opt(t.correction_mm, 6),
            opt(t.rotation_deg, 6),
            opt(t.joint_change_deg, 6),
            t.iterations,
            t.residual_mm.map_or(String::new(), |v| format!("{v:.3e}")),
            xyz(t.point_mm),
            xyz(t.command_mm),
            t.residual.map_or("", Residual::as_str),
            t.evidence.map_or("", Evidence::as_str),
        );
        self.hashes.push(self.text.len());
        self.text.push_str(HASH_PLACEHOLDER);
        self.text.push('\n');
    }

    /// The CSV, every row ending in the program's hash (16 hex digits; empty when there
    /// is none).
    pub fn finish(mut self, program_xxh3: Option<u64>) -> String {
        match program_xxh3 {
            Some(h) => {
                let hash = format!("{h:016x}");
                // As wide as its placeholder: each is replaced where it stands, nothing
                // after it moves.
                for &at in &self.hashes {
                    self.text
                        .replace_range(at..at + HASH_PLACEHOLDER.len(), &hash);
                }
                self.text
            }
            None => {
                let mut out = String::with_capacity(self.text.len());
                let mut from = 0;
                for &at in &self.hashes {
                    out.push_str(&self.text[from..at]);
                    from = at + HASH_PLACEHOLDER.len();
                }
                out.push_str(&self.text[from..]);
                out
            }
        }
    }
}

impl TargetLine {
    /// Adds `text` to the detail, after what it says already (`; ` between).
    pub fn add_detail(&mut self, text: &str) {
        if !self.detail.is_empty() {
            self.detail.push_str("; ");
        }
        self.detail.push_str(text);
    }

    /// `name (line:column)`; `name (partner line:column)` for a target written in the
    /// program's partner file.
    pub fn place(&self) -> String {
        let partner = if self.in_partner { "partner " } else { "" };
        format!("{} ({partner}{}:{})", self.name, self.line, self.column)
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} of {} targets corrected", self.corrected, self.total)?;
        // A hybrid table's model answers where its residual does not reach.
        if self.faded + self.model_only > 0 {
            write!(
                f,
                " ({} with a faded residual, {} by the calibrated model alone)",
                self.faded, self.model_only
            )?;
        }
        if self.beyond_evidence > 0 {
            write!(
                f,
                "; {} beyond the samples' evidence (an orientation, a TCP or joint angles they never had)",
                self.beyond_evidence
            )?;
        }
        if !self.not_corrected.is_empty() {
            let by: Vec<String> = self
                .not_corrected
                .iter()
                .map(|(s, n)| format!("{n} {s}"))
                .collect();
            write!(f, "; left unchanged: {}", by.join(", "))?;
        }
        if let Some((mm, place)) = &self.largest {
            write!(f, "; largest correction {mm:.4} mm at {place}")?;
        }
        Ok(())
    }
}

/// A residual's flag by the name the CSV gives it.
fn named_residual<S: serde::Serializer>(r: &Option<Residual>, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_some(&r.map(Residual::as_str))
}

/// An evidence by the name the CSV gives it.
fn named_evidence<S: serde::Serializer>(e: &Option<Evidence>, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_some(&e.map(Evidence::as_str))
}

/// A number, or an empty field where there is none.
struct Blank(Option<usize>);

impl std::fmt::Display for Blank {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(v) => write!(f, "{v}"),
            None => Ok(()),
        }
    }
}

/// A CSV field, quoted when it holds a comma, a quote or a line end.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(status: TargetStatus, residual: Option<Residual>) -> TargetLine {
        TargetLine {
            name: "P".into(),
            line: 1,
            column: 1,
            in_partner: false,
            kind: "cartesian",
            status,
            detail: String::new(),
            correction_mm: residual.map(|_| 1.0),
            rotation_deg: None,
            joint_change_deg: None,
            point_mm: None,
            command_mm: None,
            command_joints: None,
            iterations: 1,
            residual_mm: None,
            residual,
            evidence: None,
        }
    }

    #[test]
    fn the_summary_counts_targets_corrected_by_the_model_alone_or_a_faded_residual() {
        let report = Report {
            targets: vec![
                line(TargetStatus::Ok, Some(Residual::Full)),
                line(TargetStatus::Ok, Some(Residual::Faded)),
                line(TargetStatus::Ok, Some(Residual::ModelOnly)),
                line(TargetStatus::Ok, Some(Residual::ModelOnly)),
                line(TargetStatus::IkFailed, None),
            ],
            program_xxh3: Some(0xab),
        };
        let summary = report.summary();
        assert_eq!(
            (summary.corrected, summary.faded, summary.model_only),
            (4, 1, 2)
        );
        assert!(
            summary.to_string().starts_with(
                "4 of 5 targets corrected (1 with a faded residual, 2 by the calibrated model \
                 alone); left unchanged: 1 ik_failed"
            ),
            "{summary}"
        );
        let csv = report.to_csv();
        let rows: Vec<&str> = csv.lines().collect();
        assert!(rows[0].ends_with(",command_z,residual,evidence,program_xxh3"));
        let flags: Vec<&str> = rows[1..]
            .iter()
            .map(|r| r.rsplit(',').nth(2).unwrap())
            .collect();
        assert_eq!(flags, ["full", "faded", "model_only", "model_only", ""]);
        assert!(rows[1..].iter().all(|r| r.ends_with(",00000000000000ab")));
    }
}
