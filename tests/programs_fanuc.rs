//! Fanuc TP programs (`.ls`) compensated offline (`tablec compensate`, format `fanuc`): a
//! weld program as a teach pendant saves it (`tests/programs/fanuc_weld.ls`, CRLF) and a
//! raster as an offline tool writes it (`fanuc_gen.ls`), their frames from the
//! controller's `SYSFRAME.VA` (`fanuc_sysframe.va`), with the KR150-2 table and a table
//! that corrects nothing. Every written position is read back through its user and tool
//! frames and checked against `tablec query`; every motion that is not corrected is
//! reported by its reason.

use std::path::{Path, PathBuf};

use adwi_programs::fanuc::FanucOptions;
use adwi_programs::frames::{rotation_of, FrameChain};
use adwi_programs::program::TargetKind;
use adwi_programs::source::Source;
use adwi_programs::{CompensateJob, CompensateOptions, Compensated};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::common::{compensate, method_table, repo, tablec};

fn fixture(name: &str) -> PathBuf {
    repo(&format!("tests/programs/{name}"))
}

fn frames_file() -> PathBuf {
    fixture("fanuc_sysframe.va")
}

fn robot() -> PathBuf {
    repo("tables/kr150-2/robot.toml")
}

fn kr150_table(dir: &Path) -> PathBuf {
    method_table(dir, &repo("tables/kr150-2/samples.csv"), "kr150.tbl")
}

/// `tablec query --targets` at `points` (base frame, mm): per point, the predicted error.
fn query(dir: &Path, table: &Path, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut csv = String::from("x,y,z\n");
    for p in points {
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
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let answers = std::fs::read_to_string(dir.join("answers.csv")).unwrap();
    let rows: Vec<[f64; 3]> = answers
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let f = |i: usize| v[i].parse::<f64>().unwrap();
            [f(3), f(4), f(5)]
        })
        .collect();
    assert_eq!(rows.len(), points.len());
    rows
}

/// The job on a fixture with the KR150-2 robot and the frame file; the fixtures' joint
/// positions count J3 as its robot file does (`--fanuc-j23 0`).
fn job(table: &Path, program: &Path) -> (CompensateJob, Compensated) {
    let mut options = CompensateOptions::new(table, program);
    options.robot = Some(robot());
    options.fanuc.frames_file = Some(frames_file());
    options.fanuc_j23 = Some(0.0);
    let job = CompensateJob::new(options).unwrap();
    let done = job.run().unwrap();
    (job, done)
}

/// The frame file's frames, as the reader takes them.
fn frames() -> FanucOptions {
    let bytes = std::fs::read(frames_file()).unwrap();
    adwi_programs::fanuc::read_frames(&Source::new("fanuc_sysframe.va", &bytes)).unwrap()
}

#[test]
fn a_table_that_corrects_nothing_reproduces_fanuc_programs_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    for i in 0..=9 {
        for j in 0..=9 {
            for k in 0..=9 {
                let p = [
                    1300.0 + 100.0 * i as f64,
                    100.0 * j as f64,
                    800.0 + 100.0 * k as f64,
                ];
                csv += &format!("{},{},{},0,0,0,0,0,0\n", p[0], p[1], p[2]);
            }
        }
    }
    std::fs::write(dir.path().join("zero.csv"), csv).unwrap();
    let table = method_table(dir.path(), &dir.path().join("zero.csv"), "zero.tbl");
    for (program, corrected) in [("fanuc_weld.ls", 7), ("fanuc_gen.ls", 41)] {
        let out = dir.path().join("out.ls");
        let (code, stdout, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                fixture(program).to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--robot",
                robot().to_str().unwrap(),
                "--fanuc-j23",
                "0",
                "--fanuc-frames",
                frames_file().to_str().unwrap(),
            ],
        );
        assert!(code == 0 || code == 3, "{program}: {stderr}");
        assert_eq!(
            crate::common::corrected_lines(&stdout),
            corrected,
            "{stdout}"
        );
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(fixture(program)).unwrap(),
            "{program}: {stdout}"
        );
    }
}

#[test]
fn kr150_fanuc_positions_land_on_their_targets_through_their_user_and_tool_frames() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let kr150 = adwi_robot::Robot::load(robot()).unwrap();
    let options = frames();
    for (program, expected) in [("fanuc_weld.ls", 7), ("fanuc_gen.ls", 41)] {
        let (_, done) = job(&table, &fixture(program));
        let summary = done.report.summary();
        assert_eq!(summary.corrected, expected, "{program}: {summary}");
        // Read back: each corrected position's written numbers, through its frames, are its
        // command to the written precision.
        let src = Source::new("out.ls", &done.output);
        let written = adwi_programs::fanuc::read(&src, &options).unwrap();
        assert_eq!(written.targets.len(), done.report.targets.len());
        let mut commands = Vec::new();
        let mut points = Vec::new();
        let mut largest: f64 = 0.0;
        for (target, line) in written.targets.iter().zip(&done.report.targets) {
            if !line.status.corrected() {
                continue;
            }
            let command = match &target.kind {
                TargetKind::Cartesian(c) => {
                    let rotation = rotation_of(c.orientation.as_ref().unwrap()).unwrap();
                    let pose = Isometry3::from_parts(
                        Vector3::from(c.position.map(|n| n.value)).into(),
                        UnitQuaternion::from_rotation_matrix(&rotation),
                    );
                    let u = &target.uses[0];
                    // The KR150-2's samples measured its flange: the table's point.
                    let chain = FrameChain {
                        base: u.base.unwrap(),
                        tool: u.tool.unwrap(),
                        table_tool: Isometry3::identity(),
                    };
                    chain.table_point(&pose).translation.vector
                }
                TargetKind::Joints(j) => {
                    let q: Vec<f64> = j.joints.iter().map(|n| n.value.to_radians()).collect();
                    kr150.tcp_pose(&q).translation.vector
                }
                _ => unreachable!("{}", line.place()),
            };
            let expected = Vector3::from(line.command_mm.unwrap());
            assert!(
                (command - expected).norm() <= 1e-4,
                "{program} {}: {}",
                line.place(),
                (command - expected).norm()
            );
            commands.push(command.into());
            points.push(line.point_mm.unwrap());
            largest = largest.max(line.correction_mm.unwrap());
        }
        assert_eq!(commands.len(), expected);
        // |C + e(C) − P| by tablec query at every written command.
        let mut worst: f64 = 0.0;
        for (error, (c, p)) in query(dir.path(), &table, &commands)
            .iter()
            .zip(commands.iter().zip(&points))
        {
            let landed = Vector3::from(*c) + Vector3::from(*error);
            worst = worst.max((landed - Vector3::from(*p)).norm());
        }
        eprintln!("{program}: {summary}; |C + e(C) - P| at most {worst:.3e} mm");
        assert!(worst <= 1e-4, "{program}: {worst}");
        assert!(largest > 1.0 && largest < 5.0, "{largest}");
    }
}

#[test]
fn every_fanuc_motion_and_position_is_accounted_for_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let report = dir.path().join("report.csv");
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            fixture("fanuc_weld.ls").to_str().unwrap(),
            "-o",
            "out.ls",
            "--robot",
            robot().to_str().unwrap(),
            "--fanuc-j23",
            "0",
            "--fanuc-frames",
            frames_file().to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    let rows = crate::common::report_rows(&report, 0);
    let seen: Vec<(&str, &str)> = rows.iter().map(|r| (r.0.as_str(), r.1.as_str())).collect();
    assert_eq!(
        seen,
        [
            ("L P[6]", "relative"),
            ("L P[7]", "relative"),
            ("L P[10]", "relative"),
            ("J PR[3:Service]", "dynamic"),
            ("P[1]", "ok"),
            ("P[2]", "ok"),
            ("P[3]", "ok"),
            ("P[4]", "ok"),
            ("P[5]", "ok"),
            ("P[6]", "ok"),
            ("P[7]", "relative"),
            ("P[8]", "ok"),
            ("P[9]", "frame_unknown"),
            ("P[10]", "relative"),
            ("P[11]", "external_axis"),
        ],
        "{stdout}"
    );
    let detail = |name: &str| rows.iter().find(|r| r.0 == name).unwrap().2.clone();
    assert!(
        detail("L P[6]").starts_with("Offset,PR[1:Lift 30]: an offset"),
        "{}",
        detail("L P[6]")
    );
    assert!(detail("L P[10]").starts_with("INC: an incremental move"));
    assert!(
        detail("P[7]").starts_with("used only by L P[7] (36:8): Tool_Offset,PR[2:Back 20]"),
        "{}",
        detail("P[7]")
    );
    assert!(
        detail("P[9]").starts_with("user frame 3 not given"),
        "{}",
        detail("P[9]")
    );
    assert!(detail("P[11]").starts_with("GP2 (line 113): a second motion group"));
    // Only the corrected positions' numbers changed; CRLF kept.
    let before = std::fs::read_to_string(fixture("fanuc_weld.ls")).unwrap();
    let after = std::fs::read_to_string(dir.path().join("out.ls")).unwrap();
    assert_eq!(before.lines().count(), after.lines().count());
    assert_eq!(
        after.matches("\r\n").count(),
        before.matches("\r\n").count()
    );
    let changed: Vec<usize> = before
        .lines()
        .zip(after.lines())
        .enumerate()
        .filter(|(_, (a, b))| a != b)
        .map(|(i, _)| i + 1)
        .collect();
    // Two lines per corrected Cartesian position (X Y Z, W P R), two for the joints.
    assert_eq!(
        changed,
        [51, 52, 57, 58, 63, 64, 69, 70, 75, 76, 81, 82, 93, 94],
        "{after}"
    );
    for line in changed {
        let (a, b) = (
            before.lines().nth(line - 1).unwrap(),
            after.lines().nth(line - 1).unwrap(),
        );
        // The same words, only the numbers between them changed.
        let words = |s: &str| -> Vec<String> {
            s.split(|c: char| c.is_ascii_digit() || c == '.' || c == '-' || c == ' ')
                .filter(|w| !w.is_empty())
                .map(String::from)
                .collect()
        };
        assert_eq!(words(a), words(b), "{a} / {b}");
    }
}

#[test]
fn a_fanuc_position_is_corrected_as_the_same_krl_target_is() {
    // P[3] of the weld is XP1 of the KRL seam: the same torch (UT 1, TOOL_DATA[1]) in the
    // same fixture (UF 1, BASE_DATA[1]); W, P, R = C, B, A.
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let (_, fanuc) = job(&table, &fixture("fanuc_weld.ls"));
    let mut options = CompensateOptions::new(&table, fixture("seam.dat"));
    options.robot = Some(robot());
    options.krl_config = Some(fixture("config.dat"));
    let krl = CompensateJob::new(options).unwrap().run().unwrap();
    let p3 = fanuc
        .report
        .targets
        .iter()
        .find(|t| t.name == "P[3]")
        .unwrap();
    let xp1 = krl.report.targets.iter().find(|t| t.name == "XP1").unwrap();
    let gap = |a: [f64; 3], b: [f64; 3]| (Vector3::from(a) - Vector3::from(b)).norm();
    assert!(gap(p3.point_mm.unwrap(), xp1.point_mm.unwrap()) < 1e-9);
    assert!(gap(p3.command_mm.unwrap(), xp1.command_mm.unwrap()) < 1e-9);
    assert!((p3.correction_mm.unwrap() - xp1.correction_mm.unwrap()).abs() < 1e-9);
}

#[test]
fn a_frame_not_given_is_named_and_the_options_stand_before_the_frame_file() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let weld = fixture("fanuc_weld.ls");
    let kr150 = robot();
    let run = |extra: &[&str]| {
        let mut args = vec![
            table.to_str().unwrap(),
            weld.to_str().unwrap(),
            "-o",
            "out.ls",
            "--robot",
            kr150.to_str().unwrap(),
            "--fanuc-j23",
            "0",
            "--report",
            "r.csv",
            "-q",
        ];
        args.extend_from_slice(extra);
        let (code, stdout, stderr) = compensate(dir.path(), &args);
        assert!(code == 0 || code == 3, "{stderr}");
        let rows: Vec<Vec<String>> = csv::Reader::from_path(dir.path().join("r.csv"))
            .unwrap()
            .records()
            .map(|r| r.unwrap().iter().map(String::from).collect())
            .collect();
        (stdout, rows)
    };
    // No frames: every Cartesian position names its user frame; the joint position needs
    // none.
    let (stdout, rows) = run(&[]);
    let p3 = rows.iter().find(|r| r[0] == "P[3]").unwrap();
    assert_eq!(p3[4], "frame_unknown");
    assert!(p3[5].starts_with("user frame 1 not given"), "{}", p3[5]);
    assert!(stdout.contains("1 of 15 targets corrected"), "{stdout}");
    // The user frame by option, the tool frame not: the tool is named.
    let (_, rows) = run(&["--fanuc-uframe", "1=1600,250,750,0,0,30"]);
    let p3 = rows.iter().find(|r| r[0] == "P[3]").unwrap();
    assert!(p3[5].starts_with("tool frame 1 not given"), "{}", p3[5]);
    // An option stands before the frame file: user frame 1 10 mm further along x moves the
    // table's point of P[3] by 10 mm.
    let file = frames_file();
    let (_, from_file) = run(&["--fanuc-frames", file.to_str().unwrap()]);
    let (_, moved) = run(&[
        "--fanuc-frames",
        file.to_str().unwrap(),
        "--fanuc-uframe",
        "1=1610,250,750,0,0,30",
        "--fanuc-uframe",
        "3=1400,500,900,0,0,0",
    ]);
    let point_x = |rows: &[Vec<String>], name: &str| -> f64 {
        rows.iter().find(|r| r[0] == name).unwrap()[11]
            .parse()
            .unwrap()
    };
    assert!((point_x(&moved, "P[3]") - point_x(&from_file, "P[3]") - 10.0).abs() < 1e-9);
    // User frame 3, given by option, corrects P[9].
    let p9 = moved.iter().find(|r| r[0] == "P[9]").unwrap();
    assert_eq!(p9[4], "ok", "{p9:?}");
    // A frame file is for Fanuc programs.
    let (code, _, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            fixture("targets.csv").to_str().unwrap(),
            "-o",
            "out.csv",
            "--fanuc-frames",
            file.to_str().unwrap(),
        ],
    );
    // A usage error, refused before any file is read.
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("the Fanuc frame file is for Fanuc programs"),
        "{stderr}"
    );
}

#[test]
fn a_fanuc_program_saved_as_another_dialect_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    std::fs::copy(fixture("fanuc_weld.ls"), dir.path().join("weld.src")).unwrap();
    let (code, _, stderr) = compensate(
        dir.path(),
        &[table.to_str().unwrap(), "weld.src", "-o", "out.src"],
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("this reads as Fanuc TP ('/PROG' at its line 1), not KUKA KRL"),
        "{stderr}"
    );
}

/// A Fanuc program in `dir` of one position over the KR150-2's samples (their orientation),
/// in the world frame with tool 1 at the faceplate, its `CONFIG` written as `config`.
fn one_position_program(dir: &Path, config: &str) -> PathBuf {
    let path = dir.join(format!("branch-{}.ls", dir.read_dir().unwrap().count()));
    std::fs::write(
        &path,
        format!(
            "/PROG  BRANCH\n/ATTR\nOWNER\t\t= MNEDITOR;\n/MN\n   1:  UFRAME_NUM=0 ;\n   2:  UTOOL_NUM=1 ;\n\
             \x20  3:L P[1] 100mm/sec FINE    ;\n/POS\nP[1]{{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : '{config}',\n\
             \tX =   1750.000  mm,\tY =    450.000  mm,\tZ =   1250.000  mm,\n\
             \tW =       .000 deg,\tP =     90.000 deg,\tR =       .000 deg\n}};\n/END\n"
        ),
    )
    .unwrap();
    path
}

/// The program's one position compensated by `table` with the KR150-2 robot file and tool
/// 1 at the faceplate: its report line.
fn compensate_one_position(table: &Path, program: &Path) -> adwi_programs::TargetLine {
    compensate_one_position_with(table, program, |_| {})
}

/// [`compensate_one_position`], with `change` made to the options.
fn compensate_one_position_with(
    table: &Path,
    program: &Path,
    change: impl FnOnce(&mut CompensateOptions),
) -> adwi_programs::TargetLine {
    let mut o = CompensateOptions::new(table, program);
    o.robot = Some(robot());
    o.fanuc = FanucOptions {
        user_frames: Vec::new(),
        tool_frames: vec![(1, [0.0; 6])],
        frames_file: None,
    };
    change(&mut o);
    let done = CompensateJob::new(o).unwrap().run().unwrap();
    done.report.targets[0].clone()
}

/// With a hybrid table a position is solved in the posture its CONFIG writes; a CONFIG the
/// reader cannot read (a letter of no pair, a pair given twice, a pair missing, a turn that
/// is not a whole number from −4 to 4, a SCARA's) leaves the position as written, named,
/// instead of a correction in a posture the program does not give.
#[test]
fn a_fanuc_config_that_cannot_be_read_leaves_the_position_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let written =
        compensate_one_position(&table, &one_position_program(dir.path(), "F U T, 0, 0, 0"));
    assert_eq!(written.status.as_str(), "ok", "{}", written.detail);
    for config in [
        "F U X, 0, 0, 0",
        "F U U, 0, 0, 0",
        "F U, 0, 0, 0",
        "F U T, 0, 0.5, 0",
        "F U T, 0, 0, 9",
        "F U T, 0, 0",
        "N, 0, 0, 0",
    ] {
        let line = compensate_one_position(&table, &one_position_program(dir.path(), config));
        assert_eq!(line.status.as_str(), "invalid", "{config}: {}", line.detail);
        assert!(
            line.detail
                .starts_with("a Fanuc CONFIG is 'N|F U|D T|B, t1, t2, t3'")
                && line
                    .detail
                    .contains(&format!("found '{config}' (line 11, column 29)"))
                && line
                    .detail
                    .ends_with("not corrected in a posture the program does not give"),
            "{config}: {}",
            line.detail
        );
    }
}

/// One posture written on two turns of J4 (`CONFIG 'F U T, 0, 0, 0'`, J4 near 27°, and
/// `'F U T, -1, 0, 0'`, J4 near −333°): with a hybrid table whose model has joint-space
/// terms, the terms are those of the link's angle, not of the number written, so both get
/// the same command, its J4 a whole turn apart, each on its written turn.
#[test]
fn a_hybrid_table_with_joint_terms_gives_one_posture_one_command_on_either_turn() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table_with(dir.path(), 1);
    let run = |config: &str| {
        let line = compensate_one_position(&table, &one_position_program(dir.path(), config));
        assert_eq!(line.status.as_str(), "ok", "{config}: {}", line.detail);
        line
    };
    let (near, turned) = (run("F U T, 0, 0, 0"), run("F U T, -1, 0, 0"));
    let (q, q_turned) = (
        near.command_joints.clone().unwrap(),
        turned.command_joints.clone().unwrap(),
    );
    assert!(q[3] > -180.0 && q[3] <= 180.0, "{q:?}");
    assert!(
        q_turned[3] > -540.0 && q_turned[3] <= -180.0,
        "{q_turned:?}"
    );
    assert!(
        (q[3] - 360.0 - q_turned[3]).abs() < 1e-6,
        "{q:?} {q_turned:?}"
    );
    for j in [0, 1, 2, 4, 5] {
        assert!((q[j] - q_turned[j]).abs() < 1e-6, "{q:?} {q_turned:?}");
    }
    let gap = (Vector3::from(near.command_mm.unwrap()) - Vector3::from(turned.command_mm.unwrap()))
        .norm();
    assert!(gap < 1e-6, "{gap} mm between the commands");
    assert_eq!(near.evidence, turned.evidence);
}

/// A controller's `$SCR_GRP[1].$TURN_AXIS = [1, 4, 6]` (an R-2000iB's, as its SYMOTN.VA
/// holds it).
const TURN_AXIS_1_4_6: &str = "[*SYSTEM*]$SCR_GRP  Storage: SHADOW  Access: FP  : ARRAY[4] OF SCR_GRP_T\n\
     Field: $SCR_GRP[1].$NUM_AXES Access: RO: BYTE = 6\n\
     Field: $SCR_GRP[1].$TURN_AXIS  ARRAY[3] OF INTEGER\n      [1] = 1\n      [2] = 4\n      [3] = 6\n";

/// The turn numbers of a controller whose turn axes are J1, J4 and J6: `CONFIG 'F U T, 0,
/// -1, 0'` there is J4 on its turn −1 (near −333°, J4 near 27° on turn 0). Read on J4, J5
/// and J6, the default, it asks a turn of J5 its limits do not hold: the position is left
/// as written, naming the turn number, its joint and where the turn axes came from.
/// `--fanuc-turn-axes 1,4,6`, or a frame file holding `$TURN_AXIS`, corrects it on J4's
/// turn −1; and `'F U T, -1, 0, 0'`, J1's turn −1 there (J1 near 14°), is not taken for
/// J4's. Turn axes that are not the robot's, or an option the frame file contradicts, are
/// refused before any work.
#[test]
fn turn_numbers_are_of_the_joints_the_controllers_turn_axes_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let table = crate::common::kr150_hybrid_table(d);
    let j4_turned = one_position_program(d, "F U T, 0, -1, 0");
    let j1_turned = one_position_program(d, "F U T, -1, 0, 0");
    let line = compensate_one_position(&table, &j4_turned);
    assert_eq!(line.status.as_str(), "invalid", "{}", line.detail);
    assert_eq!(
        line.detail,
        "turn number -1 of J5 (turn axes 4, 5, 6, the default; --fanuc-turn-axes or the controller's $TURN_AXIS gives others): J5 in (-540°, -180°], beyond its limits [-125°, 125°]"
    );
    std::fs::write(d.join("symotn.va"), TURN_AXIS_1_4_6).unwrap();
    let option = |o: &mut CompensateOptions| o.fanuc_turn_axes = Some([1, 4, 6]);
    let file = |o: &mut CompensateOptions| o.fanuc.frames_file = Some(d.join("symotn.va"));
    let by_option = compensate_one_position_with(&table, &j4_turned, option);
    let by_file = compensate_one_position_with(&table, &j4_turned, file);
    for line in [&by_option, &by_file] {
        assert_eq!(line.status.as_str(), "ok", "{}", line.detail);
        let q = line.command_joints.clone().unwrap();
        assert!(q[3] > -540.0 && q[3] <= -180.0, "{q:?}");
        assert!(
            q[0] > -180.0 && q[0] <= 180.0 && q[5] > -180.0 && q[5] <= 180.0,
            "{q:?}"
        );
    }
    assert_eq!(by_option.command_joints, by_file.command_joints);
    let line = compensate_one_position_with(&table, &j1_turned, option);
    assert_eq!(line.status.as_str(), "ik_failed", "{}", line.detail);
    // J1's turn −1 is the reason, named.
    assert!(
        line.detail
            .contains("in its configuration: in it, only with J1 ")
            && line
                .detail
                .ends_with("on another turn than the program writes (within the joints' limits)"),
        "{}",
        line.detail
    );

    // The command line: the option, the frame file, both when they agree; the CONFIG
    // written back as it was.
    let program = j4_turned.file_name().unwrap().to_str().unwrap();
    let robot = robot();
    let run = |extra: &[&str]| {
        let mut args = vec![
            table.to_str().unwrap(),
            program,
            "-o",
            "out.ls",
            "--robot",
            robot.to_str().unwrap(),
            "--fanuc-utool",
            "1=0,0,0,0,0,0",
        ];
        args.extend_from_slice(extra);
        compensate(d, &args)
    };
    for extra in [
        &["--fanuc-turn-axes", "1,4,6"][..],
        &["--fanuc-frames", "symotn.va"],
        &["--fanuc-frames", "symotn.va", "--fanuc-turn-axes", "1,4,6"],
    ] {
        let (code, stdout, stderr) = run(extra);
        assert_eq!(code, 0, "{extra:?}: {stdout}{stderr}");
        let out = std::fs::read_to_string(d.join("out.ls")).unwrap();
        assert!(out.contains("CONFIG : 'F U T, 0, -1, 0',"), "{out}");
        assert_ne!(out, std::fs::read_to_string(&j4_turned).unwrap());
    }
    // An option the inputs cannot take is a usage error, as one refused before any is read.
    let (code, _, stderr) = run(&["--fanuc-frames", "symotn.va", "--fanuc-turn-axes", "4,5,6"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("--fanuc-turn-axes 4,5,6 and the frame file symotn.va's $SCR_GRP[1].$TURN_AXIS 1,4,6 disagree"),
        "{stderr}"
    );
    let (code, _, stderr) = run(&["--fanuc-turn-axes", "1,4,7"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains(
            "turn axes 1, 4, 7, --fanuc-turn-axes: J7 is not a joint of this robot, which has 6"
        ),
        "{stderr}"
    );
    for bad in ["1,4,4", "1,4", "0,4,6"] {
        let (code, _, stderr) = run(&["--fanuc-turn-axes", bad]);
        assert_eq!(code, 2, "{bad}: {stderr}");
        assert!(
            stderr.contains(&format!(
                "invalid value '{bad}' for '--fanuc-turn-axes <J,J,J>'"
            )),
            "{stderr}"
        );
    }
}

/// A joint position with J3 as the pendant counts it: `--fanuc-j23 K` reads J3 as the
/// robot file's J3 + K·J2 and writes it back so. The home position written with K = 1
/// (J3 plus J2) is corrected to the same posture as written the robot file's way with
/// K = 0, its J3 written back coupled; without the option it is refused, naming it.
#[test]
fn a_fanuc_joint_positions_j3_is_read_and_written_as_the_pendant_counts_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let table = kr150_table(d);
    let q = [13.846, -73.539, 117.165, 19.659, -45.347, -14.094];
    let program = |name: &str, j3: f64| {
        let path = d.join(name);
        std::fs::write(
            &path,
            format!(
                "/PROG  HOME\n/ATTR\nOWNER\t\t= MNEDITOR;\n/MN\n   1:J P[1] 100% FINE    ;\n/POS\nP[1]{{\n   GP1:\n\tUF : 0, UT : 1,\n\
                 \tJ1= {:.3} deg,\tJ2= {:.3} deg,\tJ3= {j3:.3} deg,\n\tJ4= {:.3} deg,\tJ5= {:.3} deg,\tJ6= {:.3} deg\n}};\n/END\n",
                q[0], q[1], q[3], q[4], q[5]
            ),
        )
        .unwrap();
        path
    };
    let as_file = program("file.ls", q[2]);
    let as_pendant = program("pendant.ls", q[2] + q[1]);
    let run = |path: &Path, j23: Option<f64>| {
        let mut o = CompensateOptions::new(&table, path);
        o.robot = Some(robot());
        o.fanuc.frames_file = Some(frames_file());
        o.fanuc_j23 = j23;
        let done = CompensateJob::new(o).unwrap().run().unwrap();
        (
            done.report.targets[0].clone(),
            String::from_utf8(done.output).unwrap(),
        )
    };
    let (refused, _) = run(&as_pendant, None);
    assert_eq!(refused.status.as_str(), "invalid", "{}", refused.detail);
    assert!(
        refused.detail.contains("give --fanuc-j23 1"),
        "{}",
        refused.detail
    );
    let (file, file_out) = run(&as_file, Some(0.0));
    let (pendant, pendant_out) = run(&as_pendant, Some(1.0));
    assert_eq!(file.status.as_str(), "ok", "{}", file.detail);
    assert_eq!(pendant.status.as_str(), "ok", "{}", pendant.detail);
    // The same command, J3 written back as each program counts it.
    let joints = |text: &str| -> Vec<f64> {
        (1..=6)
            .filter_map(|k| {
                let (_, after) = text.split_once(&format!("J{k}="))?;
                after.split_whitespace().next()?.parse().ok()
            })
            .collect()
    };
    let (a, b) = (joints(&file_out), joints(&pendant_out));
    assert_eq!((a.len(), b.len()), (6, 6), "{file_out}\n{pendant_out}");
    for i in [0, 1, 3, 4, 5] {
        assert!((a[i] - b[i]).abs() < 1e-5, "J{}: {a:?} {b:?}", i + 1);
    }
    assert!((b[2] - (a[2] + a[1])).abs() < 1e-5, "{a:?} {b:?}");
    assert!(
        (a[2] - q[2]).abs() > 1e-3,
        "the position was corrected: {a:?}"
    );
}
