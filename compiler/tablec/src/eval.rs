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
        print!("{}", evaluated.text());
        if let Some(page) = &evaluated.report_page {
            println!("report: {}", page.display());
        }
    }
    Ok(())
}
