//! Robot programs compensated offline.
//!
//! Most industrial controllers cannot link a library into their motion loop; there a
//! calibration reaches the robot as a filtered program: every target replaced by the
//! command that lands on it. [`CompensateJob`] does that for KUKA KRL (`.src`, `.dat`), ABB
//! RAPID (`.mod`), Universal Robots URScript, G-code (`.nc`), Yaskawa INFORM (`.jbi`), Fanuc TP (`.ls`), Stäubli VAL3 (`.pjx`, `.dtx`) and a plain CSV of poses, with a correction
//! table ([`adwi_runtime::Table`]):
//!
//! 1. **Only the numbers of targets change.** The program is read as bytes, never decoded;
//!    each target's numbers are replaced in place, in the file's own style, and only when
//!    the value changes beyond what the written text holds ([`number`]). A table that
//!    corrects nothing reproduces the program byte for byte.
//! 2. **Frames.** A target is the TCP of a tool in a work object; the table corrects the
//!    point its samples measured, in the robot's base frame ([`frames`]).
//! 3. **Joint targets** go through forward kinematics, the table and inverse kinematics in
//!    the same configuration ([`correct`]); a hybrid table's targets take their posture
//!    from the inverse kinematics of the nominal robot.
//! 4. **Every target is reported** ([`report`]), and a target the table cannot correct is
//!    left unchanged and counted; `strict` fails the job instead.
//! 5. **Safety.** A correction beyond `max_correction_mm`, a joint moving beyond
//!    `max_joint_change_deg`, a posture changing configuration: refused for that target.
//!
//! ```no_run
//! use adwi_programs::{CompensateJob, CompensateOptions};
//!
//! let mut options = CompensateOptions::new("kr150.tbl", "weld.src");
//! options.output = Some("weld-compensated.src".into());
//! let job = CompensateJob::new(options)?; // every check, before any work
//! let done = job.run()?;
//! job.write(&done)?;
//! println!("{}", done.report.summary());
//! # Ok::<(), adwi_programs::Error>(())
//! ```
//!
//! The formats' readers: [`krl`], [`rapid`], [`urscript`], [`gcode`], [`yaskawa`], [`fanuc`], [`staubli`], [`csv`]. The method and the
//! frames are documented with worked examples in `docs/programs.md`.

#![deny(missing_docs)]

pub mod bounds;
pub mod correct;
pub mod csv;
pub mod dialect;
mod error;
pub mod fanuc;
pub mod frames;
pub mod gcode;
mod job;
pub mod krl;
pub mod lex;
pub mod number;
pub mod program;
pub mod rapid;
pub mod report;
pub mod source;
pub mod staubli;
pub mod urscript;
pub mod yaskawa;

pub use correct::{Limits, TargetStatus};
pub use error::{escape_controls, Error};
pub use job::{
    CompensateJob, CompensateOptions, Compensated, Summarized, BYTES_PER_TARGET,
    DEFAULT_MAX_CORRECTION_MM, DEFAULT_MAX_JOINT_CHANGE_DEG, DEFAULT_MAX_MEMORY_BYTES,
};
pub use program::{Format, Program};
pub use report::{CsvRows, Report, Summary, TargetLine};
