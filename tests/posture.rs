//! The posture term of a hybrid table ([`adwi_runtime::posture`]): the served answer's
//! fast path (cell lists) equal to the definition over every sample, continuous along
//! joint paths, absent from the exact tier, and a table without it byte-identical to a
//! build that knows nothing of it.

use std::sync::OnceLock;

use adwi_compile::build::BuildOptions;
use adwi_compile::posture::Posture;
use adwi_runtime::posture::{self, PostureParams};
use adwi_runtime::{Status, Table, Target};
use proptest::prelude::*;

use crate::common;

/// Supports that overlap several samples of the KR150-2 set (200 mm apart) and its
/// joint-space spread, so that the term is neither zero nor one sample's.
const PARAMS: PostureParams = PostureParams {
    radius_mm: 300.0,
    length_rad: 0.6,
    floor: 0.3,
};

struct Fixture {
    samples: adwi_samples::SampleSet,
    /// Built without the term (version 4: the samples' orientations recorded).
    without: Vec<u8>,
    /// The same build with the term of [`PARAMS`] (version 4 with the term).
    with: Vec<u8>,
}

fn options(posture: Posture) -> BuildOptions {
    BuildOptions {
        cell_mm: Some(100.0),
        posture,
        ..BuildOptions::default()
    }
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let (_, samples, calibration) = common::kr150_calibration();
        let model = calibration.prepared_model();
        let without = common::hybrid_table_bytes(&samples, &model, &options(Posture::Off));
        let with = common::hybrid_table_bytes(&samples, &model, &options(Posture::Given(PARAMS)));
        Fixture {
            samples,
            without,
            with,
        }
    })
}

/// The posture term by its definition, from the values the table stores.
fn reference_term(table: &Table<adwi_runtime::AlignedBytes>, p: [f64; 3], q: &[f64]) -> [f64; 3] {
    let record = table.posture_record().unwrap();
    let positions: Vec<[f64; 3]> = record
        .positions_mm
        .iter()
        .map(|x| x.map(|v| v.to_native()))
        .collect();
    let residuals: Vec<[f64; 3]> = record
        .residuals_mm
        .iter()
        .map(|x| x.map(|v| v.to_native()))
        .collect();
    let joints: Vec<f64> = record.joints_rad.iter().map(|v| v.to_native()).collect();
    posture::reference(
        &table.posture().unwrap(),
        table.grid(),
        &positions,
        &joints,
        &residuals,
        p,
        q,
    )
}

/// A pose near sample `s`: its joints moved by `dq_rad` (joint `j` by `dq_rad · (j + 1) /
/// 6`), and the target where the nominal chain puts the tool there.
fn pose_near(
    table: &Table<adwi_runtime::AlignedBytes>,
    s: usize,
    dq_rad: f64,
) -> ([f64; 3], Vec<f64>) {
    let samples = &fixture().samples;
    let q: Vec<f64> = (samples.joints.as_ref().unwrap().row(s).iter().enumerate())
        .map(|(j, v)| v + dq_rad * (j + 1) as f64 / 6.0)
        .collect();
    let p = table.model().unwrap().at(&q).unwrap().nominal_tcp_mm;
    (p, q)
}

#[test]
fn a_table_with_the_term_holds_it_and_one_without_is_the_same_table_without() {
    let f = fixture();
    let without = Table::from_vec(&f.without).unwrap();
    let with = Table::from_vec(&f.with).unwrap();
    // Both are hybrid tables (version 6); the posture term in one alone.
    assert_eq!((without.header().version, with.header().version), (6, 6));
    assert!(!without.header().has_posture() && with.header().has_posture());
    assert!(without.posture().is_none());
    assert_eq!(with.posture(), Some(PARAMS));
    // The term off writes what a build without the option writes, byte for byte.
    let (_, samples, calibration) = common::kr150_calibration();
    let plain = BuildOptions {
        cell_mm: Some(100.0),
        ..BuildOptions::default()
    };
    let again = common::hybrid_table_bytes(&samples, &calibration.prepared_model(), &plain);
    assert!(again == f.without, "the term off changed the bytes");
}

#[test]
fn the_exact_tier_does_not_add_the_term() {
    let f = fixture();
    let without = Table::from_vec(&f.without).unwrap();
    let with = Table::from_vec(&f.with).unwrap();
    for s in 0..f.samples.len() {
        let (p, q) = pose_near(&with, s, 0.01);
        let a = without.exact().query_with_joints(&Target::at(p), &q);
        let b = with.exact().query_with_joints(&Target::at(p), &q);
        assert_eq!(a, b, "sample {s}");
    }
}

#[test]
fn the_term_is_nonzero_and_fades_to_zero_far_from_the_samples_postures() {
    let f = fixture();
    let without = Table::from_vec(&f.without).unwrap();
    let with = Table::from_vec(&f.with).unwrap();
    let term = |p: [f64; 3], q: &[f64]| {
        let a = without.query_with_joints(&Target::at(p), q);
        let b = with.query_with_joints(&Target::at(p), q);
        assert_eq!((a.status, b.status), (Status::Ok, Status::Ok));
        [0, 1, 2].map(|i| b.position_error_mm[i] - a.position_error_mm[i])
    };
    let (p, q) = pose_near(&with, 10, 0.0);
    assert!(
        term(p, &q).iter().any(|v| v.abs() > 1e-4),
        "{:?}",
        term(p, &q)
    );
    // Every joint a radian away from every sample's: beyond ℓ_q of all of them.
    let (p, q) = pose_near(&with, 10, 3.0);
    if without.query_with_joints(&Target::at(p), &q).status == Status::Ok {
        assert_eq!(term(p, &q), [0.0; 3]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The served answer with the term minus the one without is the term by its
    /// definition over every sample, to 1e-12 mm, anywhere near the samples' poses.
    #[test]
    fn the_fast_path_equals_the_reference(
        s in 0usize..1000,
        dq_rad in -0.5f64..0.5,
        offset in prop::array::uniform3(-40.0f64..40.0),
    ) {
        let f = fixture();
        let without = Table::from_vec(&f.without).unwrap();
        let with = Table::from_vec(&f.with).unwrap();
        let s = s % f.samples.len();
        let (p, q) = pose_near(&with, s, dq_rad);
        // The target a little off the joints' TCP (within the joints' tolerance).
        let p = [0, 1, 2].map(|a| p[a] + offset[a] * 0.25);
        let a = without.query_with_joints(&Target::at(p), &q);
        let b = with.query_with_joints(&Target::at(p), &q);
        prop_assert_eq!(a.status, b.status);
        if a.status == Status::Ok {
            // The term is the residual's: it fades with it beyond the samples' joints.
            let scale = crate::common::reference_residual_scale(
                f.samples.joints.as_ref().unwrap(),
                &q,
            );
            let expected = reference_term(&with, p, &q).map(|v| scale * v);
            for ((b, a), expected) in b.position_error_mm.iter().zip(a.position_error_mm).zip(expected) {
                let got = b - a;
                prop_assert!((got - expected).abs() <= 1e-12, "{} vs {}", got, expected);
            }
            prop_assert_eq!(a.orientation_error_rad, b.orientation_error_rad);
        }
    }
}

/// Along straight joint paths between random poses near the samples, the term changes by
/// at most 1 µm per step of 1e-4 rad (each joint), wherever the path crosses posture
/// cells or supports' edges.
#[test]
fn the_term_is_continuous_along_joint_paths() {
    let f = fixture();
    let without = Table::from_vec(&f.without).unwrap();
    let with = Table::from_vec(&f.with).unwrap();
    let mut rng = common::SplitMix(7);
    let joints = f.samples.joints.as_ref().unwrap();
    let mut worst_mm: f64 = 0.0;
    let mut steps = 0;
    for _ in 0..20 {
        let s = (rng.next_u64() % f.samples.len() as u64) as usize;
        let from: Vec<f64> = joints.row(s).to_vec();
        let direction: Vec<f64> = from.iter().map(|_| rng.uniform(-1.0, 1.0)).collect();
        let norm = direction.iter().map(|v| v * v).sum::<f64>().sqrt();
        let step_rad = 1e-4;
        let mut previous: Option<[f64; 3]> = None;
        for k in 0..3000 {
            let q: Vec<f64> = (from.iter().zip(&direction))
                .map(|(a, d)| a + d / norm * step_rad * k as f64)
                .collect();
            let Some(at) = with.model().unwrap().at(&q) else {
                break;
            };
            let target = Target::at(at.nominal_tcp_mm);
            let (a, b) = (
                without.query_with_joints(&target, &q),
                with.query_with_joints(&target, &q),
            );
            if a.status != Status::Ok || b.status != Status::Ok {
                previous = None;
                continue;
            }
            let term = [0, 1, 2].map(|i| b.position_error_mm[i] - a.position_error_mm[i]);
            if let Some(prev) = previous {
                let jump = adwi_runtime::method::distance_mm(prev, term);
                worst_mm = worst_mm.max(jump);
                steps += 1;
            }
            previous = Some(term);
        }
    }
    assert!(steps > 10_000, "only {steps} steps answered");
    assert!(worst_mm <= 1e-3, "the term moved {worst_mm} mm in one step");
}

/// The same samples and options give the same bytes with one worker thread or two, the
/// term fitted by leave-one-out.
#[test]
fn a_fitted_term_is_byte_identical_at_one_and_two_threads() {
    let (_, samples, calibration) = common::kr150_calibration();
    let model = calibration.prepared_model();
    let build = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| common::hybrid_table_bytes(&samples, &model, &options(Posture::Fit)))
    };
    let one = build(1);
    assert!(Table::from_vec(&one).unwrap().header().has_posture());
    assert!(one == build(2), "the bytes depend on the thread count");
}

/// `tablec eval` with the term left to `auto` (the default) decides it on each split's
/// training samples alone, by the build's own decision: every fold's verdict and figures in
/// the JSON are what `default_choices` (what `tablec build` runs) finds on that fold's
/// training samples. A third of the KR150-2 samples keeps the folds' cross-validations
/// short.
#[test]
fn eval_decides_the_term_on_each_splits_training_samples_as_a_build_does() {
    use adwi_compile::build::ServedField;
    use adwi_identify::calibrate::CalibrateOptions;
    use adwi_jobs::{ServedFieldChoice, TableArgs};
    use adwi_robot::model::shipped_robot_path;

    let dir = tempfile::tempdir().unwrap();
    let robot_path = shipped_robot_path("kr150-2");
    let text = std::fs::read_to_string(robot_path.parent().unwrap().join("samples.csv")).unwrap();
    let mut kept = String::new();
    let mut rows = 0;
    for line in text.lines() {
        let data =
            !line.starts_with('#') && line.starts_with(|c: char| c == '-' || c.is_ascii_digit());
        if data {
            rows += 1;
            if rows % 3 != 1 {
                continue;
            }
        }
        kept.push_str(line);
        kept.push('\n');
    }
    let samples_path = dir.path().join("samples.csv");
    std::fs::write(&samples_path, kept).unwrap();
    let folds = 2;
    let out = common::tablec(
        &[
            "eval",
            "samples.csv",
            "--robot",
            robot_path.to_str().unwrap(),
            "--harmonics",
            "0",
            "--folds",
            &folds.to_string(),
            "--methods",
            "hybrid-trilinear",
            "--served-field",
            "method",
            "--json",
            "eval.json",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("posture term decided on each split's training samples"),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("eval.json")).unwrap())
            .unwrap();
    let choices = json["split_choices"].as_array().unwrap();
    assert_eq!(choices.len(), folds);

    let robot = adwi_robot::Robot::load(&robot_path).unwrap();
    let samples =
        adwi_samples::read_samples(&samples_path, &adwi_samples::ColumnMap::default()).unwrap();
    let options = TableArgs {
        served_field: ServedFieldChoice::Given(ServedField::Method),
        ..TableArgs::default()
    }
    .build_options(ServedField::Method);
    // The build's own decision of the posture term on `train` (the method's served field).
    let decide = |train: &adwi_samples::SampleSet| {
        let ask = adwi_jobs::choice::Ask {
            posture: true,
            ..Default::default()
        };
        adwi_jobs::choice::default_choices(
            train,
            Some(&robot),
            &options,
            &CalibrateOptions::default(),
            ask,
        )
        .unwrap()
        .posture
        .unwrap()
    };
    let splits = adwi_eval::baselines::k_fold_splits(samples.len(), folds, 0).unwrap();
    for (split, (fold, choice)) in splits.iter().zip(choices).enumerate() {
        assert_eq!(choice["split"], split);
        assert_eq!(choice["method"], "hybrid-trilinear");
        assert_eq!(choice["served_field"], "method");
        let decided = decide(&samples.subset(&fold.train));
        let posture = &choice["posture"];
        assert_eq!(posture["on"], decided.chosen, "fold {split}");
        assert_eq!(
            posture["without_mm"].as_f64(),
            decided.without_mm,
            "fold {split}"
        );
        assert_eq!(posture["with_mm"].as_f64(), decided.with_mm, "fold {split}");
    }
    // Held-out points never take part: the folds' figures differ from one another and
    // from what the decision on every sample finds.
    let all = decide(&samples);
    for choice in choices {
        assert_ne!(choice["posture"]["with_mm"].as_f64(), all.with_mm);
    }
}
