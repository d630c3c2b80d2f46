//! Samples that cannot be right are refused by `build`, `calibrate` and `eval`, with the
//! file, the figures and the likely cause, exit status 1 and nothing written: joints in
//! the other unit, another robot's file, orientation errors in degrees or beyond any
//! number's sense, a series in metres among series in millimetres, a series given twice.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::{repo, tablec, ur5_grid, UR5_MAP};

/// `text` with the comma-separated values of `columns` (0-based) replaced by
/// `convert(value)`, on every line after the first that is not a comment.
fn converted(text: &str, columns: &[usize], convert: impl Fn(f64) -> f64) -> String {
    let mut header_seen = false;
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with('#') || !header_seen {
            header_seen |= !line.starts_with('#');
            out.push_str(line);
        } else {
            let fields: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(i, f)| {
                    if columns.contains(&i) {
                        format!("{}", convert(f.trim().parse::<f64>().unwrap()))
                    } else {
                        f.to_string()
                    }
                })
                .collect();
            out.push_str(&fields.join(","));
        }
        out.push('\n');
    }
    out
}

/// Writes `converted(source, columns, convert)` to `dir/name`.
fn write_converted(
    dir: &Path,
    name: &str,
    source: &Path,
    columns: &[usize],
    convert: impl Fn(f64) -> f64,
) -> PathBuf {
    let text = std::fs::read_to_string(source).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, converted(&text, columns, convert)).unwrap();
    path
}

/// The run failed with exit status 1, naming every needle on standard error, and wrote
/// nothing into `dir` beyond `kept`.
fn refused(o: &Output, needles: &[&str], dir: &Path, kept: usize) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} not in: {stderr}");
    }
    let files = std::fs::read_dir(dir).unwrap().count();
    assert_eq!(files, kept, "{stderr}");
}

/// The UR5 grid with its joints in radians, read as degrees: once a hybrid table whose
/// queries were 46 mm off; now refused by build, calibrate and eval, naming the unit.
#[test]
fn ur5_joints_in_radians_are_refused_by_build_calibrate_and_eval() {
    let dir = tempfile::tempdir().unwrap();
    let samples = write_converted(
        dir.path(),
        "rad.csv",
        &ur5_grid(),
        &[7, 8, 9, 10, 11, 12],
        f64::to_radians,
    );
    let samples = samples.to_str().unwrap();
    let robot = repo("tables/ur5/robot.toml");
    let robot = robot.to_str().unwrap();
    let needles = [
        "rad.csv: the robot file's nominal forward kinematics at their joint values puts the \
         tool more than 20 mm from their commanded x,y,z for 1000 of 1000 samples",
        "they fit with the joint values in radians",
        "give the joint columns the unit rad",
    ];
    let common = ["--columns", UR5_MAP, "--robot", robot];
    let build = [&["build", samples][..], &common, &["-o", "t.tbl"]].concat();
    refused(&tablec(&build, dir.path()), &needles, dir.path(), 1);
    let calibrate = [&["calibrate", samples][..], &common, &["-o", "c.toml"]].concat();
    refused(&tablec(&calibrate, dir.path()), &needles, dir.path(), 1);
    let eval = [&["eval", samples][..], &common, &["--folds", "5"]].concat();
    refused(&tablec(&eval, dir.path()), &needles, dir.path(), 1);
    // A validation set with its joints in radians, beside good samples.
    let grid = ur5_grid();
    let eval = [
        &["eval", grid.to_str().unwrap()][..],
        &common,
        &["--validation", samples, "--methods", "kinematic"],
    ]
    .concat();
    refused(&tablec(&eval, dir.path()), &needles[1..], dir.path(), 1);
}

/// The KR150-2's samples with the UR5's robot file once calibrated to "0.1098 mm after".
#[test]
fn kr150_samples_with_the_ur5_robot_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let samples = repo("tables/kr150-2/samples.csv");
    let robot = repo("tables/ur5/robot.toml");
    let o = tablec(
        &[
            "calibrate",
            samples.to_str().unwrap(),
            "--robot",
            robot.to_str().unwrap(),
            "-o",
            "c.toml",
        ],
        dir.path(),
    );
    refused(
        &o,
        &[
            "for 729 of 729 samples",
            "neither the joints in the other angle unit, the positions in metres, another base \
             frame nor another tool fits them; is the robot file this robot's",
        ],
        dir.path(),
        0,
    );
}

/// The KR150-2's orientation errors written in degrees and read as radians (as the
/// rotation vector is by default): refused at the first sample beyond 5°, with line and
/// column; 1e20 and 1e308 (once served as 2.2e19 rad, and a panic) likewise.
#[test]
fn orientation_errors_in_degrees_or_absurd_are_refused_where_read() {
    let dir = tempfile::tempdir().unwrap();
    let kr150 = repo("tables/kr150-2/samples.csv");
    // x,y,z,a,b,c,dx,dy,dz,rx,ry,rz,...: rx,ry,rz are columns 9 to 11.
    let degrees = write_converted(dir.path(), "deg.csv", &kr150, &[9, 10, 11], f64::to_degrees);
    let o = tablec(
        &["build", degrees.to_str().unwrap(), "-o", "t.tbl"],
        dir.path(),
    );
    refused(
        &o,
        &[
            "deg.csv:",
            "(column 'r",
            "more than the 5° by which any robot's orientation misses its command",
            "look like degrees read as radians",
        ],
        dir.path(),
        1,
    );
    // Read in degrees, the same file builds (the method's served field: what is checked is
    // the reading, not the field's choice, which makes the build about twenty times longer).
    let o = tablec(
        &[
            "build",
            "-q",
            degrees.to_str().unwrap(),
            "--columns",
            "rx:deg,ry:deg,rz:deg",
            "--served-field",
            "method",
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::remove_file(dir.path().join("t.tbl")).unwrap();
    for (name, value) in [("e20.csv", 1e20), ("e308.csv", 1e308)] {
        let text = std::fs::read_to_string(&kr150).unwrap();
        // The first sample's rx, on line 5 after three comment lines and the header.
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let mut fields: Vec<String> = lines[4].split(',').map(str::to_string).collect();
        fields[9] = format!("{value:e}");
        lines[4] = fields.join(",");
        std::fs::write(dir.path().join(name), lines.join("\n") + "\n").unwrap();
        let o = tablec(&["build", name, "-o", "t.tbl"], dir.path());
        refused(
            &o,
            &[
                &format!("{name}:5:10 (column 'rx'): an orientation error of"),
                "no unit makes it a robot's",
            ],
            dir.path(),
            2 + usize::from(name == "e308.csv"),
        );
    }
}

/// Series trained together: a copy of the grid in metres is named; the grid given twice,
/// by one path or by two, is refused.
#[test]
fn a_series_in_metres_and_a_series_given_twice_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let grid = ur5_grid();
    let random = repo("tables/ur5/measurements/3D_UR5_uncalibrated_random_cleaned.csv");
    let metres = write_converted(dir.path(), "metres.csv", &grid, &[1, 2, 3, 4, 5, 6], |v| {
        v / 1000.0
    });
    let (grid, random) = (grid.to_str().unwrap(), random.to_str().unwrap());
    let o = tablec(
        &[
            "build",
            grid,
            random,
            metres.to_str().unwrap(),
            "--columns",
            UR5_MAP,
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    refused(
        &o,
        &[
            "series 3 (",
            "metres.csv) has positions about",
            "it looks like metres read as millimetres among series in millimetres",
        ],
        dir.path(),
        1,
    );
    let o = tablec(
        &[
            "build",
            grid,
            random,
            grid,
            "--columns",
            UR5_MAP,
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    refused(
        &o,
        &["is given twice (series 1 and 3)", "repeatability of 0 mm"],
        dir.path(),
        1,
    );
    std::fs::copy(grid, dir.path().join("copy.csv")).unwrap();
    let robot = repo("tables/ur5/robot.toml");
    let o = tablec(
        &[
            "calibrate",
            grid,
            "copy.csv",
            "--columns",
            UR5_MAP,
            "--robot",
            robot.to_str().unwrap(),
        ],
        dir.path(),
    );
    refused(
        &o,
        &["copy.csv holds the same rows as", "(series 2 and 1)"],
        dir.path(),
        2,
    );
}
