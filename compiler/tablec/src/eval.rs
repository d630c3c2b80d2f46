//! `tablec eval`: the evaluation job ([`adwi_jobs::EvalJob`]), printed as a table.

use adwi_jobs::{EvalArgs, EvalJob};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: EvalArgs,
    /// Print nothing but errors and warnings.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let job = EvalJob::new(args.job)?;
    let command = std::env::args()
        .map(|a| if a.contains(' ') { format!("'{a}'") } else { a })
        .collect::<Vec<_>>()
        .join(" ");
    let evaluated = job.run(&command)?;
    crate::warn(&evaluated.warnings);
    if !args.quiet {
        if let Some((registration, refined)) = &evaluated.registration {
            crate::registration::print_registration(registration);
            crate::registration::print_refined(refined);
        }
        for (i, r) in evaluated.series_registrations.iter().enumerate() {
            crate::registration::print_series_registration(i + 2, r);
        }
        if let Some(v) = &evaluated.validation_registration {
            crate::registration::print_validation_registration(v);
        }
        print!(
            "{}",
            adwi_eval::output::terminal_table(&evaluated.evaluation)
        );
        if let Some(by_region) = &evaluated.by_region {
            print!("{}", adwi_eval::output::terminal_table(by_region));
        }
        if let Some(page) = &evaluated.report_page {
            println!("report: {}", page.display());
        }
    }
    Ok(())
}
