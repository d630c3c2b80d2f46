//! `tablec plan` over every inverse-kinematics branch (`--branches all`) and weighed by the
//! tracker's uncertainty (`--tracker-mpe-um`): the options refused before any work, and a
//! plan that takes other branches and says so.

use crate::common::{repo, tablec};

/// Runs tablec in a fresh folder where no input exists; returns (status, stderr).
fn refused(args: &[&str]) -> (Option<i32>, String) {
    let dir = tempfile::tempdir().unwrap();
    let o = tablec(args, dir.path());
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn the_tracker_model_and_the_branches_are_refused_before_any_work() {
    let cases: &[(&[&str], &str)] = &[
        (&["--tracker-mpe-um", "30,12"], "not provided:\n  --tracker"),
        (
            &["--tracker", "0,0,0", "--tracker-mpe-um", "30"],
            "two numbers",
        ),
        (
            &["--tracker", "0,0,0", "--tracker-mpe-um=-1,12"],
            "give a > 0 µm",
        ),
        (
            &["--tracker", "0,0,0", "--tracker-mpe-um", "30,inf"],
            "not a finite",
        ),
        (
            &["--tracker", "0,0,0", "--tracker-mpe-um", "5000,12"],
            "at most 1000",
        ),
        (&["--branches", "all"], "needs allowed orientations"),
        (&["--branches", "sideways"], "possible values: home, all"),
    ];
    for (options, needle) in cases {
        let mut args = vec![
            "plan",
            "--robot",
            "missing.toml",
            "--min",
            "0,0,0",
            "--max",
            "1,1,1",
            "--count",
            "5",
            "-o",
            "p.csv",
        ];
        args.extend_from_slice(options);
        let (code, err) = refused(&args);
        assert_eq!(code, Some(2), "{options:?}: {err}");
        assert!(
            err.to_lowercase().contains(needle),
            "{options:?}: {needle} in {err}"
        );
        assert!(
            !err.contains("missing.toml"),
            "{options:?} read the robot first: {err}"
        );
    }
}

/// On the KR150-2 at one tool orientation every branch adds wrist flips: the plan takes
/// some, says how many and over which workspace its variance is, weighs the poses by the
/// tracker (variances in mm²), and still compares with random poses of the home branch.
#[test]
fn a_plan_over_every_branch_takes_other_branches_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let robot = repo("tables/kr150-2/robot.toml");
    let o = tablec(
        &[
            "plan",
            "--robot",
            robot.to_str().unwrap(),
            "--min",
            "1350,50,850",
            "--max",
            "2150,850,1650",
            "--abc",
            "0,90,0",
            "--orientation-tolerance",
            "5",
            "--count",
            "30",
            "--pool",
            "600",
            "--branches",
            "all",
            "--tracker",
            "4500,-1500,0",
            "--tracker-mpe-um",
            "30,12",
            "-q",
            "-o",
            "p.csv",
        ],
        dir.path(),
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("branches       "), "{out}");
    assert!(out.contains("variances in mm²"), "{out}");
    assert!(out.contains(" mm², parameter variance"), "{out}");
    let plan = std::fs::read_to_string(dir.path().join("p.csv")).unwrap();
    assert!(plan.contains("# Every inverse-kinematics branch"), "{plan}");
    assert!(
        plan.contains("# Weighed by the tracker's uncertainty"),
        "{plan}"
    );
    // More than one configuration among the poses (the last column).
    let mut configs: Vec<&str> = plan
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap())
        .collect();
    configs.sort_unstable();
    configs.dedup();
    assert!(configs.len() > 1, "{configs:?}");
}
