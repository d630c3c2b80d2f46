//! `tablec`: compile robot error samples into correction tables, and query them.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod bench;
mod build;
mod eval;
mod inspect;
mod query;
mod simulate;
mod table_options;

/// Approximation-degree weighted interpolation of robot positioning errors.
#[derive(Parser)]
#[command(name = "tablec", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Compile a sample database (CSV) into a correction table.
    Build(build::Args),
    /// Predict the correction at one target, or at every row of a targets CSV.
    Query(query::Args),
    /// Print a table's header, parameters, counts and sizes.
    Inspect(inspect::Args),
    /// Simulate a sample database: a robot, an error scenario, a sampling plan.
    Simulate(simulate::Args),
    /// Compare compensation methods on held-out points: residual statistics and a report.
    Eval(eval::Args),
    /// Query and open latency of a table next to a k-d tree and the brute force.
    Bench(bench::Args),
}

fn main() -> ExitCode {
    restore_default_sigpipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Build(args) => build::run(args),
        Command::Query(args) => query::run(args),
        Command::Inspect(args) => inspect::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Bench(args) => bench::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}

/// Piped into `head`, a command-line tool should end quietly when its reader goes away.
/// Rust programs ignore SIGPIPE, which turns that into a panic in `println!`; the default
/// disposition ends the process as every other Unix tool ends.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first in `main`, before any thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Opens a table by memory map.
fn open_table(path: &std::path::Path) -> anyhow::Result<adwi_runtime::Table<memmap2::Mmap>> {
    use anyhow::Context;
    // SAFETY: tablec never writes a table in place (it renames complete files), and the
    // process holds the mapping only for the duration of one command.
    unsafe { adwi_runtime::Table::open(path) }
        .with_context(|| format!("cannot open table {}", path.display()))
}
