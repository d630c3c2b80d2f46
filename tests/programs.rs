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

use crate::common::{build_ur5_hybrid, compensate, method_table, repo, tablec};

fn fixture(name: &str) -> PathBuf {
    repo("tests/programs").join(name)
}

fn kr150_robot() -> PathBuf {
    repo("tables/kr150-2/robot.toml")
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
    let kr = method_table(dir.path(), &kr, "kr-zero.tbl");
    let ur = zero_samples(
        dir.path(),
        "ur-zero.csv",
        [-800.0, -700.0, -200.0],
        [-150.0, 100.0, 500.0],
        50.0,
    );
    let ur = method_table(dir.path(), &ur, "ur-zero.tbl");
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
            crate::common::corrected_lines(&stdout) > 0,
            "{program}: {stdout}"
        );
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(fixture(program)).unwrap(),
            "{program}: {stdout}"
        );
    }
}

/// The UR5's hybrid table at 30 mm cells (`build_ur5_hybrid`) in `dir`, as
/// `ur5-hybrid.tbl`.
fn ur5_hybrid(dir: &Path) {
    build_ur5_hybrid(
        dir,
        repo("tables/ur5/robot.toml").to_str().unwrap(),
        &["--cell", "30"],
        "ur5-hybrid.tbl",
    );
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
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
        // The tool option stands for the TOOL_DATA[1] the inline form names.
        ("weld.src", Some([0.0, 0.0, 150.0, 0.0, 0.0, 0.0]), None),
    ] {
        let (job, done) = run_job(&table, &fixture(program), &kr150_robot(), |o| {
            o.tool = tool;
            o.base = base;
            // The arithmetic is checked here, at every orientation the fixtures write;
            // the samples' own (0, 90, 0) is the evidence tests' (tests/tcp_lever.rs).
            o.limits.beyond_evidence = true;
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
            adwi_programs::Format::Gcode => {
                adwi_programs::gcode::read(&src, &job.options().gcode).map(|r| r.program)
            }
            adwi_programs::Format::Yaskawa => {
                adwi_programs::yaskawa::read(&src, &job.options().yaskawa)
            }
            adwi_programs::Format::Fanuc => adwi_programs::fanuc::read(&src, &job.options().fanuc),
            adwi_programs::Format::Val3 => adwi_programs::staubli::read(&src, &[]),
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
                // RAPID: the module's gun and fixture; KRL: the frames the inline forms
                // select, the options standing for those not given; the table's point is
                // the flange.
                Some(u) => FrameChain {
                    base: u
                        .base
                        .unwrap_or_else(|| base.as_ref().map_or_else(Isometry3::identity, to_pose)),
                    tool: u
                        .tool
                        .unwrap_or_else(|| tool.as_ref().map_or_else(Isometry3::identity, to_pose)),
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
    ur5_hybrid(dir.path());
    let table = dir.path().join("ur5-hybrid.tbl");
    let (_, done) = run_job(
        &table,
        &fixture("pick.script"),
        &repo("tables/ur5/robot.toml"),
        |_| {},
    );
    let summary = done.report.summary();
    // `movel(pose_trans(approach, offset))`: an offset from a target the correction moves,
    // reported.
    assert_eq!((summary.corrected, summary.total), (7, 8), "{summary}");
    assert_eq!(
        done.report.first_not_corrected().map(|t| t.status.as_str()),
        Some("relative")
    );
    for t in done.report.targets.iter().filter(|t| t.status.corrected()) {
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
        let error = crate::common::printed_error(&String::from_utf8_lossy(&o.stdout));
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

/// The same arm described in MD-H and as URDF compensates a program alike, whichever
/// built the table: the URDF's flange is its `tool0`, where the controller's `set_tcp`
/// starts, 82.3 mm beyond the last joint's frame, not that frame (which put every
/// target's correction at a point 82.3 mm beyond the TCP); and a robot file takes the
/// table's point where the table records it on the flange, whatever frame the table's
/// chain ends in (a URDF whose last joint's frame lies 20 mm along its axis from the
/// others' made the MD-H file "20.000000 mm apart at home", refused).
#[test]
fn the_same_arm_in_md_h_and_as_urdf_compensates_alike() {
    let dir = tempfile::tempdir().unwrap();
    ur5_hybrid(dir.path());
    build_ur5_hybrid(
        dir.path(),
        repo("tables/ur5/robot.urdf").to_str().unwrap(),
        &["--cell", "30"],
        "ur5-hybrid-urdf.tbl",
    );
    // The same arm again, its last joint's frame 20 mm further along its axis and tool0
    // 20 mm nearer: its chain ends where neither of the others does.
    let urdf = std::fs::read_to_string(repo("tables/ur5/robot.urdf")).unwrap();
    let moved = urdf
        .replace(
            r#"<origin xyz="0.0 0.0 0.09465" rpy="-1.5707963267948966 0.0 0.0"/>"#,
            r#"<origin xyz="0.0 0.02 0.09465" rpy="-1.5707963267948966 0.0 0.0"/>"#,
        )
        .replace(
            r#"<origin xyz="0.0 0.0 0.0823" rpy="0.0 0.0 0.0"/>"#,
            r#"<origin xyz="0.0 0.0 0.0623" rpy="0.0 0.0 0.0"/>"#,
        );
    assert_eq!(
        moved.matches("0.02 0.09465").count() + moved.matches("0.0623").count(),
        2
    );
    let moved_path = dir.path().join("moved.urdf");
    std::fs::write(&moved_path, moved).unwrap();
    build_ur5_hybrid(
        dir.path(),
        moved_path.to_str().unwrap(),
        &["--cell", "30"],
        "ur5-hybrid-moved.tbl",
    );
    // The URDF gives no measured point: those tables' is the flange, 31 mm from the
    // script's TCP, a lever their samples of position alone cannot turn.
    for (built, beyond) in [
        ("ur5-hybrid.tbl", false),
        ("ur5-hybrid-urdf.tbl", true),
        ("ur5-hybrid-moved.tbl", true),
    ] {
        let table = dir.path().join(built);
        let robots = [
            repo("tables/ur5/robot.toml"),
            repo("tables/ur5/robot.urdf"),
            moved_path.clone(),
        ];
        let reports: Vec<Report> = robots
            .iter()
            .map(|robot| {
                run_job(&table, &fixture("pick.script"), robot, |o| {
                    o.limits.beyond_evidence = beyond;
                })
                .1
                .report
            })
            .collect();
        for other in &reports[1..] {
            same_commands(&reports[0], other, 7, 1e-6, Some(1e-9));
        }
    }
}

/// The KR150-2 written as a URDF (the shipped MD-H file's joints as origins and axes)
/// keeps a KRL target's written Status and Turn as the MD-H file does: a URDF is read in
/// its MD-H form, so it has the configurations (every `S` was `invalid` with a URDF, and
/// `XHOME`, at the wrist's singularity, moved J4 half a turn).
#[test]
fn a_urdf_arm_keeps_a_written_configuration_as_its_md_h_file() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let urdf = dir.path().join("kr150-2.urdf");
    let mut text = String::from("<robot name=\"kr150-2\"><link name=\"base_link\"/>");
    let mut parent = "base_link".to_string();
    for (i, (xyz, axis, [lo, hi])) in [
        ("0 0 0.75", "0 0 1", [-185.0f64, 185.0]),
        ("0.35 0 0", "0 1 0", [-146.0, 0.0]),
        ("1.25 0 0", "0 1 0", [-119.0, 155.0]),
        ("0 0 -0.055", "1 0 0", [-350.0, 350.0]),
        ("1.1 0 0", "0 1 0", [-125.0, 125.0]),
        ("0.23 0 0", "1 0 0", [-350.0, 350.0]),
    ]
    .into_iter()
    .enumerate()
    {
        let (lo, hi) = (lo.to_radians(), hi.to_radians());
        text += &format!(
            "<link name=\"link_{n}\"/><joint name=\"a{n}\" type=\"revolute\"><origin xyz=\"{xyz}\"/>\
             <parent link=\"{parent}\"/><child link=\"link_{n}\"/><axis xyz=\"{axis}\"/>\
             <limit effort=\"0\" lower=\"{lo}\" upper=\"{hi}\" velocity=\"1\"/></joint>",
            n = i + 1
        );
        parent = format!("link_{}", i + 1);
    }
    // tool0, the flange as KUKA frames it: z out of the flange (the MD-H file's frame 6).
    text += "<link name=\"tool0\"/><joint name=\"flange\" type=\"fixed\">\
             <origin rpy=\"0 1.5707963267948966 0\"/><parent link=\"link_6\"/>\
             <child link=\"tool0\"/></joint></robot>";
    std::fs::write(&urdf, text).unwrap();
    for program in ["weld.dat", "config.dat"] {
        let reports: Vec<Report> = [kr150_robot(), urdf.clone()]
            .iter()
            .map(|robot| {
                run_job(&table, &fixture(program), robot, |o| {
                    o.tool = Some([0.0; 6]);
                })
                .1
                .report
            })
            .collect();
        let corrected = if program == "weld.dat" { 6 } else { 0 };
        same_commands(&reports[0], &reports[1], corrected, 1e-6, Some(1e-9));
    }
}

/// A robot file that is not the table's nominal robot is refused before any target is
/// read, with how far apart the two are at home: a link 1 mm longer, or the last joint's
/// zero turned 0.001° (which moves no point of its axis: "0.000000 mm apart" alone said
/// they agree).
#[test]
fn a_robot_file_that_is_not_the_tables_robot_is_refused_with_the_gap() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let original = std::fs::read_to_string(repo("tables/kr150-2/robot.toml")).unwrap();
    let changed = |from: &str, to: &str, name: &str| {
        assert_eq!(original.matches(from).count(), 1, "{from}");
        let path = dir.path().join(name);
        std::fs::write(&path, original.replace(from, to)).unwrap();
        path
    };
    let a6 = "# A6 (flange)\na_mm = 0.0\nd_mm = 230.0\nalpha_deg = 0.0\nbeta_deg = 0.0\n";
    for (robot, said) in [
        (
            changed("a_mm = 1250.0", "a_mm = 1251.0", "longer.toml"),
            "1.000000 mm and 0.000000° apart at home",
        ),
        (
            changed(
                &format!("{a6}theta_offset_deg = 0.0"),
                &format!("{a6}theta_offset_deg = 0.001"),
                "turned.toml",
            ),
            "0.000000 mm and 0.001000° apart at home",
        ),
    ] {
        let mut o = CompensateOptions::new(&table, fixture("seam.mod"));
        o.robot = Some(robot);
        let Err(e) = CompensateJob::new(o) else {
            panic!("accepted");
        };
        let message = e.to_string();
        assert!(
            message
                .contains("it is not the table's nominal robot with the table's point as its tool")
                && message.ends_with(said),
            "{message}"
        );
    }
}

/// Two compensations of one program, the first with seven corrected: the same statuses,
/// commands to `command_mm`, and joints to `joints` (rad) when given.
/// Two reports of one program: `corrected` targets corrected in the first, and target by
/// target the same status and commands (to `command_mm`, and the joints to `joints` rad).
fn same_commands(
    first: &Report,
    second: &Report,
    corrected: usize,
    command_mm: f64,
    joints: Option<f64>,
) {
    assert_eq!(first.summary().corrected, corrected, "{}", first.summary());
    assert_eq!(first.targets.len(), second.targets.len());
    for (a, b) in first.targets.iter().zip(&second.targets) {
        assert_eq!(a.status.as_str(), b.status.as_str(), "{}", a.place());
        if let (Some(p), Some(q)) = (a.command_mm, b.command_mm) {
            for axis in 0..3 {
                assert!(
                    (p[axis] - q[axis]).abs() < command_mm,
                    "{}: {p:?} {q:?}",
                    a.place()
                );
            }
        }
        if let (Some(p), Some(q), Some(tolerance)) = (&a.command_joints, &b.command_joints, joints)
        {
            for (x, y) in p.iter().zip(q) {
                assert!((x - y).abs() < tolerance, "{}: {p:?} {q:?}", a.place());
            }
        }
    }
}

/// A hybrid table records where its point is on the flange: without a robot file, a
/// program's tool (`set_tcp`) is placed by that record, and the commands are those made
/// with the robot file (the whole program was refused before: "where the table's point is
/// on the flange is not known").
#[test]
fn a_hybrid_table_alone_places_a_programs_tool_by_the_point_it_records() {
    let dir = tempfile::tempdir().unwrap();
    ur5_hybrid(dir.path());
    let table = dir.path().join("ur5-hybrid.tbl");
    let with_robot = run_job(
        &table,
        &fixture("pick.script"),
        &repo("tables/ur5/robot.toml"),
        |_| {},
    )
    .1
    .report;
    let alone = CompensateJob::new(CompensateOptions::new(&table, fixture("pick.script")))
        .unwrap()
        .run()
        .unwrap()
        .report;
    // The record is f32: 1e-5 mm at 200 mm.
    same_commands(&alone, &with_robot, 7, 1e-5, None);
}

/// A CSV program with more joint columns than the robot has joints: its targets are
/// refused one by one, never a crash (the prismatic joints' reading asked the robot for a
/// joint it does not have).
#[test]
fn more_joint_columns_than_the_robot_has_are_refused_per_target() {
    let dir = tempfile::tempdir().unwrap();
    ur5_hybrid(dir.path());
    let program = dir.path().join("seven.csv");
    std::fs::write(
        &program,
        "x,y,z,a,b,c,j1,j2,j3,j4,j5,j6,j7\n-430.328,-6.274,-98.637,0,90,0,\
         -22.9333,-43.7192,135.3978,-94.7403,55.4168,-5.5522,3\n",
    )
    .unwrap();
    let (_, done) = run_job(
        &dir.path().join("ur5-hybrid.tbl"),
        &program,
        &repo("tables/ur5/robot.toml"),
        |_| {},
    );
    let summary = done.report.summary();
    assert_eq!((summary.corrected, summary.total), (0, 1), "{summary}");
}

/// A joint target of a robot of two joints (a positioner, say) is answered like any
/// other, never a crash (the Fanuc J2/J3 coupling's reading indexed a third joint on every
/// dialect).
#[test]
fn a_joint_target_of_a_two_joint_robot_is_answered() {
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let robot = dir.path().join("two.toml");
    std::fs::write(
        &robot,
        "name = \"two joints\"\n[[joints]]\nxyz_mm = [0.0, 0.0, 400.0]\nlimits_deg = [-170.0, 170.0]\n\
         [[joints]]\nxyz_mm = [1600.0, 0.0, 800.0]\naxis = [0.0, 1.0, 0.0]\nlimits_deg = [-90.0, 90.0]\n",
    )
    .unwrap();
    let program = dir.path().join("two.script");
    std::fs::write(&program, "def p():\n  movej([0.1, 0.2], a=1, v=1)\nend\n").unwrap();
    let (_, done) = run_job(&table, &program, &robot, |_| {});
    let summary = done.report.summary();
    assert_eq!(
        (summary.total, done.report.targets[0].kind),
        (1, "joints"),
        "{summary}"
    );
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
    use adwi_robot::{Configuration, InverseKinematics, Robot};
    use adwi_simulate::Scenario;
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let robot = Robot::load(kr150_robot()).unwrap();
    let scenario = Scenario::load(repo("tables/kr150-2/scenario.toml")).unwrap();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    // The KRL seam in its fixture and with its torch, as the configuration gives them; the
    // weld program's gun (TOOL_DATA[1]) as the tool option.
    let gun = [0.0, 0.0, 150.0, 0.0, 0.0, 0.0];
    for (program, tool, config) in [
        ("weld.dat", None, None),
        ("weld.src", Some(gun), None),
        ("targets.csv", None, None),
        ("cell.mod", None, None),
        ("seam.dat", None, Some(fixture("config.dat"))),
        ("seam.mod", None, None),
    ] {
        let (job, done) = run_job(&table, &fixture(program), &kr150_robot(), |o| {
            o.tool = tool;
            o.krl_config = config;
        });
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
                    let option_tool = tool.map_or_else(Isometry3::identity, |t| {
                        adwi_programs::frames::kuka_pose([t[0], t[1], t[2]], [t[3], t[4], t[5]])
                    });
                    let (tool, base) =
                        original
                            .uses
                            .first()
                            .map_or((option_tool, Isometry3::identity()), |u| {
                                (
                                    u.tool.unwrap_or(option_tool),
                                    u.base.unwrap_or_else(Isometry3::identity),
                                )
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
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
    assert_eq!(code, 3);
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
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
    assert_eq!(blocks.len(), 7, "{blocks:?}");
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
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
            // The postures are checked here, not the orientations the samples had.
            "--beyond-evidence",
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stdout.contains(
            "target                   place      kind        correction  joint change  status\n"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("XS1                      2:13       joints                                outside (no_neighbour)"),
        "{stdout}"
    );
    assert!(
        stdout
            .contains("XS2                      3:13       joints                                joint_jump (a joint moves 34.5"),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            "XS3                      4:13       joints       1.9467 mm       0.6798°  ok, beyond orientation\n"
        ),
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
    method_table(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
        assert_eq!(
            std::fs::read(d.join("weld.src")).unwrap(),
            original("weld.src")
        );
        assert_eq!(
            std::fs::read(d.join("weld.dat")).unwrap(),
            original("weld.dat")
        );
    }
    // The pair is still compensated into files of its own.
    let (code, stdout, stderr) = compensate(
        d,
        &[
            "kr150.tbl",
            "weld.src",
            "-o",
            "out.src",
            "--report",
            "out.csv",
            tool,
        ],
    );
    assert_eq!(code, 3, "{stdout}{stderr}");
}

/// The `program_xxh3` of every row of a report, and the hash of the program it names.
fn report_hashes(report: &str) -> Vec<String> {
    let mut lines = report.lines();
    assert!(lines
        .next()
        .unwrap()
        .ends_with(",residual,evidence,program_xxh3"));
    lines
        .map(|l| l.rsplit(',').next().unwrap().to_string())
        .collect()
}

#[test]
fn concurrent_compensations_leave_a_program_and_its_report_from_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    method_table(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
    method_table(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
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
        &[
            "kr150.tbl",
            "huge.csv",
            "-o",
            "huge-out.csv",
            "--robot",
            robot,
        ],
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

// ---------------------------------------------------------------------------------------
// Every motion instruction accounted for: each target corrected in the tool and base (work
// object) its motion uses, as the controller applies them, or reported with its place and
// reason. The fixtures are written as the vendors' tools write them (KSS 8 inline forms and
// a `$config.dat`, a RobotStudio module with Arc, Trigg, DO, Sync and Search moves, a
// PolyScope script with waypoints on a feature); every corrected target is checked by the
// table's own model at the TCP the program uses.

/// Where the table's own model lands a command: the flange commanded at `flange` lands at
/// its position plus the table's position error there, turned by the table's orientation
/// error; the TCP `tool` rides on it. The distance from `target_tcp`, mm.
fn landing_error_at_tcp_mm(
    table: &adwi_runtime::Table<adwi_runtime::AlignedBytes>,
    flange: &Isometry3<f64>,
    tool: &Isometry3<f64>,
    target_tcp: &Isometry3<f64>,
) -> f64 {
    let c = table.query(flange.translation.vector.into());
    assert_eq!(c.status, adwi_runtime::Status::Ok, "{flange:?}");
    let error = nalgebra::Vector3::from(c.position_error_mm);
    let turn = UnitQuaternion::from_scaled_axis(nalgebra::Vector3::from(c.orientation_error_rad));
    let landed = Isometry3::from_parts(
        (flange.translation.vector + error).into(),
        turn * flange.rotation,
    );
    ((landed * tool).translation.vector - target_tcp.translation.vector).norm()
}

/// The pose a Cartesian target writes (mm; URScript's metres scaled).
fn written_pose(target: &adwi_programs::program::ProgramTarget) -> Isometry3<f64> {
    let TargetKind::Cartesian(c) = &target.kind else {
        panic!("{} is not Cartesian", target.name)
    };
    let scale = c.unit.mm();
    let r = adwi_programs::frames::rotation_of(c.orientation.as_ref().unwrap()).unwrap();
    Isometry3::from_parts(
        nalgebra::Translation3::new(
            c.position[0].value * scale,
            c.position[1].value * scale,
            c.position[2].value * scale,
        ),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// A frame turned `a_deg` about z and shifted by `xyz` mm.
fn frame_z(xyz: [f64; 3], a_deg: f64) -> Isometry3<f64> {
    Isometry3::new(
        nalgebra::Vector3::from(xyz),
        nalgebra::Vector3::z() * a_deg.to_radians(),
    )
}

/// Each named target of `before` and `after` (the program as read and as written), in
/// `frames` (base, tool), landed by the table's model before and after compensation.
fn landings(
    table_path: &Path,
    before: &adwi_programs::Program,
    after: &adwi_programs::Program,
    frames: &[(&str, Isometry3<f64>, Isometry3<f64>)],
) -> Vec<(String, f64, f64)> {
    let table = adwi_runtime::Table::from_vec(std::fs::read(table_path).unwrap()).unwrap();
    let find = |p: &adwi_programs::Program, name: &str| {
        p.targets
            .iter()
            .find(|t| t.name == name)
            .unwrap_or_else(|| panic!("{name} not read"))
            .clone()
    };
    frames
        .iter()
        .map(|(name, base, tool)| {
            let target_tcp = base * written_pose(&find(before, name));
            let command_tcp = base * written_pose(&find(after, name));
            let land = |tcp: &Isometry3<f64>| {
                landing_error_at_tcp_mm(&table, &(tcp * tool.inverse()), tool, &target_tcp)
            };
            (name.to_string(), land(&target_tcp), land(&command_tcp))
        })
        .collect()
}

/// The report's line of `name` (the first, when several share it).
fn line_of<'r>(report: &'r Report, name: &str) -> &'r adwi_programs::TargetLine {
    report
        .targets
        .iter()
        .find(|t| t.name == name)
        .unwrap_or_else(|| panic!("no line for {name}"))
}

#[test]
fn krl_targets_land_at_their_tcp_in_the_tool_and_base_their_inline_forms_select() {
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let (job, done) = run_job(&table, &fixture("seam.dat"), &kr150_robot(), |o| {
        o.krl_config = Some(fixture("config.dat"));
    });
    let report = &done.report;
    for name in ["XP1", "XP2", "XP3", "XP4", "XP5", "XP6", "XSPARE"] {
        assert!(
            line_of(report, name).status.corrected(),
            "{name}: {report:?}"
        );
    }
    // The frame the inline form of P7 selects is not in the configuration: named.
    let xp7 = line_of(report, "XP7");
    assert_eq!(xp7.status.as_str(), "frame_unknown");
    assert!(
        xp7.detail
            .starts_with("work object BASE_DATA[3] not given (used at ")
            && xp7.detail.contains("seam.src:66:1)"),
        "{}",
        xp7.detail
    );
    // On the track: E1 moves the robot, which the table does not know.
    let xp8 = line_of(report, "XP8");
    assert_eq!(xp8.status.as_str(), "external_axis");
    assert!(xp8.detail.starts_with("E1 1500.0: "), "{}", xp8.detail);
    assert!(line_of(report, "XSPARE").detail.starts_with("unused: "));
    // The .src's own motions no run corrects (its LIN_REL, its two moves to $config.dat's
    // XHOME) are counted with the .dat's targets, placed where the .src writes them.
    assert_eq!(report.summary().total, 12);
    let rel = line_of(report, "LIN_REL");
    assert_eq!(rel.status.as_str(), "relative");
    assert!(rel.detail.ends_with("seam.src:49:1)"), "{}", rel.detail);
    // Their lines are placed in the .src, not past the .dat's last line (37): the CSV
    // gives no place in the .dat, and the .dat's own targets keep theirs.
    let in_partner: Vec<(&str, usize, usize)> = (report.targets.iter())
        .filter(|t| t.in_partner)
        .map(|t| (t.name.as_str(), t.line, t.column))
        .collect();
    assert_eq!(
        in_partner,
        [("XHOME", 25, 6), ("LIN_REL", 49, 1), ("XHOME", 75, 6)]
    );
    assert_eq!(
        (line_of(report, "XP1").line, line_of(report, "XP1").column),
        (18, 12)
    );
    let csv = report.to_csv();
    assert!(
        csv.lines()
            .any(|row| row.starts_with("LIN_REL,,,motion,relative,")),
        "{csv}"
    );
    assert!(
        csv.lines().any(|row| row.starts_with("XP1,18,12,")),
        "{csv}"
    );
    // By the table's own model, each corrected target lands at its TCP: the torch
    // (TOOL_DATA[1], 180 mm) and gripper (TOOL_DATA[2]) in the fixture (BASE_DATA[1], turned
    // 30°) and the second table (BASE_DATA[2]), as $config.dat declares them.
    let torch = frame_z([0.0, 0.0, 180.0], 0.0);
    let gripper = frame_z([0.0, 25.0, 120.0], 0.0);
    let fixture_base = frame_z([1600.0, 250.0, 750.0], 30.0);
    let table2 = frame_z([1400.0, 500.0, 900.0], 0.0);
    let partner = std::fs::read(fixture("seam.src")).unwrap();
    let partner = Source::new("seam.src", &partner);
    let after =
        adwi_programs::krl::read(&Source::new("out.dat", &done.output), Some(&partner)).unwrap();
    let landed = landings(
        &table,
        job.program(),
        &after,
        &[
            ("XP1", fixture_base, torch),
            ("XP2", fixture_base, torch),
            ("XP3", fixture_base, torch),
            ("XP4", fixture_base, torch),
            ("XP5", fixture_base, gripper),
            ("XP6", table2, gripper),
        ],
    );
    for (name, before, after) in &landed {
        eprintln!("{name}: {before:.4} mm uncompensated, {after:.2e} mm compensated");
        assert!(*before > 1.5, "{name}: {before}");
        // The written numbers' rounding (1e-4 mm, 1e-6°) and the fixed point's 1e-6 mm.
        assert!(*after < 2e-4, "{name}: {after}");
    }
    assert_eq!(
        check_against_query(dir.path(), &table, report, "seam.dat"),
        7
    );
}

#[test]
fn a_hybrid_tables_text_line_says_what_its_correction_rests_on() {
    // Corrected by the model alone, at an orientation no sample had: the text line says
    // both after `ok`, as the CSV report's residual and evidence columns do.
    let dir = tempfile::tempdir().unwrap();
    ur5_hybrid(dir.path());
    std::fs::write(
        dir.path().join("far.script"),
        "def far():\n  movel(p[-0.45, -0.26, 0.36, 0, 3.1416, 0], a=1.2, v=0.25)\n\
         \x20 movel(p[0.30, 0.30, 0.30, 0, 3.1416, 0], a=1.2, v=0.25)\nend\n",
    )
    .unwrap();
    let robot = repo("tables/ur5/robot.toml");
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            "ur5-hybrid.tbl",
            "far.script",
            "-o",
            "out.script",
            "--robot",
            robot.to_str().unwrap(),
            "--report",
            "far.csv",
        ],
    );
    assert_eq!(code, 0, "{stderr}");
    let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("movel")).collect();
    assert_eq!(lines.len(), 2, "{stdout}");
    for line in &lines {
        assert!(
            line.ends_with("  ok, model_only, beyond orientation"),
            "{line}"
        );
    }
    assert_eq!(crate::common::corrected_lines(&stdout), 2);
    let csv = std::fs::read_to_string(dir.path().join("far.csv")).unwrap();
    assert_eq!(csv.matches(",model_only,orientation,").count(), 2, "{csv}");
}

#[test]
fn a_circles_end_point_that_its_angle_passes_by_is_corrected_and_said_to_be_passed() {
    // `CA` ends the motion at the angle, elsewhere on the circle: the end point written is
    // still corrected (it defines the circle), and its line says the motion's end is not it.
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let program = dir.path().join("arc.src");
    std::fs::write(
        &program,
        "DEF arc( )\n  LIN {X 1700.0, Y 300.0, Z 1000.0, A 0.0, B 90.0, C 0.0}\n\
         \x20 CIRC {X 1750.0, Y 350.0, Z 1000.0, A 0.0, B 90.0, C 0.0}, \
         {X 1700.0, Y 400.0, Z 1000.0, A 0.0, B 90.0, C 0.0}, CA 270 C_DIS\n\
         \x20 CIRC {X 1750.0, Y 350.0, Z 1050.0, A 0.0, B 90.0, C 0.0}, \
         {X 1700.0, Y 400.0, Z 1050.0, A 0.0, B 90.0, C 0.0}\nEND\n",
    )
    .unwrap();
    let (_, done) = run_job(&table, &program, &kr150_robot(), |_| {});
    let lines: Vec<(&str, &str, &str)> = (done.report.targets.iter())
        .map(|t| (t.name.as_str(), t.status.as_str(), t.detail.as_str()))
        .collect();
    let noted = "CIRC … CA 270: corrected as a point defining the circle; the motion ends at the \
                 angle, a point not corrected on its own";
    assert_eq!(
        lines,
        [
            ("LIN", "ok", ""),
            ("CIRC", "ok", ""),
            ("CIRC", "ok", noted),
            ("CIRC", "ok", ""),
            ("CIRC", "ok", "")
        ]
    );
}

/// The text report's place column is as wide as the widest place the program itself
/// writes: a target at line 20,001, column 20,005 (11 characters) widens the header and
/// every line alike, so that the kind and the figures stay in their columns.
#[test]
fn a_place_wider_than_its_column_widens_the_column_for_every_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let table = method_table(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let mut program = String::from("DEF far()\n");
    program.push_str(&"; filler\n".repeat(19_999));
    program.push_str(&" ".repeat(20_000));
    program.push_str("LIN {X 1500,Y 200,Z 1200,A 0,B 90,C 0}\n");
    program.push_str("LIN {X 1600,Y 300,Z 1100,A 0,B 90,C 0}\nEND\n");
    std::fs::write(d.join("far.src"), program).unwrap();
    let (code, stdout, stderr) =
        compensate(d, &[table.to_str().unwrap(), "far.src", "-o", "out.src"]);
    assert_eq!(code, 0, "{stderr}");
    let lines: Vec<&str> = stdout.lines().take(3).collect();
    assert_eq!(
        lines[0],
        "target                   place       kind        correction  joint change  status",
        "{stdout}"
    );
    assert!(
        lines[1].starts_with("LIN                      20001:20005 cartesian "),
        "{stdout}"
    );
    assert!(
        lines[2].starts_with("LIN                      20002:5     cartesian "),
        "{stdout}"
    );
    // The kind and the correction start where the header's do.
    for line in &lines[1..] {
        assert_eq!(line.find("cartesian"), lines[0].find("kind"), "{stdout}");
        assert_eq!(
            line.find(" mm"),
            lines[0].find("correction").map(|c| c + 7),
            "{stdout}"
        );
    }
}

#[test]
fn krl_frames_not_given_are_named_and_a_src_whose_targets_live_in_its_dat_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let table = method_table(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let table = table.to_str().unwrap();
    for name in ["seam.src", "seam.dat", "config.dat"] {
        std::fs::copy(fixture(name), d.join(name)).unwrap();
    }
    // Without the configuration, TOOL_DATA[1] is named, never corrected as the flange.
    let (code, stdout, _) = compensate(d, &[table, "seam.dat", "-o", "out.dat"]);
    assert_eq!(code, 3, "{stdout}");
    assert!(
        stdout.contains("XP1                      18:12         cartesian                             frame_unknown (tool TOOL_DATA[1] not given (used at seam.src:33:1): give it in the KRL configuration (--krl-config), or as the tool option)"),
        "{stdout}"
    );
    assert!(
        stdout
            .contains("1 of 12 targets corrected; left unchanged: 1 external_axis, 7 frame_unknown, 2 not_declared, 1 relative"),
        "{stdout}"
    );
    // The .src's motions no run corrects are placed where the .src writes them, the place
    // column as wide as their places (the header's too).
    assert!(
        stdout.contains("LIN_REL                  seam.src:49:1 motion                                relative (LIN_REL: "),
        "{stdout}"
    );
    assert!(
        stdout.starts_with(
            "target                   place         kind        correction  joint change  status\n"
        ),
        "{stdout}"
    );
    // The .src holds motions, its targets are in the .dat: refused, naming the .dat.
    let (code, stdout, stderr) = compensate(
        d,
        &[
            table,
            "seam.src",
            "-o",
            "out.src",
            "--krl-config",
            "config.dat",
        ],
    );
    assert_eq!(code, 1, "{stdout}");
    assert_eq!(
        stderr.trim(),
        "error: seam.src:25:1: PTP moves the robot, but the program holds no target it can correct: its motions' targets are declared in seam.dat; compensate that file (the motions that use them are read from this one)"
    );
    assert!(!d.join("out.src").exists());
    // A .src whose .dat holds no target is refused for its own motions' reasons, not
    // sent to the .dat (which would refuse as holding nothing).
    std::fs::write(
        d.join("lowdyn.src"),
        "DEF lowdyn()\n   DECL AXIS jtgt\n   jtgt = $AXIS_ACT_MEAS\n   PTP jtgt\nEND\n",
    )
    .unwrap();
    std::fs::write(d.join("lowdyn.dat"), "DEFDAT lowdyn\nENDDAT\n").unwrap();
    let (code, _, stderr) = compensate(d, &[table, "lowdyn.src", "-o", "low.src"]);
    assert_eq!(code, 1, "{stderr}");
    assert_eq!(
        stderr.trim(),
        "error: lowdyn.src:4:4: PTP moves the robot, but the program holds no target it can correct (dynamic: PTP jtgt: declared without a value, given when the program runs)"
    );
    // The .src reports what it writes itself: LIN_REL, and XHOME of $config.dat.
    let options = {
        let mut o = CompensateOptions::new(d.join("kr150.tbl"), d.join("seam.src"));
        o.krl_config = Some(d.join("config.dat"));
        o
    };
    assert!(CompensateJob::new(options).is_err());
    // --strict: any target unaccounted is exit status 3, and nothing written.
    let (code, _, stderr) = compensate(
        d,
        &[
            table,
            "seam.dat",
            "-o",
            "strict.dat",
            "--krl-config",
            "config.dat",
            "--strict",
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stderr.contains("5 of 12 targets not corrected (strict: nothing written); the first: XP7 (32:12) frame_unknown: work object BASE_DATA[3] not given"),
        "{stderr}"
    );
    assert!(!d.join("strict.dat").exists());
}

#[test]
fn rapid_arc_trigg_do_sync_search_and_array_targets_land_with_the_torch_in_the_fixture() {
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let (job, done) = run_job(&table, &fixture("seam.mod"), &kr150_robot(), |_| {});
    let report = &done.report;
    let statuses: Vec<(String, String, usize)> = report
        .targets
        .iter()
        .map(|t| (t.name.clone(), t.status.as_str().to_string(), t.line))
        .collect();
    let expected = [
        ("pApproach", "ok", 16),
        ("pSeamStart", "ok", 17),
        ("pSeam{1}", "ok", 18),
        ("pSeam{2}", "ok", 18),
        ("pSeam{3}", "ok", 18),
        ("pSeamEnd", "ok", 19),
        ("pTrigg", "ok", 20),
        ("pDO", "ok", 21),
        ("pSync", "ok", 22),
        ("pSearchEnd", "ok", 23),
        ("pOffsOnly", "relative", 24),
        ("pTrack", "external_axis", 25),
        ("pSpot", "unknown_motion", 26),
        ("MoveL", "dynamic", 43),
        ("MoveL", "relative", 44),
        ("MoveL", "relative", 45),
        ("SpotL", "unknown_motion", 47),
    ];
    let expected: Vec<(String, String, usize)> = expected
        .iter()
        .map(|(n, s, l)| (n.to_string(), s.to_string(), *l))
        .collect();
    assert_eq!(statuses, expected);
    assert!(
        line_of(report, "pOffsOnly")
            .detail
            .starts_with("used only by MoveL Offs(pOffsOnly,0,0,50)"),
        "{report:?}"
    );
    let torch = frame_z([0.0, 0.0, 180.0], 0.0);
    let w = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        0.965925826,
        0.0,
        0.0,
        0.258819045,
    ));
    let fixture_base = Isometry3::from_parts(nalgebra::Translation3::new(1600.0, 250.0, 750.0), w);
    let after = adwi_programs::rapid::read(&Source::new("out.mod", &done.output)).unwrap();
    let names = [
        "pApproach",
        "pSeamStart",
        "pSeam{1}",
        "pSeam{2}",
        "pSeam{3}",
        "pSeamEnd",
        "pTrigg",
        "pDO",
        "pSync",
        "pSearchEnd",
    ];
    let frames: Vec<_> = names.iter().map(|n| (*n, fixture_base, torch)).collect();
    for (name, before, after) in landings(&table, job.program(), &after, &frames) {
        eprintln!("{name}: {before:.4} mm uncompensated, {after:.2e} mm compensated");
        assert!(before > 1.5, "{name}: {before}");
        assert!(after < 2e-4, "{name}: {after}");
    }
    // Nothing else changed: the refused targets and every other byte are as written.
    let out = String::from_utf8(done.output.clone()).unwrap();
    let original = std::fs::read_to_string(fixture("seam.mod")).unwrap();
    for line in [24, 25, 26, 43, 44, 45, 47] {
        assert_eq!(out.lines().nth(line - 1), original.lines().nth(line - 1));
    }
}

#[test]
fn polyscope_waypoints_through_get_inverse_kin_and_a_feature_land_by_the_hybrid_model() {
    let dir = tempfile::tempdir().unwrap();
    ur5_hybrid(dir.path());
    let table_path = dir.path().join("ur5-hybrid.tbl");
    let (_, done) = run_job(
        &table_path,
        &fixture("waypoints.script"),
        &repo("tables/ur5/robot.toml"),
        |_| {},
    );
    let report = &done.report;
    let statuses: Vec<(&str, &str, usize)> = report
        .targets
        .iter()
        .map(|t| (t.name.as_str(), t.status.as_str(), t.line))
        .collect();
    assert_eq!(
        statuses,
        [
            ("Waypoint_1_p", "ok", 19),
            ("Waypoint_2_p", "ok", 21),
            ("movel", "ok", 35),
            ("movep", "ok", 38),
            ("movel", "relative", 41),
            ("movej", "ok", 44),
        ]
    );
    // Independently of the reader's frames: the waypoints on Plane_1 are Plane_1 · p, in
    // metres and rotation vectors as PolyScope writes them.
    let pose_m = |v: [f64; 6]| {
        Isometry3::new(
            nalgebra::Vector3::new(v[0], v[1], v[2]) * 1000.0,
            nalgebra::Vector3::new(v[3], v[4], v[5]),
        )
    };
    let plane = pose_m([-0.45, -0.2, 0.02, 0.0, 0.0, 0.4]);
    let literals = |bytes: &[u8]| -> Vec<[f64; 6]> {
        let text = String::from_utf8(bytes.to_vec()).unwrap();
        text.lines()
            .filter(|l| l.contains("pose_trans(Plane_1, p["))
            .map(|l| {
                let inner = l.split("p[").nth(1).unwrap().split(']').next().unwrap();
                let v: Vec<f64> = inner
                    .split(',')
                    .map(|x| x.trim().parse().unwrap())
                    .collect();
                v.try_into().unwrap()
            })
            .collect()
    };
    let table = adwi_runtime::Table::from_vec(std::fs::read(&table_path).unwrap()).unwrap();
    let original = std::fs::read(fixture("waypoints.script")).unwrap();
    let lines: Vec<&adwi_programs::TargetLine> = report
        .targets
        .iter()
        .filter(|t| t.name == "movel" || t.name == "movep")
        .filter(|t| t.status.corrected())
        .collect();
    for ((p, c), line) in literals(&original)
        .into_iter()
        .zip(literals(&done.output))
        .zip(lines)
    {
        let target = plane * pose_m(p);
        let command = plane * pose_m(c);
        // The TCP set_tcp sets is the table's point (the UR5's 31 mm tool).
        let point = nalgebra::Vector3::from(line.point_mm.unwrap());
        assert!(
            (target.translation.vector - point).norm() < 1e-6,
            "{}",
            line.place()
        );
        let q: Vec<f64> = line
            .command_joints
            .as_ref()
            .unwrap()
            .iter()
            .map(|v| v.to_radians())
            .collect();
        let at = command.translation.vector;
        let c = table.query_with_joints(&adwi_runtime::Target::at([at.x, at.y, at.z]), &q);
        assert_eq!(c.status, adwi_runtime::Status::Ok);
        let landed = at + nalgebra::Vector3::from(c.position_error_mm);
        let miss = (landed - target.translation.vector).norm();
        let before = {
            let t = target.translation.vector;
            let c = table.query_with_joints(&adwi_runtime::Target::at([t.x, t.y, t.z]), &q);
            (t + nalgebra::Vector3::from(c.position_error_mm) - t).norm()
        };
        eprintln!(
            "{}: {before:.4} mm uncompensated, {miss:.2e} mm compensated",
            line.place()
        );
        assert!(before > 1.0, "{}: {before}", line.place());
        // 12 decimals of a metre: the fixed point's 1e-6 mm.
        assert!(miss < 1e-5, "{}: {miss}", line.place());
    }
}

#[test]
fn cr_only_line_ends_read_as_lf_and_utf16_and_programs_of_another_dialect_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let table = method_table(d, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let table = table.to_str().unwrap();
    let crlf = std::fs::read(fixture("seam.dat")).unwrap();
    let cr: Vec<u8> = String::from_utf8(crlf.clone())
        .unwrap()
        .replace("\r\n", "\r")
        .into_bytes();
    std::fs::write(d.join("seam.dat"), &crlf).unwrap();
    std::fs::copy(fixture("seam.src"), d.join("seam.src")).unwrap();
    std::fs::create_dir(d.join("cr")).unwrap();
    std::fs::write(d.join("cr/seam.dat"), &cr).unwrap();
    let src_cr = String::from_utf8(std::fs::read(fixture("seam.src")).unwrap())
        .unwrap()
        .replace("\r\n", "\r");
    std::fs::write(d.join("cr/seam.src"), src_cr).unwrap();
    let config = fixture("config.dat");
    let config = config.to_str().unwrap();
    let run = |program: &str, out: &str| {
        compensate(
            d,
            &[
                table,
                program,
                "-o",
                out,
                "--krl-config",
                config,
                "--report",
                &format!("{out}.csv"),
            ],
        )
    };
    let (code_lf, stdout_lf, _) = run("seam.dat", "lf.dat");
    let (code_cr, stdout_cr, _) = run("cr/seam.dat", "cr.dat");
    assert_eq!((code_lf, code_cr), (3, 3));
    // The same lines, places and figures: a CR ends a line as a CRLF does (the columns'
    // padding aside: the partner's places are three characters longer in cr/).
    let words = |text: &str| -> Vec<String> {
        text.lines()
            .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
            .collect()
    };
    assert_eq!(
        words(&stdout_lf.replace("seam.src", "cr/seam.src")),
        words(&stdout_cr),
        "{stdout_cr}"
    );
    assert!(
        stdout_cr.contains("7 of 12 targets corrected"),
        "{stdout_cr}"
    );
    let written_cr = std::fs::read(d.join("cr.dat")).unwrap();
    let written_lf = String::from_utf8(std::fs::read(d.join("lf.dat")).unwrap()).unwrap();
    assert_eq!(written_cr, written_lf.replace("\r\n", "\r").into_bytes());
    // UTF-16 with its byte-order mark: refused by name, nothing written.
    let utf16: Vec<u8> = [0xff, 0xfe]
        .into_iter()
        .chain(crlf.iter().flat_map(|b| [*b, 0]))
        .collect();
    std::fs::create_dir(d.join("u16")).unwrap();
    std::fs::write(d.join("u16/seam.dat"), utf16).unwrap();
    let (code, _, stderr) = compensate(d, &[table, "u16/seam.dat", "-o", "u16.dat"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("u16/seam.dat:1:1: UTF-16 text (byte-order mark FF FE)"),
        "{stderr}"
    );
    assert!(!d.join("u16.dat").exists());
    // A RAPID module and a PolyScope script under KRL's extension: refused by name.
    std::fs::copy(fixture("seam.mod"), d.join("module.src")).unwrap();
    let (code, _, stderr) = compensate(d, &[table, "module.src", "-o", "module-out.src"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("module.src:1:1: this reads as ABB RAPID ('MODULE' at its line 1), not KUKA KRL as its extension says"),
        "{stderr}"
    );
    std::fs::copy(fixture("waypoints.script"), d.join("waypoints.dat")).unwrap();
    let (code, _, stderr) = compensate(d, &[table, "waypoints.dat", "-o", "w-out.dat"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("this reads as URScript ('def' at its line 1)"),
        "{stderr}"
    );
    // A file that moves the robot without a target this reader finds is an error, never
    // "0 of 0 targets corrected".
    std::fs::write(d.join("moves.mod"), "MODULE Moves\n  PROC main()\n    MoveL pElsewhere, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n").unwrap();
    let (code, _, stderr) = compensate(d, &[table, "moves.mod", "-o", "moves-out.mod"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("moves.mod:3:5: MoveL moves the robot, but the program holds no target it can correct (not_declared: MoveL pElsewhere: not declared in this module"), "{stderr}");
    assert!(!d.join("moves-out.mod").exists());
    std::fs::write(d.join("empty.src"), "DEF empty( )\nEND\n").unwrap();
    let (code, _, stderr) = compensate(d, &[table, "empty.src", "-o", "empty-out.src"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("no target and no motion found"), "{stderr}");
}

/// A KRL Status and Turn, or a RAPID robconf, on a robot without closed-form
/// configurations (seven axes) names the written configuration it cannot keep, as a Fanuc
/// `CONFIG` or a VAL3 `config` does, and leaves the target as written.
#[test]
fn a_krl_status_or_rapid_robconf_a_robot_cannot_keep_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let krl = dir.path().join("s.src");
    std::fs::write(
        &krl,
        "DEF s( )\nLIN {X 600,Y 0,Z 500,A 0,B 90,C 0,S 'B110',T 'B10'}\nEND\n",
    )
    .unwrap();
    let rapid = dir.path().join("m.mod");
    std::fs::write(
        &rapid,
        "MODULE m\n  PROC main()\n    MoveL [[600,0,500],[0,0,1,0],[0,0,0,1],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n  ENDPROC\nENDMODULE\n",
    )
    .unwrap();
    for (program, written) in [(&krl, "S 'B110', T 'B10'"), (&rapid, "robconf [0,0,0,1]")] {
        let mut o = CompensateOptions::new(&table, program);
        o.robot = Some(repo("tables/iiwa14/robot.toml"));
        let done = CompensateJob::new(o).unwrap().run().unwrap();
        let line = &done.report.targets[0];
        assert_eq!(line.status.as_str(), "invalid", "{}", line.detail);
        assert_eq!(
            line.detail,
            format!(
                "the written configuration ({written}) cannot be told apart on this robot file \
                 (KUKA LBR iiwa 14 R820: no closed-form inverse kinematics: 7 joints, not 6 \
                 (needs six MD-H joints with α1, α3, α4, α5 = ±90°, α2 = 0° or 180°, β = 0, \
                 a4 = a5 = a6 = d5 = 0, a2 > 0)): left as written, not corrected in a posture \
                 the program does not give"
            )
        );
    }
}

/// Targets whose wrist is at its singularity (J5 at 0° and a billionth of a degree either
/// side) in a written configuration: where no posture in it reaches the target or its
/// command, one in the other wrist configuration does, and the refusal says so, with J5,
/// rather than only that no posture reaches it.
#[test]
fn a_command_across_the_wrist_singularity_is_refused_naming_it() {
    use adwi_robot::{InverseKinematics, Robot};
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let robot = Robot::load(kr150_robot()).unwrap();
    let ik = InverseKinematics::new(&robot).unwrap();
    let mut rows = String::from("name,x,y,z,a,b,c,config\n");
    for (k, j5_deg) in [0.0, 1e-9, -1e-9].into_iter().enumerate() {
        let q = [0.2, -1.4, 1.6, 0.3, f64::to_radians(j5_deg), 0.2];
        let pose = robot.tcp_pose(&q);
        let config = ik
            .solve(&pose)
            .into_iter()
            .min_by(|a, b| {
                let d = |s: &[f64; 6]| s.iter().zip(&q).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
                d(&a.q_rad).total_cmp(&d(&b.q_rad))
            })
            .unwrap()
            .config;
        let abc =
            adwi_samples::pose::kuka_abc_deg_from_rotation(&pose.rotation.to_rotation_matrix());
        let p = pose.translation.vector;
        rows += &format!(
            "P{k},{},{},{},{},{},{},{}\n",
            p.x,
            p.y,
            p.z,
            abc[0],
            abc[1],
            abc[2],
            config.bits()
        );
    }
    let program = dir.path().join("wrist.csv");
    std::fs::write(&program, rows).unwrap();
    let (_, done) = run_job(&table, &program, &kr150_robot(), |_| {});
    let refused: Vec<&adwi_programs::TargetLine> = done
        .report
        .targets
        .iter()
        .filter(|t| t.status.as_str() == "ik_failed")
        .collect();
    assert!(!refused.is_empty(), "{}", done.report.summary());
    for t in refused {
        assert!(
            t.detail.contains(
                "configuration: one reaches it across the wrist's (J5 through 0°, axes 4 and 6 aligned) singularity"
            ),
            "{}",
            t.detail
        );
    }
}
