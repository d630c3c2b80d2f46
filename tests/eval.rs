//! `tablec eval` end to end: the real binary on files in a temporary directory.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::tablec;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A smooth error field, mm, at a nominal position: what a lattice of samples records.
fn error_mm(p: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = p.map(|v| v / 1000.0);
    [
        0.3 + 0.5 * x * y - 0.2 * z,
        -0.4 + 0.3 * (x + z).sin(),
        0.1 * x - 0.6 * y * z,
    ]
}

/// A 6 × 6 × 6 lattice of samples (50 mm step) and validation points: 25 inside the
/// lattice and 2 far outside it.
fn write_inputs(dir: &Path) {
    let mut samples = String::from("x,y,z,dx,dy,dz\n");
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                let p = [
                    1500.0 + 50.0 * f64::from(i),
                    300.0 + 50.0 * f64::from(j),
                    900.0 + 50.0 * f64::from(k),
                ];
                let e = error_mm(p);
                samples.push_str(&format!(
                    "{},{},{},{},{},{}\n",
                    p[0], p[1], p[2], e[0], e[1], e[2]
                ));
            }
        }
    }
    std::fs::write(dir.join("samples.csv"), samples).unwrap();
    let mut validation = String::from("x,y,z,dx,dy,dz\n");
    for n in 0..25 {
        let t = f64::from(n);
        let p = [
            1510.0 + (t * 37.3) % 230.0,
            310.0 + (t * 53.9) % 230.0,
            905.0 + (t * 71.1) % 240.0,
        ];
        let e = error_mm(p);
        validation.push_str(&format!(
            "{},{},{},{},{},{}\n",
            p[0], p[1], p[2], e[0], e[1], e[2]
        ));
    }
    validation.push_str("5000,0,0,0.1,0.1,0.1\n-3000,100,200,0.2,0.2,0.2\n");
    std::fs::write(dir.join("validation.csv"), validation).unwrap();
}

/// The `paper` and `paper-trilinear` methods of `tablec eval` are the table `tablec build`
/// writes, queried as `tablec query --exact` and `tablec query` do: the same prediction at
/// every point, and the same points refused.
#[test]
fn paper_methods_equal_tablec_query() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_inputs(d);
    ok(&tablec(
        &["build", "-q", "samples.csv", "-o", "t.tbl", "--k", "6"],
        d,
    ));
    ok(&tablec(
        &[
            "eval",
            "samples.csv",
            "--validation",
            "validation.csv",
            "--methods",
            "paper,paper-trilinear",
            "--k",
            "6",
            "--json",
            "e.json",
            "-q",
        ],
        d,
    ));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("e.json")).unwrap()).unwrap();
    for (index, name, exact) in [(0, "paper", true), (1, "paper-trilinear", false)] {
        let mut args = vec![
            "query",
            "t.tbl",
            "--targets",
            "validation.csv",
            "-o",
            "q.csv",
        ];
        if exact {
            args.push("--exact");
        }
        // Exit status 3: the two points far outside are not answered (and are still
        // written).
        let query = tablec(&args, d);
        assert_eq!(query.status.code(), Some(3));
        let method = &json["methods"][index];
        assert_eq!(method["method"], name);
        let predictions = method["predictions"].as_array().unwrap();
        let queried = std::fs::read_to_string(d.join("q.csv")).unwrap();
        let rows: Vec<&str> = queried.lines().skip(1).collect();
        assert_eq!(rows.len(), predictions.len());
        let mut refused = 0;
        for (row, prediction) in rows.iter().zip(predictions) {
            let fields: Vec<&str> = row.split(',').collect();
            if fields[10] != "ok" {
                assert!(prediction.is_null(), "{name} {row}");
                refused += 1;
                continue;
            }
            let predicted = &prediction["position_error_mm"];
            for axis in 0..3 {
                let q: f64 = fields[3 + axis].parse().unwrap();
                let e = predicted[axis].as_f64().unwrap();
                // `tablec query` prints nine decimals.
                assert!((q - e).abs() <= 1e-9, "{name} {row}: {e}");
            }
        }
        // The two far points are outside the grid, counted rather than dropped.
        assert_eq!(refused, 2, "{name}");
        assert_eq!(method["not_predicted"]["outside_grid"], 2, "{name}");
    }
}

/// Every method that applies runs, the lattice method included; points outside the
/// lattice are counted per method; CSV and the HTML report are written.
#[test]
fn every_method_is_compared_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_inputs(d);
    let o = tablec(
        &[
            "eval",
            "samples.csv",
            "--validation",
            "validation.csv",
            "--csv",
            "e.csv",
            "--report",
            "report",
            "--methods",
            "paper,paper-trilinear,idw,grid,kriging",
        ],
        d,
    );
    ok(&o);
    let stdout = String::from_utf8_lossy(&o.stdout);
    for method in ["uncompensated", "paper ", "idw", "grid", "kriging"] {
        assert!(stdout.contains(method), "{method} missing from:\n{stdout}");
    }
    // By default, what a table serves and the cheap baselines; without a robot or joint
    // angles the kinematic ones cannot run, and say why.
    let default = tablec(
        &["eval", "samples.csv", "--validation", "validation.csv"],
        d,
    );
    ok(&default);
    let default = String::from_utf8_lossy(&default.stdout);
    assert!(default.contains("kinematic: not run: needs a robot model"));
    assert!(!default.contains("\ngrid ") && !default.contains("\nkriging "));
    let csv = std::fs::read_to_string(d.join("e.csv")).unwrap();
    let grid = csv.lines().find(|l| l.starts_with("grid,")).unwrap();
    // 25 inside, 2 outside the lattice.
    assert!(grid.starts_with("grid,25,2,"), "{grid}");
    let mean = |line: &str| -> f64 { line.split(',').nth(3).unwrap().parse().unwrap() };
    let before = mean(csv.lines().nth(1).unwrap());
    // A smooth field on a 50 mm lattice: every interpolator removes most of the error.
    for line in csv.lines().skip(2) {
        assert!(mean(line) < 0.1 * before, "{line} vs {before}");
    }
    let page = std::fs::read_to_string(d.join("report/index.html")).unwrap();
    assert!(page.contains("<table>"));
    // Every position section, each plot inline; without a robot or orientation errors,
    // no identification and no orientation plot, but a line saying so.
    for heading in [
        "Figures",
        "Distribution of position residuals",
        "Residual against distance from the base",
        "Error vectors before and after compensation",
        "Per-axis errors",
        "Where the samples and evaluated points lie",
    ] {
        assert!(page.contains(&format!("<h2>{heading}</h2>")), "{heading}");
    }
    assert_eq!(
        page.matches("<svg").count(),
        9,
        "two distributions, distance, four vector panels, two maps"
    );
    assert!(page.contains("No orientation errors were measured"));
    assert!(!page.contains("orientation residuals</h2>"));
    assert!(!page.contains("Kinematic identification"));
}

/// The entry of `method` under `"methods"` in `tablec eval --json` output.
fn method_json<'a>(json: &'a serde_json::Value, method: &str) -> &'a serde_json::Value {
    json["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["method"] == method)
        .unwrap_or_else(|| panic!("{method} not in the JSON"))
}

/// k-fold cross-validation predicts every sample once.
#[test]
fn k_fold_predicts_every_sample_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_inputs(d);
    ok(&tablec(
        &[
            "eval",
            "samples.csv",
            "--folds",
            "4",
            "--seed",
            "3",
            "--methods",
            "idw,paper",
            "--json",
            "e.json",
            "-q",
        ],
        d,
    ));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("e.json")).unwrap()).unwrap();
    let idw = method_json(&json, "idw");
    let predictions = idw["predictions"].as_array().unwrap();
    assert_eq!(predictions.len(), 216);
    assert!(predictions.iter().all(|p| !p.is_null()));
}

/// Reads the command and the machine-checked figures of a section of
/// `docs/evaluation.md`, marked `<!-- check:NAME:command -->` and
/// `<!-- check:NAME:figures -->`, each followed by a fenced block.
fn documented(name: &str) -> (Vec<String>, Vec<(String, f64)>) {
    let doc = std::fs::read_to_string(repo().join("docs/evaluation.md")).unwrap();
    let block = |marker: &str| -> String {
        let start = doc
            .find(&format!("<!-- check:{name}:{marker} -->"))
            .unwrap_or_else(|| panic!("marker {name}:{marker} missing"));
        let rest = &doc[start..];
        let open = rest.find("```").unwrap();
        let body = &rest[open..];
        let body = &body[body.find('\n').unwrap() + 1..];
        body[..body.find("```").unwrap()].to_string()
    };
    let command: Vec<String> = block("command")
        .replace("\\\n", " ")
        .split_whitespace()
        .skip_while(|w| *w != "eval")
        .map(str::to_string)
        .collect();
    let figures = block("figures")
        .lines()
        .skip(1)
        // Rows without a mean (an unsupported method) carry nothing to check.
        .filter_map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            Some((fields[0].to_string(), fields.get(3)?.parse().ok()?))
        })
        .collect();
    (command, figures)
}

/// The UR5 figures in docs/evaluation.md are what the documented command prints, to
/// 1e-6 mm in every method's mean residual.
#[test]
fn documented_ur5_figures_are_regenerated() {
    let (command, figures) = documented("ur5");
    assert!(figures.len() >= 7, "{figures:?}");
    let out = tempfile::tempdir().unwrap();
    let csv = out.path().join("ur5.csv");
    let mut args: Vec<&str> = command.iter().map(String::as_str).collect();
    args.extend(["--csv", csv.to_str().unwrap(), "-q"]);
    ok(&tablec(&args, &repo()));
    let produced = std::fs::read_to_string(&csv).unwrap();
    let produced: Vec<(String, Option<f64>)> = produced
        .lines()
        .skip(1)
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            (fields[0].to_string(), fields[3].parse().ok())
        })
        .collect();
    for (method, documented_mean_mm) in &figures {
        let (_, mean) = produced
            .iter()
            .find(|(m, _)| m == method)
            .unwrap_or_else(|| panic!("{method} not in the output"));
        let mean = mean.unwrap_or_else(|| panic!("{method} has no mean"));
        assert!(
            (mean - documented_mean_mm).abs() <= 1e-6,
            "{method}: documented {documented_mean_mm} mm, regenerated {mean} mm"
        );
    }
}

/// On the UR5 grid: the noise floor of the kinematic residuals is in the JSON (a nugget
/// near the semivariance 0.0065 mm² at the 33 mm spacing, extrapolated to zero lag, and the
/// ~0.06 mm mean a perfect predictor would leave), and the identification holds what it
/// cannot trust: the flange's Δd6 and Δtheta6 stay nominal, the tool's z takes the
/// reflector's offset, and every parameter has a status and, when not identified, a reason.
/// What the 20 points resolve is said too: each mean's standard error, the hybrid against
/// the kinematic model point by point, and the offset the hybrid's residuals share.
#[test]
fn ur5_noise_floor_resolution_and_trusted_identification() {
    let (command, _) = documented("ur5");
    let out = tempfile::tempdir().unwrap();
    let json = out.path().join("ur5.json");
    let mut args: Vec<&str> = command.iter().map(String::as_str).collect();
    let report = out.path().join("report");
    args.extend([
        "--methods",
        "kinematic,hybrid",
        "--json",
        json.to_str().unwrap(),
    ]);
    args.extend(["--report", report.to_str().unwrap()]);
    let o = tablec(&args, &repo());
    ok(&o);
    // The report shows the identification, held and unidentifiable parameters last.
    let page = std::fs::read_to_string(report.join("index.html")).unwrap();
    let table = &page[page
        .find("<h2>Kinematic identification</h2>")
        .expect("section")..];
    let held = table.find(">held<").expect("held parameters");
    assert!(table.rfind(">identified<").unwrap() < held);
    assert!(page.contains(">Δd6<"));
    assert!(page.contains("No orientation errors were measured"));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("noise floor"), "{stdout}");
    let e: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let floor = &e["noise_floor"];
    let number = |v: &serde_json::Value| v.as_f64().unwrap_or_else(|| panic!("{floor}"));
    let cartesian = number(&floor["nugget_mm2_cartesian"]);
    let joint = number(&floor["nugget_mm2_joint"]);
    let best = number(&floor["best_mean_mm"]);
    assert!((0.0035..0.0055).contains(&cartesian), "{floor}");
    assert!((0.0035..0.0065).contains(&joint), "{floor}");
    assert!((0.055..0.07).contains(&best), "{floor}");
    assert!(cartesian < number(&floor["total_variance_mm2"]));
    // The hybrid leaves 0.0853 mm, the kinematic model 0.1004 mm: 0.0151 mm apart, known
    // point by point to about ±0.007 mm although each mean alone is known only to about
    // ±0.007-0.008 mm.
    let comparison = &e["comparison"];
    assert_eq!(comparison["reference"], "hybrid", "{comparison}");
    let kinematic = &comparison["against"][0];
    assert_eq!(kinematic["method"], "kinematic");
    assert_eq!(kinematic["points"], 20);
    let difference = number(&kinematic["mean_difference_mm"]);
    assert!((difference - 0.0151).abs() < 5e-5, "{comparison}");
    let paired = number(&kinematic["standard_error_mm"]);
    assert!((0.004..0.01).contains(&paired), "{comparison}");
    let hybrid = method_json(&e, "hybrid");
    let se = number(&hybrid["position_mm"]["mean_norm_standard_error"]);
    assert!((0.005..0.01).contains(&se), "{se}");
    // The 20 random poses share an offset of about 0.03 mm that the grid's model cannot
    // know: below 1 % chance for the hybrid's residuals.
    let p = number(&hybrid["position_mm"]["mean_per_axis_p_value"]);
    assert!(p < 0.01, "{p}");
    // Every point answered, each with its residual flag; other methods have none.
    let flags = ["residual_full", "residual_faded", "residual_model_only"];
    let counts: Vec<u64> = flags.map(|k| hybrid[k].as_u64().unwrap()).to_vec();
    assert_eq!(counts.iter().sum::<u64>(), 20, "{counts:?}");
    let line = format!(
        "residual: {} full, {} faded, {} model_only",
        counts[0], counts[1], counts[2]
    );
    assert!(stdout.contains(&line), "{stdout}");
    assert!(method_json(&e, "kinematic").get("residual_full").is_none());
    assert!(
        stdout.contains("point by point against hybrid (mean 0.0853 ± 0.0077 mm"),
        "{stdout}"
    );
    assert!(
        stdout.contains("hybrid (-0.0218, +0.0158, -0.0140) mm, p = 0.008"),
        "{stdout}"
    );
    let parameters = e["calibrations"][0]["parameters"].as_array().unwrap();
    let row = |name: &str| {
        parameters
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("{name} missing"))
    };
    for name in ["Δd6", "Δtheta6"] {
        assert_ne!(row(name)["status"], "identified", "{}", row(name));
        assert_eq!(row(name)["value"], 0.0);
        assert!(!row(name)["reason"].as_str().unwrap().is_empty());
    }
    assert_eq!(row("tool z")["status"], "identified");
    let tool_z = number(&row("tool z")["value"]);
    assert!((2.5..3.0).contains(&tool_z), "{tool_z}");
    for p in parameters {
        let identified = p["status"] == "identified";
        assert_eq!(p["reason"].as_str().unwrap().is_empty(), identified, "{p}");
    }
}

/// `tablec build --hybrid` identifies first and says so: identified count, condition
/// number, RMS before and after, and a warning naming the parameters the data cannot
/// identify (Δθ1 turns the TCP exactly like the base rotation about z). Samples without
/// joint angles are refused with a message saying what is missing.
#[test]
fn hybrid_build_reports_the_calibration_and_warns_about_unidentifiable_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("kr150-hybrid.tbl");
    let out = tablec(
        &[
            "build",
            "tables/kr150-2/samples.csv",
            "-o",
            table.to_str().unwrap(),
            "--robot",
            "tables/kr150-2/robot.toml",
            "--hybrid",
            "--cell",
            "50",
            "--served-field",
            "method",
            "--harmonics",
            "0",
        ],
        &repo(),
    );
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stdout.contains(
            "25 parameters identified, 3 held at nominal, 14 unidentifiable, condition number"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("position RMS   1.9235 mm before, 0.0659 mm after"),
        "{stdout}"
    );
    assert!(
        stderr.contains(
            "note: 14 kinematic parameters are not observable in these samples and stay at \
             nominal, as is usual"
        ),
        "{stderr}"
    );
    assert!(stderr.contains("Δtheta1"), "{stderr}");
    // The KR150-2's samples measured orientation: any TCP is within their evidence.
    assert!(!stderr.contains("measured position alone"), "{stderr}");
    // The table is hybrid: a position-only query says joint angles are missing.
    let query = tablec(
        &["query", table.to_str().unwrap(), "1750", "450", "1250"],
        &repo(),
    );
    assert_eq!(query.status.code(), Some(3));
    assert!(
        String::from_utf8_lossy(&query.stdout).contains("missing_joints"),
        "{}",
        String::from_utf8_lossy(&query.stdout)
    );

    // With the joint angles (the first sample's), it answers: model + residual.
    let query = tablec(
        &[
            "query",
            table.to_str().unwrap(),
            "--joints",
            "2.556150,-67.995407,139.177130,2.700294,-71.201150,-0.870738",
            "1350",
            "50",
            "850",
        ],
        &repo(),
    );
    ok(&query);
    let stdout = String::from_utf8_lossy(&query.stdout);
    assert!(stdout.contains("status       ok"), "{stdout}");

    write_inputs(dir.path());
    let refused = tablec(
        &[
            "build",
            "samples.csv",
            "-o",
            "t.tbl",
            "--robot",
            repo().join("tables/kr150-2/robot.toml").to_str().unwrap(),
            "--hybrid",
        ],
        dir.path(),
    );
    assert!(!refused.status.success());
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(message.contains("no joint angles"), "{message}");
}

/// On the KR150-2 with strong joint compliance and gear errors
/// (`tables/kr150-2/scenario_compliant.toml`), a calibrated geometric model (no joint-space
/// terms, `--harmonics 0`) cannot reach the measurement noise floor, and the hybrid table,
/// built and queried through the runtime, does. The floor is the mean norm of the validation points' own tracker noise,
/// `1.596 σ(d)` for σ(d) = 5 µm + 2 µm/m · d per axis, d the distance to the tracker.
/// Kriging with a nugget of the same residuals comes closer still.
#[test]
fn hybrid_reaches_the_noise_floor_where_kinematic_cannot() {
    let dir = tempfile::tempdir().unwrap();
    let robot = repo().join("tables/kr150-2/robot.toml");
    let scenario = repo().join("tables/kr150-2/scenario_compliant.toml");
    let simulate = |plan: &[&str], seed: &str, output: &str| {
        let mut args = vec![
            "simulate",
            "--robot",
            robot.to_str().unwrap(),
            "--scenario",
            scenario.to_str().unwrap(),
            "--min",
            "1350,50,850",
            "--max",
            "2150,850,1650",
            "--abc",
            "0,90,0",
            "--seed",
            seed,
            "-o",
            output,
        ];
        args.extend_from_slice(plan);
        ok(&tablec(&args, dir.path()));
    };
    simulate(&["--step", "100"], "1", "samples.csv");
    simulate(&["--random", "200"], "2", "validation.csv");
    ok(&tablec(
        &[
            "eval",
            "samples.csv",
            "--validation",
            "validation.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--methods",
            "kinematic,hybrid",
            "--harmonics",
            "0",
            "--cell",
            "50",
            "--csv",
            "figures.csv",
            "-q",
        ],
        dir.path(),
    ));
    let figures = std::fs::read_to_string(dir.path().join("figures.csv")).unwrap();
    let column = |method: &str, index: usize| -> f64 {
        let line = figures
            .lines()
            .find(|l| l.starts_with(&format!("{method},")))
            .unwrap_or_else(|| panic!("{method} missing:\n{figures}"));
        line.split(',').nth(index).unwrap().parse().unwrap()
    };
    let tracker_mm = [4500.0, -1500.0, 0.0];
    let validation = std::fs::read_to_string(dir.path().join("validation.csv")).unwrap();
    let distances_m: Vec<f64> = validation
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('x'))
        .map(|l| {
            let p: Vec<f64> = l.split(',').take(3).map(|v| v.parse().unwrap()).collect();
            (0..3)
                .map(|a| (p[a] - tracker_mm[a]).powi(2))
                .sum::<f64>()
                .sqrt()
                / 1000.0
        })
        .collect();
    assert_eq!(distances_m.len(), 200);
    let floor_mm = distances_m
        .iter()
        .map(|d| 1.596 * (0.005 + 0.002 * d))
        .sum::<f64>()
        / distances_m.len() as f64;
    let (kinematic, hybrid) = (column("kinematic", 3), column("hybrid", 3));
    assert_eq!(
        column("hybrid", 1),
        200.0,
        "every point predicted:\n{figures}"
    );
    assert!(
        kinematic > 3.0 * floor_mm,
        "kinematic {kinematic} mm, floor {floor_mm} mm"
    );
    assert!(
        hybrid < 1.25 * floor_mm,
        "hybrid {hybrid} mm, floor {floor_mm} mm"
    );
    // Orientation too: the model alone leaves ten times what the hybrid leaves.
    let (kinematic_mrad, hybrid_mrad) = (column("kinematic", 7), column("hybrid", 7));
    assert!(
        kinematic_mrad > 10.0 * hybrid_mrad,
        "{kinematic_mrad} vs {hybrid_mrad} mrad"
    );
    // A kriging served field on the same residuals smooths the tracker noise the
    // method's interpolation passes on: closer to the floor in position, and a fraction of
    // the table's orientation residual (the simulated orientation noise is tiny against
    // the smooth compliance field).
    ok(&tablec(
        &[
            "eval",
            "samples.csv",
            "--validation",
            "validation.csv",
            "--robot",
            robot.to_str().unwrap(),
            "--methods",
            "hybrid-trilinear",
            "--served-field",
            "kriging",
            // What the field reaches, not whether the posture term would add to it (its
            // decision costs twice the evaluation; `posture.rs` tests it), on the model
            // the first evaluation scored.
            "--posture",
            "off",
            "--harmonics",
            "0",
            "--cell",
            "50",
            "--csv",
            "kriging.csv",
            "-q",
        ],
        dir.path(),
    ));
    let kriging = std::fs::read_to_string(dir.path().join("kriging.csv")).unwrap();
    let line = kriging
        .lines()
        .find(|l| l.starts_with("hybrid-trilinear,"))
        .unwrap();
    let field = |index: usize| -> f64 { line.split(',').nth(index).unwrap().parse().unwrap() };
    assert_eq!(field(1), 200.0, "{kriging}");
    let (mm, mrad) = (field(3), field(7));
    assert!(
        mm < hybrid && mm < 1.25 * floor_mm,
        "served kriging {mm} mm, hybrid {hybrid}"
    );
    assert!(
        mrad < 0.25 * hybrid_mrad,
        "served kriging {mrad} mrad, hybrid {hybrid_mrad}"
    );
}

/// `eval --table` scores a table built before exactly as `eval` scores the method that
/// built it: the UR5 hybrid table's served field at the 20 random poses is
/// `hybrid-trilinear`'s figure, point for point.
#[test]
fn a_table_built_before_is_scored_as_the_method_that_built_it() {
    let dir = tempfile::tempdir().unwrap();
    let grid = crate::common::ur5_grid();
    let random = repo().join("tables/ur5/measurements/3D_UR5_uncalibrated_random_cleaned.csv");
    let robot = repo().join("tables/ur5/robot.toml");
    crate::common::build_ur5_hybrid(
        dir.path(),
        robot.to_str().unwrap(),
        &["--cell", "30", "--served-field", "method"],
        "ur5.tbl",
    );
    let scored = tablec(
        &[
            "eval",
            "--table",
            "ur5.tbl",
            "--validation",
            random.to_str().unwrap(),
            "--columns",
            crate::common::UR5_MAP,
            "--json",
            "table.json",
        ],
        dir.path(),
    );
    ok(&scored);
    let evaluated = tablec(
        &[
            "eval",
            grid.to_str().unwrap(),
            "--validation",
            random.to_str().unwrap(),
            "--columns",
            crate::common::UR5_MAP,
            "--robot",
            robot.to_str().unwrap(),
            "--cell",
            "30",
            "--served-field",
            "method",
            // The table's residual field is whole and its model has no joint-space terms
            // (`build_ur5_hybrid`).
            "--residual-weight",
            "full",
            "--harmonics",
            "0",
            "--methods",
            "hybrid-trilinear",
            "--json",
            "method.json",
        ],
        dir.path(),
    );
    ok(&evaluated);
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(name)).unwrap()).unwrap()
    };
    let (table, method) = (read("table.json"), read("method.json"));
    let predictions = |v: &serde_json::Value, name: &str| {
        v["methods"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["method"] == name)
            .unwrap_or_else(|| panic!("{name} missing"))["predictions"]
            .clone()
    };
    assert_eq!(
        predictions(&table, "table"),
        predictions(&method, "hybrid-trilinear")
    );
    let stdout = String::from_utf8_lossy(&scored.stdout);
    assert!(
        stdout.contains("the table ur5.tbl (1000 samples), evaluated at 20 validation points"),
        "{stdout}"
    );
    // Scoring takes the table as it was built: no samples, methods or table options.
    let o = tablec(
        &[
            "eval",
            "--table",
            "ur5.tbl",
            "--validation",
            "x.csv",
            "--cell",
            "20",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("scores the table as it was built"));
}

/// Splits run side by side, as many at a time as the pool has threads: an evaluation is
/// the same to the bit whatever that number (1; 2; 3, whose last batch of 5 folds has 2),
/// a method no split can build (`grid` on these samples) included.
#[test]
fn an_evaluation_is_the_same_at_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let grid = crate::common::ur5_grid();
    let robot = repo().join("tables/ur5/robot.toml");
    let run = |threads: &str| -> (Vec<u8>, Vec<u8>) {
        let json = format!("threads-{threads}.json");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_tablec"))
            .args([
                "eval",
                grid.to_str().unwrap(),
                "--folds",
                "5",
                "--columns",
                crate::common::UR5_MAP,
                "--robot",
                robot.to_str().unwrap(),
                "--cell",
                "30",
                "--methods",
                "paper,kinematic,hybrid-trilinear,grid",
                "--served-field",
                "method",
                "--posture",
                "off",
                "--json",
                &json,
            ])
            .env("RAYON_NUM_THREADS", threads)
            .current_dir(dir.path())
            .output()
            .unwrap();
        ok(&o);
        (std::fs::read(dir.path().join(&json)).unwrap(), o.stdout)
    };
    // The three runs side by side: each is one process with its own pool.
    let [one, two, three] = std::thread::scope(|scope| {
        let runs = ["1", "2", "3"].map(|threads| scope.spawn(move || run(threads)));
        runs.map(|r| r.join().unwrap())
    });
    let text = String::from_utf8_lossy(&one.1);
    assert!(
        text.contains("kinematic") && text.contains("grid"),
        "{text}"
    );
    assert_eq!(two, one);
    assert_eq!(three, one);
}
