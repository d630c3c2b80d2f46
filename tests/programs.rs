//! Robot programs compensated offline (`tablec compensate`): a fixture program per format
//! (`tests/programs/`), compensated with the KR150-2 table, a UR5 hybrid table and tables
//! that correct nothing; every command checked against `tablec query`, and a simulated
//! KR150-2 executing the compensated programs.

use std::path::{Path, PathBuf};

use adwi_programs::frames::FrameChain;
use adwi_programs::program::{Orientation, TargetKind};
use adwi_programs::source::Source;
use adwi_programs::{CompensateJob, CompensateOptions, Report};
use nalgebra::{Isometry3, UnitQuaternion};

use crate::common::{build_ur5_hybrid, repo, tablec};

fn fixture(name: &str) -> PathBuf {
    repo("tests/programs").join(name)
}

fn kr150_robot() -> PathBuf {
    repo("tables/kr150-2/robot.toml")
}

/// `tablec build` of `samples` into `dir/out`, serving the method's own field (the figures
/// checked here are those of the programs' arithmetic, not of the field's choice); it must
/// succeed.
fn build(dir: &Path, samples: &Path, out: &str) -> PathBuf {
    let o = tablec(
        &[
            "build",
            "-q",
            samples.to_str().unwrap(),
            "--served-field",
            "method",
            "-o",
            out,
        ],
        dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join(out)
}

/// Samples with zero errors on a lattice over `min..=max` (mm, step mm), with zero
/// orientation errors: a table that corrects nothing.
fn zero_samples(dir: &Path, name: &str, min: [f64; 3], max: [f64; 3], step: f64) -> PathBuf {
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    let count = |a: usize| ((max[a] - min[a]) / step).round() as usize;
    for i in 0..=count(0) {
        for j in 0..=count(1) {
            for k in 0..=count(2) {
                let p = [
                    min[0] + i as f64 * step,
                    min[1] + j as f64 * step,
                    min[2] + k as f64 * step,
                ];
                csv += &format!("{},{},{},0,0,0,0,0,0\n", p[0], p[1], p[2]);
            }
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, csv).unwrap();
    path
}

/// `tablec compensate` with `args`; returns its exit code and standard output.
fn compensate(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let mut all = vec!["compensate"];
    all.extend_from_slice(args);
    let o = tablec(&all, dir);
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn a_table_that_corrects_nothing_reproduces_every_program_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let kr = zero_samples(
        dir.path(),
        "kr-zero.csv",
        [1300.0, 0.0, 800.0],
        [2200.0, 900.0, 1700.0],
        100.0,
    );
    let kr = build(dir.path(), &kr, "kr-zero.tbl");
    let ur = zero_samples(
        dir.path(),
        "ur-zero.csv",
        [-800.0, -700.0, -200.0],
        [-150.0, 100.0, 500.0],
        50.0,
    );
    let ur = build(dir.path(), &ur, "ur-zero.tbl");
    let ur5 = repo("tables/ur5/robot.toml");
    for (table, program, robot) in [
        (&kr, "weld.dat", kr150_robot()),
        (&kr, "weld.src", kr150_robot()),
        (&kr, "cell.mod", kr150_robot()),
        (&kr, "targets.csv", kr150_robot()),
        (&ur, "pick.script", ur5.clone()),
    ] {
        let out = dir.path().join(format!("out-{program}"));
        let (code, stdout, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                fixture(program).to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--robot",
                robot.to_str().unwrap(),
            ],
        );
        assert!(code == 0 || code == 3, "{program}: {stderr}");
        // Targets were corrected (by zero), not skipped.
        assert!(
            stdout.lines().any(|l| l.contains(" ok ")),
            "{program}: {stdout}"
        );
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(fixture(program)).unwrap(),
            "{program}: {stdout}"
        );
    }
}

/// The job of `program` with `table`, the KR150-2 robot and `tweak`, run.
fn run_job(
    table: &Path,
    program: &Path,
    robot: &Path,
    tweak: impl FnOnce(&mut CompensateOptions),
) -> (CompensateJob, adwi_programs::Compensated) {
    let mut options = CompensateOptions::new(table, program);
    options.robot = Some(robot.to_path_buf());
    tweak(&mut options);
    let job = CompensateJob::new(options).unwrap();
    let done = job.run().unwrap();
    (job, done)
}

/// `tablec query --targets` at every corrected target's table point: its command columns
/// must be the job's commands to 1e-9 mm.
fn check_against_query(dir: &Path, table: &Path, report: &Report, what: &str) -> usize {
    let ok: Vec<_> = report
        .targets
        .iter()
        .filter(|t| t.status.corrected())
        .collect();
    let mut csv = String::from("x,y,z\n");
    for t in &ok {
        let p = t.point_mm.unwrap();
        csv += &format!("{},{},{}\n", p[0], p[1], p[2]);
    }
    std::fs::write(dir.join("points.csv"), csv).unwrap();
    let o = tablec(
        &[
            "query",
            table.to_str().unwrap(),
            "--targets",
            "points.csv",
            "-o",
            "answers.csv",
        ],
        dir,
    );
    assert!(
        o.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let answers = std::fs::read_to_string(dir.join("answers.csv")).unwrap();
    let rows: Vec<Vec<String>> = answers
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    assert_eq!(rows.len(), ok.len());
    for (t, row) in ok.iter().zip(&rows) {
        assert_eq!(row[18], "converged", "{what} {}", t.place());
        let command: Vec<f64> = row[12..15].iter().map(|v| v.parse().unwrap()).collect();
        let mine = t.command_mm.unwrap();
        for a in 0..3 {
            assert!(
                (command[a] - mine[a]).abs() <= 1e-9,
                "{what} {}: query {command:?}, job {mine:?}",
                t.place()
            );
        }
    }
    ok.len()
}

#[test]
fn kr150_commands_are_tablec_querys_and_the_written_numbers_hold_them() {
    let dir = tempfile::tempdir().unwrap();
    let table = build(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let mut checked = 0;
    for (program, tool, base) in [
        ("weld.dat", None, None),
        ("weld.src", None, None),
        ("targets.csv", None, None),
        ("cell.mod", None, None),
        // A tool and a base given as options turn the chain for every KRL target.
        (
            "weld.dat",
            Some([0.0, 0.0, 150.0, 0.0, 0.0, 0.0]),
            Some([-150.0, 20.0, 0.0, 0.5, 0.0, 0.0]),
        ),
    ] {
        let (job, done) = run_job(&table, &fixture(program), &kr150_robot(), |o| {
            o.tool = tool;
            o.base = base;
        });
        checked += check_against_query(dir.path(), &table, &done.report, program);
        // The written program holds every command to 1e-4 mm: read back, through the frames.
        let name = format!("out-{program}");
        let src = Source::new(&name, &done.output);
        let partner = std::fs::read(fixture(
            &program
                .replace(".dat", ".x")
                .replace(".src", ".dat")
                .replace(".x", ".src"),
        ))
        .unwrap_or_default();
        let partner = Source::new("partner", &partner);
        let written = match job.program().format {
            adwi_programs::Format::Krl => adwi_programs::krl::read(&src, Some(&partner)),
            adwi_programs::Format::Rapid => adwi_programs::rapid::read(&src),
            adwi_programs::Format::Csv => adwi_programs::csv::read(&src),
            adwi_programs::Format::UrScript => adwi_programs::urscript::read(&src),
        }
        .unwrap();
        assert_eq!(written.targets.len(), done.report.targets.len());
        let to_pose =
            |t: &[f64; 6]| adwi_programs::frames::kuka_pose([t[0], t[1], t[2]], [t[3], t[4], t[5]]);
        for (target, line) in written.targets.iter().zip(&done.report.targets) {
            let TargetKind::Cartesian(c) = &target.kind else {
                continue;
            };
            if !line.status.corrected() {
                continue;
            }
            let rotation =
                adwi_programs::frames::rotation_of(c.orientation.as_ref().unwrap()).unwrap();
            let pose = Isometry3::from_parts(
                nalgebra::Translation3::new(
                    c.position[0].value,
                    c.position[1].value,
                    c.position[2].value,
                ),
                UnitQuaternion::from_rotation_matrix(&rotation),
            );
            let chain = match target.uses.first() {
                // RAPID: the module's gun and fixture; the table's point is the flange.
                Some(u) => FrameChain {
                    base: u.base.unwrap(),
                    tool: u.tool.unwrap(),
                    table_tool: Isometry3::identity(),
                },
                None => FrameChain {
                    base: base.as_ref().map_or_else(Isometry3::identity, to_pose),
                    tool: tool.as_ref().map_or_else(Isometry3::identity, to_pose),
                    table_tool: Isometry3::identity(),
                },
            };
            let point = chain.table_point(&pose);
            let expected = nalgebra::Vector3::from(line.command_mm.unwrap());
            let gap = (point.translation.vector - expected).norm();
            assert!(
                gap < 2e-4,
                "{program} {}: written {:?}, command {expected:?}",
                line.place(),
                point.translation.vector
            );
            if let Some(Orientation::KukaAbcDeg(_)) = &c.orientation {
                assert!(c.orientation.is_some());
            }
        }
    }
    assert!(checked >= 20, "{checked} targets checked");
}

#[test]
fn ur5_hybrid_commands_land_on_their_targets_by_tablec_query() {
    let dir = tempfile::tempdir().unwrap();
    build_ur5_hybrid(
        dir.path(),
        repo("tables/ur5/robot.toml").to_str().unwrap(),
        &["--cell", "30"],
        "ur5-hybrid.tbl",
    );
    let table = dir.path().join("ur5-hybrid.tbl");
    let (_, done) = run_job(
        &table,
        &fixture("pick.script"),
        &repo("tables/ur5/robot.toml"),
        |_| {},
    );
    let summary = done.report.summary();
    assert_eq!(summary.corrected, summary.total, "{summary}");
    assert_eq!(summary.total, 7);
    for t in &done.report.targets {
        let c = t.command_mm.unwrap();
        let joints: Vec<String> = t
            .command_joints
            .as_ref()
            .unwrap()
            .iter()
            .map(|v| format!("{v}"))
            .collect();
        let (x, y, z) = (
            format!("{}", c[0]),
            format!("{}", c[1]),
            format!("{}", c[2]),
        );
        let joints = joints.join(",");
        let o = tablec(
            &[
                "query",
                table.to_str().unwrap(),
                &x,
                &y,
                &z,
                "--joints",
                &joints,
            ],
            dir.path(),
        );
        // Shortest round-trip decimals: tablec reads the very same posture.
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout);
        let error: Vec<f64> = stdout
            .lines()
            .find_map(|l| l.strip_prefix("error"))
            .unwrap()
            .split_whitespace()
            .take(3)
            .map(|v| v.parse().unwrap())
            .collect();
        let p = t.point_mm.unwrap();
        // command + error(command) = target, to the fixed point's tolerance (1e-6 mm) and
        // the query's printing (1e-9 mm).
        for a in 0..3 {
            assert!(
                (c[a] + error[a] - p[a]).abs() <= 1e-6 + 1e-9,
                "{}: {c:?} + {error:?} vs {p:?}",
                t.place()
            );
        }
    }
}

/// Mean and max of a list.
fn stats(v: &[f64]) -> (f64, f64) {
    (
        v.iter().sum::<f64>() / v.len() as f64,
        v.iter().copied().fold(0.0, f64::max),
    )
}

#[test]
fn a_simulated_kr150_executing_the_compensated_programs_lands_within_the_tables_accuracy() {
    use adwi_robot::simulate::Scenario;
    use adwi_robot::{Configuration, InverseKinematics, Robot};
    let dir = tempfile::tempdir().unwrap();
    let table = build(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let robot = Robot::load(kr150_robot()).unwrap();
    let scenario = Scenario::load(repo("tables/kr150-2/scenario.toml")).unwrap();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for program in ["weld.dat", "weld.src", "targets.csv", "cell.mod"] {
        let (job, done) = run_job(&table, &fixture(program), &kr150_robot(), |_| {});
        let name = format!("out-{program}");
        let src = Source::new(&name, &done.output);
        let partner = std::fs::read(fixture(
            &program
                .replace(".dat", ".x")
                .replace(".src", ".dat")
                .replace(".x", ".src"),
        ))
        .unwrap_or_default();
        let partner = Source::new("partner", &partner);
        let read = |src: &Source| match job.program().format {
            adwi_programs::Format::Krl => adwi_programs::krl::read(src, Some(&partner)),
            adwi_programs::Format::Rapid => adwi_programs::rapid::read(src),
            _ => adwi_programs::csv::read(src),
        };
        let written = read(&src).unwrap();
        for ((original, compensated), line) in job
            .program()
            .targets
            .iter()
            .zip(&written.targets)
            .zip(&done.report.targets)
        {
            if !line.status.corrected() {
                continue;
            }
            match (&original.kind, &compensated.kind) {
                (TargetKind::Cartesian(o), TargetKind::Cartesian(c)) => {
                    let (tool, base) = original
                        .uses
                        .first()
                        .map_or((Isometry3::identity(), Isometry3::identity()), |u| {
                            (u.tool.unwrap(), u.base.unwrap())
                        });
                    let pose = |t: &adwi_programs::program::CartesianTarget| {
                        let r = adwi_programs::frames::rotation_of(t.orientation.as_ref().unwrap())
                            .unwrap();
                        base * Isometry3::from_parts(
                            nalgebra::Translation3::new(
                                t.position[0].value,
                                t.position[1].value,
                                t.position[2].value,
                            ),
                            UnitQuaternion::from_rotation_matrix(&r),
                        )
                    };
                    // The robot carries the program's tool; the controller solves the nominal
                    // inverse kinematics (configuration 4, as the programs write it).
                    let with_tool = robot
                        .with_parts(
                            robot.name.clone(),
                            robot.base(),
                            adwi_robot::model::transform_from_isometry(&tool),
                            robot.home().to_vec(),
                        )
                        .unwrap();
                    let actual_robot = scenario.actual_robot(&with_tool).unwrap();
                    let ik = InverseKinematics::new(&with_tool).unwrap();
                    let target = pose(o);
                    for (command, out) in [(pose(o), &mut before), (pose(c), &mut after)] {
                        let q = ik
                            .solve_one(&command, Configuration::from_bits(4))
                            .unwrap()
                            .q_rad;
                        let landed = scenario.actual_pose(&actual_robot, &q);
                        out.push((landed.translation.vector - target.translation.vector).norm());
                    }
                }
                (TargetKind::Joints(o), TargetKind::Joints(c)) => {
                    let actual_robot = scenario.actual_robot(&robot).unwrap();
                    let q = |t: &adwi_programs::program::JointTarget| {
                        t.joints
                            .iter()
                            .map(|n| n.value.to_radians())
                            .collect::<Vec<f64>>()
                    };
                    let target = robot.tcp_pose(&q(o));
                    for (command, out) in [(q(o), &mut before), (q(c), &mut after)] {
                        let landed = scenario.actual_pose(&actual_robot, &command);
                        out.push((landed.translation.vector - target.translation.vector).norm());
                    }
                }
                _ => panic!("{program}: the targets of the two programs differ"),
            }
        }
    }
    let (before_mean, before_max) = stats(&before);
    let (after_mean, after_max) = stats(&after);
    eprintln!(
        "simulated KR150-2, {} targets: uncompensated {before_mean:.4} mean / {before_max:.4} max mm, compensated {after_mean:.4} / {after_max:.4} mm",
        before.len()
    );
    assert!(before.len() >= 15);
    assert!(before_mean > 1.5, "{before_mean}");
    // The table's accuracy on held-out poses: 0.0657 mm mean, 0.15 mm max (README).
    assert!(
        after_mean < 0.1 && after_max < 0.2,
        "{after_mean} {after_max}"
    );
}

#[test]
fn targets_not_corrected_are_counted_and_strict_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let table = build(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let table = table.to_str().unwrap();
    let program = fixture("targets.csv");
    let program = program.to_str().unwrap();
    // One row lies beyond the table: left unchanged, exit status 3, the report says why.
    let (code, stdout, _) = compensate(
        dir.path(),
        &[table, program, "-o", "out.csv", "--report", "report.csv"],
    );
    assert_eq!(code, 3, "{stdout}");
    assert!(
        stdout.contains("3 of 4 targets corrected; left unchanged: 1 outside"),
        "{stdout}"
    );
    let report = std::fs::read_to_string(dir.path().join("report.csv")).unwrap();
    assert_eq!(report.lines().count(), 5);
    assert!(
        report
            .lines()
            .nth(4)
            .unwrap()
            .starts_with("row 6,6,1,cartesian,outside,outside_grid,"),
        "{report}"
    );
    let out = std::fs::read_to_string(dir.path().join("out.csv")).unwrap();
    assert!(out.ends_with("far;3500;0;1200;0;90;0\n"), "{out}");
    // --strict: an error, and no file written.
    let (code, _, stderr) = compensate(
        dir.path(),
        &[table, program, "-o", "strict.csv", "--strict"],
    );
    assert_eq!(code, 1);
    assert!(stderr.contains("1 of 4 targets not corrected (strict: nothing written); the first: row 6 (6:1) outside: outside_grid"), "{stderr}");
    assert!(!dir.path().join("strict.csv").exists());
    // A bound below every correction refuses them all: the output is the input.
    let (code, stdout, _) = compensate(
        dir.path(),
        &[
            table,
            program,
            "-o",
            "small.csv",
            "--max-correction-mm",
            "0.5",
        ],
    );
    assert_eq!(code, 3);
    assert!(
        stdout.contains("left unchanged: 1 outside, 3 too_large"),
        "{stdout}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("small.csv")).unwrap(),
        std::fs::read(fixture("targets.csv")).unwrap()
    );
    // The output is never an input.
    std::fs::copy(fixture("targets.csv"), dir.path().join("mine.csv")).unwrap();
    let (code, _, stderr) = compensate(dir.path(), &[table, "mine.csv", "-o", "mine.csv"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("refusing to write mine.csv: it is the input mine.csv"),
        "{stderr}"
    );
    // A malformed program: file, line and column, nothing written.
    std::fs::write(
        dir.path().join("bad.src"),
        "DEF bad( )\r\nLIN {X 1500,Y 2oo,Z 1200}\r\nEND\r\n",
    )
    .unwrap();
    let (code, _, stderr) = compensate(dir.path(), &[table, "bad.src", "-o", "bad-out.src"]);
    assert_eq!(code, 1);
    assert_eq!(stderr.trim(), "error: bad.src:2:15: Y must be a number");
    assert!(!dir.path().join("bad-out.src").exists());
}

#[test]
fn a_million_targets_are_sized_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let table = build(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let mut csv = String::with_capacity(30_000_000);
    csv.push_str("x,y,z,a,b,c\n");
    for i in 0..1_000_000 {
        csv += &format!("{}.5,200,1200,0,90,0\n", 1400 + i % 700);
    }
    let program = dir.path().join("million.csv");
    std::fs::write(&program, csv).unwrap();
    let mut options = CompensateOptions::new(&table, &program);
    options.robot = Some(kr150_robot());
    options.max_seconds = 10.0;
    let start = std::time::Instant::now();
    let error = CompensateJob::new(options).err().expect("refused");
    let seconds = start.elapsed().as_secs_f64();
    eprintln!("a million targets refused in {seconds:.2} s: {error}");
    // Reading stops at the bound (10 s at 3e-5 s a target): 333,334 targets, then the
    // estimate for the whole file.
    assert!(
        matches!(
            error,
            adwi_programs::Error::TooLarge {
                targets: 333_334,
                read_bytes: Some(_),
                ..
            }
        ),
        "{error}"
    );
    let text = error.to_string();
    assert!(
        text.contains("23000012 bytes, more than 333334 targets in its first "),
        "{text}"
    );
    assert!(
        text.contains(" bytes: about 30 s of work, more than the 10 s allowed"),
        "{text}"
    );
    // A third of the file read, nothing corrected: seconds where the work would take 30.
    assert!(seconds < 10.0, "{seconds} s");
}

/// Every `tablec` command of docs/programs.md, run as written from a folder where the
/// repository's `tables/` and `tests/` are at hand; the lines of the `text` block that
/// follows a command block must be among what its last command printed.
#[test]
fn docs_examples_run_as_written() {
    let doc = std::fs::read_to_string(repo("docs/programs.md")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for link in ["tables", "tests"] {
        std::os::unix::fs::symlink(repo(link), dir.path().join(link)).unwrap();
    }
    // (the commands of a sh block, the lines of the first text block after it).
    let mut blocks: Vec<(Vec<String>, Vec<String>)> = Vec::new();
    let mut fence: Option<&str> = None;
    let mut awaiting_output = false;
    for line in doc.lines() {
        match fence {
            None if line == "```sh" => {
                fence = Some("sh");
                blocks.push((Vec::new(), Vec::new()));
                awaiting_output = true;
            }
            None if line == "```text" => {
                fence = Some(if awaiting_output { "output" } else { "text" })
            }
            None if line.starts_with("```") => fence = Some("other"),
            Some(f) if line == "```" => {
                awaiting_output &= f != "output";
                fence = None;
            }
            Some("sh") => blocks.last_mut().unwrap().0.push(line.to_string()),
            Some("output") => blocks.last_mut().unwrap().1.push(line.to_string()),
            _ => {}
        }
    }
    assert_eq!(blocks.len(), 5, "{blocks:?}");
    for (commands, expected) in &blocks {
        let mut output = String::new();
        for command in commands {
            let args: Vec<&str> = command
                .strip_prefix("tablec ")
                .expect("a tablec command")
                .split_whitespace()
                .collect();
            let o = tablec(&args, dir.path());
            let code = o.status.code().unwrap_or(-1);
            assert!(
                code == 0 || code == 3,
                "{command}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            output = String::from_utf8_lossy(&o.stdout).into_owned()
                + &String::from_utf8_lossy(&o.stderr);
        }
        for line in expected {
            assert!(
                output.lines().any(|l| l.trim_end() == line.trim_end()),
                "{commands:?}: '{line}' not in\n{output}"
            );
        }
    }
}

#[test]
fn a_posture_near_the_wrist_singularity_is_refused_not_flipped() {
    let dir = tempfile::tempdir().unwrap();
    let table = build(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    // A5 at -0.002°: the correction's small turn of the flange swings A4 and A6; at -1° it
    // does not. At +0.01° the wrist is not flipped, a configuration the KR150-2 samples
    // (configuration 4) do not hold.
    std::fs::write(
        dir.path().join("wrist.dat"),
        "DEFDAT WRIST\n\
         DECL E6AXIS XS1={A1 15.0,A2 -70.0,A3 100.0,A4 30.0,A5 0.01,A6 -30.0}\n\
         DECL E6AXIS XS2={A1 15.0,A2 -70.0,A3 100.0,A4 30.0,A5 -0.002,A6 -30.0}\n\
         DECL E6AXIS XS3={A1 15.0,A2 -70.0,A3 100.0,A4 30.0,A5 -1.0,A6 -30.0}\n\
         ENDDAT\n",
    )
    .unwrap();
    let robot = kr150_robot();
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            "wrist.dat",
            "-o",
            "out.dat",
            "--robot",
            robot.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stdout.contains("XS1                      2:13    joints     outside (no_neighbour)"),
        "{stdout}"
    );
    assert!(
        stdout
            .contains("XS2                      3:13    joints     joint_jump (a joint moves 34.5"),
        "{stdout}"
    );
    assert!(
        stdout.contains("XS3                      4:13    joints     ok 1.9467 mm 0.6798 ° joint"),
        "{stdout}"
    );
    let out = std::fs::read_to_string(dir.path().join("out.dat")).unwrap();
    assert!(
        out.contains("XS2={A1 15.0,A2 -70.0,A3 100.0,A4 30.0,A5 -0.002,A6 -30.0}"),
        "{out}"
    );
}

/// Copies the KRL fixtures `weld.src` and `weld.dat` into `dir`.
fn weld_pair(dir: &Path) {
    for name in ["weld.src", "weld.dat"] {
        std::fs::copy(fixture(name), dir.join(name)).unwrap();
    }
}

#[test]
fn no_output_names_an_input_a_krl_programs_partner_included_by_any_path() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    build(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    weld_pair(d);
    let original = |name: &str| std::fs::read(fixture(name)).unwrap();
    std::os::unix::fs::symlink(d.join("weld.dat"), d.join("link.dat")).unwrap();
    std::fs::hard_link(d.join("weld.src"), d.join("hard.src")).unwrap();
    let tool = "--tool=0,0,100,0,0,0";
    for (program, output, report) in [
        ("weld.src", "weld.dat", None),
        ("weld.dat", "weld.src", None),
        ("weld.src", "out.src", Some("weld.dat")),
        ("weld.dat", "out.dat", Some("weld.src")),
        ("weld.src", "./weld.dat", None),
        ("weld.src", "link.dat", None),
        ("weld.dat", "hard.src", None),
        ("weld.src", "out.src", Some("../weld.dat")),
    ] {
        let mut args = vec!["kr150.tbl", program, "-o", output, tool];
        if let Some(r) = report {
            args.extend(["--report", r]);
        }
        // `../weld.dat` seen from a folder of hard links: the partner by another path.
        let cwd = if report == Some("../weld.dat") {
            std::fs::create_dir_all(d.join("inside")).unwrap();
            for name in ["kr150.tbl", "weld.src", "weld.dat"] {
                let _ = std::fs::hard_link(d.join(name), d.join("inside").join(name));
            }
            d.join("inside")
        } else {
            d.to_path_buf()
        };
        let (code, stdout, stderr) = compensate(&cwd, &args);
        assert_eq!(code, 1, "{args:?}: {stdout}{stderr}");
        assert!(stderr.contains("refusing to write"), "{args:?}: {stderr}");
        assert_eq!(std::fs::read(d.join("weld.src")).unwrap(), original("weld.src"));
        assert_eq!(std::fs::read(d.join("weld.dat")).unwrap(), original("weld.dat"));
    }
    // The pair is still compensated into files of its own.
    let (code, stdout, stderr) = compensate(
        d,
        &["kr150.tbl", "weld.src", "-o", "out.src", "--report", "out.csv", tool],
    );
    assert_eq!(code, 3, "{stdout}{stderr}");
}

/// The `program_xxh3` of every row of a report, and the hash of the program it names.
fn report_hashes(report: &str) -> Vec<String> {
    let mut lines = report.lines();
    assert!(lines.next().unwrap().ends_with(",residual,program_xxh3"));
    lines
        .map(|l| l.rsplit(',').next().unwrap().to_string())
        .collect()
}

#[test]
fn concurrent_compensations_leave_a_program_and_its_report_from_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    build(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    // Two programs whose compensations differ.
    let a = std::fs::read_to_string(fixture("targets.csv")).unwrap();
    std::fs::write(d.join("a.csv"), &a).unwrap();
    std::fs::write(d.join("b.csv"), a.replace("1500.0;200.0", "1510.0;210.0")).unwrap();
    let run = |program: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_tablec"))
            .args(["compensate", "kr150.tbl", program, "-o", "o.csv"])
            .args(["--report", "o.rep", "-q"])
            .current_dir(d)
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap()
    };
    let mut hashes = std::collections::BTreeSet::new();
    for trial in 0..150 {
        let (mut first, mut second) = (run("a.csv"), run("b.csv"));
        assert!(matches!(first.wait().unwrap().code(), Some(0 | 3)));
        assert!(matches!(second.wait().unwrap().code(), Some(0 | 3)));
        let program = std::fs::read(d.join("o.csv")).unwrap();
        let hash = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&program));
        let report = std::fs::read_to_string(d.join("o.rep")).unwrap();
        let named = report_hashes(&report);
        assert!(!named.is_empty());
        assert!(
            named.iter().all(|h| *h == hash),
            "trial {trial}: the program's hash is {hash}, the report names {named:?}"
        );
        hashes.insert(hash);
    }
    // Both programs won some trials' race, or at least the outputs are the two runs'.
    assert!(!hashes.is_empty() && hashes.len() <= 2, "{hashes:?}");
}

#[test]
fn a_hostile_program_is_an_error_or_an_invalid_target_never_an_abort_or_a_hang() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    build(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let robot = kr150_robot();
    let robot = robot.to_str().unwrap();
    // RAPID lists 25,000 deep: a located error (exit 1), not a stack overflow (134).
    let mut deep = b"MODULE M\nCONST robtarget p:=".to_vec();
    deep.extend(vec![b'['; 25_000]);
    deep.extend_from_slice(b";\nENDMODULE\n");
    std::fs::write(d.join("deep.mod"), deep).unwrap();
    let (code, _, stderr) = compensate(d, &["kr150.tbl", "deep.mod", "-o", "deep-out.mod"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("deep.mod:2:"), "{stderr}");
    // Values beyond every bound: reported invalid (exit 3), quickly, the rest corrected.
    std::fs::write(
        d.join("huge.csv"),
        "x,y,z,a,b,c\n1.7e308,200,1200,0,90,0\n1e307,1e307,1e307,0,90,0\n1500,200,1200,0,90,0\n",
    )
    .unwrap();
    let started = std::time::Instant::now();
    let (code, stdout, stderr) = compensate(
        d,
        &["kr150.tbl", "huge.csv", "-o", "huge-out.csv", "--robot", robot],
    );
    assert_eq!(code, 3, "{stdout}{stderr}");
    assert!(started.elapsed().as_secs() < 60);
    assert!(
        stdout.contains("1 of 3 targets corrected; left unchanged: 2 invalid"),
        "{stdout}"
    );
    std::fs::write(
        d.join("huge.src"),
        "DEF huge( )\nLIN {X 1500,Y 200,Z 1200,A 1e308,B 90,C 0}\nEND\n",
    )
    .unwrap();
    let (code, stdout, _) = compensate(d, &["kr150.tbl", "huge.src", "-o", "huge-out.src"]);
    assert_eq!(code, 3, "{stdout}");
    assert!(stdout.contains("invalid"), "{stdout}");
}
