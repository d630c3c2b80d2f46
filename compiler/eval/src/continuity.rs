//! Continuity of a table's corrections along straight lines, as a servo loop meets them:
//! the largest change of the correction between two consecutive answered targets a small
//! step apart. A continuous field's largest change shrinks with the step; a field with
//! jumps keeps them whatever the step.

use adwi_runtime::{Correction, Status, Table, Target};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::latency::random_unit;

/// Which lines, and how finely they are walked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContinuityOptions {
    /// Number of straight lines.
    pub lines: usize,
    /// Length of each line, mm.
    pub length_mm: f64,
    /// Distance between consecutive targets on a line, mm.
    pub step_mm: f64,
    /// Seed of the lines' positions and directions.
    pub seed: u64,
}

impl Default for ContinuityOptions {
    fn default() -> ContinuityOptions {
        ContinuityOptions {
            lines: 100,
            length_mm: 200.0,
            step_mm: 0.01,
            seed: 1,
        }
    }
}

/// What one tier's corrections do along the lines.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TierContinuity {
    /// Steps between two answered targets.
    pub answered_steps: usize,
    /// Steps where the status changed (answered to not, or back).
    pub status_changes: usize,
    /// The largest change of the position correction over one step, mm.
    pub largest_step_mm: f64,
    /// Where it happened: the step's first target, mm.
    pub largest_step_at_mm: [f64; 3],
    /// The largest change of the orientation correction over one step, rad (0 for
    /// position-only tables).
    pub largest_orientation_step_rad: f64,
    /// Steps whose position correction changed by more than 1 µm.
    pub steps_over_1um: usize,
}

/// Both tiers along the same lines.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Continuity {
    /// The served field (`Table::query_target`); `None` for a table without one.
    pub served: Option<TierContinuity>,
    /// The paper's method (`Table::exact`).
    pub exact: TierContinuity,
    /// Lines walked (each inside the grid, its middle answered by the exact tier).
    pub lines: usize,
}

/// The most queries one measurement makes: targets per line × lines × tiers. The default
/// options make 4 million; at a few microseconds a query this bound is minutes, where an
/// unbounded `--lines` or `--step-mm` was days or never.
pub const MAX_QUERIES: f64 = 2e8;

impl ContinuityOptions {
    /// The queries these options make at most on a table with a served tier: lines × (targets
    /// on a line) × 2 tiers, plus the middles tried. As a float: it may not fit an integer.
    pub fn queries(&self) -> f64 {
        let targets = (self.length_mm / self.step_mm).round().max(1.0) + 1.0;
        self.lines as f64 * (2.0 * targets + 1.0)
    }

    /// Checks the options before any work: a positive finite step, a length of at least one
    /// step, and at most [`MAX_QUERIES`] queries.
    ///
    /// # Errors
    ///
    /// [`ContinuityError::Options`] or [`ContinuityError::TooMuchWork`], with the figures.
    pub fn check(&self) -> Result<(), ContinuityError> {
        if !(self.step_mm.is_finite() && self.step_mm > 0.0) {
            return Err(ContinuityError::Options(format!(
                "a step of {} mm: give a positive length",
                self.step_mm
            )));
        }
        if !(self.length_mm.is_finite() && self.length_mm >= self.step_mm) {
            return Err(ContinuityError::Options(format!(
                "lines of {} mm at {} mm steps: give a length of at least one step",
                self.length_mm, self.step_mm
            )));
        }
        let queries = self.queries();
        if queries > MAX_QUERIES {
            return Err(ContinuityError::TooMuchWork {
                lines: self.lines,
                targets_per_line: (self.length_mm / self.step_mm).round().max(1.0) + 1.0,
                queries,
            });
        }
        Ok(())
    }
}

/// Why continuity cannot be measured on a table.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ContinuityError {
    /// Hybrid tables answer with joint values, which a Cartesian line does not give.
    #[error("a hybrid table's correction needs joint values along the line; measure the table of its residuals (build without --hybrid) instead: the model part is a smooth function of the joints")]
    Hybrid,
    /// An option out of range.
    #[error("{0}")]
    Options(String),
    /// The options ask for more queries than a measurement makes ([`MAX_QUERIES`]).
    #[error(
        "{lines} lines of {targets_per_line} targets on two tiers are {queries:.2e} queries, \
         more than the {MAX_QUERIES:.0e} one measurement makes (minutes); give fewer lines \
         (--lines) or a longer step (--step-mm)"
    )]
    TooMuchWork {
        /// Lines asked for.
        lines: usize,
        /// Targets on each line.
        targets_per_line: f64,
        /// Queries they would make.
        queries: f64,
    },
    /// The grid is smaller than a line, or no line's middle is answered.
    #[error("found no line of {length_mm} mm inside the grid with an answered middle")]
    NoLine {
        /// The line length asked for, mm.
        length_mm: f64,
    },
}

/// Walks `options.lines` random straight lines through the table's grid and reports, for
/// each tier, the largest change of the correction between consecutive answered targets.
/// Lines lie entirely inside the grid and have an answered middle, so that they cross the
/// covered workspace rather than the empty corners of its bounding box.
///
/// # Errors
///
/// [`ContinuityError`] for options refused by [`ContinuityOptions::check`], a hybrid
/// table or a grid with no such line.
pub fn continuity<D: AsRef<[u8]>>(
    table: &Table<D>,
    options: &ContinuityOptions,
) -> Result<Continuity, ContinuityError> {
    options.check()?;
    if table.is_hybrid() {
        return Err(ContinuityError::Hybrid);
    }
    let grid = *table.grid();
    let lo = grid.origin_mm;
    let hi = grid.max_mm();
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let steps = (options.length_mm / options.step_mm).round().max(1.0) as usize;
    let mut served = table.has_served_field().then(TierContinuity::default);
    let mut exact = TierContinuity::default();
    let mut lines = 0;
    let mut attempts = 0;
    while lines < options.lines && attempts < 1000 * options.lines.max(1) {
        attempts += 1;
        let middle = [0, 1, 2].map(|a| rng.gen_range(lo[a]..=hi[a]));
        let direction = random_unit(&mut rng);
        let half = options.length_mm / 2.0;
        let start = [0, 1, 2].map(|a| middle[a] - half * direction[a]);
        let end = [0, 1, 2].map(|a| middle[a] + half * direction[a]);
        let inside = |p: [f64; 3]| (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a]);
        if !inside(start) || !inside(end) || table.exact().query(middle).status != Status::Ok {
            continue;
        }
        lines += 1;
        let at = |i: usize| {
            let t = i as f64 * options.step_mm;
            Target::at([0, 1, 2].map(|a| start[a] + t * direction[a]))
        };
        if let Some(served) = &mut served {
            walk(served, steps, at, |t| table.query_target(t));
        }
        walk(&mut exact, steps, at, |t| table.exact().query_target(t));
    }
    if lines == 0 {
        return Err(ContinuityError::NoLine {
            length_mm: options.length_mm,
        });
    }
    Ok(Continuity {
        served,
        exact,
        lines,
    })
}

/// Adds one line of `steps` steps to `tier`.
fn walk(
    tier: &mut TierContinuity,
    steps: usize,
    at: impl Fn(usize) -> Target,
    query: impl Fn(&Target) -> Correction,
) {
    let mut previous = query(&at(0));
    for i in 1..=steps {
        let target = at(i);
        let current = query(&target);
        match (previous.status, current.status) {
            (Status::Ok, Status::Ok) => {
                tier.answered_steps += 1;
                let change = distance(previous.position_error_mm, current.position_error_mm);
                if change > 1e-3 {
                    tier.steps_over_1um += 1;
                }
                if change > tier.largest_step_mm {
                    tier.largest_step_mm = change;
                    tier.largest_step_at_mm = at(i - 1).position_mm;
                }
                let turn = distance(
                    previous.orientation_error_rad,
                    current.orientation_error_rad,
                );
                tier.largest_orientation_step_rad = tier.largest_orientation_step_rad.max(turn);
            }
            (a, b) if (a == Status::Ok) != (b == Status::Ok) => tier.status_changes += 1,
            _ => {}
        }
        previous = current;
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    adwi_runtime::method::distance_mm(a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A billion lines (58 days) and a nanometre step (never ends) are refused with their
    /// size; the default options and a step of nothing are answered as before.
    #[test]
    fn options_are_sized_before_any_work() {
        let default = ContinuityOptions::default();
        assert_eq!(default.check(), Ok(()));
        for options in [
            ContinuityOptions {
                lines: 1_000_000_000,
                ..default
            },
            ContinuityOptions {
                step_mm: 1e-9,
                ..default
            },
        ] {
            let e = options.check().unwrap_err();
            assert!(matches!(e, ContinuityError::TooMuchWork { .. }), "{e}");
            assert!(e.to_string().contains("queries, more than"), "{e}");
        }
        for step_mm in [0.0, -1.0, f64::NAN] {
            let options = ContinuityOptions { step_mm, ..default };
            assert!(matches!(options.check(), Err(ContinuityError::Options(_))));
        }
    }
}
