//! Stäubli VAL3 applications compensated offline (`tablec compensate`, format `val3`): an
//! application as Stäubli Robotics Suite saves it (`tests/programs/staubli/weld/`: a torch,
//! a fixture frame and a jig chained to it, a joint home, `movec`, `appro`, a point the
//! code assigns, one in a frame the data lacks, points no motion moves to) and one an
//! offline tool generates (`tests/programs/staubli/raster/`: 300 points), with the KR150-2
//! table and a table that corrects nothing. Every written command is read back through its
//! frames and checked by the table's own model.

use std::path::{Path, PathBuf};

use adwi_programs::frames::FrameChain;
use adwi_programs::program::{Program, TargetKind};
use adwi_programs::source::Source;
use adwi_programs::staubli::Application;
use adwi_programs::{CompensateJob, CompensateOptions};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::common::{compensate, method_table, repo};

fn application(name: &str) -> PathBuf {
    repo(&format!("tests/programs/staubli/{name}/{name}.pjx"))
}

/// The application's data read with its programs, from `bytes` in place of its `.dtx`.
fn read(pjx: &Path, bytes: &[u8]) -> Program {
    let app = Application::locate(pjx).unwrap();
    let files = app.read_programs().unwrap();
    let programs: Vec<Source> = files.iter().map(|(n, b)| Source::new(n, b)).collect();
    adwi_programs::staubli::read(&Source::new("app.dtx", bytes), &programs).unwrap()
}

#[test]
fn a_table_that_corrects_nothing_reproduces_val3_data_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    for i in 0..=12 {
        for j in 0..=10 {
            for k in 0..=10 {
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
    for (name, corrected) in [("weld", 9), ("raster", 300)] {
        let out = dir.path().join(format!("out-{name}.dtx"));
        let (code, stdout, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                application(name).to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--robot",
                repo("tables/kr150-2/robot.toml").to_str().unwrap(),
            ],
        );
        assert!(code == 0 || code == 3, "{name}: {stderr}");
        assert_eq!(
            crate::common::corrected_lines(&stdout),
            corrected,
            "{name}: {stdout}"
        );
        let data = repo(&format!("tests/programs/staubli/{name}/{name}.dtx"));
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(&data).unwrap(),
            "{name}: {stdout}"
        );
    }
}

/// What the table's own model makes of an application's corrected points, read back from
/// the written data through each point's frames.
struct Landings {
    checked: usize,
    /// The least distance of the torch from its target, uncompensated.
    uncompensated: f64,
    /// The largest distance of the torch from its target, as written.
    tcp: f64,
    /// The largest |C + e(C) − P| at the table's point, for the command as written.
    written: f64,
    largest: f64,
}

impl std::fmt::Display for Landings {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "{} points: at the torch by the table's model {:.3} mm or more uncompensated, at most {:.2e} mm compensated; |C + e(C) - P| at most {:.2e} mm as written; largest correction {:.4} mm",
            self.checked, self.uncompensated, self.tcp, self.written, self.largest
        )
    }
}

/// The pose a Cartesian target writes.
fn written_pose(target: &adwi_programs::program::ProgramTarget) -> Isometry3<f64> {
    let TargetKind::Cartesian(c) = &target.kind else {
        panic!("{} is not Cartesian", target.name)
    };
    let r = adwi_programs::frames::rotation_of(c.orientation.as_ref().unwrap()).unwrap();
    Isometry3::from_parts(
        Vector3::from(c.position.map(|n| n.value)).into(),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// Where the table's model lands the table's point for the written pose `written`: the
/// distance of the TCP from `target` and |C + e(C) − P| for the table's point `point`.
fn landing(
    table: &adwi_runtime::Table<adwi_runtime::AlignedBytes>,
    chain: &FrameChain,
    written: &Isometry3<f64>,
    target: &Isometry3<f64>,
    point: [f64; 3],
) -> (f64, f64) {
    let c = chain.table_point(written);
    let answer = table.query(c.translation.vector.into());
    assert_eq!(answer.status, adwi_runtime::Status::Ok, "{c:?}");
    let error = Vector3::from(answer.position_error_mm);
    let turn = UnitQuaternion::from_scaled_axis(Vector3::from(answer.orientation_error_rad));
    let landed_point =
        Isometry3::from_parts((c.translation.vector + error).into(), turn * c.rotation);
    let tcp = chain.base.inverse() * landed_point * chain.table_tool.inverse() * chain.tool;
    (
        (tcp.translation.vector - target.translation.vector).norm(),
        (c.translation.vector + error - Vector3::from(point)).norm(),
    )
}

fn landings(
    table: &adwi_runtime::Table<adwi_runtime::AlignedBytes>,
    pjx: &Path,
    data: &Path,
    done: &adwi_programs::Compensated,
) -> Landings {
    let before = read(pjx, &std::fs::read(data).unwrap());
    let after = read(pjx, &done.output);
    assert_eq!(before.targets.len(), after.targets.len());
    let mut l = Landings {
        checked: 0,
        uncompensated: f64::INFINITY,
        tcp: 0.0,
        written: 0.0,
        largest: 0.0,
    };
    for ((b, a), line) in before
        .targets
        .iter()
        .zip(&after.targets)
        .zip(&done.report.targets)
    {
        assert_eq!(b.name, line.name);
        assert_eq!(a.name, line.name);
        if line.status.as_str() != "ok" || !matches!(b.kind, TargetKind::Cartesian(_)) {
            continue;
        }
        let u = &b.uses[0];
        let chain = FrameChain {
            base: u.base.unwrap(),
            tool: u.tool.unwrap(),
            // The KR150-2 robot file's tool is its flange: the table's point.
            table_tool: Isometry3::identity(),
        };
        let target = written_pose(b);
        let point = line.point_mm.unwrap();
        let (tcp, gap) = landing(table, &chain, &written_pose(a), &target, point);
        let (uncompensated, _) = landing(table, &chain, &target, &target, point);
        l.tcp = l.tcp.max(tcp);
        l.written = l.written.max(gap);
        l.uncompensated = l.uncompensated.min(uncompensated);
        l.largest = l.largest.max(line.correction_mm.unwrap());
        l.checked += 1;
    }
    l
}

fn kr150(dir: &Path) -> (PathBuf, adwi_runtime::Table<adwi_runtime::AlignedBytes>) {
    let path = method_table(dir, &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let table = adwi_runtime::Table::from_vec(std::fs::read(&path).unwrap()).unwrap();
    (path, table)
}

fn options(table: &Path, program: &Path) -> CompensateOptions {
    let mut o = CompensateOptions::new(table, program);
    o.robot = Some(repo("tables/kr150-2/robot.toml"));
    o
}

#[test]
fn kr150_val3_points_land_at_the_torch_in_their_frames_and_the_rest_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let (table_path, table) = kr150(dir.path());
    let pjx = application("weld");
    let data = repo("tests/programs/staubli/weld/weld.dtx");
    let job = CompensateJob::new(options(&table_path, &pjx)).unwrap();
    let done = job.run().unwrap();
    weld_statuses_say_why(&done);
    weld_commands_land(&table, &pjx, &data, &done);
    weld_changes_only_its_corrected_values(&data, &done);
    // Round trip: the written data compensated again by a table that corrects nothing,
    // read back, holds the same targets with the same statuses' kinds.
    let again = read(&pjx, &done.output);
    assert_eq!(
        again
            .targets
            .iter()
            .map(|t| t.name.clone())
            .collect::<Vec<_>>(),
        done.report
            .targets
            .iter()
            .map(|t| t.name.clone())
            .collect::<Vec<_>>()
    );
}

/// The weld application's statuses, and why each point not corrected is left.
fn weld_statuses_say_why(done: &adwi_programs::Compensated) {
    let statuses: Vec<String> = done
        .report
        .targets
        .iter()
        .map(|t| format!("{} {}", t.name, t.status.as_str()))
        .collect();
    assert_eq!(
        statuses,
        [
            "jHome[0] ok",
            "pApproach[0] ok",
            "pEnd[0] ok",
            "pFound[0] dynamic",
            "pJig[0] ok",
            "pJig[1] ok",
            "pLost[0] frame_unknown",
            "pOff[0] relative",
            "pRef[0] not_moved",
            "pSeam[0] ok",
            "pSeam[1] ok",
            "pSeam[2] ok",
            "pSpare[0] not_moved",
            "pVia[0] ok",
            "movel relative",
            "movel relative",
        ]
    );
    let detail = |name: &str| {
        done.report
            .targets
            .iter()
            .find(|t| t.name == name)
            .unwrap()
            .detail
            .clone()
    };
    let seam = repo("tests/programs/staubli/weld/seam.pgx")
        .display()
        .to_string();
    assert_eq!(
        detail("pLost[0]"),
        format!(
            "work object fTable2[0] not given (used at {seam}:22:3): give it as the base option"
        )
    );
    assert_eq!(
        detail("pFound[0]"),
        format!("assigned as the program runs ({seam}:23:3)")
    );
    assert_eq!(
        detail("pOff[0]"),
        format!("moved to only as movel(appro(pOff, trLift), tTorch, mFast) ({seam}:17:3): appro(…): an offset computed as the program runs")
    );
    assert_eq!(
        detail("pRef[0]"),
        format!("no motion moves to it; the code uses it otherwise (first at {seam}:25:20)")
    );
    assert_eq!(
        detail("pSpare[0]"),
        "no motion moves to it, and no program names it"
    );
}

/// Read back: every corrected point's written numbers, in its frame chain and with the
/// torch, put the table's point on its target by the table's own model; the home's joints
/// likewise through the robot's forward kinematics.
fn weld_commands_land(
    table: &adwi_runtime::Table<adwi_runtime::AlignedBytes>,
    pjx: &Path,
    data: &Path,
    done: &adwi_programs::Compensated,
) {
    let l = landings(table, pjx, data, done);
    assert_eq!(l.checked, 8);
    eprintln!("weld: {}; {l}", done.report.summary());
    assert!(l.written <= 1e-4, "{l}");
    assert!(l.tcp <= 2e-4, "{l}");
    assert!(l.uncompensated > 1.0, "{l}");
    let kr150 = adwi_robot::Robot::load(repo("tables/kr150-2/robot.toml")).unwrap();
    let after = read(pjx, &done.output);
    let TargetKind::Joints(j) = &after.targets[0].kind else {
        panic!("{}", after.targets[0].name)
    };
    let q: Vec<f64> = j.joints.iter().map(|n| n.value.to_radians()).collect();
    let c = kr150.tcp_pose(&q).translation.vector;
    let home = &done.report.targets[0];
    let answer = table.query(c.into());
    let gap = (c + Vector3::from(answer.position_error_mm) - Vector3::from(home.point_mm.unwrap()))
        .norm();
    eprintln!("weld: jHome[0] as written: |C + e(C) - P| {gap:.2e} mm");
    assert!(gap <= 1e-4, "{gap}");
}

/// Only the corrected values' lines changed; the byte-order mark and CRLF are kept, and an
/// attribute the file omitted is inserted where the correction gives it a value.
fn weld_changes_only_its_corrected_values(data: &Path, done: &adwi_programs::Compensated) {
    let original = std::fs::read(data).unwrap();
    let written = &done.output;
    assert!(written.starts_with(b"\xef\xbb\xbf"));
    let original = String::from_utf8(original).unwrap();
    let written = String::from_utf8(written.clone()).unwrap();
    assert_eq!(
        written.matches("\r\n").count(),
        original.matches("\r\n").count()
    );
    let changed: Vec<(&str, &str)> = original
        .lines()
        .zip(written.lines())
        .filter(|(o, w)| o != w)
        .collect();
    assert_eq!(changed.len(), 9);
    let attributes = |line: &str| -> Vec<String> {
        line.split_whitespace()
            .filter_map(|w| w.split_once('=').map(|(k, _)| k.to_string()))
            .collect()
    };
    for (o, w) in &changed {
        assert!(o.trim_start().starts_with("<Value key="), "{o}");
        // The same attributes but the inserted ones, and every non-numeric one unchanged.
        let (a, b) = (attributes(o), attributes(w));
        assert!(a.iter().all(|k| b.contains(k)), "{o} -> {w}");
        for tail in ["shoulder=", "fatherId="] {
            assert_eq!(o.split(tail).nth(1), w.split(tail).nth(1), "{o} -> {w}");
        }
    }
    let approach = changed
        .iter()
        .find(|(o, _)| o.contains("fatherId=\"world[0]\""))
        .unwrap();
    assert_eq!(
        attributes(approach.0),
        ["key", "x", "y", "z", "ry", "shoulder", "elbow", "wrist", "fatherId"]
    );
    assert_eq!(
        attributes(approach.1),
        ["key", "x", "y", "z", "rx", "ry", "rz", "shoulder", "elbow", "wrist", "fatherId"]
    );
    // The home's omitted nothing; the torch, the frames and the code are untouched.
    for unchanged in [
        "tTorch", "fPart", "fJig", "pOff", "pRef", "pSpare", "pLost", "pFound",
    ] {
        let line = |s: &str| {
            s.lines()
                .skip_while(|l| !l.contains(&format!("name=\"{unchanged}\"")))
                .nth(1)
                .unwrap()
                .to_string()
        };
        assert_eq!(line(&original), line(&written), "{unchanged}");
    }
}

#[test]
fn a_generated_raster_of_300_points_lands_within_the_written_precision() {
    let dir = tempfile::tempdir().unwrap();
    let (table_path, table) = kr150(dir.path());
    let pjx = application("raster");
    let data = repo("tests/programs/staubli/raster/raster.dtx");
    let job = CompensateJob::new(options(&table_path, &pjx)).unwrap();
    let done = job.run().unwrap();
    assert_eq!(
        done.report.summary().corrected,
        300,
        "{}",
        done.report.summary()
    );
    let l = landings(&table, &pjx, &data, &done);
    eprintln!("raster: {}; {l}", done.report.summary());
    assert_eq!(l.checked, 300);
    assert!(l.written <= 1e-4, "{l}");
    assert!(l.uncompensated > 1.0, "{l}");
    // Its numbers keep the generator's three decimals where they hold the command, more
    // where they do not; every attribute was written, so none is inserted.
    let original = String::from_utf8(std::fs::read(&data).unwrap()).unwrap();
    let written = String::from_utf8(done.output.clone()).unwrap();
    assert_eq!(original.lines().count(), written.lines().count());
    assert!(!written.contains('\r'));
    assert_eq!(
        written.matches("=\"").count(),
        original.matches("=\"").count()
    );
}

#[test]
fn the_application_is_found_by_its_project_folder_or_data_and_never_written_over() {
    let dir = tempfile::tempdir().unwrap();
    let (table, _) = kr150(dir.path());
    let weld = repo("tests/programs/staubli/weld");
    let robot = repo("tables/kr150-2/robot.toml");
    let mut outputs = Vec::new();
    for (program, format) in [
        (weld.join("weld.pjx"), None),
        (weld.clone(), Some("val3")),
        (weld.join("weld.dtx"), None),
    ] {
        let out = dir.path().join(format!("out{}.dtx", outputs.len()));
        let mut args = vec![
            table.to_str().unwrap(),
            program.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--robot",
            robot.to_str().unwrap(),
            "-q",
        ];
        args.extend(format.map(|f| ["--format", f]).into_iter().flatten());
        let (code, stdout, stderr) = compensate(dir.path(), &args);
        assert_eq!(code, 3, "{program:?}: {stderr}");
        assert!(stdout.contains("9 of 16 targets corrected"), "{stdout}");
        outputs.push(std::fs::read(&out).unwrap());
    }
    assert!(outputs.windows(2).all(|w| w[0] == w[1]));
    // The data, the project and each program are inputs: never an output.
    for input in ["weld.dtx", "weld.pjx", "seam.pgx"] {
        let (code, _, stderr) = compensate(
            dir.path(),
            &[
                table.to_str().unwrap(),
                weld.join("weld.pjx").to_str().unwrap(),
                "-o",
                weld.join(input).to_str().unwrap(),
            ],
        );
        assert_eq!(code, 1, "{input}: {stderr}");
        assert!(stderr.contains(input), "{stderr}");
    }
    // A folder with no project is refused by name.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let (code, _, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            empty.to_str().unwrap(),
            "-o",
            "x.dtx",
            "--format",
            "val3",
        ],
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("holds one .pjx project, this one 0"),
        "{stderr}"
    );
}

#[test]
fn options_are_checked_before_the_application_is_read() {
    let dir = tempfile::tempdir().unwrap();
    // A usage error: exit 2, whatever the files (none of them exists).
    for bad in [
        &["--format", "val4"][..],
        &["--format", "val3", "--max-correction-mm", "x"][..],
        &["--format", "val3", "--tool", "1,2,3"][..],
    ] {
        let mut args = vec!["missing.tbl", "missing/app.pjx", "-o", "out.dtx"];
        args.extend_from_slice(bad);
        let (code, _, stderr) = compensate(dir.path(), &args);
        assert_eq!(code, 2, "{bad:?}: {stderr}");
        assert!(!stderr.contains("missing"), "{stderr}");
    }
    // The job: a bad bound before the application is looked for.
    let mut o = CompensateOptions::new("missing.tbl", "missing/app.pjx");
    o.limits.max_correction_mm = -1.0;
    let err = CompensateJob::new(o).err().unwrap();
    assert!(matches!(err, adwi_programs::Error::Option(_)), "{err}");
}

#[test]
fn hostile_val3_files_give_located_errors_never_a_panic() {
    let dtx = std::fs::read(repo("tests/programs/staubli/weld/weld.dtx")).unwrap();
    let pgx = std::fs::read(repo("tests/programs/staubli/weld/seam.pgx")).unwrap();
    // Truncated anywhere: a program read, or an error inside the file it names.
    for cut in (0..dtx.len()).step_by(7) {
        let src = Source::new("t.dtx", &dtx[..cut]);
        let program = Source::new("t.pgx", &pgx);
        match adwi_programs::staubli::read(&src, std::slice::from_ref(&program)) {
            Ok(_) => {}
            Err(adwi_programs::Error::Syntax { file, line, .. }) => {
                assert_eq!(file, "t.dtx");
                assert!(line <= src.location(cut).0 + 1, "{cut}");
            }
            Err(e) => panic!("{cut}: {e}"),
        }
    }
    for cut in (0..pgx.len()).step_by(5) {
        let src = Source::new("t.dtx", &dtx);
        let program = Source::new("t.pgx", &pgx[..cut]);
        match adwi_programs::staubli::read(&src, std::slice::from_ref(&program)) {
            Ok(_) => {}
            Err(adwi_programs::Error::Syntax { file, .. }) => assert_eq!(file, "t.pgx"),
            Err(e) => panic!("{cut}: {e}"),
        }
    }
    // Huge sizes and deep nesting: the size is not trusted, the nesting bounded.
    let huge = b"<Database><Datas><Data name=\"p\" type=\"pointRx\" size=\"99999999999999999999\"><Value key=\"0\" x=\"1e308\" /></Data></Datas></Database>";
    let p = adwi_programs::staubli::read(&Source::new("h.dtx", huge), &[]).unwrap();
    assert_eq!(p.targets.len(), 1);
    let deep = format!("<Database>{}", "<a>".repeat(100_000));
    let err = adwi_programs::staubli::read(&Source::new("d.dtx", deep.as_bytes()), &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("nested more than 64 deep"), "{err}");
    // A number beyond any bound is reported where it is written, never corrected.
    let dir = tempfile::tempdir().unwrap();
    let (table, _) = kr150(dir.path());
    let app = dir.path().join("app");
    std::fs::create_dir(&app).unwrap();
    std::fs::write(
        app.join("a.dtx"),
        "<Database><Datas><Data name=\"p\" type=\"pointRx\"><Value key=\"0\" x=\"1e308\" ry=\"90\" /></Data></Datas></Database>\n",
    )
    .unwrap();
    std::fs::write(
        app.join("s.pgx"),
        "<Programs><Program name=\"s\"><Code><![CDATA[movel(p, flange, m)]]></Code></Program></Programs>\n",
    )
    .unwrap();
    let (code, stdout, stderr) = compensate(
        dir.path(),
        &[
            table.to_str().unwrap(),
            app.join("a.dtx").to_str().unwrap(),
            "-o",
            "o.dtx",
        ],
    );
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stdout.contains("p[0]") && stdout.contains("invalid (a position 1e308 at 1:66"),
        "{stdout}"
    );
}

/// A VAL3 application in `dir` of one point over the KR150-2's samples (their
/// orientation), moved to with the flange as the tool, its value written with `config`
/// (its `shoulder`, `elbow` and `wrist` attributes).
fn one_point_application(dir: &Path, config: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(
        dir.join("branch.pjx"),
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n\
         <Project xmlns=\"http://www.staubli.com/robotics/VAL3/Project/3\">\r\n\
         \x20 <Parameters version=\"s8.12\" stackSize=\"5000\" millimeterUnit=\"true\" />\r\n\
         \x20 <Programs>\r\n    <Program file=\"start.pgx\" />\r\n  </Programs>\r\n\
         \x20 <Database>\r\n    <Data file=\"branch.dtx\" />\r\n  </Database>\r\n\
         \x20 <Libraries />\r\n</Project>\r\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("start.pgx"),
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n\
         <Programs xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xmlns=\"http://www.staubli.com/robotics/VAL3/Program/2\">\r\n\
         \x20 <Program name=\"start\" access=\"public\">\r\n\
         \x20   <Code><![CDATA[begin\r\n  movej(pTarget[0], tFlange, mNom)\r\n  waitEndMove()\r\nend\r\n]]></Code>\r\n\
         \x20 </Program>\r\n</Programs>\r\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("branch.dtx"),
        format!(
            "<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n\
             <Database xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xmlns=\"http://www.staubli.com/robotics/VAL3/Data/2\">\r\n\
             \x20 <Datas>\r\n\
             \x20   <Data name=\"mNom\" access=\"public\" xsi:type=\"array\" type=\"mdesc\" size=\"1\">\r\n\
             \x20     <Value key=\"0\" accel=\"100\" vel=\"100\" decel=\"100\" tmax=\"99999\" rmax=\"99999\" blend=\"off\" leave=\"50\" reach=\"50\" />\r\n\
             \x20   </Data>\r\n\
             \x20   <Data name=\"pTarget\" access=\"public\" xsi:type=\"array\" type=\"pointRx\" size=\"1\">\r\n\
             \x20     <Value key=\"0\" x=\"1750\" y=\"450\" z=\"1250\" ry=\"90\" {config} fatherId=\"world[0]\" />\r\n\
             \x20   </Data>\r\n\
             \x20   <Data name=\"tFlange\" access=\"public\" xsi:type=\"array\" type=\"tool\" size=\"1\">\r\n\
             \x20     <Value key=\"0\" fatherId=\"flange[0]\" />\r\n\
             \x20   </Data>\r\n\
             \x20 </Datas>\r\n</Database>\r\n"
        ),
    )
    .unwrap();
    dir.join("branch.pjx")
}

/// A report line's command posture (radians), checked to be the command's by forward
/// kinematics (the robot file's tool is the flange: the table's point), and the
/// configuration the robot's geometry gives it.
fn command_posture(line: &adwi_programs::TargetLine) -> (Vec<f64>, adwi_robot::Configuration) {
    let robot = adwi_robot::Robot::load(repo("tables/kr150-2/robot.toml")).unwrap();
    let q: Vec<f64> = line
        .command_joints
        .as_ref()
        .unwrap_or_else(|| panic!("{}: no command posture", line.name))
        .iter()
        .map(|d| d.to_radians())
        .collect();
    let at = robot.tcp_pose(&q).translation.vector;
    let gap = (at - Vector3::from(line.command_mm.unwrap())).norm();
    assert!(gap < 1e-6, "{}: {gap} mm", line.name);
    let rows: [adwi_runtime::kinematics::MdhJoint; 6] = robot.mdh().unwrap().try_into().unwrap();
    let configuration = adwi_robot::ik::configuration_of(&rows, &q.clone().try_into().unwrap());
    (q, configuration)
}

#[test]
fn a_hybrid_table_solves_a_val3_point_on_its_written_wrist_not_the_nearest() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let mut flips = Vec::new();
    for wrist in ["wfree", "wnegative", "wpositive"] {
        let config = format!("shoulder=\"lefty\" elbow=\"epositive\" wrist=\"{wrist}\"");
        let pjx = one_point_application(&dir.path().join(wrist), &config);
        let done = CompensateJob::new(options(&table, &pjx))
            .unwrap()
            .run()
            .unwrap();
        let line = &done.report.targets[0];
        assert_eq!(line.status.as_str(), "ok", "{wrist}: {}", line.detail);
        let (q, configuration) = command_posture(line);
        eprintln!(
            "val3 {wrist}: J4 {:.3}°, J5 {:.3}°, configuration {}, correction {:.4} mm, |C + e(C) - P| {:.2e} mm",
            q[3].to_degrees(),
            q[4].to_degrees(),
            configuration.bits(),
            line.correction_mm.unwrap(),
            line.residual_mm.unwrap()
        );
        // Stäubli's wrist is the sign of J5, as the robot file counts it; the elbow J3's.
        match wrist {
            "wpositive" => assert!(q[4] >= 0.0, "{q:?}"),
            "wnegative" => assert!(q[4] < 0.0, "{q:?}"),
            _ => {}
        }
        assert!(q[2] >= 0.0, "{wrist}: epositive, {q:?}");
        assert!(!configuration.shoulder_back(), "{wrist}: lefty");
        flips.push(configuration.wrist_flip());
    }
    // Free, the controller's choice: the branch nearest the home posture, J5 < 0. The
    // written wpositive is the other branch, and lands there; wnegative on the nearest.
    assert_eq!(flips, [true, true, false]);
}

#[test]
fn a_val3_config_that_cannot_be_read_or_kept_leaves_the_point_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate::common::kr150_hybrid_table(dir.path());
    let pjx = one_point_application(
        &dir.path().join("upright"),
        "shoulder=\"upright\" elbow=\"epositive\"",
    );
    let done = CompensateJob::new(options(&table, &pjx))
        .unwrap()
        .run()
        .unwrap();
    let line = &done.report.targets[0];
    assert_eq!(line.status.as_str(), "invalid");
    assert_eq!(
        line.detail,
        "shoulder is righty, lefty, ssame or sfree, found 'upright' (line 8, column 66): left as written, not corrected in a posture the program does not give"
    );
    // A seven-axis robot has no shoulder, elbow and wrist labels to keep a written one in.
    let position_table = method_table(dir.path(), &repo("tables/kr150-2/samples.csv"), "kr150.tbl");
    let pjx = one_point_application(
        &dir.path().join("iiwa"),
        "shoulder=\"lefty\" wrist=\"wpositive\"",
    );
    let mut o = CompensateOptions::new(&position_table, &pjx);
    o.robot = Some(repo("tables/iiwa14/robot.toml"));
    let done = CompensateJob::new(o).unwrap().run().unwrap();
    let line = &done.report.targets[0];
    assert_eq!(line.status.as_str(), "invalid", "{}", line.detail);
    assert_eq!(
        line.detail,
        "the written configuration (shoulder lefty, elbow free, wrist wpositive) cannot be told apart on this robot file (KUKA LBR iiwa 14 R820: no closed-form inverse kinematics: 7 joints, not 6 (needs six MD-H joints with α1, α3, α4, α5 = ±90°, α2 = 0° or 180°, β = 0, a4 = a5 = a6 = d5 = 0, a2 > 0)): left as written, not corrected in a posture the program does not give"
    );
}
