//! Hostile programs: the fixtures mutated byte by byte, and random bytes, through every
//! reader and the whole job. Every outcome is a program or an error located by file, line
//! and column; never a panic, never a non-finite number written. Every case goes through
//! every dialect (KRL `.src` and `.dat`, RAPID, URScript, CSV, G-code, Yaskawa), a fixed number of cases
//! (the same on every machine, a few seconds in all).

use adwi_programs::source::Source;
use adwi_programs::{CompensateJob, CompensateOptions, Error, Format};
use proptest::prelude::*;

const FIXTURES: [(&str, &[u8]); 7] = [
    (
        "weld.dat",
        include_bytes!("../../../tests/programs/weld.dat"),
    ),
    (
        "weld.src",
        include_bytes!("../../../tests/programs/weld.src"),
    ),
    (
        "cell.mod",
        include_bytes!("../../../tests/programs/cell.mod"),
    ),
    (
        "pick.script",
        include_bytes!("../../../tests/programs/pick.script"),
    ),
    (
        "targets.csv",
        include_bytes!("../../../tests/programs/targets.csv"),
    ),
    (
        "pocket.nc",
        include_bytes!("../../../tests/programs/pocket.nc"),
    ),
    (
        "bracket.jbi",
        include_bytes!("../../../tests/programs/bracket.jbi"),
    ),
];

/// Bytes that matter to the readers, and some that do not.
const ALPHABET: &[u8] = b"0123456789.-+eE{}[](),;:=!#%\"'\\ \t\r\nXYZABCSTpPGNIJR\xdf\x00";

/// A mutation: at a position (a fraction of the length), replace, insert or delete a byte.
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

/// Reads `bytes` as `name`'s format; an error must be located inside the file.
fn read(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    let src = Source::new(name, bytes);
    let result = match Format::from_path(name.as_ref()).unwrap() {
        Format::Krl => adwi_programs::krl::read(&src, None),
        Format::Rapid => adwi_programs::rapid::read(&src),
        Format::UrScript => adwi_programs::urscript::read(&src),
        Format::Csv => adwi_programs::csv::read(&src),
        Format::Gcode => adwi_programs::gcode::read(
            &src,
            &adwi_programs::gcode::GcodeOptions {
                work_offsets: vec![(54, [1750.0, 450.0, 1200.0, 0.0, 0.0, 0.0])],
                ..Default::default()
            },
        )
        .map(|r| r.program),
        Format::Yaskawa => adwi_programs::yaskawa::read(&src, &yaskawa_options()),
        Format::Fanuc => adwi_programs::fanuc::read(&src, &Default::default()),
        Format::Val3 => adwi_programs::staubli::read(&src, &[]),
    };
    match result {
        Ok(_) => Ok(()),
        Err(Error::Syntax {
            file, line, column, ..
        }) => {
            // Lines end with LF, CRLF or a CR alone.
            let lines = bytes
                .iter()
                .enumerate()
                .filter(|&(i, b)| *b == b'\n' || (*b == b'\r' && bytes.get(i + 1) != Some(&b'\n')))
                .count()
                + 1;
            prop_assert_eq!(file, name);
            prop_assert!(
                line >= 1 && line <= lines && column >= 1,
                "{}:{}",
                line,
                column
            );
            Ok(())
        }
        Err(e) => Err(TestCaseError::fail(format!("not a syntax error: {e}"))),
    }
}

/// A Yaskawa job's tools, user frames and pulses per degree (the bracket's cell).
fn yaskawa_options() -> adwi_programs::yaskawa::YaskawaOptions {
    adwi_programs::yaskawa::YaskawaOptions {
        tools: vec![(1, [0.0, 0.0, 180.0, 0.0, 0.0, 0.0])],
        users: vec![(1, [1600.0, 250.0, 750.0, 0.0, 0.0, 30.0])],
        pulses_per_deg: Some(vec![1456.356, 1456.356, 1350.0, 910.222, 910.222, 555.556]),
    }
}

/// A small table around the KR150-2 fixtures' targets: errors of 1-2 mm, orientation too.
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
    let samples =
        parse_samples("zero.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn mutated_fixtures_read_or_are_located(m in mutations()) {
        for (name, bytes) in FIXTURES {
            read(name, &mutate(bytes, &m))?;
        }
    }

    #[test]
    fn random_bytes_read_or_are_located(
        bytes in prop::collection::vec(prop::sample::select(ALPHABET.to_vec()), 0..400),
    ) {
        for (name, _) in FIXTURES {
            read(name, &bytes)?;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// The whole job on mutated programs, with and without a robot: an error or a
    /// program, and then only finite numbers in place of the targets'.
    #[test]
    fn the_job_never_panics_on_a_mutated_program(m in mutations(), robot in any::<bool>()) {
        for fixture in 0..FIXTURES.len() {
            job_on_a_mutated_program(fixture, &m, robot)?;
        }
    }
}

/// The whole job on fixture `fixture` mutated by `m`.
fn job_on_a_mutated_program(
    fixture: usize,
    m: &[(f64, u8, usize)],
    robot: bool,
) -> Result<(), TestCaseError> {
    {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("t.tbl");
        std::fs::write(&table, TABLE.with(|t| t.clone())).unwrap();
        let (name, bytes) = FIXTURES[fixture];
        let program = dir.path().join(name);
        std::fs::write(&program, mutate(bytes, m)).unwrap();
        let mut options = CompensateOptions::new(&table, &program);
        if robot {
            options.robot = Some(
                concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/../../tables/kr150-2/robot.toml"
                )
                .into(),
            );
        }
        options.tool = Some([0.0, 0.0, 100.0, 0.0, 0.0, 0.0]);
        options.base = Some([0.0; 6]);
        options.gcode.work_offsets = vec![(54, [1750.0, 450.0, 1200.0, 0.0, 0.0, 0.0])];
        options.yaskawa = yaskawa_options();
        if let Ok(job) = CompensateJob::new(options) {
            let done = job.run().unwrap();
            prop_assert_eq!(done.report.targets.len(), job.program().targets.len());
            for t in &done.report.targets {
                if let Some(c) = t.correction_mm {
                    prop_assert!(!c.is_nan());
                }
            }
            let text = String::from_utf8_lossy(&done.output);
            prop_assert!(
                !text.contains("NaN") || String::from_utf8_lossy(&mutate(bytes, m)).contains("NaN")
            );
        }
    }
    Ok(())
}

thread_local! {
    static TABLE: Vec<u8> = table_bytes();
}
