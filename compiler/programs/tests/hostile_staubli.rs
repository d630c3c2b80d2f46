//! Hostile VAL3 applications: the taught fixture's data file and program mutated byte by
//! byte, truncated, and random bytes, through the reader. Every outcome is a program whose
//! numbers are finite and lie in the data file (an omitted attribute a zero with an empty
//! span), or an error located by file, line and column in the file it names; never a panic.

use adwi_programs::program::{Orientation, TargetKind};
use adwi_programs::source::Source;
use adwi_programs::Error;
use proptest::prelude::*;

const DTX: &[u8] = include_bytes!("../../../tests/programs/staubli/weld/weld.dtx");
const PGX: &[u8] = include_bytes!("../../../tests/programs/staubli/weld/seam.pgx");

/// Bytes that matter to the reader, and some that do not.
const ALPHABET: &[u8] = b"0123456789.-+eE<>/=\"'[]()!?-, \t\r\nxyzrkeyDataValue\xef\xbb\xbf\x00";

fn mutate(bytes: &[u8], mutations: &[(f64, u8, usize)]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for &(at, op, b) in mutations {
        let i = ((at * out.len() as f64) as usize).min(out.len());
        match op {
            0 if i < out.len() => out[i] = ALPHABET[b],
            1 => out.insert(i, ALPHABET[b]),
            _ if i < out.len() => {
                out.remove(i);
            }
            _ => {}
        }
    }
    out
}

fn lines(bytes: &[u8]) -> usize {
    bytes
        .iter()
        .enumerate()
        .filter(|&(i, b)| *b == b'\n' || (*b == b'\r' && bytes.get(i + 1) != Some(&b'\n')))
        .count()
        + 1
}

fn check(dtx: &[u8], pgx: &[u8]) -> Result<(), TestCaseError> {
    let src = Source::new("w.dtx", dtx);
    let program = Source::new("s.pgx", pgx);
    match adwi_programs::staubli::read(&src, std::slice::from_ref(&program)) {
        Ok(p) => {
            for t in &p.targets {
                prop_assert!(t.offset <= dtx.len());
                let numbers: Vec<_> = match &t.kind {
                    TargetKind::Cartesian(c) => {
                        let mut n: Vec<_> = c.position.to_vec();
                        if let Some(Orientation::XyzIntrinsicDeg(o)) = c.orientation {
                            n.extend(o);
                        }
                        n
                    }
                    TargetKind::Joints(j) => j.joints.clone(),
                    _ => Vec::new(),
                };
                for n in numbers {
                    prop_assert!(n.value.is_finite());
                    prop_assert!(n.span.0 <= n.span.1 && n.span.1 <= dtx.len());
                    prop_assert!(n.span.0 < n.span.1 || n.value == 0.0);
                }
            }
            Ok(())
        }
        Err(e) => {
            let Error::Syntax {
                file, line, column, ..
            } = &e
            else {
                return Err(TestCaseError::fail(format!("not a syntax error: {e}")));
            };
            let within = if file == "w.dtx" {
                lines(dtx)
            } else {
                lines(pgx)
            };
            prop_assert!(file == "w.dtx" || file == "s.pgx", "{}", file);
            prop_assert!(
                *line >= 1 && *line <= within && *column >= 1,
                "{}:{}",
                line,
                column
            );
            // Printed with every control character escaped.
            prop_assert!(!e.to_string().chars().any(char::is_control), "{}", e);
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn mutated_applications_read_or_are_located(
        m in prop::collection::vec((0.0..1.0f64, 0..3u8, 0..ALPHABET.len()), 1..8),
        in_program in any::<bool>(),
    ) {
        if in_program {
            check(DTX, &mutate(PGX, &m))?;
        } else {
            check(&mutate(DTX, &m), PGX)?;
        }
    }

    #[test]
    fn random_bytes_read_or_are_located(
        bytes in prop::collection::vec(prop::sample::select(ALPHABET.to_vec()), 0..400),
    ) {
        check(&bytes, PGX)?;
        check(DTX, &bytes)?;
    }
}

#[test]
fn every_truncation_reads_or_is_located() {
    for cut in 0..=DTX.len() {
        check(&DTX[..cut], PGX).unwrap();
    }
    for cut in 0..=PGX.len() {
        check(DTX, &PGX[..cut]).unwrap();
    }
}
