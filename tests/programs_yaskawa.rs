//! Yaskawa INFORM jobs compensated offline (`tablec compensate`, format `yaskawa`): a job
//! as the pendant saves it (`tests/programs/bracket.jbi`: pulses, the robot frame, user
//! frames, a torch, SFTON, IMOV, P variables) and one an offline tool generates
//! (`tests/programs/trace.jbi`), with the KR150-2 table and a table that corrects nothing.
//! Every written command is read back and landed by the table's own model at its TCP.

use std::path::{Path, PathBuf};

use adwi_programs::frames::FrameChain;
use adwi_programs::program::TargetKind;
use adwi_programs::source::Source;
use adwi_programs::yaskawa::{pose, YaskawaOptions};
use adwi_programs::{CompensateJob, CompensateOptions};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::common::{compensate, method_table, repo};

/// The torch (tool 1) and the fixture (user frame 1) of the jobs' cell, as the pendant
/// shows them: X, Y, Z mm, Rx, Ry, Rz degrees.
const TOOL1: [f64; 6] = [0.0, 0.0, 180.0, 0.0, 0.0, 0.0];
const USER1: [f64; 6] = [1600.0, 250.0, 750.0, 0.0, 0.0, 30.0];
/// The pulses per degree of the stand-in robot's axes (the KR150-2 file).
const PULSES: [f64; 6] = [1456.356, 1456.356, 1350.0, 910.222, 910.222, 555.556];

fn fixture(name: &str) -> PathBuf {
    repo(&format!("tests/programs/{name}"))
}

fn options(table: &Path, program: &Path) -> CompensateOptions {
    let mut o = CompensateOptions::new(table, program);
    o.yaskawa = YaskawaOptions {
        tools: vec![(1, TOOL1)],
        users: vec![(1, USER1)],
        pulses_per_deg: Some(PULSES.to_vec()),
    };
    o
}

/// A job's statuses by target name, in the report's order.
fn statuses(done: &adwi_programs::Compensated) -> Vec<(String, String)> {
    done.report
        .targets
        .iter()
        .map(|t| (t.name.clone(), t.status.as_str().to_string()))
        .collect()
}

#[test]
fn a_table_that_corrects_nothing_reproduces_yaskawa_jobs_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    for i in 0..=12 {
        for j in 0..=10 {
            for k in 0..=10 {
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
    for (program, corrected) in [("bracket.jbi", 9), ("trace.jbi", 41)] {
        let out = dir.path().join(format!("out-{program}"));
        let (code, stdout, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                fixture(program).to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--yaskawa-tool",
                "1=0,0,180,0,0,0",
                "--yaskawa-user",
                "1=1600,250,750,0,0,30",
                "--yaskawa-pulses-per-deg",
                "1456.356,1456.356,1350.0,910.222,910.222,555.556",
                "--robot",
                repo("tables/kr150-2/robot.toml").to_str().unwrap(),
            ],
        );
        assert!(code == 0 || code == 3, "{program}: {stderr}");
        assert_eq!(
            crate::common::corrected_lines(&stdout),
            corrected,
            "{program}: {stdout}"
        );
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(fixture(program)).unwrap(),
            "{program}: {stdout}"
        );
    }
}

/// Where the table's own model lands the written pose `written` (in `chain`'s work
/// object): the table's point moved by the table's position error there and turned by
/// its orientation error, the TCP riding on it; the distance from `target` (same frame),
/// mm, and |C + e(C) − P| at the table's point for `point` P.
fn landing(
    table: &adwi_runtime::Table<adwi_runtime::AlignedBytes>,
    chain: &FrameChain,
    written: &Isometry3<f64>,
    target: &Isometry3<f64>,
    point: [f64; 3],
) -> (f64, f64) {
    let c = chain.table_point(written);
    let answer = table.query(c.translation.vector.into());
    assert_eq!(answer.status, adwi_runtime::Status::Ok, "{c:?}");
    let error = Vector3::from(answer.position_error_mm);
    let turn = UnitQuaternion::from_scaled_axis(Vector3::from(answer.orientation_error_rad));
    let landed_point =
        Isometry3::from_parts((c.translation.vector + error).into(), turn * c.rotation);
    let tcp = chain.base.inverse() * landed_point * chain.table_tool.inverse() * chain.tool;
    (
        (tcp.translation.vector - target.translation.vector).norm(),
        (c.translation.vector + error - Vector3::from(point)).norm(),
    )
}

/// The pose a Cartesian target writes.
fn written_pose(target: &adwi_programs::program::ProgramTarget) -> Isometry3<f64> {
    let TargetKind::Cartesian(c) = &target.kind else {
        panic!("{} is not Cartesian", target.name)
    };
    let r = adwi_programs::frames::rotation_of(c.orientation.as_ref().unwrap()).unwrap();
    Isometry3::from_parts(
        Vector3::from(c.position.map(|n| n.value)).into(),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

#[test]
fn kr150_yaskawa_positions_land_at_the_torch_in_their_frames_and_the_rest_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let table_path = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let table = adwi_runtime::Table::from_vec(std::fs::read(&table_path).unwrap()).unwrap();
    let program = fixture("bracket.jbi");
    let job = CompensateJob::new(options(&table_path, &program)).unwrap();
    let done = job.run().unwrap();
    let s = statuses(&done);
    let names: Vec<String> = s.iter().map(|(n, st)| format!("{n} {st}")).collect();
    assert_eq!(
        names,
        [
            "C00000 needs_robot",
            "C00001 ok",
            "C00002 ok",
            "C00003 ok",
            "C00004 ok",
            "C00005 ok",
            "C00006 ok",
            "C00007 ok",
            "C00008 ok",
            "C00009 relative",
            "C00010 frame_unknown",
            "C00011 frame_unknown",
            "MOVL relative",
            "IMOV relative",
            "MOVL dynamic",
        ]
    );
    let detail = |name: &str| {
        done.report
            .targets
            .iter()
            .find(|t| t.name == name)
            .unwrap()
            .detail
            .clone()
    };
    assert!(
        detail("C00010").starts_with("work object USER 2 not given (used at 56:1): give it as --yaskawa-user 2=X,Y,Z,Rx,Ry,Rz, or as the base option"),
        "{}",
        detail("C00010")
    );
    assert!(
        detail("C00011").starts_with("tool TOOL 2 not given"),
        "{}",
        detail("C00011")
    );
    assert!(
        detail("C00009").contains("under SFTON P010 UF#(1) (line 51)"),
        "{}",
        detail("C00009")
    );
    // Read back: each corrected position's written numbers, in its frames, land at the
    // torch's tip on the target by the table's own model.
    let l = landings(&table, &job, &done, &program);
    assert_eq!(l.checked, 8);
    eprintln!("bracket.jbi: {}; {l}", done.report.summary());
    let (worst_exact, worst_tcp, worst_point, off) = (l.exact, l.tcp, l.written, l.uncompensated);
    // The controller's resolution: 0.001 mm and 0.0001° (a 180 mm torch turns 0.0001° into
    // 3e-4 mm), rounded to the half.
    assert!(worst_exact <= 1e-4, "{worst_exact}");
    assert!(worst_tcp <= 1.5e-3, "{worst_tcp}");
    assert!(worst_point <= 1.5e-3, "{worst_point}");
    assert!(off > 1.0, "{off}");
    // Only numbers of corrected positions changed, in the pendant's style: three decimals
    // in mm, four in degrees, CRLF kept.
    let original = String::from_utf8(std::fs::read(&program).unwrap()).unwrap();
    let written = String::from_utf8(done.output.clone()).unwrap();
    assert_eq!(original.lines().count(), written.lines().count());
    assert_eq!(
        written.matches("\r\n").count(),
        original.matches("\r\n").count()
    );
    for (o, w) in original.lines().zip(written.lines()) {
        if o == w {
            continue;
        }
        assert!(o.starts_with('C'), "{o} -> {w}");
        let (name, values) = w.split_once('=').unwrap();
        assert!(o.starts_with(name), "{o} -> {w}");
        for (k, v) in values.split(',').enumerate() {
            let decimals = v.split_once('.').map_or(0, |(_, d)| d.len());
            assert_eq!(decimals, if k < 3 { 3 } else { 4 }, "{w}");
        }
    }
}

/// What the table's own model makes of a job's corrected positions, read back from the
/// written job through each position's frames.
struct Landings {
    checked: usize,
    /// The largest distance of the torch from its target, uncompensated (the least of them).
    uncompensated: f64,
    /// The largest distance of the torch from its target, as written.
    tcp: f64,
    /// The largest |C + e(C) − P| at the table's point, for the command as written and for
    /// the fixed point's command before rounding.
    written: f64,
    exact: f64,
    largest: f64,
}

impl std::fmt::Display for Landings {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "{} positions: at the torch by the table's model {:.3} mm or more uncompensated, at most {:.2e} mm compensated; |C + e(C) - P| at most {:.2e} mm for the command, {:.2e} mm as written; largest correction {:.4} mm",
            self.checked, self.uncompensated, self.tcp, self.exact, self.written, self.largest
        )
    }
}

fn landings(
    table: &adwi_runtime::Table<adwi_runtime::AlignedBytes>,
    job: &CompensateJob,
    done: &adwi_programs::Compensated,
    program: &Path,
) -> Landings {
    let read = |bytes: &[u8]| {
        adwi_programs::yaskawa::read(&Source::new("b.jbi", bytes), &job.options().yaskawa).unwrap()
    };
    let before = read(&std::fs::read(program).unwrap());
    let after = read(&done.output);
    let mut l = Landings {
        checked: 0,
        uncompensated: f64::INFINITY,
        tcp: 0.0,
        written: 0.0,
        exact: 0.0,
        largest: 0.0,
    };
    for ((b, a), line) in before
        .targets
        .iter()
        .zip(&after.targets)
        .zip(&done.report.targets)
    {
        if line.status.as_str() != "ok" || !matches!(b.kind, TargetKind::Cartesian(_)) {
            continue;
        }
        let u = &b.uses[0];
        let chain = FrameChain {
            base: u.base.unwrap(),
            tool: u.tool.unwrap(),
            table_tool: Isometry3::identity(),
        };
        let target = written_pose(b);
        let point = line.point_mm.unwrap();
        let (tcp, gap) = landing(table, &chain, &written_pose(a), &target, point);
        let (uncompensated, _) = landing(table, &chain, &target, &target, point);
        // The command before the controller's rounding: the fixed point itself.
        let command = Vector3::from(line.command_mm.unwrap());
        let answer = table.query(command.into());
        let exact =
            (command + Vector3::from(answer.position_error_mm) - Vector3::from(point)).norm();
        l.exact = l.exact.max(exact);
        l.tcp = l.tcp.max(tcp);
        l.written = l.written.max(gap);
        l.uncompensated = l.uncompensated.min(uncompensated);
        l.largest = l.largest.max(line.correction_mm.unwrap());
        l.checked += 1;
    }
    l
}

#[test]
fn kr150_generated_trace_lands_at_the_torch_in_its_user_frame() {
    let dir = tempfile::tempdir().unwrap();
    let table_path = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let table = adwi_runtime::Table::from_vec(std::fs::read(&table_path).unwrap()).unwrap();
    let program = fixture("trace.jbi");
    let job = CompensateJob::new(options(&table_path, &program)).unwrap();
    let done = job.run().unwrap();
    let l = landings(&table, &job, &done, &program);
    eprintln!("trace.jbi: {}; {l}", done.report.summary());
    assert_eq!(l.checked, 41);
    assert!(l.exact <= 1e-4, "{l}");
    assert!(l.tcp <= 1.5e-3 && l.written <= 1.5e-3, "{l}");
    assert!(l.uncompensated > 1.0, "{l}");
}

#[test]
fn pulse_positions_are_corrected_in_whole_pulses_with_a_robot_and_named_without() {
    let dir = tempfile::tempdir().unwrap();
    let table_path = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let program = fixture("bracket.jbi");
    let mut o = options(&table_path, &program);
    o.robot = Some(repo("tables/kr150-2/robot.toml"));
    let job = CompensateJob::new(o).unwrap();
    let done = job.run().unwrap();
    let home = &done.report.targets[0];
    assert_eq!(home.status.as_str(), "ok", "{}", home.detail);
    let line = |bytes: &[u8]| {
        String::from_utf8_lossy(bytes)
            .lines()
            .find(|l| l.starts_with("C00000="))
            .unwrap()
            .to_string()
    };
    let written = line(&done.output);
    let original = line(&std::fs::read(&program).unwrap());
    assert_ne!(written, original);
    let pulses: Vec<i64> = written[7..]
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    // The written pulses are the command's joints to half a pulse.
    let joints = home.command_joints.as_ref().unwrap();
    for ((p, q), per) in pulses.iter().zip(joints).zip(PULSES) {
        assert!((*p as f64 - q * per).abs() <= 0.5, "{p} {q}");
    }
    // The same job without pulses per degree: the pulse position is named, not guessed.
    let mut o = options(&table_path, &program);
    o.yaskawa.pulses_per_deg = None;
    let done = CompensateJob::new(o).unwrap().run().unwrap();
    let home = &done.report.targets[0];
    assert_eq!(home.status.as_str(), "incomplete");
    assert!(
        home.detail.contains("--yaskawa-pulses-per-deg"),
        "{}",
        home.detail
    );
}

#[test]
fn a_generated_trace_in_a_user_frame_is_corrected_whole_and_its_frames_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            "kr150.tbl",
            fixture("trace.jbi").to_str().unwrap(),
            "-o",
            "trace-out.jbi",
            "--yaskawa-tool",
            "1=0,0,180,0,0,0",
            "--yaskawa-user",
            "1=1600,250,750,0,0,30",
            "--quiet",
        ],
    );
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(stdout.starts_with("41 of 41 targets corrected"), "{stdout}");
    let _ = table;
    // Without the user frame: every position names it, and nothing is written as corrected.
    let (code, stdout, _) = compensate(
        dir.path(),
        &[
            "kr150.tbl",
            fixture("trace.jbi").to_str().unwrap(),
            "-o",
            "trace-out2.jbi",
            "--yaskawa-tool",
            "1=0,0,180,0,0,0",
        ],
    );
    assert_eq!(code, 3);
    let first = stdout
        .lines()
        .find(|l| l.starts_with("C00000 "))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        first.contains(" 10:1 ")
            && first.contains(" frame_unknown ")
            && first.contains("work object USER 1 not given (used at 57:1): give it as --yaskawa-user 1=X,Y,Z,Rx,Ry,Rz, or as the base option"),
        "{stdout}"
    );
    assert!(stdout.contains("0 of 41 targets corrected"), "{stdout}");
    // A job read as another dialect, and another dialect read as a job, are refused by
    // name.
    std::fs::copy(fixture("trace.jbi"), dir.path().join("trace.src")).unwrap();
    let (code, _, stderr) = compensate(dir.path(), &["kr150.tbl", "trace.src", "-o", "t.src"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("this reads as Yaskawa INFORM ('/JOB' at its line 1), not KUKA KRL"),
        "{stderr}"
    );
    std::fs::copy(fixture("weld.src"), dir.path().join("weld.jbi")).unwrap();
    let (code, _, stderr) = compensate(dir.path(), &["kr150.tbl", "weld.jbi", "-o", "w.jbi"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("this reads as KUKA KRL"), "{stderr}");
}

#[test]
fn yaskawa_angles_are_fixed_axis_rx_ry_rz() {
    // Rx 90 about x, then Rz 90 about the fixed z: x goes to y, y to z, z to x.
    let p = pose(&[0.0, 0.0, 0.0, 90.0, 0.0, 90.0]);
    let r = p.rotation.to_rotation_matrix();
    let m = r.matrix();
    let expected = nalgebra::Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
    assert!((m - expected).abs().max() < 1e-12, "{m}");
}

/// A job in `dir` of one Cartesian position over the KR150-2's samples (their
/// orientation) in the robot frame with the flange as the tool, after `///RCONF rconf`
/// (no `///RCONF` line when `None`).
fn one_position_job(dir: &Path, rconf: Option<&str>) -> PathBuf {
    let rconf = rconf.map_or(String::new(), |r| format!("///RCONF {r}\r\n"));
    let path = dir.join(format!(
        "branch-{}.jbi",
        rconf.len() + dir.read_dir().unwrap().count()
    ));
    std::fs::write(
        &path,
        format!(
            "/JOB\r\n//NAME BRANCH\r\n//POS\r\n///NPOS 1,0,0,0,0,0\r\n///TOOL 0\r\n///POSTYPE ROBOT\r\n\
             ///RECTAN\r\n{rconf}C00000=1750.000,450.000,1250.000,0.0000,90.0000,0.0000\r\n//INST\r\n\
             ///DATE 2026/11/20 14:32\r\n///ATTR SC,RW\r\n///GROUP1 RB1\r\nNOP\r\nMOVL C00000 V=100.0\r\nEND\r\n"
        ),
    )
    .unwrap();
    path
}

/// The job's one position compensated by `table` with the KR150-2 robot file: its report
/// line.
fn compensate_one(table: &Path, job: &Path) -> adwi_programs::TargetLine {
    let mut o = CompensateOptions::new(table, job);
    o.robot = Some(repo("tables/kr150-2/robot.toml"));
    o.yaskawa = YaskawaOptions {
        tools: vec![(0, [0.0; 6])],
        users: Vec::new(),
        pulses_per_deg: None,
    };
    let done = CompensateJob::new(o).unwrap().run().unwrap();
    done.report.targets[0].clone()
}

/// A report line's command posture (degrees), checked to be the command's by forward
/// kinematics (the robot file's tool is the flange: the table's point), and the
/// configuration the robot's geometry gives it.
fn command_posture(line: &adwi_programs::TargetLine) -> (Vec<f64>, adwi_robot::Configuration) {
    let robot = adwi_robot::Robot::load(repo("tables/kr150-2/robot.toml")).unwrap();
    let deg = line.command_joints.clone().unwrap();
    let q: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
    let at = robot.tcp_pose(&q).translation.vector;
    let gap = (at - Vector3::from(line.command_mm.unwrap())).norm();
    assert!(gap < 1e-6, "{}: {gap} mm", line.name);
    let rows: [adwi_runtime::kinematics::MdhJoint; 6] = robot.mdh().unwrap().try_into().unwrap();
    let configuration = adwi_robot::ik::configuration_of(&rows, &q.try_into().unwrap());
    (deg, configuration)
}

#[test]
fn a_hybrid_table_solves_a_yaskawa_position_on_its_written_rconf_not_the_nearest() {
    solves_on_the_written_rconf(0);
}

/// With joint-space terms the model is evaluated at the commanded J4, which the written R
/// flag (under 180° or not) takes a whole turn apart: one posture of the arm, whose terms
/// must be the same on either turn (held at the same end of the angles the samples span,
/// around the circle), so that both turns get the same command, 360° apart in J4.
#[test]
fn a_hybrid_table_with_joint_terms_solves_a_yaskawa_position_on_its_written_rconf() {
    solves_on_the_written_rconf(1);
}

/// A position written with each `///RCONF` (and none), compensated by the KR150-2 hybrid
/// table with joint-space terms up to `harmonics`: each on its written branch and turn.
fn solves_on_the_written_rconf(harmonics: u8) {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table_with(dir.path(), harmonics);
    let run = |rconf: Option<&str>| {
        let line = compensate_one(&table, &one_position_job(dir.path(), rconf));
        assert_eq!(line.status.as_str(), "ok", "{rconf:?}: {}", line.detail);
        let (q, configuration) = command_posture(&line);
        eprintln!(
            "yaskawa RCONF {rconf:?}: J4 {:.3}°, J5 {:.3}°, J6 {:.3}°, configuration {}, correction {:.4} mm, |C + e(C) - P| {:.2e} mm",
            q[3],
            q[4],
            q[5],
            configuration.bits(),
            line.correction_mm.unwrap(),
            line.residual_mm.unwrap()
        );
        (q, configuration)
    };
    // Flip: the R axis (J4) within (−90°, 90°], turn for turn.
    let flipped = |j4: f64| {
        let r = j4.rem_euclid(360.0);
        r <= 90.0 || r > 270.0
    };
    // Nothing written: the branch nearest the home posture, the flipped one.
    let (nearest, nearest_c) = run(None);
    assert!(flipped(nearest[3]), "{nearest:?}");
    // Written flip: that branch.
    let (flip, flip_c) = run(Some("0,0,0,0,0,0,0,0"));
    assert!(flipped(flip[3]) && flip[3] < 180.0, "{flip:?}");
    assert_eq!(flip_c, nearest_c);
    // Written no flip, R under 180°: the other wrist, J4 turned half a turn the short way
    // below 180°, the other wrist label.
    let (no_flip, no_flip_c) = run(Some("1,0,0,0,0,0,0,0"));
    assert!(!flipped(no_flip[3]) && no_flip[3] < 180.0, "{no_flip:?}");
    assert_ne!(no_flip_c.wrist_flip(), nearest_c.wrist_flip());
    assert_eq!(no_flip[4].signum(), -nearest[4].signum());
    // Written no flip, R at 180° or more: the same wrist, J4 the turn above 180°.
    let (above, above_c) = run(Some("1,0,0,1,0,0,0,0"));
    assert!(!flipped(above[3]) && above[3] >= 180.0, "{above:?}");
    assert_eq!(above_c, no_flip_c);
    assert!(
        (above[3] - 360.0 - no_flip[3]).abs() < 1e-6,
        "{above:?} {no_flip:?}"
    );
    // The lower arm (elbow down), which the KR150-2 cannot reach there within its
    // limits: not the reachable upper arm in its place, but the target left as written.
    let line = compensate_one(
        &table,
        &one_position_job(dir.path(), Some("0,1,0,0,0,0,0,0")),
    );
    assert_eq!(line.status.as_str(), "ik_failed");
    assert_eq!(
        line.detail,
        "no posture reaches the target in its written configuration (RCONF flip, lower arm, front, R < 180°, T < 180°, S < 180°)"
    );
}

#[test]
fn a_yaskawa_rconf_that_cannot_be_read_leaves_the_position_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let line = compensate_one(
        &table,
        &one_position_job(dir.path(), Some("0,2,0,0,0,0,0,0")),
    );
    assert_eq!(line.status.as_str(), "invalid");
    assert_eq!(
        line.detail,
        "a ///RCONF field is 0 or 1, found '2' (line 8, column 12): left as written, not corrected in a posture the program does not give"
    );
    let line = compensate_one(
        &table,
        &one_position_job(dir.path(), Some("0,0,0,0,0,0,1,0")),
    );
    assert_eq!(line.status.as_str(), "invalid");
    assert!(line.detail.contains("after the sixth"), "{}", line.detail);
}
