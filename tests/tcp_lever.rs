//! A program's TCP as the controller applies it, on the UR5 hybrid table: its samples
//! measured position alone, which does not determine the rotation error that turns a lever
//! (docs/runtime.md, "Another TCP"), so the table serves none. A TCP away from their point
//! is beyond their evidence: compensation refuses it unless `--beyond-evidence`, and a
//! query flags it; with it, the TCP is carried with the point's correction, unturned, and
//! lands as the table predicts. (A table whose samples measured orientation turns the
//! lever by its model: `runtime/tests/tcp_and_evidence.rs` holds that to the chains.)

use std::path::Path;

use adwi_programs::{CompensateJob, CompensateOptions};
use adwi_runtime::{Evidence, Table, Target};

use crate::common::{build_ur5_hybrid, repo};

/// TCP poses of the UR5 (m and rotation vectors, rad, base frame) in the measured grid, as
/// PolyScope writes them.
const POSES: [[f64; 6]; 4] = [
    [
        -0.476472, -0.292440, 0.069339, 1.123205, -1.167681, -1.250492,
    ],
    [
        -0.460489, -0.057514, -0.098017, 1.188867, -1.052092, -0.970786,
    ],
    [
        -0.496458, -0.004637, 0.337236, 1.398012, -1.300755, -0.932323,
    ],
    [
        -0.482200, -0.117731, 0.297162, 1.131240, -0.784138, -1.050057,
    ],
];

/// The robot file's tool: the measured point in the flange frame, mm.
const POINT_MM: [f64; 3] = [0.0, 0.09, 31.0];

/// A URScript moving a TCP `tcp_z_m` metres along the flange's z axis to [`POSES`]; line
/// `3 + i` moves to pose `i`.
fn script(tcp_z_m: f64) -> String {
    let mut s = format!("def seam():\n  set_tcp(p[0, 0, {tcp_z_m}, 0, 0, 0])\n");
    for p in POSES {
        let p: Vec<String> = p.iter().map(|v| format!("{v}")).collect();
        s += &format!("  movel(p[{}], a=1.2, v=0.25)\n", p.join(", "));
    }
    s += "end\nseam()\n";
    s
}

/// For each pose, how far from it the TCP lands by the table's own prediction (the point's
/// error, its model's and residual's, the lever carried unturned) when the robot is
/// commanded the compensated joint values, mm.
fn landing_errors(dir: &Path, table_path: &Path, tcp_z_m: f64) -> Vec<f64> {
    let program = dir.join(format!("seam-{tcp_z_m}.script"));
    std::fs::write(&program, script(tcp_z_m)).unwrap();
    let mut options = CompensateOptions::new(table_path, &program);
    options.robot = Some(repo("tables/ur5/robot.toml"));
    options.limits.max_correction_mm = 20.0;
    // The table's own prediction at any lever, beyond its samples' evidence or not.
    options.limits.beyond_evidence = true;
    let done = CompensateJob::new(options).unwrap().run().unwrap();
    // SAFETY: the test's own file, not modified while mapped.
    let table = unsafe { Table::open(table_path) }.unwrap();
    let model = table.model().unwrap();
    let tcp_mm = [0.0, 0.0, 1000.0 * tcp_z_m];
    let lever_mm = [0, 1, 2].map(|a| tcp_mm[a] - POINT_MM[a]);
    let mut errors = Vec::new();
    for (i, pose) in POSES.iter().enumerate() {
        let line = done
            .report
            .targets
            .iter()
            .find(|t| t.line == 3 + i)
            .unwrap_or_else(|| panic!("no report line for line {}", 3 + i));
        assert!(line.status.corrected(), "{}: {}", line.place(), line.detail);
        // The report's joints are in degrees (the UR5's are all revolute).
        let q: Vec<f64> = line
            .command_joints
            .as_ref()
            .unwrap()
            .iter()
            .map(|v| v.to_radians())
            .collect();
        // The table's prediction at the command: the point's error there (no rotation
        // served), the TCP riding on the point with the nominal orientation.
        let nominal = model.nominal().tcp_pose(&q).unwrap();
        let at_point = table.query_with_joints(&Target::at(nominal.translation_mm), &q);
        assert_eq!(at_point.status, adwi_runtime::Status::Ok);
        assert_eq!(at_point.orientation_error_rad, [0.0; 3]);
        let carried = nominal.transform_point(lever_mm);
        let landed = [0, 1, 2].map(|a| carried[a] + at_point.position_error_mm[a]);
        let target_mm = [pose[0], pose[1], pose[2]].map(|v| 1000.0 * v);
        errors.push(adwi_runtime::method::distance_mm(landed, target_mm));
    }
    errors
}

/// The UR5 hybrid table both tests read, built once: its folder and its path.
fn ur5_table() -> &'static (tempfile::TempDir, std::path::PathBuf) {
    static TABLE: std::sync::OnceLock<(tempfile::TempDir, std::path::PathBuf)> =
        std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        build_ur5_hybrid(
            dir.path(),
            repo("tables/ur5/robot.toml").to_str().unwrap(),
            &["--cell", "30"],
            "ur5.tbl",
        );
        let path = dir.path().join("ur5.tbl");
        (dir, path)
    })
}

#[test]
fn a_200_mm_tcp_lands_as_the_tables_prediction_carries_it() {
    let dir = tempfile::tempdir().unwrap();
    let table = &ur5_table().1;
    let short = landing_errors(dir.path(), table, 0.031);
    let long = landing_errors(dir.path(), table, 0.2);
    for (i, (s, l)) in short.iter().zip(&long).enumerate() {
        // The fixed point's tolerance and the written precision (1e-6 m) bound both.
        assert!(*s < 0.01, "pose {i}: the 31 mm TCP lands {s} mm off");
        assert!(*l < 0.01, "pose {i}: the 200 mm TCP lands {l} mm off");
        assert!(
            (l - s).abs() < 0.01,
            "pose {i}: 200 mm {l} mm, 31 mm {s} mm"
        );
    }
    eprintln!("landing errors, mm: 31 mm TCP {short:?}, 200 mm TCP {long:?}");
}

/// A hybrid build of samples of position alone says, as it writes the table, that it
/// serves no orientation error and that a TCP away from their point will be flagged.
#[test]
fn a_hybrid_build_of_positions_alone_notes_the_rotation_it_cannot_vouch_for() {
    let dir = tempfile::tempdir().unwrap();
    let robot = repo("tables/ur5/robot.toml");
    let stderr = build_ur5_hybrid(
        dir.path(),
        robot.to_str().unwrap(),
        &["--cell", "100"],
        "t.tbl",
    );
    assert!(
        stderr.contains(
            "note: the samples measured position alone: the table corrects position and \
             serves no orientation error (its model's, which positions do not determine, can \
             be further from the robot's than none), and a TCP more than 1 mm from their point \
             is carried unturned and flagged `tcp`"
        ),
        "{stderr}"
    );
}

/// Without `--beyond-evidence` the UR5 table (samples of position alone) corrects the TCP
/// at its measured point and refuses the 200 mm one, by name and with the reason.
#[test]
fn a_lever_the_samples_did_not_measure_is_refused_by_compensation() {
    let dir = tempfile::tempdir().unwrap();
    for (tcp_z_m, refused) in [(0.031, false), (0.2, true)] {
        let program = dir.path().join(format!("seam-{tcp_z_m}.script"));
        std::fs::write(&program, script(tcp_z_m)).unwrap();
        let mut options = CompensateOptions::new(&ur5_table().1, &program);
        options.robot = Some(repo("tables/ur5/robot.toml"));
        options.limits.max_correction_mm = 20.0;
        let done = CompensateJob::new(options).unwrap().run().unwrap();
        for i in 0..POSES.len() {
            let line = done
                .report
                .targets
                .iter()
                .find(|t| t.line == 3 + i)
                .unwrap();
            if refused {
                assert!(
                    !line.status.corrected(),
                    "{}: {}",
                    line.place(),
                    line.detail
                );
                assert!(
                    line.detail
                        .contains("never had this TCP lever, nor any orientation to turn it by"),
                    "{}",
                    line.detail
                );
            } else {
                assert!(line.status.corrected(), "{}: {}", line.place(), line.detail);
            }
        }
    }
}

/// A joint target's TCP is the motion's, as a Cartesian target's is: on the UR5 table
/// (samples of position alone, so no rotation to turn a lever by) a `movej` under a 200 mm
/// `set_tcp` is refused with the lever's reason, as the `movel` beside it, and corrected
/// under the 31 mm TCP of the table's point; a RAPID `MoveAbsJ` with a tool the module
/// does not declare is left frame_unknown (its work object does not matter), with the
/// flange a lever, and corrected with a tool at the table's point.
#[test]
fn a_joint_targets_tcp_is_its_motions() {
    let dir = tempfile::tempdir().unwrap();
    let q_deg = [17.2729, -81.9889, 88.4100, 0.0713, 93.4555, -0.1215];
    let q_rad: Vec<String> = q_deg
        .iter()
        .map(|v: &f64| format!("{}", v.to_radians()))
        .collect();
    let p: Vec<String> = POSES[0].iter().map(|v| format!("{v}")).collect();
    let run = |name: &str, text: String| {
        let program = dir.path().join(name);
        std::fs::write(&program, text).unwrap();
        let mut options = CompensateOptions::new(&ur5_table().1, &program);
        options.robot = Some(repo("tables/ur5/robot.toml"));
        options.limits.max_correction_mm = 20.0;
        let done = CompensateJob::new(options).unwrap().run().unwrap();
        done.report.targets
    };
    for (tcp_z_m, refused) in [(0.031, false), (0.2, true)] {
        let targets = run(
            &format!("j-{tcp_z_m}.script"),
            format!(
                "def j():\n  set_tcp(p[0, 0, {tcp_z_m}, 0, 0, 0])\n  movej([{}], a=1.4, v=1.05)\n  movel(p[{}], a=1.2, v=0.25)\nend\nj()\n",
                q_rad.join(", "),
                p.join(", ")
            ),
        );
        assert_eq!(targets.len(), 2);
        assert_eq!(targets[0].kind, "joints");
        for t in &targets {
            assert_eq!(
                !t.status.corrected(),
                refused,
                "{}: {}",
                t.place(),
                t.detail
            );
            if refused {
                assert!(
                    t.detail
                        .contains("never had this TCP lever, nor any orientation to turn it by"),
                    "{}",
                    t.detail
                );
            }
        }
    }
    let joints: Vec<String> = q_deg.iter().map(|v| format!("{v}")).collect();
    let module = |tool: &str| {
        format!(
            "MODULE M\n  PERS wobjdata wAnywhere:=[FALSE,TRUE,\"\",[[100,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n  CONST jointtarget jPose:=[[{}],[9E9,9E9,9E9,9E9,9E9,9E9]];\n  PROC main()\n    MoveAbsJ jPose,v100,fine,{tool}\\WObj:=wAnywhere;\n  ENDPROC\nENDMODULE\n",
            joints.join(",")
        )
    };
    let unknown = run("gun.mod", module("tGun"));
    assert_eq!(
        unknown[0].status.as_str(),
        "frame_unknown",
        "{}",
        unknown[0].detail
    );
    assert!(
        unknown[0].detail.starts_with("tool tGun not given"),
        "{}",
        unknown[0].detail
    );
    // The flange is 31 mm from the table's point: a lever; the point itself is none.
    let flange = run("flange.mod", module("tool0"));
    assert!(
        flange[0].detail.contains("never had this TCP lever"),
        "{}",
        flange[0].detail
    );
    let point = run(
        "point.mod",
        module("tPoint").replace(
            "  CONST jointtarget",
            "  PERS tooldata tPoint:=[TRUE,[[0,0.09,31],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n  CONST jointtarget",
        ),
    );
    assert!(point[0].status.corrected(), "{}", point[0].detail);
}

#[test]
fn a_query_naming_a_far_tcp_is_flagged_and_its_lever_carried_unturned() {
    // SAFETY: the tests' own file, not modified while mapped.
    let table = unsafe { Table::open(&ur5_table().1) }.unwrap();
    let model = table.model().unwrap();
    // The README's query pose.
    let q: Vec<f64> = [17.2729, -81.9889, 88.4100, 0.0713, 93.4555, -0.1215]
        .iter()
        .map(|v: &f64| v.to_radians())
        .collect();
    let nominal = model.nominal().tcp_pose(&q).unwrap();
    let tcp_mm = [0.0, 0.0, 200.0];
    let lever_mm = [0, 1, 2].map(|a| tcp_mm[a] - POINT_MM[a]);
    let at_tcp = nominal.transform_point(lever_mm);
    let got = table.query_with_joints(&Target::at(at_tcp).with_tcp(tcp_mm), &q);
    let plain = table.query_with_joints(&Target::at(nominal.translation_mm), &q);
    // Answered, and flagged: the samples measured position alone.
    assert_eq!(
        (got.evidence, plain.evidence),
        (Evidence::TCP, Evidence::WITHIN)
    );
    // The point's error, carried unturned: no rotation served.
    let moved = adwi_runtime::method::distance_mm(got.position_error_mm, plain.position_error_mm);
    assert!(moved < 1e-9, "{moved} mm");
    assert_eq!(
        (got.orientation_error_rad, plain.orientation_error_rad),
        ([0.0; 3], [0.0; 3])
    );
}

/// A position-only table's targets at orientations its samples never had are refused by
/// name (exit 3), unless `--beyond-evidence`; then they are corrected and counted.
#[test]
fn compensate_refuses_a_position_only_tables_targets_beyond_its_samples_orientations() {
    let dir = tempfile::tempdir().unwrap();
    let samples = repo("tables/kr150-2/samples.csv");
    let build = crate::common::tablec(
        &[
            "build",
            "-q",
            samples.to_str().unwrap(),
            "--served-field",
            "method",
            "-o",
            "kr150.tbl",
        ],
        dir.path(),
    );
    assert!(
        build.status.success(),
        "{}",
        String::from_utf8_lossy(&build.stderr)
    );
    // The samples' orientation, then B = 45 and A = 90 (KUKA degrees).
    std::fs::write(
        dir.path().join("t.csv"),
        "x,y,z,a,b,c\n2000,700,1000,0,90,0\n2000,700,1000,0,45,0\n1800,600,1200,90,90,0\n",
    )
    .unwrap();
    let run = |extra: &[&str], out: &str| {
        let mut args = vec!["compensate", "kr150.tbl", "t.csv", "-o", out, "--report"];
        let report = format!("{out}.report.csv");
        args.push(&report);
        args.extend_from_slice(extra);
        let o = crate::common::tablec(&args, dir.path());
        let report = std::fs::read_to_string(dir.path().join(&report)).unwrap_or_default();
        (o.status.code(), report)
    };
    let (code, report) = run(&[], "refused.csv");
    assert_eq!(code, Some(3));
    let statuses: Vec<(String, String)> = report
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[4].to_string(), f[f.len() - 2].to_string())
        })
        .collect();
    let expected = [
        ("ok", "within"),
        ("beyond_evidence", "orientation"),
        ("beyond_evidence", "orientation"),
    ];
    assert_eq!(
        statuses,
        expected.map(|(s, e)| (s.to_string(), e.to_string()))
    );
    let (code, report) = run(&["--beyond-evidence"], "corrected.csv");
    assert_eq!(code, Some(0));
    let evidence: Vec<&str> = report
        .lines()
        .skip(1)
        .map(|l| l.split(',').rev().nth(1).unwrap())
        .collect();
    assert_eq!(evidence, ["within", "orientation", "orientation"]);
    // A program that writes no orientation is not checked against the samples' (an
    // orientation it does not give is not one they never had).
    std::fs::write(
        dir.path().join("t.csv"),
        "x,y,z\n2000,700,1000\n1800,600,1200\n",
    )
    .unwrap();
    let (code, report) = run(&[], "positions.csv");
    assert_eq!(code, Some(0), "{report}");
}

/// A position-only table without orientation errors cannot turn a TCP's lever: a program
/// whose TCP lies 169 mm from the measured point is refused by name (`beyond_evidence`,
/// the TCP), where the measured point's own TCP is corrected.
#[test]
fn compensate_refuses_a_lever_a_table_without_orientations_cannot_turn() {
    let dir = tempfile::tempdir().unwrap();
    let grid = crate::common::ur5_grid();
    let o = crate::common::tablec(
        &[
            "build",
            "-q",
            grid.to_str().unwrap(),
            "--columns",
            crate::common::UR5_MAP,
            "--served-field",
            "method",
            "-o",
            "ur5p.tbl",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let robot = repo("tables/ur5/robot.toml");
    for (tcp_z_m, code, status) in [(0.031, 0, "ok"), (0.2, 3, "beyond_evidence")] {
        let program = format!("seam-{tcp_z_m}.script");
        std::fs::write(dir.path().join(&program), script(tcp_z_m)).unwrap();
        let report = format!("{program}.csv");
        let o = crate::common::tablec(
            &[
                "compensate",
                "ur5p.tbl",
                &program,
                "--robot",
                robot.to_str().unwrap(),
                "-o",
                "out.script",
                "--report",
                &report,
            ],
            dir.path(),
        );
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(code), "{stdout}");
        let report = std::fs::read_to_string(dir.path().join(&report)).unwrap();
        // The 200 mm TCP moves some table points off the served field (`outside`); every
        // other target is refused for its lever.
        let statuses: Vec<String> = (report.lines().skip(1))
            .map(|row| row.split(',').nth(4).unwrap().to_string())
            .collect();
        assert!(statuses.iter().any(|s| s == status), "{report}");
        assert!(
            statuses
                .iter()
                .all(|s| s == status || (code == 3 && s == "outside")),
            "{report}"
        );
        if code == 3 {
            assert!(stdout.contains("TCP lever"), "{stdout}");
        }
    }
}
