//! `tablec iso9283 --path`: the path characteristics of simulated tracker streams with known
//! errors, through the real executable, as docs/measure.md runs them; with a table, the
//! compensation; options refused before any file is read; a stream too large refused with
//! its count.

use adwi_measure::path::{parse_command, simulated_stream, CommandPath, Simulation};

use crate::common::{lattice_table, tablec};

fn quiet(cycles: usize) -> Simulation {
    Simulation {
        speed_factors: vec![1.0; cycles],
        fluctuation: (0.0, 0.0),
        offset_mm: [0.0; 3],
        cycle_spread_mm: 0.0,
        radius_scale: 1.0,
        fillet_mm: 0.0,
        overshoot_mm: 0.0,
        noise_mm: 0.0,
        rate_hz: 500.0,
        dwell_s: 0.5,
        seed: 1,
    }
}

/// A horizontal unit vector across a path's first segment.
fn across(path: &CommandPath) -> [f64; 3] {
    let (s, e) = (path.point_at(0.0), path.point_at(1.0));
    let d = [e[0] - s[0], e[1] - s[1]];
    let n = d[0].hypot(d[1]);
    [d[1] / n, -d[0] / n, 0.0]
}

/// The stream of every path run as `sim` says, with a path column.
fn stream(paths: &[CommandPath], sim: impl Fn(&CommandPath) -> Simulation) -> String {
    let mut out = String::from("t,x,y,z,path\n");
    let mut t0 = 0.0;
    for path in paths {
        let mut last = t0;
        for line in simulated_stream(path, &sim(path)).lines().skip(1) {
            let (t, rest) = line.split_once(',').unwrap();
            last = t0 + t.parse::<f64>().unwrap();
            out.push_str(&format!("{last:.6},{rest},{}\n", path.name));
        }
        t0 = last + 1.0;
    }
    out
}

/// The path plan of a cube (`tablec iso9283 --cube CUBE --path-plan`, `extra` added)
/// written to `paths.csv` in `dir`, and its paths.
fn path_plan(cube: &str, extra: &[&str], dir: &std::path::Path) -> Vec<CommandPath> {
    let mut args = vec!["iso9283", "--cube", cube, "--path-plan"];
    args.extend(extra);
    args.extend(["-o", "paths.csv"]);
    run(&args, dir);
    let plan = std::fs::read_to_string(dir.join("paths.csv")).unwrap();
    parse_command(plan.as_bytes(), "paths.csv").unwrap()
}

fn run(args: &[&str], dir: &std::path::Path) -> String {
    let o = tablec(args, dir);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// The commands of docs/measure.md's path section on a stream with known errors: a line
/// 0.3 mm off across it at 0.95 of the speed, a circle 0.2 % large, a rectangle whose
/// corners are cut by a 5 mm fillet and overshoot 0.4 mm: AT_P 0.3 mm and AV −5 %, AT_P
/// 0.48 mm, CR 2.0711 and CO 0.4 mm at each corner; the JSON and the page carry them.
#[test]
fn the_path_test_runs_as_documented_on_a_simulated_stream() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let paths = path_plan("1750,450,1250,600", &["--speed", "200"], d);
    let text = stream(&paths, |p| match p.name.as_str() {
        "line" => Simulation {
            offset_mm: across(p).map(|v| 0.3 * v),
            speed_factors: vec![0.95; 3],
            ..quiet(3)
        },
        "circle" | "small_circle" => Simulation {
            radius_scale: 1.002,
            ..quiet(3)
        },
        _ => Simulation {
            fillet_mm: 5.0,
            overshoot_mm: 0.4,
            ..quiet(3)
        },
    });
    std::fs::write(d.join("stream.csv"), text).unwrap();
    let out = run(
        &[
            "iso9283",
            "--path",
            "stream.csv",
            "--command",
            "paths.csv",
            "--json",
            "path.json",
            "--report",
            "path-report",
        ],
        d,
    );
    assert!(out.contains("AT_P mm") && out.contains("CR mm"), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("path.json")).unwrap()).unwrap();
    let path = |name: &str| {
        json["paths"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap()
            .clone()
    };
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let line = path("line");
    assert_eq!(line["n"], 3);
    assert!((f(&line["at_p_mm"]) - 0.3).abs() < 1e-4, "{line}");
    assert!(
        (f(&line["velocity"]["av_percent"]) + 5.0).abs() < 0.01,
        "{line}"
    );
    let circle = path("circle");
    assert!((f(&circle["at_p_mm"]) - 0.48).abs() < 1e-3, "{circle}");
    let rectangle = path("rectangle");
    let corners = rectangle["corners"].as_array().unwrap();
    assert_eq!(corners.len(), 3);
    let cr = 5.0 * (2f64.sqrt() - 1.0);
    let page = std::fs::read_to_string(d.join("path-report/index.html")).unwrap();
    for c in corners {
        assert!((f(&c["cr_mm"]) - cr).abs() < 1e-3, "{c}");
        assert!((f(&c["co_mm"]) - 0.4).abs() < 2e-3, "{c}");
        assert!(page.contains(&format!("<td>{:.4}</td>", f(&c["cr_mm"]))));
    }
    for p in json["paths"].as_array().unwrap() {
        for key in ["at_p_mm", "rt_p_mm"] {
            assert!(
                page.contains(&format!("<td>{:.4}</td>", f(&p[key]))),
                "{key}"
            );
        }
    }
}

/// A line in the lattice table's workspace attained off by the table's error at its middle:
/// compensated by the table, what is left of AT_P is the error's change along the line
/// and the table's own residual, a fraction of it.
#[test]
fn a_table_compensates_the_path_it_was_measured_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("t.tbl"), lattice_table(1, 1.0)).unwrap();
    let line: Vec<CommandPath> = path_plan("1600,0,900,150", &[], d)
        .into_iter()
        .filter(|p| p.name == "line")
        .collect();
    // The lattice's error field at the cube's centre (tests/common: 0.2 + 1e-4 y, ...).
    let e = [0.2, -0.1 + 2e-4 * 1600.0, 0.3 - 1e-4 * 900.0];
    let text = stream(&line, |_| Simulation {
        offset_mm: e,
        ..quiet(3)
    });
    std::fs::write(d.join("stream.csv"), text).unwrap();
    run(
        &[
            "iso9283",
            "--path",
            "stream.csv",
            "--command",
            "paths.csv",
            "--table",
            "t.tbl",
            "--json",
            "p.json",
        ],
        d,
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("p.json")).unwrap()).unwrap();
    let measured = json["paths"][0]["at_p_mm"].as_f64().unwrap();
    let compensated = json["compensated"]["paths"][0]["at_p_mm"].as_f64().unwrap();
    assert!(measured > 0.25, "{json}");
    assert!(compensated < 0.05, "{measured} then {compensated}");
    // Repeatability is the robot's: unchanged.
    let rt = |v: &serde_json::Value| v["paths"][0]["rt_p_mm"].as_f64().unwrap();
    assert!(
        (rt(&json) - rt(&json["compensated"])).abs() < 1e-3,
        "{json}"
    );
}

/// Every option of a path test is checked before a file is read: exit 2 naming it, though
/// no input exists.
#[test]
fn path_options_are_refused_before_any_file_is_read() {
    let dir = tempfile::tempdir().unwrap();
    for (args, says) in [
        (&["iso9283", "--path", "s.csv"][..], "--command"),
        (&["iso9283", "--command", "c.csv"][..], "--path"),
        (
            &[
                "iso9283",
                "--path",
                "s.csv",
                "--command",
                "c.csv",
                "--cycles",
                "5",
            ][..],
            "--cycles",
        ),
        (
            &["iso9283", "--path", "s.csv", "--command", "c.csv", "m.csv"][..],
            "",
        ),
        (&["iso9283", "--path-plan", "-o", "p.csv"][..], "--cube"),
        (
            &[
                "iso9283",
                "--cube",
                "0,0,1000,300",
                "--speed",
                "50",
                "-o",
                "p.csv",
            ][..],
            "--path-plan",
        ),
        (
            &[
                "iso9283",
                "--cube",
                "0,0,1000,300",
                "--path-plan",
                "--speed",
                "0",
                "-o",
                "p.csv",
            ][..],
            "speed",
        ),
    ] {
        let o = tablec(args, dir.path());
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// A stream over the row limit is refused with its count before a row is parsed, and no
/// output is written.
#[test]
fn a_stream_too_large_is_refused_with_its_count() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("c.csv"),
        "path,kind,x,y,z\nline,start,0,0,1000\nline,line,100,0,1000\n",
    )
    .unwrap();
    let rows = adwi_measure::path::MAX_STREAM_ROWS + 1;
    let mut text = String::with_capacity(rows as usize * 8 + 8);
    text.push_str("t,x,y,z\n");
    for _ in 0..rows {
        text.push_str("0,0,0,0\n");
    }
    std::fs::write(d.join("s.csv"), text).unwrap();
    let o = tablec(
        &[
            "iso9283",
            "--path",
            "s.csv",
            "--command",
            "c.csv",
            "--json",
            "o.json",
        ],
        d,
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!("s.csv: {rows} rows, more than 2000000")),
        "{stderr}"
    );
    assert!(!d.join("o.json").exists());
}

/// A hybrid table's correction needs the joints, which neither measured cycles nor a
/// tracker stream carry: both reductions refuse it, naming the table and why, and write
/// no JSON.
#[test]
fn a_hybrid_table_is_refused_by_both_reductions() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let hybrid = crate::common::repo("tables/compat/v4/ur5_hybrid.tbl");
    let hybrid = hybrid.to_str().unwrap();
    let paths = path_plan("400,0,400,100", &[], d);
    std::fs::write(d.join("stream.csv"), stream(&paths[..1], |_| quiet(2))).unwrap();
    run(
        &[
            "iso9283",
            "--cube",
            "400,0,400,100",
            "--cycles",
            "2",
            "-o",
            "plan.csv",
        ],
        d,
    );
    let plan = std::fs::read_to_string(d.join("plan.csv")).unwrap();
    let mut cycles = String::new();
    for line in plan.lines().filter(|l| !l.starts_with('#')) {
        match line.starts_with("position") {
            true => cycles.push_str(&format!("{line},mx,my,mz\n")),
            false => {
                let xyz: Vec<&str> = line.split(',').skip(2).take(3).collect();
                cycles.push_str(&format!("{line},{}\n", xyz.join(",")));
            }
        }
    }
    std::fs::write(d.join("cycles.csv"), cycles).unwrap();
    for (args, lacking) in [
        (
            &[
                "iso9283",
                "cycles.csv",
                "--table",
                hybrid,
                "--json",
                "out.json",
            ][..],
            "which cycles do not carry",
        ),
        (
            &[
                "iso9283",
                "--path",
                "stream.csv",
                "--command",
                "paths.csv",
                "--table",
                hybrid,
                "--json",
                "out.json",
            ][..],
            "which a tracker stream does not carry",
        ),
    ] {
        let o = tablec(args, d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains(&format!(
                "{hybrid} is a hybrid table: its correction needs joint values, {lacking}"
            )),
            "{args:?}: {err}"
        );
        assert!(!d.join("out.json").exists(), "{args:?}");
    }
}
