//! `tablec continuity`: the continuity job ([`adwi_jobs::ContinuityJob`]), both tiers
//! printed as a table.

use adwi_jobs::continuity::TierContinuity;
use adwi_jobs::{ContinuityArgs, ContinuityJob};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: ContinuityArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let result = ContinuityJob::new(args.job)?.run()?;
    let c = &result.continuity;
    println!(
        "{} lines of {} mm at {} mm steps",
        c.lines, result.length_mm, result.step_mm
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
