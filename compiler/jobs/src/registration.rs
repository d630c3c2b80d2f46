//! A registration of tracker-frame measurements (`--measured-in tracker`) as the front ends
//! give it, written once: its JSON form (the Python package's dict) and its text (what
//! `tablec` prints), the transforms and the residuals they leave.

use std::fmt::Write as _;

use adwi_identify::register::{translation_and_rotation_deg, Refined, Registration};
use adwi_runtime::kinematics::Transform;
use serde::Serialize;

/// A registration: the rigid fit of the nominal robot, and the transforms as an
/// identification of the registered samples refined them, when it did.
#[derive(Debug, Clone, Serialize)]
pub struct RegistrationSummary {
    /// Rows registered.
    pub rows: usize,
    /// Whether orientations were measured (6-D), or positions only.
    pub orientation: bool,
    /// Levenberg–Marquardt iterations of the rigid fit.
    pub iterations: u32,
    /// The rigid fit's transforms and residuals.
    #[serde(flatten)]
    pub fit: FitSummary,
    /// The transforms as the identification refined them, with the identified model's
    /// residuals.
    pub refined: Option<FitSummary>,
}

/// Both transforms of a registration and the residuals they leave.
#[derive(Debug, Clone, Serialize)]
pub struct FitSummary {
    /// The robot's frame in the tracker's.
    pub base_in_tracker: TransformSummary,
    /// The probe in the flange frame.
    pub probe: TransformSummary,
    /// RMS of the position residual norms, mm.
    pub position_rms_mm: f64,
    /// Largest position residual norm, mm.
    pub position_max_mm: f64,
    /// RMS of the orientation residual norms, rad, when measured.
    pub orientation_rms_rad: Option<f64>,
    /// Largest orientation residual norm, rad, when measured.
    pub orientation_max_rad: Option<f64>,
}

/// A transform as `tablec` prints it (translation, mm; rotation vector, degrees) and as
/// its rotation matrix (row-major), for those who apply it. Lists, not tuples, in every
/// serialized form.
#[derive(Debug, Clone, Serialize)]
pub struct TransformSummary {
    /// Translation, mm.
    #[serde(serialize_with = "list")]
    pub translation_mm: [f64; 3],
    /// Rotation vector, degrees.
    #[serde(serialize_with = "list")]
    pub rotation_vector_deg: [f64; 3],
    /// Rotation matrix, row-major.
    #[serde(serialize_with = "rows")]
    pub rotation: [[f64; 3]; 3],
}

fn list<S: serde::Serializer>(v: &[f64; 3], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(v)
}

fn rows<S: serde::Serializer>(v: &[[f64; 3]; 3], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(v.iter().map(|row| row.as_slice()))
}

impl TransformSummary {
    fn of(t: &Transform) -> TransformSummary {
        let (translation_mm, rotation_vector_deg) = translation_and_rotation_deg(t);
        TransformSummary {
            translation_mm,
            rotation_vector_deg,
            rotation: t.rotation,
        }
    }
}

impl FitSummary {
    fn of(fit: &Refined) -> FitSummary {
        FitSummary {
            base_in_tracker: TransformSummary::of(&fit.base_in_tracker),
            probe: TransformSummary::of(&fit.probe),
            position_rms_mm: fit.position_rms_mm,
            position_max_mm: fit.position_max_mm,
            orientation_rms_rad: fit.orientation_rms_rad,
            orientation_max_rad: fit.orientation_max_rad,
        }
    }

    /// Both transforms, then the residuals they leave on a line of its own called
    /// `residuals`.
    fn text(&self, residuals: &str) -> String {
        let mut out = String::new();
        for (name, t) in [
            ("base in tracker", &self.base_in_tracker),
            ("probe on flange", &self.probe),
        ] {
            let (p, r) = (t.translation_mm, t.rotation_vector_deg);
            let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            let _ = writeln!(
                out,
                "  {name}  translation ({:.4}, {:.4}, {:.4}) mm, rotation vector ({:.5}, \
                 {:.5}, {:.5})° ({angle:.5}°)",
                p[0], p[1], p[2], r[0], r[1], r[2]
            );
        }
        let orientation = self
            .orientation_rms_rad
            .zip(self.orientation_max_rad)
            .map_or(String::new(), |(rms, max)| {
                format!(
                    "; orientation RMS {:.4} mrad, max {:.4} mrad",
                    rms * 1e3,
                    max * 1e3
                )
            });
        let _ = writeln!(
            out,
            "  {residuals:<15}  position RMS {:.4} mm, max {:.4} mm{orientation}",
            self.position_rms_mm, self.position_max_mm
        );
        out
    }
}

impl RegistrationSummary {
    /// The summary of `registration`, and of the transforms an identification refined.
    pub fn of(registration: &Registration, refined: Option<&Refined>) -> RegistrationSummary {
        RegistrationSummary {
            rows: registration.rows,
            orientation: registration.orientation,
            iterations: registration.iterations,
            fit: FitSummary::of(&registration.fit()),
            refined: refined.map(FitSummary::of),
        }
    }

    /// The samples' registration as `tablec` prints it: both transforms and the rigid
    /// fit's residuals.
    pub fn text(&self) -> String {
        format!(
            "registration   {} rows in the tracker frame, {}, rigid fit of the nominal robot \
             ({} iterations)\n{}",
            self.rows,
            if self.orientation {
                "6-D (positions and orientations)"
            } else {
                "positions only (probe rotation kept from the robot file)"
            },
            self.iterations,
            self.fit.text("fit residuals")
        )
    }

    /// Both transforms as an identification of the registered samples refined them, with
    /// the identified model's residuals; nothing when none refined them.
    pub fn refined_text(&self) -> String {
        self.refined.as_ref().map_or(String::new(), |refined| {
            format!(
                "refined        by the identification's base and tool parameters:\n{}",
                refined.text("residuals")
            )
        })
    }

    /// A validation set's own registration (registered apart): its tracker-to-base
    /// transform and the calibrated model's residuals.
    pub fn validation_text(&self) -> String {
        format!(
            "validation     registered apart ({} rows): the robot's frame in the moved \
             tracker's, fitted to the calibrated model's TCP positions; the probe is the \
             samples'\n{}",
            self.rows,
            self.fit.text("fit residuals")
        )
    }

    /// The registration of series `index` (from 2; several series trained together): its
    /// tracker-to-base transform, fitted to the robot identified from all of them, and
    /// the probe they share.
    pub fn series_text(&self, index: usize) -> String {
        format!(
            "series {index}       registered to the robot identified from every series ({} \
             rows); the probe is the first series'\n{}",
            self.rows,
            self.fit.text("fit residuals")
        )
    }
}

/// The text of every registration a job made, in the order `tablec` prints them: the
/// samples' (with its refinement when `refined`), then each later series'.
pub(crate) fn registrations_text(
    registration: Option<&(Registration, Refined)>,
    series: &[Registration],
    refined: bool,
) -> String {
    let mut out = String::new();
    if let Some((r, f)) = registration {
        let summary = RegistrationSummary::of(r, Some(f));
        out.push_str(&summary.text());
        if refined {
            out.push_str(&summary.refined_text());
        }
    }
    for (i, r) in series.iter().enumerate() {
        out.push_str(&RegistrationSummary::of(r, None).series_text(i + 2));
    }
    out
}
