//! The continuity job: the largest change of both tiers' corrections along straight lines,
//! step by step, as a servo loop meets them (`tablec continuity`).

use std::path::PathBuf;

use adwi_eval::continuity::{continuity, ContinuityError, ContinuityOptions};
use adwi_runtime::Table;
use memmap2::Mmap;
use serde::{Deserialize, Serialize};

use crate::inputs::open_table;
use crate::JobError;

pub use adwi_eval::continuity::{Continuity, TierContinuity};

/// Continuity along straight lines: every option of `tablec continuity`.
#[derive(clap::Args, Deserialize, Debug, Clone)]
#[serde(default)]
pub struct ContinuityArgs {
    /// The table (not hybrid).
    pub table: PathBuf,
    /// Number of straight lines, each inside the grid with an answered middle.
    #[arg(long, default_value_t = ContinuityOptions::default().lines)]
    pub lines: usize,
    /// Length of each line, mm.
    #[arg(long, default_value_t = ContinuityOptions::default().length_mm)]
    pub length_mm: f64,
    /// Distance between consecutive targets, mm.
    #[arg(long, default_value_t = ContinuityOptions::default().step_mm)]
    pub step_mm: f64,
    /// Seed of the lines.
    #[arg(long, default_value_t = ContinuityOptions::default().seed)]
    pub seed: u64,
}

impl Default for ContinuityArgs {
    fn default() -> ContinuityArgs {
        let options = ContinuityOptions::default();
        ContinuityArgs {
            table: PathBuf::new(),
            lines: options.lines,
            length_mm: options.length_mm,
            step_mm: options.step_mm,
            seed: options.seed,
        }
    }
}

/// A continuity measurement checked, its table open, ready to run.
pub struct ContinuityJob {
    options: ContinuityOptions,
    table: Table<Mmap>,
}

/// What the lines met.
#[derive(Debug, Clone, Serialize)]
pub struct ContinuityResult {
    /// Length of each line, mm.
    pub length_mm: f64,
    /// Distance between consecutive targets, mm.
    pub step_mm: f64,
    /// Both tiers along the lines walked.
    #[serde(flatten)]
    pub continuity: Continuity,
}

impl ContinuityJob {
    /// Checks the options — at least one line, a positive step, a length of at least one
    /// step, a bounded number of queries — before the table is opened, then opens it.
    ///
    /// # Errors
    ///
    /// [`JobError::Options`] with the figures, or [`JobError::Table`].
    pub fn new(args: ContinuityArgs) -> Result<ContinuityJob, JobError> {
        if args.lines == 0 {
            return Err(JobError::option(
                "lines",
                "0 lines: give at least one line to walk",
            ));
        }
        let options = ContinuityOptions {
            lines: args.lines,
            length_mm: args.length_mm,
            step_mm: args.step_mm,
            seed: args.seed,
        };
        // Sized before the table is opened: refused in milliseconds, with the figure.
        options
            .check()
            .map_err(|e| JobError::Options(e.to_string()))?;
        let table = open_table(&args.table)?;
        Ok(ContinuityJob { options, table })
    }

    /// Walks the lines.
    ///
    /// # Errors
    ///
    /// [`JobError::Continuity`]: a hybrid table (its correction needs joint values), or a
    /// grid with no line of the length inside it with an answered middle.
    pub fn run(self) -> Result<ContinuityResult, JobError> {
        let continuity = continuity(&self.table, &self.options)?;
        Ok(ContinuityResult {
            length_mm: self.options.length_mm,
            step_mm: self.options.step_mm,
            continuity,
        })
    }
}

impl From<ContinuityError> for JobError {
    fn from(e: ContinuityError) -> JobError {
        match e {
            ContinuityError::Options(_) | ContinuityError::TooMuchWork { .. } => {
                JobError::Options(e.to_string())
            }
            other => JobError::Continuity(Box::new(other)),
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use serde::de::value::{Error, MapDeserializer};

    use super::*;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: ContinuityArgs,
    }

    /// clap's defaults are the struct's `Default`, which Python's keywords start from.
    #[test]
    fn the_command_line_and_python_have_the_same_defaults() {
        let parsed = Cli::parse_from(["continuity", "t.tbl"]).args;
        let mut expected = ContinuityArgs::deserialize(MapDeserializer::<_, Error>::new(
            std::iter::empty::<(&str, &str)>(),
        ))
        .unwrap();
        expected.table = "t.tbl".into();
        assert_eq!(format!("{parsed:?}"), format!("{expected:?}"));
    }

    /// No line, a step of nothing, a billion lines: refused as options before the table
    /// is read (it does not exist here).
    #[test]
    fn options_are_refused_before_the_table_is_opened() {
        let missing = ContinuityArgs {
            table: "/nonexistent/t.tbl".into(),
            ..ContinuityArgs::default()
        };
        for args in [
            ContinuityArgs {
                lines: 0,
                ..missing.clone()
            },
            ContinuityArgs {
                step_mm: 0.0,
                ..missing.clone()
            },
            ContinuityArgs {
                lines: 1_000_000_000,
                ..missing.clone()
            },
        ] {
            let e = ContinuityJob::new(args).err().unwrap();
            assert!(matches!(e, JobError::Options(_)), "{e}");
        }
        let e = ContinuityJob::new(missing).err().unwrap();
        assert!(matches!(e, JobError::Table { .. }), "{e}");
    }
}
