//! The command line names a refused option by its flag, never by the Python package's
//! keyword for it (`tests/python`: the package names the keyword, never the flag).

use crate::common::tablec;

#[test]
fn a_refused_option_is_named_by_its_flag_alone() {
    let cases: &[(&[&str], &str, &str)] = &[
        (
            &[
                "eval",
                "missing.csv",
                "--validation",
                "v.csv",
                "--by-region",
            ],
            "--by-region",
            "by_region",
        ),
        (
            &[
                "eval",
                "missing.csv",
                "--register-validation-apart",
                "--folds",
                "3",
            ],
            "--register-validation-apart",
            "register_validation_apart",
        ),
        (
            &[
                "build",
                "missing.csv",
                "-o",
                "t.tbl",
                "--tune-folds",
                "1",
                "--tune",
            ],
            "--tune-folds",
            "tune_folds",
        ),
        (
            &["eval", "missing.csv", "--folds", "3", "--base-link", "b"],
            "--base-link",
            "base_link",
        ),
    ];
    for (args, flag, keyword) in cases {
        let dir = tempfile::tempdir().unwrap();
        let o = tablec(args, dir.path());
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(
            !err.contains(keyword),
            "{args:?} names Python's keyword: {err}"
        );
    }
}
