//! `tablec`: compile robot error samples into correction tables, and query them.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod bench;
mod build;
mod calibrate;
mod compensate;
mod continuity;
mod eval;
mod inspect;
mod iso9283;
mod plan;
mod progress;
mod query;
mod simulate;

/// Approximation-degree weighted interpolation of robot positioning errors.
#[derive(Parser)]
#[command(name = "tablec", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    job: Job,
}

// The subcommands, one per job of `adwi_jobs` (a `Command` there is what a robot is
// commanded to).
#[derive(Subcommand)]
enum Job {
    /// Compile a sample database (CSV) into a correction table.
    Build(build::Args),
    /// Predict the correction at one target, or at every row of a targets CSV.
    Query(query::Args),
    /// Compensate a robot program: every target replaced by the command that lands on it.
    Compensate(compensate::Args),
    /// Identify a robot's kinematic deviations from samples; write the calibrated robot.
    Calibrate(calibrate::Args),
    /// Print a table's header, parameters, counts and sizes.
    Inspect(inspect::Args),
    /// Simulate a sample database: a robot, an error scenario, a sampling plan.
    Simulate(simulate::Args),
    /// Compare compensation methods on held-out points: residual statistics and a report.
    Eval(eval::Args),
    /// Query and open latency of a table next to a k-d tree and the brute force.
    Bench(bench::Args),
    /// The largest change of both tiers' corrections along straight lines, step by step.
    Continuity(continuity::Args),
    /// ISO 9283 pose accuracy and repeatability of measured cycles, or the standard's cube
    /// positions as a plan to measure.
    Iso9283(iso9283::Args),
    /// Plan the poses to measure for an identification and a table.
    Plan(plan::Args),
}

/// Exit status when a query gave no correction for its target, or for some rows of a
/// targets file (docs/cli.md, "Exit status"). 1 is an error.
const EXIT_UNANSWERED: u8 = 3;
/// Exit status of a usage error: clap's, and a combination of options a job refuses.
const EXIT_USAGE: u8 = 2;

/// Whether a query answered every target it was given.
pub enum Answered {
    /// Every target got a correction (status `ok`).
    All,
    /// At least one target got none; its status says why.
    NotAll,
}

fn main() -> ExitCode {
    restore_default_sigpipe();
    let cli = Cli::parse();
    let done = |r: anyhow::Result<()>| r.map(|()| Answered::All);
    let result = match cli.job {
        Job::Build(args) => done(build::run(args)),
        Job::Query(args) => query::run(args),
        Job::Compensate(args) => compensate::run(args),
        Job::Calibrate(args) => done(calibrate::run(args)),
        Job::Inspect(args) => done(inspect::run(args)),
        Job::Simulate(args) => done(simulate::run(args)),
        Job::Eval(args) => done(eval::run(args)),
        Job::Bench(args) => done(bench::run(args)),
        Job::Continuity(args) => done(continuity::run(args)),
        Job::Iso9283(args) => done(iso9283::run(args)),
        Job::Plan(args) => done(plan::run(args)),
    };
    match result {
        Ok(Answered::All) => ExitCode::SUCCESS,
        Ok(Answered::NotAll) => ExitCode::from(EXIT_UNANSWERED),
        Err(e) => {
            // Messages quote what they read (a field, a line): a file's control bytes are
            // shown escaped, never sent to the terminal.
            eprintln!("error: {}", terminal_safe(&e.to_string()));
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {}", terminal_safe(&cause.to_string()));
            }
            // A refused combination of options is a usage error, as clap's own are.
            let usage = matches!(
                e.downcast_ref::<adwi_jobs::JobError>(),
                Some(adwi_jobs::JobError::Options(_))
            );
            ExitCode::from(if usage { EXIT_USAGE } else { 1 })
        }
    }
}

/// Prints a job's warnings on standard error, even with `--quiet`: the work was done, but
/// the user should know.
pub fn warn(warnings: &[adwi_jobs::Warning]) {
    for w in warnings {
        let kind = if w.is_note() { "note" } else { "warning" };
        eprintln!("{kind}: {}", terminal_safe(&w.to_string()));
    }
}

/// `text` with every control character but its line ends escaped
/// ([`adwi_jobs::compensate::escape_controls`], line by line): what a message quotes of a file
/// cannot move the cursor, change colours or ring the terminal.
fn terminal_safe(text: &str) -> String {
    let lines: Vec<_> = text
        .split('\n')
        .map(adwi_jobs::compensate::escape_controls)
        .collect();
    lines.join("\n")
}

/// Piped into `head`, a command-line tool should end quietly when its reader goes away.
/// Rust programs ignore SIGPIPE, which turns that into a panic in `println!`; the default
/// disposition ends the process as every other Unix tool ends.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first in `main`, before any thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// The method's parameters in one line, as `build` and `inspect` print them.
pub fn describe_method(m: &adwi_runtime::method::MethodParams) -> String {
    format!(
        "ε {} mm, k {}, w1 {}, w2 {}, r {}, [λ] {} 1/mm, [ζ] {} 1/mm², screen (40) {}",
        micrometres(m.radius_mm),
        m.max_neighbours,
        m.w1,
        m.w2,
        m.power,
        m.lambda_min_per_mm,
        m.zeta_min_per_mm2,
        if m.consistency_screen { "on" } else { "off" }
    )
}

/// A served field as the options name it: on a hybrid table `kriging` holds a part that
/// turns with the tool's approach axis (its older name, `kriging-tool-axis`, is not what a
/// user asked for).
pub fn served_field_name(field: adwi_runtime::format::ServedField) -> &'static str {
    use adwi_runtime::format::ServedField;
    match field {
        ServedField::KrigingToolAxis => "kriging (tool-axis part)",
        other => other.name(),
    }
}

/// A length in mm to the micrometre, without trailing zeros: a derived ε reads `66.787`,
/// not `66.78746957755581` (the table keeps every digit).
pub fn micrometres(mm: f64) -> String {
    let text = format!("{mm:.3}");
    match text.find('.') {
        Some(_) => text.trim_end_matches('0').trim_end_matches('.').to_string(),
        None => text,
    }
}

/// The joint-space screen in words, as `build` and `inspect` print it.
pub fn describe_joint_screen(joint_radius_rad: f64) -> String {
    if joint_radius_rad > 0.0 {
        format!(
            "every joint within {}° of the target's, when queried with joint angles",
            joint_radius_rad.to_degrees()
        )
    } else {
        "off".to_string()
    }
}

/// A hybrid table's joint angles its samples span (degrees per joint, `None` for a joint
/// they do not bound), beyond which its residual fades: `build` and `inspect` say it alike.
fn describe_joint_ranges(ranges_deg: &[Option<[f64; 2]>]) -> String {
    let joints: Vec<String> = ranges_deg
        .iter()
        .enumerate()
        .map(|(j, r)| match r {
            Some([lo, hi]) => format!("j{} [{lo:.1}, {hi:.1}]", j + 1),
            None => format!("j{} any", j + 1),
        })
        .collect();
    format!(
        "{}°: the angles the samples span; beyond them the residual fades, to none {:.0}° past \
         (the model alone)",
        joints.join(", "),
        adwi_runtime::joint_terms::RESIDUAL_FADE_RAD.to_degrees()
    )
}
