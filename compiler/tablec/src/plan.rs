//! `tablec plan`: the planning job ([`adwi_jobs::PlanJob`]).

use adwi_jobs::{PlanArgs, PlanJob};

/// Plan the poses to measure: reachable candidates in the box (seen by the tracker),
/// chosen for the identification (I- or D-optimality) and for coverage, ordered as a
/// short joint-space path.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: PlanArgs,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let bar = crate::progress::Bar::new(args.quiet);
    let planned = PlanJob::new(args.job)?.run(&bar);
    bar.finish();
    let planned = planned?;
    let p = &planned.plan;
    println!(
        "planned        {} poses of the {} from {} candidates ({} draws)",
        p.poses.len(),
        planned.robot_name,
        p.pool,
        p.draws
    );
    println!(
        "criterion      log det {:.3} over {} identifiable parameters; {}; joint travel {:.2} rad",
        p.log_det,
        p.parameters.len(),
        adwi_jobs::plan::smallest_distance(p.min_distance_mm),
        p.path_travel
    );
    println!(
        "variance       mean prediction variance over the candidates {:.4} σ²; no {} of them below {:.4} σ² (efficiency ≥ {:.2})",
        p.mean_variance,
        p.poses.len(),
        p.variance_bound,
        p.variance_bound / p.mean_variance
    );
    println!("wrote          {}", planned.output.display());
    Ok(())
}
