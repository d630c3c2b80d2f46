//! Samples too many for a table's size bound: a tracked path's samples merged in voxels
//! (`adwi_compile::build::merge`), the voxel recorded in the header, the bound kept and the
//! table's size predicted before the build, at a size a test affords (a path of 10,000
//! samples and a bound of a few megabytes stand in for 10⁶ samples and 64 MB).

use adwi_compile::build::{compile, plan, predicted_table_bytes, BuildError, BuildOptions};
use adwi_runtime::{Status, Table};
use adwi_samples::{parse_samples, ColumnMap, SampleSet};

/// A helix of `n` samples 0.1 mm apart (a tracker following the tool at 100 mm/s, at
/// 1 kHz), radius 50 mm, rising 20 mm a turn, with smooth errors and orientation errors.
fn tracked_path(n: usize) -> SampleSet {
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    for i in 0..n {
        let t = 0.1 * i as f64 / 50.0;
        let p = [
            1500.0 + 50.0 * t.cos(),
            400.0 + 50.0 * t.sin(),
            1000.0 + 20.0 * t / std::f64::consts::TAU,
        ];
        let e = [
            0.5 + 1e-3 * (p[0] - 1500.0),
            -0.3 + 2e-3 * (p[1] - 400.0),
            0.1 * (p[2] / 100.0).sin(),
        ];
        csv += &format!(
            "{},{},{},{},{},{},{},0,{}\n",
            p[0],
            p[1],
            p[2],
            e[0],
            e[1],
            e[2],
            1e-6 * (p[0] - 1500.0),
            1e-6 * (p[2] - 1000.0)
        );
    }
    parse_samples("path.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap()
}

fn bytes_of(samples: &SampleSet, options: &BuildOptions) -> Result<Vec<u8>, BuildError> {
    compile(samples, options, &|_| {}).map(|(bytes, _)| bytes)
}

#[test]
fn samples_too_many_for_the_bound_are_merged_within_it_and_the_voxel_recorded() {
    let s = tracked_path(10_000);
    let bound = 2_000_000;
    let bounded = BuildOptions {
        max_table_bytes: Some(bound),
        ..BuildOptions::default()
    };
    let plan = plan(&s, &bounded).unwrap();
    let merge = plan.merge.expect("merged");
    assert_eq!(merge.measured, 10_000);
    assert!(merge.merged < 10_000 && merge.voxel_mm < plan.grid.cell_mm);
    // Every sample kept, on the same grid: beyond the bound.
    let kept = BuildOptions {
        merge_voxel_mm: Some(0.0),
        cell_mm: Some(plan.grid.cell_mm),
        ..BuildOptions::default()
    };
    let all = bytes_of(&s, &kept).unwrap();
    assert!(all.len() as u128 > bound, "{} bytes", all.len());
    let (bytes, report) = compile(&s, &bounded, &|_| {}).unwrap();
    assert!(bytes.len() as u128 <= bound, "{} bytes", bytes.len());
    // Predicted before any work, within a few per cent.
    let merged = adwi_compile::build::merge::merge(&s, merge.voxel_mm);
    let predicted =
        predicted_table_bytes(&merged, &plan.params, &plan.grid, plan.node_bytes, false);
    let error = (predicted as f64 - bytes.len() as f64).abs() / bytes.len() as f64;
    assert!(error < 0.05, "predicted {predicted}, built {}", bytes.len());
    assert_eq!(report.plan.merge, Some(merge));
    let table = Table::from_vec(&bytes).unwrap();
    let h = table.header();
    assert_eq!(h.merge_voxel_mm, Some(merge.voxel_mm));
    assert_eq!(h.version, 4);
    assert_eq!(h.sample_count as usize, merge.merged);
    assert_eq!(
        f32::from_le_bytes(bytes[244..248].try_into().unwrap()) as f64,
        merge.voxel_mm
    );
    // Both tiers still answer on the path, near what every sample answers.
    let full = Table::from_vec(&all).unwrap();
    for i in (0..10_000).step_by(97) {
        let p = s.nominal_mm[i];
        for (a, b) in [
            (table.query(p), full.query(p)),
            (table.exact().query(p), full.exact().query(p)),
        ] {
            assert_eq!(a.status, b.status, "at {p:?}");
            if b.status != Status::Ok {
                continue;
            }
            for axis in 0..3 {
                let d = a.position_error_mm[axis] - b.position_error_mm[axis];
                assert!(d.abs() < 0.01, "at {p:?}: {a:?} against {b:?}");
            }
        }
    }
}

#[test]
fn a_merged_table_is_the_same_at_any_thread_count() {
    let s = tracked_path(10_000);
    let options = BuildOptions {
        max_table_bytes: Some(2_000_000),
        ..BuildOptions::default()
    };
    let with = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| bytes_of(&s, &options).unwrap())
    };
    let one = with(1);
    assert!(Table::from_vec(&one)
        .unwrap()
        .header()
        .merge_voxel_mm
        .is_some());
    assert_eq!(one, with(2));
    assert_eq!(one, with(3));
}

#[test]
fn a_bound_that_cannot_be_kept_is_refused_before_any_work() {
    // 10,000 samples a spacing apart (a lattice): merging below a quarter of the spacing
    // merges none, and 10,000 samples take more than 100 kB whatever the cell.
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for i in 0..10_000 {
        let p = [i % 25, (i / 25) % 20, i / 500].map(|v| 1000.0 + 10.0 * f64::from(v));
        csv += &format!("{},{},{},0.1,0.2,0.3\n", p[0], p[1], p[2]);
    }
    let s = parse_samples("l.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    let options = BuildOptions {
        max_table_bytes: Some(100_000),
        ..BuildOptions::default()
    };
    let started = std::time::Instant::now();
    let err = plan(&s, &options).unwrap_err();
    assert!(matches!(err, BuildError::TableBound { .. }), "{err}");
    assert!(err.to_string().contains("100.0 kB"), "{err}");
    // The figure a bound must exceed: the lattice's samples, none merged, and their bytes.
    let BuildError::TableBound {
        merged,
        merged_bytes,
        ..
    } = err
    else {
        unreachable!()
    };
    assert_eq!(merged, 10_000);
    assert!(err.to_string().contains("they are 10000 samples"), "{err}");
    assert!(merged_bytes > 500_000, "{merged_bytes}");
    assert!(
        started.elapsed().as_secs_f64() < 1.0,
        "{:?}",
        started.elapsed()
    );
    // Without a bound given, such samples are kept, as before.
    assert_eq!(plan(&s, &BuildOptions::default()).unwrap().merge, None);
}

#[test]
fn tables_within_the_bound_are_built_as_before() {
    // The path's samples fit 64 MB: no merge, the same bytes as a build told not to merge,
    // a version-2 table.
    let s = tracked_path(10_000);
    let default = bytes_of(&s, &BuildOptions::default()).unwrap();
    let kept = BuildOptions {
        merge_voxel_mm: Some(0.0),
        ..BuildOptions::default()
    };
    assert_eq!(default, bytes_of(&s, &kept).unwrap());
    let table = Table::from_vec(&default).unwrap();
    assert_eq!(table.header().merge_voxel_mm, None);
    assert_eq!(table.header().version, 2);
}

#[test]
fn a_merge_voxel_out_of_range_is_refused_as_an_option() {
    for voxel_mm in [-1.0, f64::NAN, f64::INFINITY, 1e-9, 2e6] {
        let options = BuildOptions {
            merge_voxel_mm: Some(voxel_mm),
            ..BuildOptions::default()
        };
        let err = adwi_compile::build::check_options(&options).unwrap_err();
        assert!(matches!(err, BuildError::Params(_)), "{voxel_mm}: {err}");
    }
    let options = BuildOptions {
        max_table_bytes: Some(0),
        ..BuildOptions::default()
    };
    assert!(adwi_compile::build::check_options(&options).is_err());
}

/// An evaluation of samples too many for the bound scores each held-out point with the
/// merged table a build of that fold's training samples makes (the held-out points in none
/// of its voxel averages), to the bit; and `idw` from that fold's training samples alone.
#[test]
fn each_fold_is_scored_with_the_merged_table_its_training_samples_build() {
    use adwi_eval::baselines::{k_fold_splits, Idw, IdwParams};
    use adwi_eval::{evaluate, EvalOptions, Method, Protocol};
    use adwi_runtime::{Target, Tier};
    let s = tracked_path(10_000);
    let bound = 1_500_000;
    let build = BuildOptions {
        max_table_bytes: Some(bound),
        ..BuildOptions::default()
    };
    let options = EvalOptions {
        methods: Some(vec![Method::Paper, Method::Idw]),
        build: build.clone(),
        ..EvalOptions::default()
    };
    let evaluation = evaluate(&s, &Protocol::KFold { folds: 5, seed: 4 }, &options).unwrap();
    let paper = evaluation.method(Method::Paper).unwrap();
    let idw = evaluation.method(Method::Idw).unwrap();
    let mut scored = 0;
    for fold in k_fold_splits(s.len(), 5, 4).unwrap() {
        let train = s.subset(&fold.train);
        let merge = plan(&train, &build)
            .unwrap()
            .merge
            .expect("a fold's samples merged");
        assert!(merge.merged < train.len());
        let bytes = bytes_of(&train, &build).unwrap();
        assert!(bytes.len() as u128 <= bound, "{} bytes", bytes.len());
        let table = Table::from_vec(&bytes).unwrap();
        assert_eq!(table.sample_count(), merge.merged);
        let reference = Idw::new(&train.nominal_mm, &train.error_mm, IdwParams::default()).unwrap();
        for &i in &fold.test {
            let target = Target {
                position_mm: s.nominal_mm[i],
                config: None,
                rotation_rad: None,
                tcp_mm: None,
            };
            let answer = table.answer(&target, None, Tier::Exact);
            match &paper.predictions[i] {
                Some(p) => {
                    assert_eq!(answer.status, Status::Ok);
                    assert_eq!(p.position_error_mm, answer.position_error_mm, "point {i}");
                    scored += 1;
                }
                None => assert_ne!(answer.status, Status::Ok),
            }
            let want = reference.predict(s.nominal_mm[i]).unwrap();
            let got = idw.predictions[i].as_ref().unwrap().position_error_mm;
            assert_eq!(got, want, "point {i}");
        }
    }
    assert!(scored > 9_000, "{scored} of 10,000 held-out points scored");
}
