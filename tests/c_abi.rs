//! The C ABI end to end: `tests/c/smoke.c` is compiled with the system C compiler against
//! `runtime/include/adwi.h` and the runtime's libraries, once statically and once
//! dynamically, each with exactly the link line docs/runtime.md and the header document, then
//! run on a table built from the paper's worked example. Its answers must equal the Rust
//! API's bit for bit, and every bad input must give its documented code.
//!
//! The libraries are those the build of this test made (the runtime's crate types include
//! `staticlib` and `cdylib`); it needs a C compiler (`cc`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use adwi_compile::build::{compile, BuildOptions};
use adwi_runtime::{Residual, Status, Table, Target};
use adwi_samples::{read_samples, ColumnMap};

const P1: [f64; 3] = [2000.0, 700.0, 1000.0];
const PREDICTED_MM: [f64; 3] = [0.044584991, 0.995639127, -0.230310237];

/// The system libraries a static link needs after `libadwi_runtime.a`, as docs/runtime.md and
/// `adwi.h` document them: what `rustc --print native-static-libs` lists on Linux.
const NATIVE_STATIC_LIBS: &str = "-lgcc_s -lutil -lrt -lpthread -lm -ldl -lc";

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The runtime's static and shared libraries, as the build of this test made them: the
/// runtime's crate types include `staticlib` and `cdylib`, so cargo writes
/// `libadwi_runtime.a` and `.so` beside its rlib, in the `deps` folder this test binary runs
/// from, in the same rustc run as the rlib the test links. Returns that folder and the
/// native libraries rustc lists for the static library.
fn libraries() -> (PathBuf, String) {
    let exe = std::env::current_exe().expect("the test binary's path");
    let dir = exe
        .parent()
        .expect("the test binary's folder")
        .to_path_buf();
    for lib in [
        "libadwi_runtime.a",
        "libadwi_runtime.so",
        "libadwi_runtime.rlib",
    ] {
        assert!(
            dir.join(lib).exists(),
            "{lib} was not built in {}",
            dir.display()
        );
    }
    (dir.clone(), native_static_libs(&dir))
}

/// What `rustc --print native-static-libs` lists for the runtime's static library, asked
/// of a static library holding the runtime's compiled rlib and nothing else: rustc bundles
/// it and its dependencies as they are (no compilation) and lists every native library
/// they link, the runtime's list.
fn native_static_libs(deps: &Path) -> String {
    let scratch = tempfile::tempdir().unwrap();
    let source = scratch.path().join("runtime_only.rs");
    std::fs::write(&source, "pub use adwi_runtime::*;\n").unwrap();
    let mut extern_runtime = std::ffi::OsString::from("adwi_runtime=");
    extern_runtime.push(deps.join("libadwi_runtime.rlib"));
    let mut dependencies = std::ffi::OsString::from("dependency=");
    dependencies.push(deps);
    // From the workspace, so that rustup picks the toolchain that built the rlib.
    let output = Command::new("rustc")
        .current_dir(workspace())
        .args(["--edition", "2021", "--crate-type", "staticlib"])
        .args([
            "--crate-name",
            "runtime_only",
            "--print",
            "native-static-libs",
        ])
        .arg("--extern")
        .arg(extern_runtime)
        .arg("-L")
        .arg(dependencies)
        .arg("--out-dir")
        .arg(scratch.path())
        .arg(&source)
        .output()
        .expect("cannot run rustc");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "rustc failed:\n{stderr}");
    stderr
        .lines()
        .find_map(|l| l.split("native-static-libs: ").nth(1))
        .unwrap_or_else(|| panic!("no native-static-libs note in:\n{stderr}"))
        .trim()
        .to_string()
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Linking {
    /// `cc app.c -I runtime/include DIR/libadwi_runtime.a NATIVE_STATIC_LIBS`
    Static,
    /// `cc app.c -I runtime/include -L DIR -ladwi_runtime -Wl,-rpath,DIR`
    Shared,
}

/// Compiles `tests/c/smoke.c` into `dir` against the libraries in `lib_dir` and returns
/// the executable.
fn compile_smoke(dir: &Path, lib_dir: &Path, linking: Linking) -> PathBuf {
    let exe = dir.join(format!("smoke-{linking:?}").to_lowercase());
    let cc = std::env::var_os("CC").unwrap_or_else(|| "cc".into());
    let mut command = Command::new(cc);
    command
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-O1"])
        .arg(workspace().join("tests/c/smoke.c"))
        .arg("-I")
        .arg(workspace().join("runtime/include"));
    match linking {
        Linking::Static => {
            command.arg(lib_dir.join("libadwi_runtime.a"));
            command.args(NATIVE_STATIC_LIBS.split_whitespace());
        }
        Linking::Shared => {
            let mut rpath = std::ffi::OsString::from("-Wl,-rpath,");
            rpath.push(lib_dir);
            command
                .arg("-L")
                .arg(lib_dir)
                .arg("-ladwi_runtime")
                .arg(rpath);
        }
    }
    let output = command
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("cannot run the C compiler (cc)");
    assert!(
        output.status.success(),
        "cc ({linking:?}) failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    exe
}

#[test]
fn the_documented_link_lines_are_the_ones_tested() {
    let (_, native) = libraries();
    assert_eq!(
        native, NATIVE_STATIC_LIBS,
        "rustc's list changed: update docs/runtime.md and adwi.h"
    );
    let readme = std::fs::read_to_string(workspace().join("docs/runtime.md")).unwrap();
    let header = std::fs::read_to_string(workspace().join("runtime/include/adwi.h")).unwrap();
    let static_line = format!("target/release/libadwi_runtime.a {NATIVE_STATIC_LIBS}");
    assert!(
        readme.contains(&static_line),
        "docs/runtime.md lacks {static_line:?}"
    );
    let header_static =
        format!("target/release/libadwi_runtime.a \\\n *           {NATIVE_STATIC_LIBS}");
    assert!(
        header.contains(&header_static),
        "adwi.h lacks {header_static:?}"
    );
    let shared = r#"-L "$PWD/target/release" -ladwi_runtime -Wl,-rpath,"$PWD/target/release""#;
    assert!(readme.contains(shared), "docs/runtime.md lacks {shared:?}");
    assert!(
        header.contains(r#"-L "$PWD/target/release" -ladwi_runtime \"#)
            && header.contains(r#"-Wl,-rpath,"$PWD/target/release""#),
        "adwi.h lacks the shared link line"
    );
}

fn worked_example_table() -> Vec<u8> {
    let csv = workspace().join("tables/paper/worked_example_p1.csv");
    let samples = read_samples(&csv, &ColumnMap::default()).unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

/// The line of `stdout` starting with `name `, split into words after the name.
fn line<'a>(stdout: &'a str, name: &str) -> Vec<&'a str> {
    let prefix = format!("{name} ");
    let l = stdout
        .lines()
        .find(|l| l.starts_with(&prefix))
        .unwrap_or_else(|| panic!("no line {name:?} in:\n{stdout}"));
    l[prefix.len()..].split_whitespace().collect()
}

#[test]
fn c_program_linked_statically_matches_the_rust_api_and_refuses_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let (lib_dir, _) = libraries();
    let exe = compile_smoke(dir.path(), &lib_dir, Linking::Static);
    // Nothing of the shared library is needed: it is not even named.
    let binary = std::fs::read(&exe).unwrap();
    assert!(!contains(&binary, b"libadwi_runtime.so"));
    run_smoke(&exe, dir.path());
}

#[test]
fn c_program_linked_dynamically_matches_the_rust_api_and_refuses_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let (lib_dir, _) = libraries();
    let exe = compile_smoke(dir.path(), &lib_dir, Linking::Shared);
    // The executable names the shared library (its dynamic section's NEEDED entry).
    let binary = std::fs::read(&exe).unwrap();
    assert!(contains(&binary, b"libadwi_runtime.so"));
    run_smoke(&exe, dir.path());
}

/// Targets of the UR5 hybrid table with their joint values (rad), each target the nominal
/// forward kinematics of its joints: the first pose of its samples whose residual is full
/// (inside the grid), the first whose residual is faded (the edge of the samples), and
/// the first turned half a revolution about the base (beyond the fade: the model alone).
fn hybrid_targets(table: &Table<adwi_runtime::AlignedBytes>) -> Vec<([f64; 3], [f64; 6])> {
    let csv = workspace().join("tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv");
    let nominal = table.model().unwrap().nominal();
    let at = |q: [f64; 6]| (nominal.tcp_pose(&q).unwrap().translation_mm, q);
    let residual = |(p, q): &([f64; 3], [f64; 6])| {
        let c = table.query_with_joints(&Target::at(*p), q);
        assert_eq!(c.status, Status::Ok, "{p:?}");
        c.residual
    };
    let poses: Vec<([f64; 3], [f64; 6])> = csv::Reader::from_path(csv)
        .unwrap()
        .records()
        .map(|r| {
            let r = r.unwrap();
            at([7, 8, 9, 10, 11, 12].map(|i| r[i].parse::<f64>().unwrap().to_radians()))
        })
        .collect();
    let first = |flag| *poses.iter().find(|t| residual(t) == flag).unwrap();
    let mut turned = poses[0].1;
    turned[0] += std::f64::consts::PI;
    let far = at(turned);
    assert_eq!(residual(&far), Residual::ModelOnly);
    vec![first(Residual::Full), first(Residual::Faded), far]
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

/// Runs the smoke program in `dir` and checks every line it prints.
fn run_smoke(exe: &Path, dir: &Path) {
    let bytes = worked_example_table();
    let table_path = dir.join("p1.tbl");
    std::fs::write(&table_path, &bytes).unwrap();
    let mut corrupt = bytes.clone();
    let last = corrupt.len() - 1;
    corrupt[last] ^= 0x40;
    let corrupt_path = dir.join("corrupt.tbl");
    std::fs::write(&corrupt_path, &corrupt).unwrap();

    let table = Table::from_vec(&bytes).unwrap();
    let grid_max = table.grid().max_mm();
    // The worked example's target, points around it, a sample itself, outside the grid,
    // a configuration, and a NaN.
    let targets: Vec<([f64; 3], i32)> = vec![
        (P1, -1),
        ([1980.0, 690.0, 1010.0], -1),
        ([2040.0, 740.0, 960.0], 3),
        ([1950.0, 750.0, 1050.0], -1),
        ([grid_max[0] + 1.0, 700.0, 1000.0], -1),
        ([f64::NAN, 700.0, 1000.0], -1),
    ];
    let hybrid_path = workspace().join("tables/compat/v2/ur5_hybrid.tbl");
    let hybrid = Table::from_vec(std::fs::read(&hybrid_path).unwrap()).unwrap();
    let hybrid_targets = hybrid_targets(&hybrid);
    let input = smoke_input(&targets, &hybrid_targets);
    let tables = [
        table_path,
        dir.join("missing.tbl"),
        corrupt_path,
        hybrid_path,
    ];
    let stdout = run_program(exe, &tables, &input);
    check_refusals(&stdout, &corrupt);
    check_hybrid_answers(&stdout, &hybrid, &hybrid_targets);
    assert!(stdout.lines().last() == Some("done"), "{stdout}");
    check_answers(&stdout, &table, &targets);
    check_worked_example(&stdout, &table);
}

/// The smoke program's standard input: a line per target (x y z config), then `hybrid`
/// and a line per hybrid target (x y z and its joint values).
fn smoke_input(targets: &[([f64; 3], i32)], hybrid_targets: &[([f64; 3], [f64; 6])]) -> String {
    let mut input: String = targets
        .iter()
        .map(|(p, c)| format!("{:?} {:?} {:?} {c}\n", p[0], p[1], p[2]))
        .collect::<String>()
        .replace("NaN", "nan");
    input.push_str("hybrid\n");
    for (p, q) in hybrid_targets {
        let words: Vec<String> = p.iter().chain(q).map(|v| format!("{v:?}")).collect();
        input.push_str(&words.join(" "));
        input.push('\n');
    }
    input
}

/// Runs `exe` on `tables` with `input`; its standard output, once it succeeded. Without
/// the library path cargo gives a test: it lists `target/debug` too, where an earlier
/// `cargo build` may have left an older `libadwi_runtime.so`, and would come before the
/// executable's own run path to the library this test's build made.
fn run_program(exe: &Path, tables: &[PathBuf], input: &str) -> String {
    let mut child = Command::new(exe)
        .env_remove("LD_LIBRARY_PATH")
        .args(tables)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let output = child.wait_with_output().unwrap();
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(
        output.status.success(),
        "smoke failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );

    stdout
}

/// Every refusal with its documented code: null pointers, a missing and a corrupt table
/// (the message the Rust API gives), bad arguments, bogus handles.
fn check_refusals(stdout: &str, corrupt: &[u8]) {
    // Refusals: ADWI_NULL_POINTER 1, ADWI_INVALID_ARGUMENT 2, ADWI_IO 3,
    // ADWI_INVALID_TABLE 4.
    assert_eq!(line(stdout, "open_null_path")[0], "1");
    assert_eq!(line(stdout, "open_null_out"), ["1"]);
    let missing = line(stdout, "open_missing");
    assert_eq!(missing[0], "3", "{stdout}");
    assert!(
        stdout.contains("cannot read the table | cannot read the table:"),
        "{stdout}"
    );
    for name in ["open_corrupt_bytes", "open_corrupt_file"] {
        let words = line(stdout, name);
        assert_eq!(words[0], "4", "{name}: {stdout}");
        // The message length reported equals the Rust error's.
        let expected = Table::from_vec(corrupt).err().unwrap().to_string();
        assert_eq!(words[1], expected.len().to_string(), "{name}: {stdout}");
        assert!(stdout.contains(&expected), "{stdout}");
    }
    assert_eq!(line(stdout, "open_null_bytes"), ["1"]);
    assert_eq!(line(stdout, "handle_untouched"), ["1"]);
    assert_eq!(line(stdout, "open")[..2], ["0", "0"]);
    assert_eq!(line(stdout, "open_bytes"), ["0"]);
    assert_eq!(line(stdout, "sample_count"), ["0", "8"]);
    assert_eq!(line(stdout, "query_null_table"), ["1"]);
    assert_eq!(line(stdout, "query_null_target"), ["1"]);
    assert_eq!(line(stdout, "query_null_out"), ["1"]);
    assert_eq!(line(stdout, "query_bad_config"), ["2"]);
    assert_eq!(line(stdout, "query_untouched"), ["1"]);
    assert_eq!(line(stdout, "query_joints_null_joints"), ["1"]);
    assert_eq!(line(stdout, "query_joints_too_many"), ["2"]);
    assert_eq!(line(stdout, "joint_count"), ["0", "0"]);
    assert_eq!(line(stdout, "compensate_null_out"), ["1"]);
    assert_eq!(line(stdout, "compensate_bad_tolerance"), ["2"]);
    // ADWI_INVALID_HANDLE 8, from every function, for each of the three bogus handles.
    let refusals: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("invalid_handle "))
        .collect();
    assert_eq!(refusals, ["invalid_handle 8 8 8 8 8"; 3], "{stdout}");
    assert_eq!(
        stdout
            .lines()
            .filter(|l| *l == "invalid_handle_untouched 1")
            .count(),
        3,
        "{stdout}"
    );
    assert_eq!(line(stdout, "invalid_handle_memory_untouched"), ["1"]);
    assert_eq!(line(stdout, "result_name_8"), ["invalid", "handle"]);
    assert_eq!(line(stdout, "close"), ["0", "0", "0"]);
    assert_eq!(line(stdout, "hybrid_close"), ["0"]);
}

/// The hybrid table's answers at its targets with joint values, and as poses with a TCP
/// the table cannot place: every value the Rust API's.
fn check_hybrid_answers(
    stdout: &str,
    hybrid: &Table<adwi_runtime::AlignedBytes>,
    hybrid_targets: &[([f64; 3], [f64; 6])],
) {
    let hybrids: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("hybrid "))
        .collect();
    assert_eq!(hybrids.len(), hybrid_targets.len(), "{stdout}");
    for ((p, q), line) in hybrid_targets.iter().zip(hybrids) {
        let c = hybrid.query_with_joints(&Target::at(*p), q);
        let words: Vec<&str> = line.split_whitespace().skip(1).collect();
        let want = [c.status as i32, c.neighbours as i32, c.residual as i32];
        assert_eq!(words[..3], want.map(|v| v.to_string()), "{p:?}");
        for axis in 0..3 {
            assert_eq!(
                words[3 + axis].parse::<f64>().unwrap(),
                c.position_error_mm[axis]
            );
        }
    }
    // The pose query: a TCP this version-2 table cannot place (it does not record its
    // point) is flagged, and every value is the Rust API's.
    let poses: Vec<&str> = stdout.lines().filter(|l| l.starts_with("pose ")).collect();
    assert_eq!(poses.len(), hybrid_targets.len(), "{stdout}");
    for ((p, q), line) in hybrid_targets.iter().zip(poses) {
        let target = Target::at(*p)
            .with_rotation([std::f64::consts::PI, 0.0, 0.0])
            .with_tcp([0.0, 0.0, 200.0]);
        let c = hybrid.query_with_joints(&target, q);
        assert_eq!(c.evidence, adwi_runtime::Evidence::TCP);
        let words: Vec<&str> = line.split_whitespace().skip(1).collect();
        let want = [c.status as i32, c.residual as i32, i32::from(c.evidence.0)];
        assert_eq!(words[..3], want.map(|v| v.to_string()), "{p:?}");
        let values = c.position_error_mm.iter().chain(&c.orientation_error_rad);
        for (word, v) in words[3..].iter().zip(values) {
            assert_eq!(word.parse::<f64>().unwrap(), *v);
        }
    }
}

/// The worked example table's answers and compensations, through both tiers: bit for bit
/// the Rust API's (17 significant digits round-trip a double).
fn check_answers(
    stdout: &str,
    table: &Table<adwi_runtime::AlignedBytes>,
    targets: &[([f64; 3], i32)],
) {
    let queries: Vec<&str> = stdout.lines().filter(|l| l.starts_with("query ")).collect();
    let compensations: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("compensate "))
        .collect();
    // A target that is not finite has no command: both compensations refuse it
    // (ADWI_INVALID_ARGUMENT, 2) and leave the output as it was.
    let finite: Vec<bool> = (targets.iter())
        .map(|(p, _)| p.iter().all(|v| v.is_finite()))
        .collect();
    let refused: Vec<&str> = (stdout.lines())
        .filter(|l| l.starts_with("compensate_refused "))
        .collect();
    assert_eq!(refused.len(), finite.iter().filter(|f| !**f).count());
    assert!(
        refused.iter().all(|l| *l == "compensate_refused 2 2 1"),
        "{stdout}"
    );
    let finite_count = finite.iter().filter(|f| **f).count();
    assert_eq!(queries.len(), targets.len(), "{stdout}");
    assert_eq!(compensations.len(), finite_count, "{stdout}");
    assert_eq!(
        stdout.lines().filter(|l| *l == "handles_agree 1").count(),
        targets.len(),
        "{stdout}"
    );
    assert_eq!(
        stdout
            .lines()
            .filter(|l| *l == "query_joints_agree 1 1")
            .count(),
        targets.len(),
        "{stdout}"
    );
    let exacts: Vec<&str> = stdout.lines().filter(|l| l.starts_with("exact ")).collect();
    let exact_compensations: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("compensate_exact "))
        .collect();
    assert_eq!(exacts.len(), targets.len(), "{stdout}");
    assert_eq!(exact_compensations.len(), finite_count, "{stdout}");
    let mut compensated = 0;
    for (i, (p, config)) in targets.iter().enumerate() {
        let target = Target {
            position_mm: *p,
            config: (*config >= 0).then_some(*config as u8),
            rotation_rad: None,
            tcp_mm: None,
        };
        let c = table.query_target(&target);
        let words: Vec<&str> = queries[i].split_whitespace().skip(1).collect();
        assert_eq!(words[0], (c.status as i32).to_string(), "target {p:?}");
        assert_eq!(words[1], c.neighbours.to_string(), "target {p:?}");
        assert_eq!(words[2], (c.residual as i32).to_string(), "target {p:?}");
        for axis in 0..3 {
            assert_eq!(
                c_number(words[3 + axis]),
                c.position_error_mm[axis],
                "{p:?}"
            );
            assert_eq!(
                c_number(words[6 + axis]),
                c.orientation_error_rad[axis],
                "{p:?}"
            );
        }
        let e = table.exact().query_target(&target);
        let words: Vec<&str> = exacts[i].split_whitespace().skip(1).collect();
        assert_eq!(words[0], (e.status as i32).to_string(), "target {p:?}");
        assert_eq!(words[1], e.neighbours.to_string(), "target {p:?}");
        for axis in 0..3 {
            assert_eq!(
                c_number(words[2 + axis]),
                e.position_error_mm[axis],
                "{p:?}"
            );
        }
        if !finite[i] {
            continue;
        }
        let j = compensated;
        compensated += 1;
        for (k, line) in [
            (table.compensate(&target, 1e-9, 50), compensations[j]),
            (
                table.exact().compensate(&target, 1e-9, 50),
                exact_compensations[j],
            ),
        ] {
            let words: Vec<&str> = line.split_whitespace().skip(1).collect();
            assert_eq!(words[0], (k.correction.status as i32).to_string());
            assert_eq!(words[1], k.iterations.to_string());
            assert_eq!(words[2], i32::from(k.converged).to_string());
            for axis in 0..3 {
                let got = c_number(words[3 + axis]);
                let want = k.command_position_mm[axis];
                assert!(got == want || (got.is_nan() && want.is_nan()), "{p:?}");
            }
            let residual = c_number(words[6]);
            assert!(residual == k.residual_mm || (residual.is_nan() && k.residual_mm.is_nan()));
        }
    }
}

/// The worked example's printed prediction, through C's exact tier.
fn check_worked_example(stdout: &str, table: &Table<adwi_runtime::AlignedBytes>) {
    let exacts: Vec<&str> = stdout.lines().filter(|l| l.starts_with("exact ")).collect();
    let p1: Vec<f64> = exacts[0]
        .split_whitespace()
        .skip(3)
        .take(3)
        .map(c_number)
        .collect();
    assert_eq!(exacts[0].split_whitespace().nth(1), Some("0"));
    for axis in 0..3 {
        assert!(
            (p1[axis] - PREDICTED_MM[axis]).abs() <= 1e-9,
            "axis {axis}: {} vs {}",
            p1[axis],
            PREDICTED_MM[axis]
        );
    }
    assert_eq!(
        table.query(P1).status,
        Status::Ok,
        "the Rust API answers P1 too"
    );
}

/// A number as the smoke program prints it (`nan` for a NaN).
fn c_number(w: &str) -> f64 {
    match w {
        "nan" | "-nan" => f64::NAN,
        _ => w.parse().unwrap(),
    }
}
