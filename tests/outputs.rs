//! Every output of every command goes through one writer (`adwi_output::
//! OutputPlan`): checked before any work, written complete beside its target and renamed
//! into place, all outputs of a command or none, never over an input, never over a FIFO,
//! a device or a directory.

use std::path::Path;
use std::process::{Command, Output};

use crate::common::{repo, tablec};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A folder with the KR150-2 samples, a table built from them and old files at every
/// output name the tests use.
fn workspace() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(repo("tables/kr150-2/samples.csv"), dir.path().join("s.csv")).unwrap();
    std::fs::copy(
        repo("tables/kr150-2/validation.csv"),
        dir.path().join("v.csv"),
    )
    .unwrap();
    std::fs::copy(repo("tables/kr150-2/robot.toml"), dir.path().join("r.toml")).unwrap();
    let o = tablec(
        &[
            "build",
            "-q",
            "s.csv",
            "--served-field",
            "method",
            "-o",
            "t.tbl",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["old.csv", "old.json", "old.toml", "old.urdf"] {
        std::fs::write(dir.path().join(name), format!("old {name}\n")).unwrap();
    }
    dir
}

/// Runs tablec with its file size limited to `bytes` (as `ulimit -f`): a write beyond it
/// kills the process (SIGXFSZ), as a full disk or a kill would end it mid-write.
#[cfg(unix)]
fn tablec_with_file_limit(args: &[&str], dir: &Path, bytes: u64) -> Output {
    use std::os::unix::process::CommandExt;
    let mut command = Command::new(env!("CARGO_BIN_EXE_tablec"));
    command.args(args).current_dir(dir);
    // SAFETY: setrlimit is async-signal-safe, and the closure touches nothing else.
    unsafe {
        command.pre_exec(move || {
            let limit = libc::rlimit {
                rlim_cur: bytes,
                rlim_max: bytes,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    command.output().unwrap()
}

/// No file in `dir` but `names` (no temporary left behind).
fn only(dir: &Path, names: &[&str]) {
    let mut found: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    found.sort();
    let mut expected: Vec<String> = names.iter().map(|s| s.to_string()).collect();
    expected.sort();
    assert_eq!(found, expected);
}

/// Killed mid-write, every writer leaves the file it was replacing as it was, and no
/// partial or temporary file: `simulate -o`, `eval --csv/--json`, `query -o` and
/// `calibrate -o` (`build` is tested in cli.rs).
#[cfg(unix)]
#[test]
fn a_write_cut_short_leaves_every_old_file_intact() {
    let dir = workspace();
    std::fs::copy(
        repo("tables/kr150-2/scenario.toml"),
        dir.path().join("sc.toml"),
    )
    .unwrap();
    let names = [
        "s.csv", "v.csv", "r.toml", "sc.toml", "t.tbl", "old.csv", "old.json", "old.toml",
        "old.urdf",
    ];
    let runs: [&[&str]; 5] = [
        &[
            "simulate",
            "--robot",
            "r.toml",
            "--scenario",
            "sc.toml",
            "--min",
            "1350,50,850",
            "--max",
            "2150,850,1650",
            "--step",
            "100",
            "-o",
            "old.csv",
        ],
        &[
            "eval",
            "--served-field",
            "method",
            "s.csv",
            "--validation",
            "v.csv",
            "-q",
            "--csv",
            "old.csv",
        ],
        &[
            "eval",
            "--served-field",
            "method",
            "s.csv",
            "--validation",
            "v.csv",
            "-q",
            "--json",
            "old.json",
        ],
        &["query", "t.tbl", "--targets", "v.csv", "-o", "old.csv"],
        &["calibrate", "s.csv", "--robot", "r.toml", "-o", "old.toml"],
    ];
    for args in runs {
        // 256 bytes: every one of these outputs is larger.
        let o = tablec_with_file_limit(args, dir.path(), 256);
        assert!(!o.status.success(), "{args:?} should have been cut short");
        for name in ["old.csv", "old.json", "old.toml", "old.urdf"] {
            assert_eq!(
                std::fs::read_to_string(dir.path().join(name)).unwrap(),
                format!("old {name}\n"),
                "{args:?} damaged {name}"
            );
        }
        only(dir.path(), &names);
    }
}

/// An evaluation whose report cannot be written writes none of its other outputs: every
/// output is checked before the work, and all are written or none.
#[test]
fn outputs_are_checked_before_the_work_and_written_all_or_none() {
    let dir = workspace();
    // A file stands where the report's folder would be created.
    std::fs::write(dir.path().join("blocker"), "x").unwrap();
    let started = std::time::Instant::now();
    let o = tablec(
        &[
            "eval",
            "--served-field",
            "method",
            "s.csv",
            "--validation",
            "v.csv",
            "-q",
            "--csv",
            "new.csv",
            "--json",
            "new.json",
            "--report",
            "blocker/report",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("blocker is not an existing directory"),
        "{}",
        stderr(&o)
    );
    assert!(started.elapsed().as_secs_f64() < 5.0);
    assert!(!dir.path().join("new.csv").exists());
    assert!(!dir.path().join("new.json").exists());
}

/// Two outputs of one command that are one file are refused: `calibrate -o X --urdf X`
/// would silently write one over the other.
#[test]
fn two_outputs_that_are_one_file_are_refused() {
    let dir = workspace();
    let o = tablec(
        &[
            "calibrate",
            "s.csv",
            "--robot",
            "r.toml",
            "-o",
            "old.toml",
            "--urdf",
            "old.toml",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("refusing to write old.toml and old.toml: they are the same file"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("old.toml")).unwrap(),
        "old old.toml\n"
    );
}

/// An existing output that is not a regular file — a FIFO, a device, a directory — is
/// refused with what it is, before any work; a symbolic link to a regular file is written
/// through (its target replaced, the link kept).
#[cfg(unix)]
#[test]
fn only_regular_files_are_replaced() {
    let dir = workspace();
    let fifo = dir.path().join("fifo");
    let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o644) }, 0);
    std::fs::create_dir(dir.path().join("folder")).unwrap();
    for (output, kind) in [
        ("fifo", "a FIFO"),
        ("/dev/null", "a character device"),
        ("folder", "a directory"),
    ] {
        for args in [
            vec!["build", "-q", "s.csv", "-o", output],
            vec!["calibrate", "s.csv", "--robot", "r.toml", "-o", output],
            vec![
                "eval",
                "--served-field",
                "method",
                "s.csv",
                "--folds",
                "2",
                "-q",
                "--csv",
                output,
            ],
        ] {
            let o = tablec(&args, dir.path());
            assert_eq!(o.status.code(), Some(1), "{args:?}");
            assert!(
                stderr(&o).contains(&format!("it exists and is {kind}, not a regular file")),
                "{args:?}: {}",
                stderr(&o)
            );
        }
    }
    let meta = std::fs::symlink_metadata(&fifo).unwrap();
    use std::os::unix::fs::FileTypeExt;
    assert!(meta.file_type().is_fifo(), "the FIFO is still a FIFO");

    std::os::unix::fs::symlink("old.csv", dir.path().join("link.csv")).unwrap();
    let o = tablec(
        &[
            "eval",
            "--served-field",
            "method",
            "s.csv",
            "--folds",
            "2",
            "-q",
            "--csv",
            "link.csv",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(dir.path().join("link.csv"))
        .unwrap()
        .file_type()
        .is_symlink());
    let written = std::fs::read_to_string(dir.path().join("old.csv")).unwrap();
    assert!(written.starts_with("method,predicted"), "{written}");
}

/// A robot file's `urdf =` key makes the URDF it names an input of every command that
/// loads the robot: `calibrate --urdf`, `simulate -o`, `build -o` and `eval --csv` each
/// refuse to write over it.
#[test]
fn the_urdf_a_robot_file_names_is_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("robot")).unwrap();
    std::fs::copy(repo("tables/iiwa14/robot.urdf"), d.join("robot/robot.urdf")).unwrap();
    std::fs::write(
        d.join("robot/robot.toml"),
        "name = \"x\"\nurdf = \"robot.urdf\"\n",
    )
    .unwrap();
    // Joint offsets a URDF chain can carry, one per joint.
    std::fs::write(
        d.join("sc.toml"),
        "[[joints]]\ndelta_offset_deg = 0.01\n".repeat(7),
    )
    .unwrap();
    let o = tablec(
        &[
            "simulate",
            "--robot",
            "robot/robot.toml",
            "--scenario",
            "sc.toml",
            "--min",
            "400,-200,300",
            "--max",
            "600,200,600",
            "--random",
            "60",
            "--abc",
            "0,180,0",
            "-o",
            "s.csv",
        ],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let urdf = std::fs::read(d.join("robot/robot.urdf")).unwrap();
    let runs: [&[&str]; 4] = [
        &[
            "calibrate",
            "s.csv",
            "--robot",
            "robot/robot.toml",
            "--urdf",
            "robot/robot.urdf",
        ],
        &[
            "simulate",
            "--robot",
            "robot/robot.toml",
            "--scenario",
            "sc.toml",
            "--min",
            "400,-200,300",
            "--max",
            "600,200,600",
            "--random",
            "10",
            "--abc",
            "0,180,0",
            "-o",
            "robot/robot.urdf",
        ],
        &[
            "build",
            "s.csv",
            "--robot",
            "robot/robot.toml",
            "-o",
            "robot/robot.urdf",
        ],
        &[
            "eval",
            "--served-field",
            "method",
            "s.csv",
            "--folds",
            "2",
            "--robot",
            "robot/robot.toml",
            "--csv",
            "robot/robot.urdf",
        ],
    ];
    for args in runs {
        let o = tablec(args, d);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        assert!(
            stderr(&o).contains("refusing to write robot/robot.urdf: it is the input"),
            "{args:?}: {}",
            stderr(&o)
        );
        assert_eq!(std::fs::read(d.join("robot/robot.urdf")).unwrap(), urdf);
    }
}
