//! `tablec calibrate`: the calibration job ([`adwi_jobs::CalibrateJob`]), its parameters
//! printed with their standard errors.

use adwi_jobs::{CalibrateArgs, CalibrateJob};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: CalibrateArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let calibrated = CalibrateJob::new(args.job)?.run()?;
    print!("{}", calibrated.text());
    crate::warn(&calibrated.warnings);
    Ok(())
}
