//! `tablec compensate`: a robot program with every target replaced by the command that
//! lands on it ([`adwi_jobs::CompensateJob`]).

use std::fmt::Write;

use adwi_jobs::compensate::{
    escape_controls, CompensateArgs, CompensateJob, ProgramError, TargetLine,
};
use adwi_jobs::JobError;
use adwi_runtime::Residual;

use crate::Answered;

#[derive(clap::Args)]
#[command(
    after_help = "Exit status: 0 when every target was corrected; 3 when some target \
    was left unchanged (the program is still written, each target's status in the report), \
    a position-only table's target beyond its samples' evidence among them; \
    with --strict, 3 and nothing written; 1 on an error (a malformed program, a program that \
    moves but holds no target, an unreadable input, a refused output: nothing is written); 2 on \
    a usage error."
)]
pub struct Args {
    #[command(flatten)]
    job: CompensateArgs,
    /// Print only the targets left unchanged and the summary.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<Answered> {
    let job = CompensateJob::new(args.job)?;
    // The lines printed once the outputs are written: with --quiet only those left
    // unchanged, so that a long program's lines are not held.
    let mut printed = String::new();
    // A line written in the partner file is placed there, by its name as the details
    // give it; the place column is as wide as the widest place, the program's own or
    // such a one, so that every line keeps the columns.
    let partner = job.partner_name();
    let columns = Columns {
        place: (job.program().in_partner.iter())
            .map(|p| partner_place(partner, p.line, p.column).chars().count())
            .fold(PLACE_WIDTH.max(job.widest_place()), usize::max),
    };
    let done = job.run_and_write(|t| {
        if !(args.quiet && t.status.corrected()) {
            print_line(&mut printed, &t, partner, &columns);
        }
    });
    let done = match done {
        // --strict: every target unaccounted or not corrected is the exit status 3 that
        // any target left unchanged gives, with nothing written.
        Err(JobError::Program(e)) if matches!(*e, ProgramError::NotAllCorrected { .. }) => {
            eprintln!("error: {e}");
            return Ok(Answered::NotAll);
        }
        done => done?,
    };
    if !printed.is_empty() {
        println!("{}", header(&columns));
    }
    print!("{printed}");
    let summary = &done.summary;
    println!("{}", escape_controls(&summary.to_string()));
    Ok(if summary.corrected == summary.total {
        Answered::All
    } else {
        Answered::NotAll
    })
}

/// The text report's columns: fixed widths, the status last with its detail after it,
/// so that the figures line up whatever the status (the CSV report, `--report`, has every
/// field): `target  place  kind  correction  joint change  status`.
fn header(columns: &Columns) -> String {
    let place = columns.place;
    format!(
        "{:<24} {:<place$} {:<10} {:>11} {:>13}  status",
        "target", "place", "kind", "correction", "joint change"
    )
}

/// The place column's width, unless a place is wider (a line and column of ten digits
/// together, or a place in the partner file).
const PLACE_WIDTH: usize = 10;

/// The widths of the text report's columns that vary with the program.
struct Columns {
    /// The place's: [`PLACE_WIDTH`], or the widest place.
    place: usize,
}

/// A place in the partner file (`cell/seam.src:25:6`).
fn partner_place(partner: Option<&str>, line: usize, column: usize) -> String {
    format!(
        "{}:{line}:{column}",
        escape_controls(partner.unwrap_or("partner"))
    )
}

/// A line's status, and for a corrected target on a hybrid table what its correction
/// rests on where that is less than the samples: the residual flag where the correction
/// did not hold all of the residual field (`faded`, `model_only`) and the evidence flag
/// where it lies beyond the samples (`beyond orientation`), as the CSV report's
/// `residual` and `evidence` say, so that neither reads as a plain `ok`.
fn status_of(t: &TargetLine) -> String {
    let mut status = t.status.as_str().to_string();
    if t.status.corrected() {
        if let Some(r @ (Residual::Faded | Residual::ModelOnly)) = t.residual {
            let _ = write!(status, ", {}", r.as_str());
        }
        if let Some(e) = t.evidence.filter(|e| !e.is_within()) {
            let _ = write!(status, ", beyond {}", e.as_str());
        }
    }
    status
}

/// A target's line of the text report ([`header`]'s columns, the place's as wide as the
/// widest; a name longer than its column pushes the rest of its line along, never cut). A target written in the program's
/// partner file (`partner`, by name) is placed there: `cell/seam.src:25:6`.
fn print_line(out: &mut String, t: &TargetLine, partner: Option<&str>, columns: &Columns) {
    let figure = |v: Option<f64>, unit: &str| v.map_or(String::new(), |v| format!("{v:.4}{unit}"));
    let place = if t.in_partner {
        partner_place(partner, t.line, t.column)
    } else {
        format!("{}:{}", t.line, t.column)
    };
    let place_width = columns.place;
    let _ = writeln!(
        out,
        "{:<24} {:<place_width$} {:<10} {:>11} {:>13}  {}{}",
        escape_controls(&t.name),
        place,
        t.kind,
        figure(t.correction_mm, " mm"),
        figure(t.joint_change_deg, "°"),
        status_of(t),
        if t.detail.is_empty() {
            String::new()
        } else {
            format!(" ({})", escape_controls(&t.detail))
        },
    );
}
