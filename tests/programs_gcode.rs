//! G-code programs compensated offline (`tablec compensate`, format `gcode`): the pocket a
//! CAM post-processor writes (`tests/programs/pocket.nc`) and generated programs, with the
//! KR150-2 table and a table that corrects nothing. Every written command is read back and
//! checked against `tablec query`; every corrected arc against the table's commands along
//! it; every motion that is not corrected is reported by its reason.

use std::path::{Path, PathBuf};

use adwi_programs::frames::{kuka_pose, rotation_of, FrameChain};
use adwi_programs::gcode::{GcodeOptions, DEFAULT_ARC_TOLERANCE_MM};
use adwi_programs::program::TargetKind;
use adwi_programs::source::Source;
use adwi_programs::{CompensateJob, CompensateOptions};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::common::{compensate, method_table, repo, tablec};

/// The pocket's work offset: its origin in the KR150-2's workspace.
const G54: [f64; 6] = [1750.0, 450.0, 1200.0, 0.0, 0.0, 0.0];
const G54_ARG: &str = "G54=1750,450,1200";

fn pocket() -> PathBuf {
    repo("tests/programs/pocket.nc")
}

fn kr150_table(dir: &Path) -> PathBuf {
    method_table(dir, &repo("tables/kr150-2/samples.csv"), "kr150.tbl")
}

/// `tablec query --targets` at `points` (base frame, mm): per point, the predicted error
/// and the command.
fn query(dir: &Path, table: &Path, points: &[[f64; 3]]) -> Vec<([f64; 3], [f64; 3])> {
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
    let rows: Vec<_> = answers
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            assert_eq!(v[18], "converged", "{l}");
            let f = |i: usize| v[i].parse::<f64>().unwrap();
            ([f(3), f(4), f(5)], [f(12), f(13), f(14)])
        })
        .collect();
    assert_eq!(rows.len(), points.len());
    rows
}

/// The pocket's job with the KR150-2 table (its samples' orientation, A 0 B 90 C 0).
fn pocket_job(table: &Path) -> (CompensateJob, adwi_programs::Compensated) {
    let mut options = CompensateOptions::new(table, pocket());
    options.gcode.work_offsets = vec![(54, G54)];
    let job = CompensateJob::new(options).unwrap();
    let done = job.run().unwrap();
    (job, done)
}

#[test]
fn a_table_that_corrects_nothing_reproduces_g_code_byte_for_byte() {
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
    // A program in inches with CRLF line ends, modal axes, block numbers and comments.
    let inches = "%\r\nO0002 (INCH, CRLF)\r\nN5 G20 G90 G17\r\nN10 G0 X59.0551 Y17.7165 Z47.2441 A0 B90 C0\r\n\
                  N15 G1 X60.0551 Y17.7165 Z47.2441 F40. (cut)\r\n\
                  N20 G2 X61.0551 Y17.7165 Z47.2441 I0.5 J0.\r\nN25 G3 X60.0551 Y17.7165 Z47.2441 R-0.5\r\n\
                  N30 G1 Y18.2165 ; modal X, Z\r\nN35 M30\r\n%\r\n";
    std::fs::write(dir.path().join("inch.tap"), inches).unwrap();
    for program in [pocket(), dir.path().join("inch.tap")] {
        let out = dir.path().join("out.nc");
        let (code, stdout, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                program.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--work-offset",
                G54_ARG,
            ],
        );
        assert!(code == 0 || code == 3, "{}: {stderr}", program.display());
        assert!(crate::common::corrected_lines(&stdout) >= 4, "{stdout}");
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(&program).unwrap(),
            "{}: {stdout}",
            program.display()
        );
    }
}

#[test]
fn kr150_g_code_commands_land_on_their_targets_by_tablec_query() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let (job, done) = pocket_job(&table);
    let summary = done.report.summary();
    let statuses: Vec<&str> = done
        .report
        .targets
        .iter()
        .map(|t| t.status.as_str())
        .collect();
    // The boss's full circle bends beyond 0.01 mm (its own test below), G91 G28 returns home.
    assert_eq!(summary.total, 17, "{summary}");
    assert_eq!(summary.corrected, 15, "{summary}");
    assert_eq!(statuses[11], "arc_tolerance");
    assert_eq!(statuses[16], "dynamic");
    // Read back: every corrected target's written numbers, through G54, are its command
    // to the written precision, and the robot at that command lands on the target.
    let src = Source::new("out.nc", &done.output);
    let written = adwi_programs::gcode::read(&src, &job.options().gcode).unwrap();
    assert_eq!(written.program.targets.len(), done.report.targets.len());
    let base = kuka_pose([G54[0], G54[1], G54[2]], [G54[3], G54[4], G54[5]]);
    let chain = FrameChain {
        base,
        tool: Isometry3::identity(),
        table_tool: Isometry3::identity(),
    };
    let mut commands = Vec::new();
    let mut points = Vec::new();
    let mut largest: f64 = 0.0;
    for (target, line) in written.program.targets.iter().zip(&done.report.targets) {
        let TargetKind::Cartesian(c) = &target.kind else {
            continue;
        };
        if !line.status.corrected() {
            continue;
        }
        let rotation = rotation_of(c.orientation.as_ref().unwrap()).unwrap();
        let pose = Isometry3::from_parts(
            Vector3::from(c.position.map(|n| n.value)).into(),
            UnitQuaternion::from_rotation_matrix(&rotation),
        );
        let command = chain.table_point(&pose).translation.vector;
        let expected = Vector3::from(line.command_mm.unwrap());
        assert!((command - expected).norm() <= 1e-4, "{}", line.place());
        commands.push(command.into());
        points.push(line.point_mm.unwrap());
        largest = largest.max(line.correction_mm.unwrap());
    }
    assert_eq!(commands.len(), 15);
    // |C + e(C) − P| by tablec query at every written command.
    let mut worst: f64 = 0.0;
    for ((error, _), (c, p)) in query(dir.path(), &table, &commands)
        .iter()
        .zip(commands.iter().zip(&points))
    {
        let landed = Vector3::from(*c) + Vector3::from(*error);
        worst = worst.max((landed - Vector3::from(*p)).norm());
    }
    eprintln!("pocket.nc: {summary}; |C + e(C) - P| at most {worst:.3e} mm");
    assert!(worst <= 1e-4, "{worst}");
    assert!(largest > 1.0 && largest < 5.0, "{largest}");
}

/// An arc as a program writes it: its centre in its plane, its start and end (mm, program
/// frame), and whether it turns clockwise.
type WrittenArc = ([f64; 2], [f64; 3], [f64; 3], bool);

/// The arcs of `output` at the blocks `corrected` marks; the start is the previous target's
/// written end.
fn written_arcs(output: &[u8], options: &GcodeOptions, corrected: &[bool]) -> Vec<WrittenArc> {
    let src = Source::new("out.nc", output);
    let read = adwi_programs::gcode::read(&src, options).unwrap();
    let ends: Vec<Option<[f64; 3]>> = read
        .program
        .targets
        .iter()
        .map(|t| match &t.kind {
            TargetKind::Cartesian(c) => Some(c.position.map(|n| n.value)),
            _ => None,
        })
        .collect();
    let mut arcs = Vec::new();
    for (i, arc) in read.arcs.iter().enumerate() {
        let Some(arc) = arc else { continue };
        if !corrected[i] {
            continue;
        }
        let start = ends[arc.start_target].unwrap();
        let end = ends[i].unwrap();
        arcs.push((arc.centre_mm, start, end, arc.clockwise));
    }
    arcs
}

#[test]
fn corrected_arcs_stay_within_their_tolerance_of_the_commands_along_them() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let (job, done) = pocket_job(&table);
    let corrected: Vec<bool> = done
        .report
        .targets
        .iter()
        .map(|t| t.status.corrected())
        .collect();
    // The written program's arcs, and the original's at the same blocks.
    let original = std::fs::read(pocket()).unwrap();
    let before = written_arcs(&original, &job.options().gcode, &corrected);
    let after = written_arcs(&done.output, &job.options().gcode, &corrected);
    assert_eq!(
        before.len(),
        5,
        "four corners' and the boss's two half circles"
    );
    let (g54x, g54y, g54z) = (G54[0], G54[1], G54[2]);
    let mut checked = 0;
    let mut worst: f64 = 0.0;
    for ((c0, s0, e0, cw), (c1, s1, e1, _)) in before.iter().zip(&after) {
        // Points along the original arc, in the base frame.
        let polar = |c: &[f64; 2], p: &[f64; 3]| {
            (
                (p[1] - c[1]).atan2(p[0] - c[0]),
                (p[0] - c[0]).hypot(p[1] - c[1]),
            )
        };
        let (a0, r0) = polar(c0, s0);
        let (a1, _) = polar(c0, e0);
        let tau = std::f64::consts::TAU;
        let sweep = if *cw { a0 - a1 } else { a1 - a0 }.rem_euclid(tau);
        let sweep = if sweep < 1e-12 { tau } else { sweep };
        let sign = if *cw { -1.0 } else { 1.0 };
        let n = 24;
        let points: Vec<[f64; 3]> = (0..=n)
            .map(|k| {
                let f = k as f64 / n as f64;
                let a = a0 + sign * sweep * f;
                [
                    g54x + c0[0] + r0 * a.cos(),
                    g54y + c0[1] + r0 * a.sin(),
                    g54z + s0[2] + (e0[2] - s0[2]) * f,
                ]
            })
            .collect();
        let commands = query(dir.path(), &table, &points);
        // The written arc: centre c1 (from the written I J or R), from s1 to e1.
        let (b0, q0) = polar(c1, s1);
        let (b1, q1) = polar(c1, e1);
        let sweep1 = if *cw { b0 - b1 } else { b1 - b0 }.rem_euclid(tau);
        let sweep1 = if sweep1 < 1e-9 { tau } else { sweep1 };
        for (_, command) in &commands {
            let p = [command[0] - g54x, command[1] - g54y, command[2] - g54z];
            let (angle, radius) = polar(c1, &p);
            let along = (sign * (angle - b0)).rem_euclid(tau) / sweep1;
            let dist = |q: &[f64; 3]| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            };
            let gap = if along <= 1.0 {
                let expected_radius = q0 + (q1 - q0) * along;
                let expected_z = s1[2] + (e1[2] - s1[2]) * along;
                (radius - expected_radius).hypot(p[2] - expected_z)
            } else {
                // Beyond the sweep (a command just outside an end): the nearer end.
                dist(s1).min(dist(e1))
            };
            // The tolerance, and the written numbers' rounding.
            assert!(gap <= DEFAULT_ARC_TOLERANCE_MM + 2e-4, "{gap} mm");
            worst = worst.max(gap);
            checked += 1;
        }
    }
    assert_eq!(checked, 5 * 25);
    eprintln!("pocket.nc arcs: at most {worst:.4} mm from the commands along them");
}

#[test]
fn modal_axes_work_offsets_and_every_other_motion_are_reported_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let text = "(REFUSALS)\nN1 G21 G90 G54\nN2 G0 X0 Y0 Z50 A0 B90 C0\nN3 G1 X10 Y0\n\
                N4 G1 X10 Y0 Z50\nN5 G91 G1 X5 Y0 Z0\nN6 G90 G81 X0 Y0 Z-5 R2 F100\nN7 G80\n\
                N8 G41 D1 G1 X20 Y0 Z50\nN9 G40\nN10 G68 X0 Y0 R15\nN11 G1 X0 Y10 Z50\nN12 G69\n\
                N13 G53 G0 Z0\nN14 G55\nN15 G1 X0 Y10 Z50\nN16 G54\nN17 G1 X0 Y10 Z50 W3\nN18 G28 X0 Y0 Z0\nN19 M30\n";
    std::fs::write(dir.path().join("refusals.ngc"), text).unwrap();
    let report = dir.path().join("report.csv");
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            "refusals.ngc",
            "-o",
            "out.ngc",
            "--work-offset",
            G54_ARG,
            "--report",
            report.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    let rows = crate::common::report_rows(&report, 1);
    let seen: Vec<(&str, &str)> = rows.iter().map(|r| (r.0.as_str(), r.1.as_str())).collect();
    assert_eq!(
        seen,
        [
            ("3", "ok"),
            ("4", "incomplete"),
            ("5", "incomplete"),
            ("6", "relative"),
            ("7", "unknown_motion"),
            ("9", "relative"),
            ("12", "frame_unknown"),
            ("14", "frame_unknown"),
            ("16", "frame_unknown"),
            ("18", "external_axis"),
            ("19", "dynamic"),
        ],
        "{stdout}"
    );
    assert!(
        rows[1]
            .2
            .starts_with("Z (modal from line 3) not written on this block"),
        "{}",
        rows[1].2
    );
    // The table turns the tool: the modal A, B, C of line 3 cannot carry it.
    assert!(
        rows[2]
            .2
            .starts_with("A, B, C not written on this block (modal from line 3)"),
        "{}",
        rows[2].2
    );
    assert!(
        rows[8].2.contains("work offset G55 not given"),
        "{}",
        rows[8].2
    );
    assert!(rows[6].2.contains("G68"), "{}", rows[6].2);
    assert!(
        rows[7].2.contains("G53: machine coordinates"),
        "{}",
        rows[7].2
    );
    // A work offset the options do not give, and a program that only returns home: no
    // target to correct is an error, not "0 of 0".
    std::fs::write(dir.path().join("home.nc"), "G21 G90\nG28 X0 Y0 Z0\nM30\n").unwrap();
    let (code, _, stderr) = compensate(
        dir.path(),
        &[table.to_str().unwrap(), "home.nc", "-o", "home-out.nc"],
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains(
            "home.nc:2:1: G28 moves the robot, but the program holds no target it can correct"
        ),
        "{stderr}"
    );
    assert!(!dir.path().join("home-out.nc").exists());
}

#[test]
fn the_fixed_axis_convention_turns_a_b_c_about_x_y_z() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    // KUKA A 0 B 90 C 0 is fixed-axis A 0 B 90 C 0 too; KUKA A 30 B 0 C 0 (about z) is
    // fixed-axis C 30.
    let kuka = "G21 G90\nG1 X1700 Y400 Z1200 A30 B0 C0\n";
    let xyz = "G21 G90\nG1 X1700 Y400 Z1200 A0 B0 C30\n";
    let mut answers = Vec::new();
    for (text, convention) in [(kuka, "kuka"), (xyz, "xyz")] {
        std::fs::write(dir.path().join("p.nc"), text).unwrap();
        let (code, stdout, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                "p.nc",
                "-o",
                "out.nc",
                "--gcode-abc",
                convention,
                "--beyond-evidence",
                "--report",
                "r.csv",
            ],
        );
        assert_eq!(code, 0, "{stdout}{stderr}");
        let report = std::fs::read_to_string(dir.path().join("r.csv")).unwrap();
        let row: Vec<String> = report
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .map(String::from)
            .collect();
        assert_eq!(row[4], "ok", "{report}");
        // Every figure but the written program's hash.
        answers.push(row[6..row.len() - 1].to_vec());
    }
    assert_eq!(answers[0], answers[1]);
}

/// A raster pocket of `lines` blocks as a CAM post writes it: G1 passes joined by
/// half-circle arcs, every block with X Y Z A B C.
pub fn raster_program(lines: usize) -> String {
    let mut out = String::from("%\nO2000 (RASTER POCKET)\nN1 G21 G90 G17 G54\n");
    out += "N2 G0 X-200.000 Y-200.000 Z20.000 A0. B90. C0.\nN3 S9000 M3\n";
    let mut n = 4;
    let (mut x, mut y) = (-200.0f64, -200.0f64);
    let mut forward = true;
    // The passes step 2 mm over, up to y 200 and back.
    let mut step = 2.0;
    out += "N4 G1 X-200.000 Y-200.000 Z-1.000 A0. B90. C0. F600.\n";
    while n < lines {
        n += 1;
        if n % 10 == 0 {
            // A half circle to the next pass, 2 mm over.
            if !(-200.0..=200.0).contains(&(y + step)) {
                step = -step;
            }
            y += step;
            let cw = if forward { "G3" } else { "G2" };
            out += &format!(
                "N{n} {cw} X{x:.3} Y{y:.3} Z-1.000 I0. J{:.3} A0. B90. C0.\n",
                step / 2.0
            );
            forward = !forward;
        } else {
            x += if forward { 4.5 } else { -4.5 };
            out += &format!("N{n} G1 X{x:.3} Y{y:.3} Z-1.000 A0. B90. C0.\n");
        }
    }
    out += &format!("N{} M30\n%\n", n + 1);
    out
}

#[test]
fn a_generated_program_of_100000_blocks_is_accounted_for_block_by_block() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let text = raster_program(100_000);
    assert!(text.lines().count() >= 100_000);
    let program = dir.path().join("raster.nc");
    std::fs::write(&program, &text).unwrap();
    let mut options = CompensateOptions::new(&table, &program);
    options.gcode.work_offsets = vec![(54, G54)];
    let job = CompensateJob::new(options).unwrap();
    let done = job.run().unwrap();
    let summary = done.report.summary();
    assert_eq!(summary.total, 100_000 - 2, "{summary}");
    // Every block corrected, arcs within the tolerance included.
    assert_eq!(summary.corrected, summary.total, "{summary}");
    let src = Source::new("out.nc", &done.output);
    let written = adwi_programs::gcode::read(&src, &job.options().gcode).unwrap();
    assert_eq!(written.program.targets.len(), summary.total);
    // Where the table writes the program for the release binary's figures.
    if let Some(path) = std::env::var_os("ADWI_GCODE_RASTER") {
        std::fs::write(path, &text).unwrap();
    }
}

/// Plain 3-axis G-code in a work offset (no A, B, C, no tool): its positions map through
/// the offset alone and are corrected in position.
#[test]
fn three_axis_g_code_in_a_work_offset_is_corrected_in_position() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::repo("tables/kr150-2/samples.csv");
    let o = crate::common::tablec(
        &[
            "build",
            "-q",
            table.to_str().unwrap(),
            "--served-field",
            "method",
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::write(
        dir.path().join("p.nc"),
        "G21 G90 G54\nG0 X100. Y100. Z50.\nG1 X150. Y120. Z40. F500\nM30\n",
    )
    .unwrap();
    let o = crate::common::tablec(
        &[
            "compensate",
            "t.tbl",
            "p.nc",
            "-o",
            "out.nc",
            "--work-offset",
            "G54=1750,450,1200",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{stdout}");
    assert!(stdout.contains("2 of 2 targets corrected"), "{stdout}");
}

/// A slicer's `G92 E0` sets the extruder's position alone: the moves after it stay in their
/// frame and are corrected, the E words kept. A `G92` naming Z sets an offset of the robot's
/// axes as the program runs: the moves after it are refused by it, and a later `G92 E0`
/// does not make it known.
#[test]
fn an_extruder_reset_keeps_the_frame_and_an_axis_offset_does_not() {
    let dir = tempfile::tempdir().unwrap();
    let table = kr150_table(dir.path());
    let text = "; generated by PrusaSlicer\nG21\nG90\nM83\nG92 E0\n\
                G1 X10.000 Y10.000 Z0.200 E0.5 F1500\nG1 X60.000 Y10.000 Z0.200 E1.66331\n\
                G92 E0\nG1 X60.000 Y60.000 Z0.200 E1.66331\nG92 Z0\n\
                G1 X10.000 Y60.000 Z0.400 E1.66331\nG92 E0\nG1 X10.000 Y10.000 Z0.400 E1.66331\nM84\n";
    std::fs::write(dir.path().join("slicer.gcode"), text).unwrap();
    let report = dir.path().join("report.csv");
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            "slicer.gcode",
            "-o",
            "out.gcode",
            "--base",
            "1750,450,1200,0,0,0",
            "--report",
            report.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    let rows = crate::common::report_rows(&report, 1);
    let seen: Vec<(&str, &str)> = rows.iter().map(|r| (r.0.as_str(), r.1.as_str())).collect();
    assert_eq!(
        seen,
        [
            ("6", "ok"),
            ("7", "ok"),
            ("9", "ok"),
            ("11", "frame_unknown"),
            ("13", "frame_unknown"),
        ],
        "{stdout}"
    );
    for row in &rows[3..] {
        assert_eq!(
            row.2, "G1 under G92 (line 10): an offset the program sets as it runs",
            "{stdout}"
        );
    }
    // Only X, Y, Z change: the resets and the extrusions are as written.
    let out = std::fs::read_to_string(dir.path().join("out.gcode")).unwrap();
    let (written, read): (Vec<&str>, Vec<&str>) = (out.lines().collect(), text.lines().collect());
    assert_eq!(written.len(), read.len());
    for (w, r) in written.iter().zip(&read) {
        let tail = |l: &str| l.split_once(" E").map(|(_, e)| e.to_string());
        assert_eq!(tail(w), tail(r), "{w}");
        if !r.starts_with("G1 X") || r.contains("Z0.400") {
            assert_eq!(w, r);
        }
    }
    assert_ne!(written[5], read[5]);
}
