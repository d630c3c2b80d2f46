//! Hostile values and sizes: every number range-checked where it is read, nesting and
//! lines bounded, the inverse kinematics refusing what is not finite, CSV programs read
//! as sample files are, and messages that never carry a file's control bytes.

use std::path::{Path, PathBuf};
use std::time::Duration;

use adwi_programs::source::Source;
use adwi_programs::{CompensateJob, CompensateOptions, Error, TargetStatus};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// A small table around the KR150-2 fixtures' targets (errors of 1-2 mm).
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
                csv += &format!(
                    "{},{},{},{},{},{},1e-4,-2e-4,5e-5\n",
                    p[0],
                    p[1],
                    p[2],
                    1.0 + 1e-4 * p[1],
                    -0.5 + 2e-4 * p[0],
                    0.8 - 1e-4 * p[2]
                );
            }
        }
    }
    let samples = parse_samples("t.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

/// Runs `f` on another thread and fails the test if it takes longer than `seconds`,
/// rather than hang the test run.
fn within<T: Send + 'static>(seconds: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(seconds))
        .unwrap_or_else(|_| panic!("did not finish within {seconds} s"))
}

/// The job on `program` (written as `name`) with the KR150-2 robot; every target's status
/// and detail.
fn statuses(name: &str, program: &[u8], robot: Option<&str>) -> Vec<(TargetStatus, String)> {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, table_bytes()).unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, program).unwrap();
    let mut options = CompensateOptions::new(&table, &path);
    options.robot = robot.map(repo);
    options.tool = Some([0.0, 0.0, 100.0, 0.0, 0.0, 0.0]);
    options.base = Some([0.0; 6]);
    let job = CompensateJob::new(options).unwrap();
    let done = within(60, move || job.run().map(|d| d.report));
    done.unwrap()
        .targets
        .into_iter()
        .map(|t| (t.status, t.detail))
        .collect()
}

#[test]
fn rapid_lists_nested_25000_deep_are_refused_not_a_stack_overflow() {
    let mut text = b"MODULE M\nCONST robtarget p:=".to_vec();
    text.extend(vec![b'['; 25_000]);
    text.extend_from_slice(b";\nENDMODULE\n");
    // A small stack, as the reader must not need one deeper than its bound.
    let err = std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(move || {
            adwi_programs::rapid::read(&Source::new("deep.mod", &text))
                .err()
                .map(|e| e.to_string())
        })
        .unwrap()
        .join()
        .unwrap()
        .expect("refused");
    assert!(
        err.starts_with("deep.mod:2:")
            && err.contains(&format!(
                "nested more than {} deep",
                adwi_programs::rapid::MAX_NESTING
            )),
        "{err}"
    );
}

#[test]
fn numbers_beyond_their_bounds_are_invalid_targets_with_their_place() {
    // KRL: an angle of 1e308 is finite, and no orientation.
    let krl = b"DEF p( )\nLIN {X 1500,Y 200,Z 1200,A 1e308,B 90,C 0}\nLIN {X 1500,Y 200,Z 1200,A 0,B 90,C 0}\nEND\n";
    let s = statuses("p.src", krl, None);
    assert_eq!(s[0].0, TargetStatus::Invalid, "{s:?}");
    assert!(s[0].1.contains("1e308 at 2:"), "{s:?}");
    assert_eq!(s[1].0, TargetStatus::Ok, "{s:?}");
    // CSV: x = 1.7e308, and a position beyond a kilometre.
    let csv = b"x,y,z,a,b,c\n1.7e308,200,1200,0,90,0\n1500,2e6,1200,0,90,0\n1500,200,1200,0,90,0\n";
    let s = statuses("p.csv", csv, Some("tables/kr150-2/robot.toml"));
    assert_eq!(
        s.iter().map(|t| t.0).collect::<Vec<_>>(),
        [
            TargetStatus::Invalid,
            TargetStatus::Invalid,
            TargetStatus::Ok
        ],
        "{s:?}"
    );
    assert!(s[0].1.contains("1.7e308 at 2:1"), "{s:?}");
    assert!(s[1].1.contains("2e6 at 3:6"), "{s:?}");
    // RAPID: a quaternion of 1e307.
    let rapid = b"MODULE M\nCONST robtarget p1:=[[1500,200,1200],[1e307,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nPROC main()\nMoveL p1, v100, z1, tool0;\nENDPROC\nENDMODULE\n";
    let s = statuses("p.mod", rapid, Some("tables/kr150-2/robot.toml"));
    assert_eq!(s[0].0, TargetStatus::Invalid, "{s:?}");
    // URScript: a rotation of 1e200 rad (the UR5, solved numerically, once hung on it).
    let script = b"def p():\n  movel(p[1.5, 0.2, 1.2, 1e200, -1.17, -1.25], a=1.2, v=0.25)\nend\n";
    let s = statuses("p.script", script, Some("tables/ur5/robot.toml"));
    assert_eq!(s[0].0, TargetStatus::Invalid, "{s:?}");
    assert!(s[0].1.contains("1e200 at 2:"), "{s:?}");
}

#[test]
fn the_inverse_kinematics_refuses_a_pose_that_is_not_finite() {
    for robot in ["tables/ur5/robot.toml", "tables/kr150-2/robot.toml"] {
        let robot = adwi_robot::Robot::load(repo(robot)).unwrap();
        for pose in [
            nalgebra::Isometry3::translation(f64::NAN, 0.0, 500.0),
            nalgebra::Isometry3::translation(1e300, 1e300, 1e300),
            nalgebra::Isometry3::from_parts(
                nalgebra::Translation3::new(400.0, 0.0, 400.0),
                nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
                    f64::INFINITY,
                    0.0,
                    0.0,
                    0.0,
                )),
            ),
        ] {
            let seed = robot.home().to_vec();
            let r = robot.clone();
            let q = within(30, move || adwi_robot::ik::solve_near(&r, &pose, &seed));
            assert!(q.is_none(), "{q:?}");
        }
    }
}

#[test]
fn a_line_longer_than_the_bound_is_refused_with_its_length_before_it_is_split() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, table_bytes()).unwrap();
    let long = adwi_programs::bounds::MAX_LINE_BYTES + 10;
    for (name, line) in [
        ("p.csv", "1,".repeat(long / 2)),
        ("p.src", format!("LIN {{X 1{}}}", "0".repeat(long))),
        ("p.script", format!("movel({})", "[".repeat(long))),
        ("p.mod", format!("MoveL {}", "[".repeat(long))),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, format!("x,y,z\n{line}\n")).unwrap();
        let err = CompensateJob::new(CompensateOptions::new(&table, &path))
            .err()
            .expect("refused")
            .to_string();
        assert!(
            err.contains(":2:1: this line is ")
                && err.contains(&format!(
                    "more than the {} a program's line may have",
                    adwi_programs::bounds::MAX_LINE_BYTES
                )),
            "{name}: {err}"
        );
    }
}

#[test]
fn a_rapid_statement_without_its_semicolon_is_bounded_in_tokens() {
    let mut text = b"MODULE M\nVAR num a := 1".to_vec();
    for _ in 0..adwi_programs::rapid::MAX_STATEMENT_TOKENS {
        text.extend_from_slice(b"\n+");
    }
    let err = adwi_programs::rapid::read(&Source::new("m.mod", &text)).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("m.mod:2:1: a statement of more than"),
        "{err}"
    );
}

/// The CSV reader's targets' positions and configurations.
fn csv_targets(text: &[u8]) -> Result<Vec<([f64; 3], String)>, Error> {
    let p = adwi_programs::csv::read(&Source::new("t.csv", text))?;
    Ok(p.targets
        .iter()
        .map(|t| match &t.kind {
            adwi_programs::program::TargetKind::Cartesian(c) => {
                (c.position.map(|n| n.value), format!("{:?}", c.config))
            }
            _ => panic!("a CSV row is a Cartesian target"),
        })
        .collect())
}

#[test]
fn csv_programs_read_what_sample_files_read() {
    // A byte-order mark is not part of the first name.
    let t = csv_targets(b"\xef\xbb\xbfx,y,z\n1500,200,1200\n").unwrap();
    assert_eq!(t[0].0, [1500.0, 200.0, 1200.0]);
    // Decimal commas where semicolons separate.
    let t = csv_targets(b"x;y;z\n1500,5;200;1200,25\n").unwrap();
    assert_eq!(t[0].0, [1500.5, 200.0, 1200.25]);
    // Quoted fields, a separator inside one.
    let t = csv_targets(b"name,x,y,z\n\"P1, seam\",\"1500.5\",200,\"1200\"\n").unwrap();
    assert_eq!(t[0].0, [1500.5, 200.0, 1200.0]);
    // Configurations 0-254, as samples.
    let t = csv_targets(b"x,y,z,config\n1500,200,1200,200\n").unwrap();
    assert_eq!(t[0].1, "Configuration(200)");
    let err = csv_targets(b"x,y,z,config\n1500,200,1200,255\n").unwrap_err();
    assert!(err.to_string().contains("0-254"), "{err}");
    // Once a decimal comma is read, a decimal point is refused, and the reverse.
    let err = csv_targets(b"x;y;z\n1500,5;200.5;1200\n").unwrap_err();
    assert!(
        err.to_string()
            .starts_with("t.csv:2:8: (column 'y'): not a number with a decimal comma"),
        "{err}"
    );
}

#[test]
fn a_decimal_comma_is_written_back_as_a_comma() {
    let s = statuses("p.csv", b"x;y;z;a;b;c\n1500,5;200;1200,25;0;90;0\n", None);
    assert_eq!(s[0].0, TargetStatus::Ok, "{s:?}");
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, table_bytes()).unwrap();
    let path = dir.path().join("p.csv");
    std::fs::write(&path, b"x;y;z;a;b;c\n1500,5;200;1200,25;0;90;0\n").unwrap();
    let done = CompensateJob::new(CompensateOptions::new(&table, &path))
        .unwrap()
        .run()
        .unwrap();
    let text = String::from_utf8(done.output).unwrap();
    let row = text.lines().nth(1).unwrap();
    let fields: Vec<&str> = row.split(';').collect();
    assert!(
        fields[..3]
            .iter()
            .all(|f| !f.contains('.') && f.contains(',')),
        "{row}"
    );
    let x: f64 = fields[0].replace(',', ".").parse().unwrap();
    assert!(
        (x - 1500.5).abs() > 0.1 && (x - 1500.5).abs() < 5.0,
        "{row}"
    );
}

#[test]
fn a_syntax_error_never_carries_a_files_control_bytes() {
    let err = adwi_programs::csv::read(&Source::new(
        "t.csv",
        b"x,y,z\n1,2,\x1b[2J\x1b]0;owned\x07\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(!err.chars().any(|c| c.is_control()), "{err:?}");
    assert!(err.contains("\\u{1b}[2J"), "{err}");
}

#[test]
fn a_program_needing_more_memory_than_allowed_is_refused_before_it_is_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, table_bytes()).unwrap();
    let path = dir.path().join("p.csv");
    let mut text = String::from("x,y,z\n");
    for i in 0..20_000 {
        text += &format!("{},200,1200\n", 1400 + i % 500);
    }
    std::fs::write(&path, &text).unwrap();
    let mut options = CompensateOptions::new(&table, &path);
    // Room for the program and some thousand targets, not twenty thousand.
    options.max_memory_bytes = 3 * text.len() as u64 + 1000 * adwi_programs::BYTES_PER_TARGET;
    let err = CompensateJob::new(options.clone()).err().expect("refused");
    let Error::TooMuchMemory {
        targets,
        read_bytes: Some(read),
        estimated_bytes,
        limit_bytes,
        ..
    } = &err
    else {
        panic!("{err}");
    };
    assert!(*targets <= 1001 && *read < text.len() / 10, "{err}");
    assert!(*estimated_bytes > *limit_bytes, "{err}");
    assert!(
        err.to_string().contains("MB of memory, more than the"),
        "{err}"
    );
    // With the memory the estimate asks for, the job goes ahead.
    options.max_memory_bytes = estimated_bytes + 1_000_000;
    assert!(CompensateJob::new(options).is_ok());
}

#[test]
fn a_krl_partner_larger_than_a_program_may_be_is_refused_before_it_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, table_bytes()).unwrap();
    let program = dir.path().join("p.src");
    std::fs::write(
        &program,
        "DEF p( )\nLIN {X 1500,Y 200,Z 1200,A 0,B 90,C 0}\nEND\n",
    )
    .unwrap();
    // A sparse file of 2 GiB: refused by its size, in no time and no memory.
    let partner = std::fs::File::create(dir.path().join("p.dat")).unwrap();
    partner.set_len(2 << 30).unwrap();
    let err = within(20, move || {
        CompensateJob::new(CompensateOptions::new(&table, &program))
            .err()
            .map(|e| e.to_string())
    })
    .expect("refused");
    assert!(
        err.contains("p.dat: 2147483648 bytes, more than the"),
        "{err}"
    );
}
