//! Tables for the end-to-end tests: a noisy lattice of samples, compiled by the real
//! compiler.

#![allow(dead_code)]

use adwi_compile::build::{compile, BuildOptions};
use adwi_samples::{parse_samples, ColumnMap};

mod once;
pub use once::{repository_folder, tablec_once};

/// A deterministic generator (SplitMix64): the same tables on every run.
pub struct SplitMix(pub u64);

impl SplitMix {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The lattice's minimum corner and spacing, mm.
pub const ORIGIN_MM: [f64; 3] = [1500.0, -100.0, 800.0];
pub const SPACING_MM: f64 = 50.0;
/// Samples per axis.
pub const PER_AXIS: usize = 5;

/// Sample CSV for a `PER_AXIS`³ lattice with smooth errors (times `scale`) plus noise.
pub fn lattice_csv(seed: u64, scale: f64) -> String {
    let mut rng = SplitMix(seed);
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for k in 0..PER_AXIS {
        for j in 0..PER_AXIS {
            for i in 0..PER_AXIS {
                let p = [
                    ORIGIN_MM[0] + i as f64 * SPACING_MM,
                    ORIGIN_MM[1] + j as f64 * SPACING_MM,
                    ORIGIN_MM[2] + k as f64 * SPACING_MM,
                ];
                let e = [
                    scale * (0.2 + 1e-4 * p[1] + rng.uniform(-0.01, 0.01)),
                    scale * (-0.1 + 2e-4 * p[0] + rng.uniform(-0.01, 0.01)),
                    scale * (0.3 - 1e-4 * p[2] + rng.uniform(-0.01, 0.01)),
                ];
                csv += &format!("{},{},{},{},{},{}\n", p[0], p[1], p[2], e[0], e[1], e[2]);
            }
        }
    }
    csv
}

/// The compiled table of [`lattice_csv`], with the default options.
pub fn lattice_table(seed: u64, scale: f64) -> Vec<u8> {
    let csv = lattice_csv(seed, scale);
    let samples = parse_samples(
        "lattice.csv".as_ref(),
        csv.as_bytes(),
        &ColumnMap::default(),
    )
    .unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

/// Random targets inside the lattice box.
pub fn targets(seed: u64, count: usize) -> Vec<[f64; 3]> {
    let mut rng = SplitMix(seed);
    let extent = SPACING_MM * (PER_AXIS - 1) as f64;
    (0..count)
        .map(|_| [0, 1, 2].map(|a| ORIGIN_MM[a] + rng.uniform(0.0, extent)))
        .collect()
}

/// The shipped KR150-2 samples and the kinematic calibration identified from them: the
/// starting point of every hybrid-table test.
pub fn kr150_calibration() -> (
    adwi_robot::Robot,
    adwi_samples::SampleSet,
    adwi_identify::calibrate::Calibration,
) {
    use adwi_identify::calibrate::{identify, CalibrateOptions};
    use adwi_robot::{model::shipped_robot_path, Robot};
    use adwi_samples::read_samples;
    let robot_path = shipped_robot_path("kr150-2");
    let robot = Robot::load(&robot_path).unwrap();
    let samples = read_samples(
        &robot_path.parent().unwrap().join("samples.csv"),
        &ColumnMap::default(),
    )
    .unwrap();
    let calibration = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    (robot, samples, calibration)
}

/// Runs the real `tablec` binary with `args` in `dir`.
pub fn tablec(args: &[&str], dir: &std::path::Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_tablec"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("tablec runs")
}

/// The brute-force reference of a hybrid query at `target` reached with joint angles
/// `joints_rad`, computed independently of the table: the calibrated model's predicted
/// error by the robot crate's own forward kinematics ([`Calibration::predict_error`]),
/// plus the reference prediction over every residual in `residual_records` (with the
/// joint-space screen when `joint_radius_rad > 0`). Position (mm) and orientation (rad,
/// zero without `orientation`), or `None` when no residual sample is admissible.
#[allow(clippy::too_many_arguments)]
pub fn hybrid_reference_predict(
    residual_records: &[adwi_runtime::format::SampleRecord],
    sample_joints: &adwi_samples::Joints,
    params: &adwi_runtime::method::MethodParams,
    joint_radius_rad: f64,
    calibration: &adwi_identify::calibrate::Calibration,
    orientation: bool,
    target: &adwi_runtime::Target,
    joints_rad: &[f64],
) -> Option<([f64; 3], [f64; 3])> {
    use adwi_compile::reference::{self, JointScreen};
    let screen = JointScreen {
        samples: sample_joints,
        target_rad: joints_rad,
        radius_rad: joint_radius_rad,
    };
    let screen = (joint_radius_rad > 0.0).then_some(&screen);
    let rest = reference::predict_screened(residual_records, params, target, screen)?;
    let (p, r) = calibration.predict_error(joints_rad);
    let scale = reference_residual_scale(sample_joints, joints_rad);
    let position = [0, 1, 2].map(|a| p[a] + scale * rest.position_error_mm[a]);
    let rotation = if orientation {
        [0, 1, 2].map(|a| r[a] + scale * rest.orientation_error_rad[a])
    } else {
        [0.0; 3]
    };
    Some((position, rotation))
}

/// The factor on a hybrid table's residual at `joints_rad` (every joint revolute), by its
/// definition ([`adwi_runtime::testing::reference_residual_scale`]), with each joint's
/// range the lowest and highest of `sample_joints`.
pub fn reference_residual_scale(sample_joints: &adwi_samples::Joints, joints_rad: &[f64]) -> f64 {
    let ranges: Vec<[f64; 2]> = (0..joints_rad.len())
        .map(|j| {
            let column = sample_joints.rows().map(|row| row[j]);
            let (lo, hi) = column.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q), hi.max(q))
            });
            [lo, hi]
        })
        .collect();
    adwi_runtime::testing::reference_residual_scale(joints_rad, &ranges)
}

/// The UR5 measurements' column mapping (joint angles included).
pub const UR5_MAP: &str = "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,\
                           j1=joint_1,j2=joint_2,j3=joint_3,j4=joint_4,j5=joint_5,j6=joint_6";

/// The UR5's 20 random poses shipped in `tables/ur5/measurements`, read with [`UR5_MAP`].
pub fn ur5_random() -> adwi_samples::SampleSet {
    adwi_samples::read_samples(
        &repo("tables/ur5/measurements/3D_UR5_uncalibrated_random_cleaned.csv"),
        &ColumnMap::parse(UR5_MAP).unwrap(),
    )
    .unwrap()
}

/// A compatibility fixture's recorded answers (its README's) at the first of the UR5's
/// random poses (`points`, [`ur5_random`]): for each, the served and exact position errors
/// (mm) and the model's orientation error (rad), which neither tier serves (the UR5's
/// samples measured position alone), each within 1e-9 (recorded to 9
/// decimals). Returns both tiers' answers, pose by pose, for the caller's own checks.
pub fn assert_recorded_ur5_answers<D: AsRef<[u8]>>(
    table: &adwi_runtime::Table<D>,
    points: &adwi_samples::SampleSet,
    answers: &[([f64; 3], [f64; 3], [f64; 3])],
) -> Vec<(adwi_runtime::Correction, adwi_runtime::Correction)> {
    let mut out = Vec::new();
    for (i, (served, exact, rotation)) in answers.iter().enumerate() {
        let q = points.joints_rad(i).unwrap();
        let target = adwi_runtime::Target::at(points.nominal_mm[i]);
        let s = table.query_with_joints(&target, q);
        let e = table.exact().query_with_joints(&target, q);
        let close = |got: f64, want: f64| (got - want).abs() < 1e-9;
        // The recorded rotation is the model's; the UR5's samples measured position
        // alone, which does not determine it, and neither tier serves it.
        let model_rotation = table.model().unwrap().error(q).unwrap().1;
        for a in 0..3 {
            assert!(close(s.position_error_mm[a], served[a]), "pose {i}: {s:?}");
            assert!(close(e.position_error_mm[a], exact[a]), "pose {i}: {e:?}");
            assert!(
                close(model_rotation[a], rotation[a]),
                "pose {i}: {model_rotation:?}"
            );
        }
        assert_eq!(s.orientation_error_rad, [0.0; 3], "pose {i}");
        assert_eq!(e.orientation_error_rad, [0.0; 3], "pose {i}");
        out.push((s, e));
    }
    out
}

/// The UR5 grid measurements shipped in `tables/ur5/measurements` (the samples).
pub fn ur5_grid() -> std::path::PathBuf {
    repo("tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv")
}

/// `tablec build -q` of a hybrid table `out` from the UR5 grid with `robot`, and `extra`
/// arguments, in `dir`; it must succeed. Its standard error (the notes `-q` keeps).
pub fn build_ur5_hybrid(dir: &std::path::Path, robot: &str, extra: &[&str], out: &str) -> String {
    let grid = ur5_grid();
    let mut args = vec![
        "build",
        "-q",
        grid.to_str().unwrap(),
        "--columns",
        UR5_MAP,
        "--robot",
        robot,
        "--hybrid",
    ];
    // The method's own served field, no posture term, the whole residual field and no
    // joint-space terms unless asked otherwise: the tests that use this table check its
    // figures, not the choices a default build makes (tests of their own).
    if !extra.contains(&"--served-field") {
        args.extend(["--served-field", "method"]);
    }
    if !extra.contains(&"--posture") {
        args.extend(["--posture", "off"]);
    }
    if !extra.contains(&"--residual-weight") {
        args.extend(["--residual-weight", "full"]);
    }
    if !extra.contains(&"--harmonics") {
        args.extend(["--harmonics", "0"]);
    }
    args.extend_from_slice(extra);
    args.extend(["-o", out]);
    let o = tablec(&args, dir);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    stderr
}

/// A path in the repository.
pub fn repo(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The bytes of a hybrid table of `samples` with `model`, as `tablec build --hybrid` writes
/// them with `options`.
pub fn hybrid_table_bytes(
    samples: &adwi_samples::SampleSet,
    model: &adwi_runtime::model::PreparedModel,
    options: &adwi_compile::build::BuildOptions,
) -> Vec<u8> {
    let plan = adwi_compile::build::plan(samples, options).unwrap();
    adwi_compile::hybrid::compile(samples, model, &plan, &|_| {})
        .unwrap()
        .bytes
}

/// `tablec build` of `samples` into `dir/out`, serving the method's own field (what the
/// program tests check is the programs' arithmetic, not the field's choice); it must
/// succeed.
pub fn method_table(
    dir: &std::path::Path,
    samples: &std::path::Path,
    out: &str,
) -> std::path::PathBuf {
    let o = tablec(
        &[
            "build",
            "-q",
            samples.to_str().unwrap(),
            "--served-field",
            "method",
            "-o",
            out,
        ],
        dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join(out)
}

/// The KR150-2 hybrid table built in `dir` as `kr150-hybrid.tbl`: the robot file's
/// kinematics with the model calibrated on the shipped samples (all in one wrist branch,
/// J4 near 0°, J5 < 0), the method's field and no posture term, so that its answer depends
/// on the posture a program writes. Built once per test process ([`tablec_once`]).
pub fn kr150_hybrid_table(dir: &std::path::Path) -> std::path::PathBuf {
    kr150_hybrid_table_with(dir, 0)
}

/// [`kr150_hybrid_table`] with the model's joint-space terms up to `harmonics` (0 none),
/// held at their ends beyond the joint angles the samples cover (J4 near 0°): built in
/// `dir` as `kr150-hybrid.tbl`, or `kr150-hybrid-h{harmonics}.tbl` with terms.
pub fn kr150_hybrid_table_with(dir: &std::path::Path, harmonics: u8) -> std::path::PathBuf {
    let samples = repo("tables/kr150-2/samples.csv");
    let robot = repo("tables/kr150-2/robot.toml");
    let out = if harmonics == 0 {
        "kr150-hybrid.tbl".to_string()
    } else {
        format!("kr150-hybrid-h{harmonics}.tbl")
    };
    let harmonics = harmonics.to_string();
    let mut args = vec![
        "build",
        "-q",
        samples.to_str().unwrap(),
        "--robot",
        robot.to_str().unwrap(),
        "--hybrid",
        "--served-field",
        "method",
        "--posture",
        "off",
    ];
    args.extend(["--harmonics", harmonics.as_str()]);
    args.extend(["-o", out.as_str()]);
    let o = tablec_once(&args, dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join(out)
}

/// `tablec compensate` with `args`: exit code, standard output and error.
pub fn compensate(dir: &std::path::Path, args: &[&str]) -> (i32, String, String) {
    let mut all = vec!["compensate"];
    all.extend_from_slice(args);
    let o = tablec(&all, dir);
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The predicted error `tablec query` prints for one target: its `error dx dy dz` line's
/// three numbers, mm.
pub fn printed_error(stdout: &str) -> [f64; 3] {
    let values: Vec<f64> = stdout
        .lines()
        .find_map(|l| l.strip_prefix("error"))
        .expect("an error line")
        .split_whitespace()
        .take(3)
        .map(|v| v.parse().expect("a number"))
        .collect();
    values.try_into().expect("three numbers")
}

/// A compensation report's rows as (the column `key`, status, detail): `key` 0 the name,
/// 1 the line.
pub fn report_rows(path: &std::path::Path, key: usize) -> Vec<(String, String, String)> {
    csv::Reader::from_path(path)
        .unwrap()
        .records()
        .map(|r| {
            let r = r.unwrap();
            (r[key].to_string(), r[4].to_string(), r[5].to_string())
        })
        .collect()
}

/// How many targets a `tablec compensate` text report prints as corrected: lines whose
/// status, the last column before any detail, is `ok` (with a hybrid table's residual
/// flag where it is not `full`: `ok, model_only`).
pub fn corrected_lines(stdout: &str) -> usize {
    stdout
        .lines()
        .filter(|l| l.ends_with("  ok") || l.contains("  ok (") || l.contains("  ok, "))
        .count()
}
