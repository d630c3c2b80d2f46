//! What every program reader's fuzz target checks of its outcome: a program whose targets
//! and numbers lie inside the input and are finite, or an error located inside the input
//! whose message carries no control character.

use adwi_programs::program::{Orientation, Program, TargetKind};
use adwi_programs::source::Source;
use adwi_programs::Error;

/// Panics (a finding) when `result`, read from `src`, breaks a reader's promises.
pub fn check(src: &Source, result: Result<Program, Error>) {
    match result {
        Ok(program) => {
            // A target placed in the partner file names a target of the program, written
            // nowhere in it (at its end), in the order of the targets.
            let mut last = None;
            for p in &program.in_partner {
                assert_eq!(program.targets[p.target].offset, src.bytes.len());
                assert!(last.is_none_or(|l| l < p.target));
                assert!(p.line >= 1 && p.column >= 1);
                assert_eq!(program.partner_place(p.target), Some(*p));
                last = Some(p.target);
            }
            for target in &program.targets {
                assert!(target.offset <= src.bytes.len());
                let numbers: Vec<&adwi_programs::number::Number> = match &target.kind {
                    TargetKind::Cartesian(c) => {
                        let mut n: Vec<_> = c.position.iter().chain(&c.joints).collect();
                        match &c.orientation {
                            Some(Orientation::KukaAbcDeg(o)) => n.extend(o),
                            Some(Orientation::QuaternionWxyz(o)) => n.extend(o),
                            Some(Orientation::RotationVectorRad(o)) => n.extend(o),
                            Some(Orientation::XyzIntrinsicDeg(o)) => n.extend(o),
                            None => {}
                        }
                        n
                    }
                    TargetKind::Joints(j) => j.joints.iter().collect(),
                    _ => Vec::new(),
                };
                for n in numbers {
                    assert!(n.value.is_finite());
                    // An empty span is a VAL3 attribute the file omits: a zero.
                    assert!(n.span.0 < n.span.1 || (n.span.0 == n.span.1 && n.value == 0.0));
                    assert!(n.span.1 <= src.bytes.len());
                }
                // The bounds never panic on what a reader gives.
                let _ = adwi_programs::bounds::out_of_range(src, &target.kind, None);
            }
        }
        Err(e) => {
            let lines = src
                .bytes
                .iter()
                .filter(|b| matches!(b, b'\n' | b'\r'))
                .count()
                + 1;
            if let Error::Syntax { line, column, .. } = &e {
                assert!(*line >= 1 && *line <= lines && *column >= 1);
            }
            assert!(!e.to_string().chars().any(char::is_control));
        }
    }
}
