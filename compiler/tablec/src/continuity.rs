//! `tablec continuity`.

use std::path::PathBuf;

use adwi_eval::continuity::{continuity, ContinuityOptions, TierContinuity};

#[derive(clap::Args)]
pub struct Args {
    /// The table (not hybrid).
    table: PathBuf,
    /// Number of straight lines, each inside the grid with an answered middle.
    #[arg(long, default_value_t = ContinuityOptions::default().lines)]
    lines: usize,
    /// Length of each line, mm.
    #[arg(long, default_value_t = ContinuityOptions::default().length_mm)]
    length_mm: f64,
    /// Distance between consecutive targets, mm.
    #[arg(long, default_value_t = ContinuityOptions::default().step_mm)]
    step_mm: f64,
    /// Seed of the lines.
    #[arg(long, default_value_t = ContinuityOptions::default().seed)]
    seed: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let options = ContinuityOptions {
        lines: args.lines,
        length_mm: args.length_mm,
        step_mm: args.step_mm,
        seed: args.seed,
    };
    // Sized before the table is opened: refused in milliseconds, with the figure.
    options.check()?;
    let table = crate::open_table(&args.table)?;
    let c = continuity(&table, &options)?;
    println!(
        "{} lines of {} mm at {} mm steps",
        c.lines, options.length_mm, options.step_mm
    );
    println!(
        "{:<8} {:>14} {:>16} {:>12} {:>14} {:>12}",
        "tier", "answered steps", "largest step mm", "steps >1 µm", "status changes", "largest rad"
    );
    let row = |name: &str, t: &TierContinuity| {
        println!(
            "{name:<8} {:>14} {:>16.6} {:>12} {:>14} {:>12.3e}    at ({:.3}, {:.3}, {:.3}) mm",
            t.answered_steps,
            t.largest_step_mm,
            t.steps_over_1um,
            t.status_changes,
            t.largest_orientation_step_rad,
            t.largest_step_at_mm[0],
            t.largest_step_at_mm[1],
            t.largest_step_at_mm[2],
        );
    };
    match &c.served {
        Some(served) => row("served", served),
        None => println!("served   none: a version-1 table has no served field"),
    }
    row("exact", &c.exact);
    Ok(())
}
