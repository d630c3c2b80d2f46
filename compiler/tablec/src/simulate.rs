//! `tablec simulate`: the simulation job ([`adwi_jobs::SimulateJob`]).

use adwi_jobs::{SimulateArgs, SimulateJob};

/// Simulate measured samples: nominal poses on a lattice or at random in a box, their exact
/// actual poses under an error scenario, measured with laser-tracker noise.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: SimulateArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let simulated = SimulateJob::new(args.job)?.run()?;
    let (mean_mm, max_mm) = simulated.error_mean_max_mm;
    eprintln!(
        "{}: {} samples of {}; position error mean {mean_mm:.3} mm, max {max_mm:.3} mm",
        simulated.output.display(),
        simulated.samples,
        simulated.robot_name
    );
    Ok(())
}
