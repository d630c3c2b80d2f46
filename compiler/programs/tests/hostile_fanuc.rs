//! Hostile Fanuc programs and frame files: the fixtures mutated byte by byte, and random
//! bytes, through the `.ls` reader, the `SYSFRAME.VA` reader and the whole job. Every outcome
//! is a program or an error located by file, line and column; never a panic, never a
//! non-finite number written. A fixed number of cases (the same on every machine).

use adwi_programs::fanuc::FanucOptions;
use adwi_programs::program::{Orientation, TargetKind};
use adwi_programs::source::Source;
use adwi_programs::{CompensateJob, CompensateOptions, Error};
use proptest::prelude::*;

const FIXTURES: [(&str, &[u8]); 2] = [
    (
        "fanuc_weld.ls",
        include_bytes!("../../../tests/programs/fanuc_weld.ls"),
    ),
    (
        "fanuc_gen.ls",
        include_bytes!("../../../tests/programs/fanuc_gen.ls"),
    ),
];

const FRAMES: &[u8] = include_bytes!("../../../tests/programs/fanuc_sysframe.va");

/// Bytes that matter to the reader, and some that do not.
const ALPHABET: &[u8] = b"0123456789.-+eE{}[](),;:=!/'\"\\ \t\r\nPRJLCAXYZWUTFGN*\xdf\x00";

fn mutations() -> impl Strategy<Value = Vec<(f64, u8, usize)>> {
    prop::collection::vec((0.0..1.0f64, 0..3u8, 0..ALPHABET.len()), 1..8)
}

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

fn frames() -> FanucOptions {
    FanucOptions {
        user_frames: vec![
            (1, [1600.0, 250.0, 750.0, 0.0, 0.0, 30.0]),
            (2, [1400.0, 500.0, 900.0, 0.0, 0.0, 0.0]),
        ],
        tool_frames: vec![
            (1, [0.0, 0.0, 180.0, 0.0, 0.0, 0.0]),
            (2, [0.0, 25.0, 120.0, 0.0, 0.0, 0.0]),
        ],
        frames_file: None,
    }
}

/// An error located inside `bytes`, whose message carries no control character.
fn located(name: &str, bytes: &[u8], e: Error) -> Result<(), TestCaseError> {
    let lines = bytes
        .iter()
        .enumerate()
        .filter(|&(i, b)| *b == b'\n' || (*b == b'\r' && bytes.get(i + 1) != Some(&b'\n')))
        .count()
        + 1;
    prop_assert!(!e.to_string().chars().any(char::is_control), "{}", e);
    match e {
        Error::Syntax {
            file, line, column, ..
        } => {
            prop_assert_eq!(file, name);
            prop_assert!(
                line >= 1 && line <= lines && column >= 1,
                "{}:{}",
                line,
                column
            );
            Ok(())
        }
        e => Err(TestCaseError::fail(format!("not a syntax error: {e}"))),
    }
}

/// Reads `bytes` as a Fanuc program: its targets' numbers inside the file and finite, or an
/// error located in it.
fn read(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    let src = Source::new(name, bytes);
    match adwi_programs::fanuc::read(&src, &frames()) {
        Ok(program) => {
            for t in &program.targets {
                prop_assert!(t.offset <= bytes.len());
                let numbers: Vec<_> = match &t.kind {
                    TargetKind::Cartesian(c) => {
                        let mut n: Vec<_> = c.position.to_vec();
                        if let Some(Orientation::KukaAbcDeg(o)) = c.orientation {
                            n.extend(o);
                        }
                        n
                    }
                    TargetKind::Joints(j) => j.joints.clone(),
                    _ => Vec::new(),
                };
                for n in numbers {
                    prop_assert!(n.value.is_finite());
                    prop_assert!(n.span.0 < n.span.1 && n.span.1 <= bytes.len());
                }
            }
            Ok(())
        }
        Err(e) => located(name, bytes, e),
    }
}

/// A small table around the fixtures' targets: errors of 1-2 mm, orientation too.
fn table_bytes() -> Vec<u8> {
    use adwi_compile::build::{compile, BuildOptions};
    use adwi_samples::{parse_samples, ColumnMap};
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    for i in 0..7 {
        for j in 0..7 {
            for k in 0..7 {
                let p = [
                    1350.0 + 150.0 * i as f64,
                    50.0 + 150.0 * j as f64,
                    800.0 + 150.0 * k as f64,
                ];
                let e = [1.0 + 1e-4 * p[1], -0.5 + 2e-4 * p[0], 0.8 - 1e-4 * p[2]];
                csv += &format!(
                    "{},{},{},{},{},{},1e-4,-2e-4,5e-5\n",
                    p[0], p[1], p[2], e[0], e[1], e[2]
                );
            }
        }
    }
    let samples = parse_samples("t.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

thread_local! {
    static TABLE: Vec<u8> = table_bytes();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn mutated_fanuc_programs_read_or_are_located(m in mutations()) {
        for (name, bytes) in FIXTURES {
            read(name, &mutate(bytes, &m))?;
        }
    }

    #[test]
    fn random_bytes_read_as_fanuc_or_are_located(
        bytes in prop::collection::vec(prop::sample::select(ALPHABET.to_vec()), 0..400),
    ) {
        read("random.ls", &bytes)?;
    }

    #[test]
    fn mutated_frame_files_read_or_are_located(m in mutations()) {
        let bytes = mutate(FRAMES, &m);
        let src = Source::new("SYSFRAME.VA", &bytes);
        match adwi_programs::fanuc::read_frames(&src) {
            Ok(f) => {
                for (_, frame) in f.user_frames.iter().chain(&f.tool_frames) {
                    prop_assert!(adwi_programs::bounds::option_frame_within(frame));
                }
            }
            Err(e) => located("SYSFRAME.VA", &bytes, e)?,
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// The whole job on mutated programs and frame files, with and without a robot: an
    /// error, or a program with only finite numbers in place of the targets'.
    #[test]
    fn the_job_never_panics_on_a_mutated_fanuc_program(m in mutations(), robot in any::<bool>(), mutate_frames in any::<bool>()) {
        for (name, bytes) in FIXTURES {
            let dir = tempfile::tempdir().unwrap();
            let table = dir.path().join("t.tbl");
            std::fs::write(&table, TABLE.with(|t| t.clone())).unwrap();
            let program = dir.path().join(name);
            let (program_bytes, frame_bytes) = if mutate_frames {
                (bytes.to_vec(), mutate(FRAMES, &m))
            } else {
                (mutate(bytes, &m), FRAMES.to_vec())
            };
            std::fs::write(&program, &program_bytes).unwrap();
            let frames_file = dir.path().join("SYSFRAME.VA");
            std::fs::write(&frames_file, &frame_bytes).unwrap();
            let mut options = CompensateOptions::new(&table, &program);
            if robot {
                options.robot = Some(
                    concat!(env!("CARGO_MANIFEST_DIR"), "/../../tables/kr150-2/robot.toml").into(),
                );
            }
            options.fanuc.frames_file = Some(frames_file);
            if let Ok(job) = CompensateJob::new(options) {
                let done = job.run().unwrap();
                prop_assert_eq!(done.report.targets.len(), job.program().targets.len());
                for t in &done.report.targets {
                    if let Some(c) = t.correction_mm {
                        prop_assert!(!c.is_nan());
                    }
                }
                let text = String::from_utf8_lossy(&done.output);
                prop_assert!(!text.contains("NaN") && !text.contains("inf"));
            }
        }
    }
}
