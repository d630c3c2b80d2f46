//! `tablec iso9283`: the ISO 9283 job ([`adwi_jobs::Iso9283Job`]), its characteristics
//! printed as a table per position and per distance.

use adwi_jobs::{Iso9283Args, Iso9283Job};

/// ISO 9283:1998 pose characteristics of measured cycles: pose accuracy AP and
/// repeatability RP per position, distance accuracy AD and repeatability RD between the
/// standard's P2 and P4 or the pairs named (as text, --json and an HTML page, --report);
/// the path characteristics of a tracker stream (--path with --command: AT, RT, CR, CO,
/// AV, RV, FV); or the standard's five cube positions as a plan (--cube), or its test
/// paths (--cube --path-plan).
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: Iso9283Args,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let result = Iso9283Job::new(args.job)?.run()?;
    print!("{}", result.text());
    Ok(())
}
