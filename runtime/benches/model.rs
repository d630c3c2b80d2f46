//! Where a hybrid table's query spends its time in the model part, piece by piece, for a
//! UR5 (Universal Robots' published geometry and link masses, `tables/ur5/robot.toml`) with
//! a calibrated chain that differs by a few tenths of a millimetre and milliradian and has
//! gravity compliance:
//!
//! - `model/sin_cos`: the sines and cosines of six joint angles by the library's `sin_cos`,
//!   the floor of any forward kinematics; `model/trig_sin_cos_each`: the same by
//!   [`adwi_runtime::trig::sin_cos_each`], the query path's;
//! - `model/nominal_tcp_pose`, `model/loaded_tcp_pose`: one chain's forward kinematics, joint
//!   by joint, without and with its gravity deflection (a second pass);
//! - `model/at_by_chains`: the model part as the two chains compute it (the reference);
//! - `model/at`: the model part with the orientation error, as a query of a table with
//!   orientations computes it (chains folded at open, shared `sin_cos`);
//! - `model/at_position`: the model part without the orientation error and with a
//!   calibrated chain without compliance, as a query of the UR5 table built from the
//!   shipped measurements computes it (both chains walked together from the tool back);
//! - `model/at_rigid`: the same chains with the orientation error, as every query of that
//!   table computes them (both TCP frames, point and two axes, in one walk);
//! - `model/at_terms`: the same with joint-space terms (first harmonics) on the calibrated
//!   chain, as a table built with `--harmonics 1` computes it (the calibrated lane at `q'`).
//!
//! Run: `cargo bench -p adwi-runtime --bench model`. Under `cargo test` it runs once in
//! criterion's test mode.

use std::hint::black_box;

use adwi_runtime::chain::{Chain, Compliance};
use adwi_runtime::joint_terms::JointTerms;
use adwi_runtime::kinematics::{MdhJoint, Transform};
use adwi_runtime::model::PreparedModel;
use adwi_runtime::testing::model_at_by_chains;
use criterion::{criterion_group, criterion_main, Criterion};

/// The UR5 of `tables/ur5/robot.toml`: MD-H rows (a, d mm; α deg), link masses (kg) and
/// centres of mass (mm).
const UR5: [(f64, f64, f64, f64, [f64; 3]); 6] = [
    (0.0, 89.159, 90.0, 3.7, [0.0, -25.61, 1.93]),
    (-425.0, 0.0, 0.0, 8.393, [212.5, 0.0, 113.36]),
    (-392.25, 0.0, 0.0, 2.33, [150.0, 0.0, 26.5]),
    (0.0, 109.15, 90.0, 1.219, [0.0, -1.8, 16.34]),
    (0.0, 94.65, -90.0, 1.219, [0.0, 1.8, 16.34]),
    (0.0, 82.3, 0.0, 0.1879, [0.0, 0.0, -1.159]),
];

fn ur5(perturbation: f64, compliance_per_unit: f64) -> Chain {
    let rows = UR5.map(|(a_mm, d_mm, alpha_deg, _, _)| MdhJoint {
        a_mm: a_mm + 0.3 * perturbation,
        d_mm: d_mm - 0.2 * perturbation,
        alpha_rad: alpha_deg.to_radians() + 4e-4 * perturbation,
        beta_rad: 2e-4 * perturbation,
        theta_offset_rad: -3e-4 * perturbation,
    });
    let tool = Transform {
        translation_mm: [0.0, 0.09, 31.0],
        ..Transform::IDENTITY
    };
    let compliance = (compliance_per_unit > 0.0).then(|| {
        let mut c = Compliance::NONE;
        for (j, (_, _, _, mass_kg, com_mm)) in UR5.iter().enumerate() {
            c.link_mass_kg[j] = *mass_kg;
            c.link_com_mm[j] = *com_mm;
            c.compliance[j] = compliance_per_unit;
        }
        c
    });
    Chain::from_mdh(Transform::IDENTITY, &rows, tool, compliance).expect("a valid chain")
}

fn bench(c: &mut Criterion) {
    let nominal = ur5(0.0, 0.0);
    // 5 µrad/(N·m): 5e-12 rad per kg·mm²/s².
    let calibrated = ur5(1.0, 5e-12);
    let model = PreparedModel::new(nominal, calibrated).expect("equal joint counts");
    // Joint poses spread over the whole range, as `tablec bench`'s random workload.
    let poses: Vec<[f64; 6]> = (0..1024)
        .map(|i| [0.7, -1.3, 2.1, -0.4, 1.7, 0.9].map(|v: f64| (v * (i as f64 + 1.0)).sin() * 3.0))
        .collect();
    let mut group = c.benchmark_group("model");
    let mut i = 0;
    let mut next = || {
        i = (i + 1) % poses.len();
        &poses[i]
    };
    group.bench_function("sin_cos", |b| {
        b.iter(|| black_box(next()).map(f64::sin_cos))
    });
    group.bench_function("trig_sin_cos_each", |b| {
        b.iter(|| {
            let mut out = [(0.0, 1.0); 6];
            adwi_runtime::trig::sin_cos_each(black_box(next()), &mut out);
            out
        })
    });
    group.bench_function("nominal_tcp_pose", |b| {
        b.iter(|| model.nominal().tcp_pose(black_box(next())))
    });
    group.bench_function("loaded_tcp_pose", |b| {
        b.iter(|| model.calibrated().loaded_tcp_pose(black_box(next())))
    });
    group.bench_function("at_by_chains", |b| {
        b.iter(|| model_at_by_chains(&model, black_box(next())))
    });
    group.bench_function("at", |b| b.iter(|| model.at(black_box(next()))));
    // The shipped UR5 table's case: a calibrated chain without compliance, no orientations.
    let rigid = PreparedModel::new(nominal, ur5(1.0, 0.0)).expect("equal joint counts");
    group.bench_function("at_position", |b| {
        b.iter(|| rigid.at_position(black_box(next())))
    });
    // The same chains with the orientation error, as every hybrid query of that table
    // computes them (both TCP frames in one walk from the tool back).
    group.bench_function("at_rigid", |b| b.iter(|| rigid.at(black_box(next()))));
    // The same with first harmonics on every joint (a UR5 table built with `--harmonics
    // 1`): the calibrated chain at `q'`, walked beside the nominal one.
    let mut terms = JointTerms::NONE;
    for (j, c) in terms.coefficients_rad.iter_mut().take(6).enumerate() {
        *c = [
            4e-4 * (j as f64 + 1.0).sin(),
            6e-4 * (j as f64).cos(),
            0.0,
            0.0,
        ];
    }
    let harmonic = rigid
        .with_joint_terms(terms)
        .expect("first harmonics of revolute joints");
    group.bench_function("at_terms", |b| b.iter(|| harmonic.at(black_box(next()))));
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
