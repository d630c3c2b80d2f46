//! Hostile inputs to every command but `compensate`'s program reading, and to the C ABI:
//! special files given as inputs, report folders holding links, absurd numbers, work
//! without bound, a host short of memory. Each is refused at once with a message, and
//! nothing outside the named outputs is written.

use std::ffi::CString;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use adwi_runtime::capi::{
    adwi_last_open_error, adwi_table_close, adwi_table_compensate, adwi_table_compensate_exact,
    adwi_table_open, adwi_table_open_bytes, adwi_table_open_with, AdwiCompensation, AdwiResult,
    AdwiTable, ADWI_OPEN_PREFAULT,
};
use adwi_runtime::{OpenError, Table};

use crate::common::{lattice_csv, lattice_table};

/// How long a refusal may take: generous for a loaded machine, far below "forever".
const PROMPT: Duration = Duration::from_secs(20);

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `tablec` with `args` in `dir`, killed (and the test failed) if it has not ended
/// within [`PROMPT`]: a command waiting on a FIFO would otherwise hang the test run.
fn tablec_bounded(args: &[&str], dir: &Path) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tablec"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("tablec runs");
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > PROMPT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("tablec {args:?} did not end within {PROMPT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn mkfifo(path: &Path) {
    let c = CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "{path:?}");
}

/// A folder with the lattice samples (`samples.csv`), their table (`t.tbl`), held-out
/// points of the same field (`validation.csv`) and a FIFO (`fifo`).
fn workspace() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("samples.csv"), lattice_csv(1, 1.0)).unwrap();
    std::fs::write(dir.path().join("validation.csv"), lattice_csv(2, 1.0)).unwrap();
    std::fs::write(dir.path().join("t.tbl"), lattice_table(1, 1.0)).unwrap();
    mkfifo(&dir.path().join("fifo"));
    dir
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// `--report DIR` names a folder: a link already in it (to a file the user never named) is
/// replaced by the report, never written through.
#[test]
fn a_link_in_a_report_folder_is_replaced_never_written_through() {
    let dir = workspace();
    let victim = dir.path().join("README.md");
    std::fs::write(&victim, "an unrelated file\n").unwrap();
    std::fs::create_dir(dir.path().join("report")).unwrap();
    std::os::unix::fs::symlink(&victim, dir.path().join("report/index.html")).unwrap();
    let o = tablec_bounded(
        &[
            "eval",
            "--table",
            "t.tbl",
            "--validation",
            "validation.csv",
            "--report",
            "report",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(&victim).unwrap(),
        "an unrelated file\n"
    );
    let page = dir.path().join("report/index.html");
    assert!(std::fs::symlink_metadata(&page).unwrap().is_file());
    assert!(std::fs::read_to_string(&page).unwrap().contains("<html"));
}

/// Every reader refuses an input that is not a regular file at once, saying what it is: a
/// FIFO would block the command forever, a character device would be read without end.
#[test]
fn special_files_as_inputs_are_refused_at_once() {
    let dir = workspace();
    let poses = dir.path().join("poses.csv");
    std::fs::write(&poses, "j1,j2,j3,j4,j5,j6\n0,-90,90,0,90,0\n").unwrap();
    let ur5 = repo("tables/ur5/robot.toml");
    let ur5 = ur5.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["query", "fifo", "1600", "0", "900"], "a FIFO"),
        (vec!["build", "fifo", "-o", "o.tbl"], "a FIFO"),
        (
            vec!["build", "samples.csv", "/dev/zero", "-o", "o.tbl"],
            "a character device",
        ),
        (
            vec!["build", "samples.csv", "--robot", "fifo", "-o", "o.tbl"],
            "a FIFO",
        ),
        (
            vec![
                "compensate",
                "t.tbl",
                "fifo",
                "--format",
                "krl",
                "-o",
                "o.src",
            ],
            "a FIFO",
        ),
        (vec!["iso9283", "fifo"], "a FIFO"),
        (
            vec!["eval", "--table", "t.tbl", "--validation", "fifo"],
            "a FIFO",
        ),
        (
            vec![
                "simulate",
                "--robot",
                ur5,
                "--scenario",
                "fifo",
                "--poses",
                "poses.csv",
                "-o",
                "o.csv",
            ],
            "a FIFO",
        ),
    ];
    for (args, kind) in cases {
        let started = Instant::now();
        let o = tablec_bounded(&args, dir.path());
        let message = stderr(&o);
        assert!(!o.status.success(), "{args:?}");
        assert!(message.contains(kind), "{args:?}: {message}");
        assert!(started.elapsed() < Duration::from_secs(10), "{args:?}");
    }
    assert!(!dir.path().join("o.tbl").exists());
}

/// Runs `open` on a thread and waits at most [`PROMPT`] for it: an open blocked on a FIFO
/// fails the test instead of hanging it (the thread is left blocked).
fn bounded<T: Send + 'static>(open: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(open());
    });
    rx.recv_timeout(PROMPT)
        .expect("the open returned within the bound")
}

#[test]
fn a_fifo_table_is_refused_by_the_rust_and_the_c_open() {
    let dir = workspace();
    let fifo = dir.path().join("fifo");
    let path = fifo.clone();
    // SAFETY: the file is not a table anyone writes.
    let rust = bounded(move || unsafe { Table::open(&path) }.err().map(|e| e.to_string()));
    let rust = rust.expect("refused");
    assert!(rust.contains("a FIFO, not a regular file"), "{rust}");
    let c_path = CString::new(fifo.to_str().unwrap()).unwrap();
    let (code, message) = bounded(move || {
        let mut handle: *mut AdwiTable = std::ptr::null_mut();
        // SAFETY: a NUL-terminated path and a writable handle.
        let code = unsafe { adwi_table_open(c_path.as_ptr(), &mut handle) };
        (code, last_open_error())
    });
    assert_eq!(code, AdwiResult::Io);
    assert!(message.contains("a FIFO"), "{message}");
}

/// This thread's last open error message.
fn last_open_error() -> String {
    let mut buf = vec![0u8; 1024];
    // SAFETY: a writable buffer of its length.
    let n = unsafe { adwi_last_open_error(buf.as_mut_ptr().cast(), buf.len()) };
    buf.truncate(n.min(buf.len() - 1));
    String::from_utf8(buf).unwrap()
}

/// An open flag this runtime does not know is refused with a code, not ignored.
#[test]
fn unknown_open_flags_are_refused() {
    let dir = workspace();
    let path = CString::new(dir.path().join("t.tbl").to_str().unwrap()).unwrap();
    let mut handle: *mut AdwiTable = std::ptr::null_mut();
    for flags in [8, 1 << 31, ADWI_OPEN_PREFAULT | 16] {
        // SAFETY: a NUL-terminated path and a writable handle.
        let code = unsafe { adwi_table_open_with(path.as_ptr(), flags, &mut handle) };
        assert_eq!(code, AdwiResult::InvalidArgument, "{flags:#x}");
        assert!(handle.is_null());
        assert!(last_open_error().contains("unknown open flags"));
    }
    // SAFETY: as above.
    let code = unsafe { adwi_table_open_with(path.as_ptr(), ADWI_OPEN_PREFAULT, &mut handle) };
    assert_eq!(code, AdwiResult::Ok);
    // SAFETY: an open handle, closed once.
    assert_eq!(unsafe { adwi_table_close(handle) }, AdwiResult::Ok);
}

/// `max_iterations` 0 makes no query, so no command: refused, as the header says. A target
/// that is not a point has no command either: refused, never answered `ADWI_OK` with a NaN
/// command.
#[test]
fn c_compensation_refuses_zero_iterations_and_targets_that_are_not_finite() {
    let bytes = lattice_table(1, 1.0);
    let mut handle: *mut AdwiTable = std::ptr::null_mut();
    // SAFETY: valid bytes and a writable handle.
    let code = unsafe { adwi_table_open_bytes(bytes.as_ptr(), bytes.len(), &mut handle) };
    assert_eq!(code, AdwiResult::Ok);
    let inside = [1600.0, 0.0, 900.0];
    let untouched = AdwiCompensation {
        iterations: 77,
        ..AdwiCompensation::default()
    };
    for compensate in [adwi_table_compensate, adwi_table_compensate_exact] {
        let mut out = untouched;
        // SAFETY: an open handle and valid pointers.
        let code = unsafe { compensate(handle, inside.as_ptr(), -1, 1e-6, 0, &mut out) };
        assert_eq!(code, AdwiResult::InvalidArgument);
        assert_eq!(out, untouched);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let target = [1600.0, bad, 900.0];
            // SAFETY: as above.
            let code = unsafe { compensate(handle, target.as_ptr(), -1, 1e-6, 20, &mut out) };
            assert_eq!(code, AdwiResult::InvalidArgument, "{bad}");
            assert_eq!(out, untouched);
        }
        // SAFETY: as above.
        let code = unsafe { compensate(handle, inside.as_ptr(), -1, 1e-6, 1, &mut out) };
        assert_eq!(code, AdwiResult::Ok);
        assert_eq!(out.iterations, 1);
        assert!(out.command_position_mm.iter().all(|v| v.is_finite()));
    }
    // SAFETY: an open handle, closed once.
    assert_eq!(unsafe { adwi_table_close(handle) }, AdwiResult::Ok);
}

/// rkyv reports a bad pointer with its address; a message gives the byte of the file
/// instead (an address is meaningless to a reader and tells a host's log where this
/// process keeps its memory).
#[test]
fn open_errors_name_file_bytes_never_heap_addresses() {
    let good = lattice_table(1, 1.0);
    let mut archive_messages = Vec::new();
    // Large relative offsets written over the end of the payload, where the root object
    // and its pointers are.
    for at in (good.len() - 1024..good.len() - 4).step_by(4) {
        let mut bytes = good.clone();
        bytes[at..at + 4].copy_from_slice(&0x4000_0000u32.to_le_bytes());
        adwi_runtime::testing::reseal(&mut bytes);
        if let Err(e @ OpenError::Archive(_)) = Table::from_vec(&bytes) {
            archive_messages.push(e.to_string());
        }
    }
    assert!(
        archive_messages.iter().any(|m| m.contains("file byte")),
        "{archive_messages:#?}"
    );
    for m in &archive_messages {
        let hex = m
            .match_indices("0x")
            .any(|(i, _)| m[i + 2..].bytes().take_while(u8::is_ascii_hexdigit).count() >= 6);
        assert!(!hex, "{m}");
    }
}

/// The child scenarios below run in a process of their own (this test binary, started
/// again): one that sets a memory limit, one whose standard error is checked.
fn run_child(scenario: &str) -> Output {
    Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "hostile_inputs::child_scenario",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("ADWI_HOSTILE_CHILD", scenario)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// A table copy that does not fit in memory is an error code, never an abort of the host.
#[test]
fn open_bytes_short_of_memory_returns_a_code_and_does_not_abort() {
    let o = run_child("memory_limit");
    assert!(o.status.success(), "{:?}\n{}", o.status, stderr(&o));
}

/// A length no buffer can have is refused before anything could panic: nothing is
/// printed into the host's standard error.
#[test]
fn open_bytes_of_size_max_is_refused_in_silence() {
    let o = run_child("size_max");
    assert!(o.status.success(), "{:?}\n{}", o.status, stderr(&o));
    assert_eq!(stderr(&o).trim(), "");
}

/// The scenarios [`run_child`] starts; ignored in a normal run (it sets a process-wide
/// memory limit).
#[test]
#[ignore = "run in a child process by the tests above"]
fn child_scenario() {
    let scenario = std::env::var("ADWI_HOSTILE_CHILD").expect("started by run_child");
    let mut handle: *mut AdwiTable = std::ptr::null_mut();
    match scenario.as_str() {
        "memory_limit" => {
            const LEN: usize = 1 << 30;
            // SAFETY: a fresh private anonymous mapping; nothing else refers to it.
            let buffer = unsafe {
                libc::mmap(
                    std::ptr::null_mut(),
                    LEN,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
                    -1,
                    0,
                )
            };
            assert_ne!(buffer, libc::MAP_FAILED);
            // The address space in use now, and 256 MiB more: not room for a 1 GiB copy.
            let status = std::fs::read_to_string("/proc/self/status").unwrap();
            let vm_kb: u64 = status
                .lines()
                .find_map(|l| l.strip_prefix("VmSize:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
                .unwrap();
            let limit = vm_kb * 1024 + (256 << 20);
            let rlimit = libc::rlimit {
                rlim_cur: limit,
                rlim_max: limit,
            };
            // SAFETY: a valid rlimit for this process.
            assert_eq!(unsafe { libc::setrlimit(libc::RLIMIT_AS, &rlimit) }, 0);
            // SAFETY: the mapping is readable for LEN bytes; the handle is writable.
            let code = unsafe { adwi_table_open_bytes(buffer.cast(), LEN, &mut handle) };
            assert_eq!(code, AdwiResult::OutOfMemory);
            assert!(handle.is_null());
            assert!(last_open_error().contains("cannot allocate"));
        }
        "size_max" => {
            let bytes = [0u8; 64];
            // SAFETY: the length is refused before the pointer is read.
            let code = unsafe { adwi_table_open_bytes(bytes.as_ptr(), usize::MAX, &mut handle) };
            assert_eq!(code, AdwiResult::InvalidArgument);
            assert!(handle.is_null());
        }
        other => panic!("unknown scenario {other}"),
    }
}

/// A box of ±1e200 mm has an infinite volume to draw from: refused with the figure, as a
/// usage error, not a panic.
#[test]
fn plan_refuses_a_box_beyond_any_workspace() {
    let dir = workspace();
    let ur5 = repo("tables/ur5/robot.toml");
    let o = tablec_bounded(
        &[
            "plan",
            "--robot",
            ur5.to_str().unwrap(),
            "--min",
            "-1e200,-1e200,-1e200",
            "--max",
            "1e200,1e200,1e200",
            "--count",
            "10",
            "-o",
            "plan.csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("1e6 mm"), "{}", stderr(&o));
    assert!(!dir.path().join("plan.csv").exists());
}

/// Work without a bound is refused before any work, with its size: a billion lines (58
/// days) and a step of a nanometre (2e11 targets a line).
#[test]
fn continuity_refuses_unbounded_work_at_once() {
    let dir = workspace();
    for args in [["--lines", "1000000000"], ["--step-mm", "1e-9"]] {
        let mut all = vec!["continuity", "t.tbl"];
        all.extend(args);
        let started = Instant::now();
        let o = tablec_bounded(&all, dir.path());
        // A usage error, as every refused option is.
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(started.elapsed() < Duration::from_secs(5), "{args:?}");
        assert!(stderr(&o).contains("queries, more than"), "{}", stderr(&o));
    }
    let o = tablec_bounded(&["continuity", "t.tbl", "--lines", "2"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
}

/// An angle beyond three turns or a position beyond a kilometre is a typing error: refused
/// as a usage error, never answered `ok`.
#[test]
fn query_refuses_absurd_angles_positions_and_joints() {
    let dir = workspace();
    for pose in [
        ["1600", "0", "900", "1e308", "90", "0"],
        ["1600", "0", "900", "0", "-1081", "0"],
        ["1e7", "0", "900", "0", "90", "0"],
    ] {
        let mut args = vec!["query", "t.tbl"];
        args.extend(pose);
        let o = tablec_bounded(&args, dir.path());
        assert_eq!(o.status.code(), Some(2), "{pose:?}: {}", stderr(&o));
    }
    let o = tablec_bounded(
        &["query", "t.tbl", "1600", "0", "900", "0", "90", "0"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let hybrid = repo("tables/compat/v1/ur5_hybrid.tbl");
    let o = tablec_bounded(
        &[
            "query",
            hybrid.to_str().unwrap(),
            "-495.48",
            "-261.22",
            "359.40",
            "--joints",
            "1e308,-81.9889,88.4100,0.0713,93.4555,-0.1215",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("J1"), "{}", stderr(&o));
}

#[test]
fn compensate_refuses_a_tool_beyond_any_robot() {
    let dir = workspace();
    std::fs::write(dir.path().join("p.csv"), "x,y,z\n1600,0,900\n").unwrap();
    for tool in ["0,0,1e308,0,0,0", "0,0,100,0,1e308,0"] {
        let o = tablec_bounded(
            &[
                "compensate",
                "t.tbl",
                "p.csv",
                "--tool",
                tool,
                "-o",
                "o.csv",
            ],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(2), "{tool}: {}", stderr(&o));
        assert!(!dir.path().join("o.csv").exists());
    }
}

/// A cube centred 1.7e308 mm away has infinite corners: refused, no plan written.
#[test]
fn iso9283_refuses_a_cube_beyond_any_workspace() {
    let dir = workspace();
    for cube in ["1.7e308,0,0,100", "0,0,0,1e300"] {
        let o = tablec_bounded(&["iso9283", "--cube", cube, "-o", "plan.csv"], dir.path());
        assert!(!o.status.success(), "{cube}");
        assert!(stderr(&o).contains("1e6 mm"), "{}", stderr(&o));
        assert!(!dir.path().join("plan.csv").exists());
    }
    let o = tablec_bounded(
        &[
            "iso9283",
            "--cube",
            "1600,0,900,200",
            "--abc",
            "0,1e300,0",
            "-o",
            "plan.csv",
        ],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(!dir.path().join("plan.csv").exists());
}

/// A cycle number too large for the file's integers is out of range, not "not a whole
/// number".
#[test]
fn iso9283_says_a_huge_cycle_number_is_out_of_range() {
    let dir = workspace();
    std::fs::write(
        dir.path().join("cycles.csv"),
        "position,cycle,x,y,z,mx,my,mz\nP1,5000000000,1,2,3,1,2,3\n",
    )
    .unwrap();
    let o = tablec_bounded(&["iso9283", "cycles.csv"], dir.path());
    assert!(!o.status.success());
    let message = stderr(&o);
    assert!(message.contains("out of range"), "{message}");
    assert!(!message.contains("not a whole number"), "{message}");
}

/// A table evaluated where it predicts nothing is no evaluation: a failure with the
/// reasons counted, and no report.
#[test]
fn eval_of_a_table_that_predicts_no_point_fails_with_the_reasons() {
    let dir = workspace();
    let far: String = std::iter::once("x,y,z,dx,dy,dz\n".to_string())
        .chain((0..20).map(|i| format!("{},0,0,0.1,0.1,0.1\n", 9000 + i)))
        .collect();
    std::fs::write(dir.path().join("far.csv"), far).unwrap();
    let o = tablec_bounded(
        &[
            "eval",
            "--table",
            "t.tbl",
            "--validation",
            "far.csv",
            "--json",
            "e.json",
        ],
        dir.path(),
    );
    assert!(!o.status.success());
    let message = stderr(&o);
    assert!(message.contains("none of the 20 points"), "{message}");
    assert!(message.contains("20 outside_grid"), "{message}");
    assert!(!dir.path().join("e.json").exists());
}

/// A validation file of a 7-joint robot against a 6-joint table is one message up front,
/// not an `invalid_input` per point.
#[test]
fn eval_refuses_a_validation_file_with_another_joint_count_at_once() {
    let dir = workspace();
    let hybrid = repo("tables/compat/v1/ur5_hybrid.tbl");
    std::fs::write(
        dir.path().join("seven.csv"),
        "x,y,z,dx,dy,dz,j1,j2,j3,j4,j5,j6,j7\n-495.48,-261.22,359.40,0.1,0.1,0.1,17.27,-81.99,88.41,0.07,93.46,-0.12,0\n",
    )
    .unwrap();
    let o = tablec_bounded(
        &[
            "eval",
            "--table",
            hybrid.to_str().unwrap(),
            "--validation",
            "seven.csv",
        ],
        dir.path(),
    );
    assert!(!o.status.success());
    let message = stderr(&o);
    assert!(message.contains("6 joints"), "{message}");
    assert!(message.contains("7 joint values"), "{message}");
}

/// `simulate --poses` measures joint vectors: a file of `j1..jn` alone is enough.
#[test]
fn simulate_poses_need_joint_values_only() {
    let dir = workspace();
    std::fs::write(
        dir.path().join("poses.csv"),
        "j1,j2,j3,j4,j5,j6\n0,-90,90,0,90,0\n10,-80,80,5,85,3\n",
    )
    .unwrap();
    let o = tablec_bounded(
        &[
            "simulate",
            "--robot",
            repo("tables/ur5/robot.toml").to_str().unwrap(),
            "--scenario",
            repo("tables/ur5/scenario.toml").to_str().unwrap(),
            "--poses",
            "poses.csv",
            "-o",
            "measured.csv",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let written = std::fs::read_to_string(dir.path().join("measured.csv")).unwrap();
    let rows = written.lines().filter(|l| !l.starts_with('#')).count();
    assert_eq!(rows, 3, "{written}");
}

/// Messages quote what they read: a file's control bytes (an escape sequence, a bell) are
/// shown escaped, never sent to the terminal, by every command.
#[test]
fn control_bytes_quoted_from_a_file_are_escaped_in_every_message() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("samples.csv"),
        b"x,y,z,dx,dy,dz\n1,2,3,0.1,0.2,\x1b[31mBAD\x07\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("cycles.csv"),
        b"position,cycle,x,y,z,mx,my,mz\nP1,1,1000,0,1000,\x1b[31mX,0,0\n",
    )
    .unwrap();
    for args in [
        &["build", "samples.csv", "-o", "t.tbl"][..],
        &["iso9283", "cycles.csv"][..],
    ] {
        let o = tablec_bounded(args, dir.path());
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        let err = stderr(&o);
        assert!(
            !err.contains('\x1b') && !err.contains('\x07'),
            "{args:?}: {err:?}"
        );
        assert!(err.contains("\\u{1b}[31m"), "{args:?}: {err}");
    }
}
