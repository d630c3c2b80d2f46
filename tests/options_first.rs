//! Every option is checked before any file is read: a bad option is a usage error (exit
//! status 2) naming the option, even when the input it would read does not exist.

use crate::common::tablec;

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
fn build_options_are_refused_before_the_samples_are_read() {
    let cases: &[(&[&str], &str)] = &[
        (&["--k", "0"], "neighbour count k"),
        (&["--k", "17"], "neighbour count k"),
        (&["--w1", "0.3", "--w2", "0.3"], "w1 + w2"),
        (&["--power", "5"], "power r"),
        (&["--radius=-3"], "radius"),
        (&["--cell=-1"], "cell size"),
        (&["--cell", "0"], "cell size"),
        (&["--lambda-min=-1"], "lambda-min"),
        (&["--joint-radius=-5"], "joint radius"),
        (
            &["--joint-radius", "5", "--served-field", "kriging"],
            "served tier",
        ),
        (&["--bounds=0,0,0,-1,1,1"], "bounds"),
    ];
    for (options, needle) in cases {
        let mut args = vec!["build", "missing.csv", "-o", "t.tbl"];
        args.extend_from_slice(options);
        let (code, err) = refused(&args);
        assert_eq!(code, Some(2), "{options:?}: {err}");
        assert!(err.contains(needle), "{options:?}: {err}");
        assert!(
            !err.contains("missing.csv"),
            "{options:?} read the samples first: {err}"
        );
    }
}

#[test]
fn query_options_are_refused_before_the_table_is_opened() {
    let cases: &[(&[&str], &str)] = &[
        (&["missing.tbl", "1", "2"], "X Y Z or X Y Z A B C"),
        (&["missing.tbl", "1", "2", "3", "4"], "4 numbers given"),
        (
            &["missing.tbl", "1", "2", "3", "--tcp", "1,2"],
            "--tcp takes X,Y,Z",
        ),
        (&["missing.tbl", "1", "2", "3e9"], "mm is more than"),
        (
            &["missing.tbl", "1", "2", "3", "0", "4000", "0"],
            "three turns",
        ),
    ];
    for (options, needle) in cases {
        let mut args = vec!["query"];
        args.extend_from_slice(options);
        let (code, err) = refused(&args);
        assert_eq!(code, Some(2), "{options:?}: {err}");
        assert!(err.contains(needle), "{options:?}: {err}");
        assert!(
            !err.contains("missing.tbl"),
            "{options:?} opened the table first: {err}"
        );
    }
}
