//! `tablec plan` continuing a measurement: a second round planned from the first round's
//! samples and the table built from them (`--measured`, `--table`), compared with random
//! poses drawn from the same workspace, and measured into a table of both rounds.

use crate::common::{repo, tablec};

fn run(args: &[&str], dir: &std::path::Path) -> String {
    let o = tablec(args, dir);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The rows of a plan (its `#` lines and header left out).
fn rows(path: &std::path::Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(String::from)
        .collect()
}

/// The numbers after `key` on `line`, up to the next non-number.
fn number_after(line: &str, key: &str) -> f64 {
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("{key} in {line}")) + key.len()..];
    rest.trim_start()
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
        .next()
        .unwrap()
        .parse()
        .unwrap_or_else(|e| panic!("{key} in {line}: {e}"))
}

#[test]
fn a_second_round_is_planned_from_the_first_rounds_samples_and_table() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = repo("tables/kr150-2/robot.toml");
    let scenario = repo("tables/kr150-2/scenario.toml");
    let (robot, scenario) = (robot.to_str().unwrap(), scenario.to_str().unwrap());
    let place = [
        "--robot",
        robot,
        "--min",
        "1350,50,850",
        "--max",
        "2150,850,1650",
        "--abc",
        "0,90,0",
        "--orientation-tolerance",
        "5",
        "--pool",
        "400",
        "-q",
    ];
    let plan = |extra: &[&str], out: &str| {
        let mut args = vec!["plan"];
        args.extend_from_slice(&place);
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", out]);
        run(&args, d)
    };
    let first = plan(&["--count", "30", "--seed", "1"], "r1.plan.csv");
    // The first round compares itself with random poses of the same workspace: as many
    // and twice as many, with the observability indices.
    let random: Vec<&str> = first.lines().filter(|l| l.starts_with("random ")).collect();
    assert_eq!(random.len(), 2, "{first}");
    assert!(
        random[0].contains("   30 poses") && random[1].contains("   60 poses"),
        "{first}"
    );
    assert!(
        first.contains("O1 ") && first.contains("noise amplification"),
        "{first}"
    );
    run(
        &[
            "simulate",
            "--robot",
            robot,
            "--scenario",
            scenario,
            "--poses",
            "r1.plan.csv",
            "--seed",
            "1",
            "-o",
            "r1.csv",
        ],
        d,
    );
    run(
        &["build", "r1.csv", "--robot", robot, "-o", "t1.tbl", "-q"],
        d,
    );
    let second = plan(
        &[
            "--count",
            "30",
            "--seed",
            "2",
            "--measured",
            "r1.csv",
            "--table",
            "t1.tbl",
        ],
        "r2.plan.csv",
    );
    // With the measured poses counted: 60 poses in the figures, the random line too.
    let planned = second
        .lines()
        .find(|l| l.starts_with("planned ") && l.contains("poses:"))
        .unwrap();
    assert!(planned.contains("   60 poses"), "{second}");
    let field = second.lines().find(|l| l.starts_with("field")).unwrap();
    let before = number_after(field, "candidates:");
    let after = number_after(field, "before,");
    assert!(
        before.is_finite() && after.is_finite() && 0.0 < after && after <= before,
        "{field}"
    );
    let (r1, r2) = (rows(&d.join("r1.plan.csv")), rows(&d.join("r2.plan.csv")));
    assert_eq!(r2.len(), 30);
    assert!(
        r2.iter().all(|row| !r1.contains(row)),
        "a measured pose planned again"
    );
    run(
        &[
            "simulate",
            "--robot",
            robot,
            "--scenario",
            scenario,
            "--poses",
            "r2.plan.csv",
            "--seed",
            "2",
            "-o",
            "r2.csv",
        ],
        d,
    );
    // Both rounds make one table, as two series.
    run(
        &[
            "build", "r1.csv", "r2.csv", "--robot", robot, "-o", "t2.tbl", "-q",
        ],
        d,
    );
    assert!(d.join("t2.tbl").exists());
}

/// The plan's options, `--measured` and `--table` among them, are checked before any
/// of their files is read: a usage error (exit status 2) naming the option.
#[test]
fn plan_options_are_refused_before_the_measured_samples_or_the_table_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let o = tablec(
        &[
            "plan",
            "--robot",
            "missing.toml",
            "--min",
            "0,0,0",
            "--max",
            "1,1,1",
            "--count",
            "5",
            "--coverage",
            "2",
            "--measured",
            "missing.csv",
            "--table",
            "missing.tbl",
            "-o",
            "p.csv",
        ],
        dir.path(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("coverage"), "{err}");
    assert!(!err.contains("missing"), "a file was read first: {err}");
}
