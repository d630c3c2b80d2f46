//! `tablec build`.

use std::path::PathBuf;
use std::time::Instant;

use adwi_compiler::build::{compile, write_atomically};
use adwi_compiler::samples::{read_samples, ColumnMap};
use anyhow::Context;

#[derive(clap::Args)]
pub struct Args {
    /// The sample database (CSV: x,y,z and dx,dy,dz or mx,my,mz; see the README).
    samples: PathBuf,
    /// Where to write the table (written to a temporary file, then renamed).
    #[arg(short, long)]
    output: PathBuf,
    /// Column mapping for files named otherwise: `x=x_t,y=y_t,dx=-x_dif,...`
    /// (`-` negates).
    #[arg(long, value_name = "MAP")]
    columns: Option<String>,
    #[command(flatten)]
    table: crate::table_options::TableOptions,
    /// Worker threads [default: all cores]; the table is the same for any count.
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bar or summary.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    let columns =
        ColumnMap::parse(args.columns.as_deref().unwrap_or("")).map_err(anyhow::Error::msg)?;
    let samples = read_samples(&args.samples, &columns)?;
    let (w1, w2) = args.table.weights();
    let options = args.table.build_options()?;
    let (_, _, plan) = adwi_compiler::build::resolve(&samples, &options)?;
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(plan.cells as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} cells, {eta} left")
            .context("progress bar template")?
            .progress_chars("=> "),
    );
    bar.set_message("compiling");
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        pool = pool.num_threads(n);
    }
    let pool = pool.build().context("cannot start worker threads")?;
    let (bytes, report) = pool.install(|| compile(&samples, &options, &|n| bar.inc(n)))?;
    bar.finish_and_clear();
    write_atomically(&args.output, &bytes)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if !args.quiet {
        let derived = |yes| if yes { " (derived: default)" } else { "" };
        let spacing = report
            .spacing_mm
            .map_or("n/a".to_string(), |s| format!("{s:.3} mm"));
        let g = report.grid;
        println!(
            "samples        {} from {}",
            report.samples,
            args.samples.display()
        );
        println!("spacing        {spacing} (median nearest-neighbour distance)");
        println!(
            "radius ε       {:.3} mm{}",
            report.radius_mm,
            derived(report.radius_derived)
        );
        println!(
            "cell           {:.3} mm{}",
            report.cell_mm,
            derived(report.cell_derived)
        );
        println!(
            "grid           {} × {} × {} cells from ({:.3}, {:.3}, {:.3}) to ({:.3}, {:.3}, {:.3}) mm",
            g.dims[0],
            g.dims[1],
            g.dims[2],
            g.origin_mm[0],
            g.origin_mm[1],
            g.origin_mm[2],
            g.max_mm()[0],
            g.max_mm()[1],
            g.max_mm()[2]
        );
        println!(
            "candidates     {} distinct lists, {} of {} cells covered, mean {:.1}, max {} per cell",
            report.distinct_lists,
            report.cells_covered,
            report.cells,
            report.mean_list_len,
            report.max_list_len
        );
        println!(
            "method         k {}, w1 {}, w2 {}, r {}, [λ] {}, [ζ] {}, screen (40) {}",
            args.table.k,
            w1,
            w2,
            args.table.power,
            args.table.lambda_min,
            args.table.zeta_min,
            if args.table.no_consistency_screen {
                "off"
            } else {
                "on"
            }
        );
        println!(
            "wrote          {} ({} bytes) in {:.2} s",
            args.output.display(),
            report.table_bytes,
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
