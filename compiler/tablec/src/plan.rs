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
    let (unit, _) = adwi_jobs::plan::variance_units(p);
    let figure = |v: f64| adwi_jobs::plan::figure(p, v);
    if let Some([lo, hi]) = p.tracker_sigma_mm {
        println!(
            "tracker        σ {lo:.4} to {hi:.4} mm per coordinate over the candidates (MPE/2 at their distances): each pose weighed by 1/σ², variances in mm²"
        );
    }
    if p.workspace_candidates != p.pool {
        println!(
            "branches       {} of the candidates in the home branch (the workspace the variances are over), {} of the planned poses in another",
            p.workspace_candidates, p.other_branches
        );
    }
    println!(
        "variance       mean prediction variance over the candidates {} {unit}; no {} of them below {} {unit} (efficiency ≥ {:.2})",
        figure(p.mean_variance),
        p.poses.len(),
        figure(p.variance_bound),
        p.variance_bound / p.mean_variance
    );
    if p.criterion_value != p.mean_variance || p.criterion_bound != p.variance_bound {
        println!(
            "criterion      {} {unit}; no {} of the candidates below {} {unit} (efficiency ≥ {:.2})",
            figure(p.criterion_value),
            p.poses.len(),
            figure(p.criterion_bound),
            p.criterion_bound / p.criterion_value
        );
    }
    println!(
        "planned     {}",
        adwi_jobs::plan::figures_line(p, &p.planned)
    );
    match p.random.as_slice() {
        [] => println!("random         the workspace gave too few further poses to compare with"),
        sets => {
            for f in sets {
                println!("random      {}", adwi_jobs::plan::figures_line(p, f));
            }
            println!(
                "               (random poses drawn from the same workspace apart from the candidates; variances over the candidates)"
            );
        }
    }
    if let Some([before, after, random]) = p.field_variance_mm2 {
        println!(
            "field          the table's residual field's variance, mean over the candidates: {before:.3e} mm² before, {after:.3e} mm² after the plan, {random:.3e} mm² after as many random poses"
        );
    }
    println!("wrote          {}", planned.output.display());
    Ok(())
}
