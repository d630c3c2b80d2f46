//! The compiled table's answer equals the brute-force reference's, for random sample
//! clouds, random parameters and targets chosen where a cell table is most likely to go
//! wrong: inside cells, on cell faces and corners, exactly on samples, and collinear with a
//! sample through the base origin.

use crate::common;

use adwi_compile::build::{compile, BuildOptions};
use adwi_compile::reference;
use adwi_runtime::method::MethodParams;
use adwi_runtime::{Status, Table, Target};
use adwi_samples::SampleSet;
use proptest::prelude::*;

#[derive(Debug, Clone)]
struct Case {
    samples: SampleSet,
    options: BuildOptions,
    targets: Vec<Target>,
}

fn cloud() -> impl Strategy<Value = SampleSet> {
    // A lattice with noise, or a uniform random cloud, around a point 1-2 m from the base.
    let lattice = (2usize..5, 20.0..80.0f64, 0.0..0.3f64);
    let n = 3usize..40;
    (
        prop_oneof![lattice.prop_map(Some), Just(None)],
        n,
        prop::array::uniform3(-1500.0..1500.0f64),
        prop::collection::vec(prop::array::uniform3(-1.0..1.0f64), 200),
        prop::collection::vec(prop::array::uniform3(-2.0..2.0f64), 200),
        prop::option::of(prop::collection::vec(0u8..3, 200)),
    )
        .prop_map(|(lattice, n, centre, unit, errors, configs)| {
            let mut nominal = Vec::new();
            match lattice {
                Some((side, step, noise)) => {
                    for (i, u) in unit.iter().enumerate().take(side * side * side) {
                        let ijk = [i % side, (i / side) % side, i / (side * side)];
                        nominal.push(
                            [0, 1, 2]
                                .map(|a| centre[a] + ijk[a] as f64 * step + noise * step * u[a]),
                        );
                    }
                }
                None => {
                    for u in unit.iter().take(n) {
                        nominal.push([0, 1, 2].map(|a| centre[a] + 150.0 * u[a]));
                    }
                }
            }
            let len = nominal.len();
            SampleSet {
                error_mm: errors[..len].to_vec(),
                rotation_error_rad: Some(
                    errors[..len].iter().map(|e| e.map(|v| v * 1e-4)).collect(),
                ),
                config: configs.map(|c| c[..len].to_vec()),
                lines: (2..2 + len as u64).collect(),
                nominal_mm: nominal,
                ..SampleSet::default()
            }
        })
}

fn options() -> impl Strategy<Value = BuildOptions> {
    (
        1u32..10,
        prop_oneof![Just(0.0), Just(0.5), Just(1.0), Just(2.0)],
        0.0..1.0f64,
        any::<bool>(),
        prop_oneof![3 => Just((0.0, 0.0)), 1 => (0.0..2e-3f64, 0.0..1e-4f64)],
        prop_oneof![Just(None), (30.0..200.0f64).prop_map(Some)],
    )
        .prop_map(
            |(k, power, w1, screen, (lambda, zeta), radius)| BuildOptions {
                method: MethodParams {
                    radius_mm: radius,
                    max_neighbours: k,
                    w1,
                    w2: 1.0 - w1,
                    power,
                    lambda_min_per_mm: lambda,
                    zeta_min_per_mm2: zeta,
                    consistency_screen: screen,
                },
                ..BuildOptions::default()
            },
        )
}

fn case() -> impl Strategy<Value = Case> {
    (
        cloud(),
        options(),
        prop::collection::vec(
            (0usize..5, prop::array::uniform3(0.0..1.0f64), any::<u8>()),
            60,
        ),
    )
        .prop_map(|(samples, mut options, picks)| {
            let (lo, hi) = samples.nominal_bounds_mm().unwrap();
            let pad = options.method.radius_mm.unwrap_or(60.0);
            let lo = lo.map(|v| v - pad);
            let hi = hi.map(|v| v + pad);
            // About 5,000 cells at most, so that a case builds in milliseconds.
            let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
            let cell = (extent / 17.0).max(1.0);
            options.cell_mm = Some(cell);
            options.bounds_mm = Some((lo, hi));
            let configured = samples.config.is_some();
            let targets = picks
                .into_iter()
                .map(|(kind, u, pick)| {
                    let i = pick as usize % samples.len();
                    let actual = samples.actual_mm(i);
                    let position_mm = match kind {
                        // Anywhere in the grid.
                        0 => [0, 1, 2].map(|a| lo[a] + u[a] * (hi[a] - lo[a])),
                        // On a cell face (x), edge (x, y) or corner.
                        1 => {
                            let mut p = [0, 1, 2].map(|a| lo[a] + u[a] * (hi[a] - lo[a]));
                            for a in 0..=(pick as usize % 3) {
                                p[a] = lo[a] + ((p[a] - lo[a]) / cell).round() * cell;
                            }
                            p
                        }
                        // Exactly on a sample's actual position.
                        2 => actual,
                        // Collinear with a sample through the origin.
                        3 => actual.map(|v| v * (1.0 + 0.05 * (u[0] - 0.5))),
                        // Near a sample.
                        _ => [0, 1, 2].map(|a| actual[a] + (u[a] - 0.5) * 10.0),
                    };
                    Target {
                        position_mm,
                        config: (configured && pick % 2 == 0).then_some(pick % 3),
                        rotation_rad: None,
                        tcp_mm: None,
                    }
                })
                .collect();
            Case {
                samples,
                options,
                targets,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(500)
    ))]

    #[test]
    fn table_answers_equal_reference(case in case()) {
        let (bytes, _) = compile(&case.samples, &case.options, &|_| {}).unwrap();
        let table = Table::from_vec(bytes).unwrap();
        let records = case.samples.records();
        let params = *table.method();
        for target in &case.targets {
            if table.grid().cell_of(target.position_mm).is_none() {
                // A collinear or nearby target can leave the grid: refused, not guessed.
                prop_assert_eq!(table.explain(target).err(), Some(Status::OutsideGrid));
                continue;
            }
            let expected = reference::predict(&records, &params, target);
            let got = table.explain(target);
            match (got, expected) {
                (Ok(got), Some(want)) => {
                    let g: Vec<u32> = got.neighbours.as_slice().iter().map(|n| n.sample).collect();
                    let w: Vec<u32> = want.neighbours.as_slice().iter().map(|n| n.sample).collect();
                    prop_assert_eq!(&g, &w, "neighbours at {:?}", target);
                    for axis in 0..3 {
                        prop_assert!((got.position_error_mm[axis] - want.position_error_mm[axis]).abs() <= 1e-12);
                        prop_assert!((got.orientation_error_rad[axis] - want.orientation_error_rad[axis]).abs() <= 1e-12);
                    }
                }
                (Err(Status::NoAdmissibleNeighbour), None) => {}
                (got, want) => prop_assert!(false, "table {:?}, reference {:?} at {:?}", got.map(|p| p.position_error_mm), want.map(|p| p.position_error_mm), target),
            }
        }
    }
}

/// The served field, as the obvious reference computes it: the brute-force method at the
/// 8 nodes of the target's cell, blended trilinearly.
fn served_reference(
    table: &Table<adwi_runtime::AlignedBytes>,
    records: &[adwi_runtime::format::SampleRecord],
    target: &Target,
) -> Result<([f64; 3], [f64; 3]), Status> {
    let g = table.grid();
    let params = *table.method();
    let mut cell = [0usize; 3];
    let mut t = [0.0; 3];
    for a in 0..3 {
        let u = (target.position_mm[a] - g.origin_mm[a]) / g.cell_mm;
        if !(0.0..=g.dims[a] as f64).contains(&u) {
            return Err(Status::OutsideGrid);
        }
        cell[a] = (u.floor() as usize).min(g.dims[a] as usize - 1);
        t[a] = u - cell[a] as f64;
    }
    // A configuration no sample has: no sample is admissible anywhere.
    let configs: Vec<u8> = records.iter().map(|r| r.config).collect();
    let config = target
        .config
        .filter(|_| configs.iter().all(|&c| c != u8::MAX));
    if let Some(c) = config {
        if !configs.contains(&c) {
            return Err(Status::NoAdmissibleNeighbour);
        }
    }
    let mut position = [0.0; 3];
    let mut orientation = [0.0; 3];
    for corner in 0..8 {
        let d = [corner & 1, corner >> 1 & 1, corner >> 2 & 1];
        let node = [0, 1, 2].map(|a| g.origin_mm[a] + (cell[a] + d[a]) as f64 * g.cell_mm);
        let weight: f64 = (0..3)
            .map(|a| if d[a] == 1 { t[a] } else { 1.0 - t[a] })
            .product();
        let at = Target {
            position_mm: node,
            config,
            rotation_rad: None,
            tcp_mm: None,
        };
        let Some(p) = reference::predict(records, &params, &at) else {
            return Err(Status::UncoveredCell);
        };
        for a in 0..3 {
            position[a] += weight * p.position_error_mm[a];
            orientation[a] += weight * p.orientation_error_rad[a];
        }
    }
    Ok((position, orientation))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(200)
    ))]

    /// The served field equals the exact method at the nodes, blended trilinearly, to
    /// 1e-12, with the same statuses; and the exact tier's queries equal the reference.
    #[test]
    fn served_field_equals_the_nodes_blended(case in case()) {
        let (bytes, _) = compile(&case.samples, &case.options, &|_| {}).unwrap();
        let table = Table::from_vec(bytes).unwrap();
        prop_assert!(table.has_served_field());
        let records = case.samples.records();
        let params = *table.method();
        for target in &case.targets {
            let got = table.query_target(target);
            match served_reference(&table, &records, target) {
                Ok((p, r)) => {
                    prop_assert_eq!(got.status, Status::Ok, "at {:?}", target);
                    for a in 0..3 {
                        prop_assert!((got.position_error_mm[a] - p[a]).abs() <= 1e-12, "{:?} vs {:?}", got, p);
                        prop_assert!((got.orientation_error_rad[a] - r[a]).abs() <= 1e-12);
                    }
                }
                Err(status) => prop_assert_eq!(got.status, status, "at {:?}", target),
            }
            let exact = table.exact().query_target(target);
            if table.grid().cell_of(target.position_mm).is_some() {
                match reference::predict(&records, &params, target) {
                    Some(want) => {
                        prop_assert_eq!(exact.status, Status::Ok);
                        for a in 0..3 {
                            prop_assert!((exact.position_error_mm[a] - want.position_error_mm[a]).abs() <= 1e-12);
                        }
                    }
                    None => prop_assert_eq!(exact.status, Status::NoAdmissibleNeighbour),
                }
            }
        }
    }

    /// The served field is continuous, with the slope its nodes allow: along random
    /// segments, no step between consecutive answers changes the correction by more than
    /// the step times `√3 · Δ / cell`, `Δ` the largest difference between two neighbouring
    /// nodes (each partial derivative of a trilinear blend is a convex combination of its
    /// cell's edge differences over the cell). A jump breaks such a bound once the step
    /// is small enough. (A bound on the ratio of two step sizes' largest changes is no
    /// test: a steep stretch shorter than a step, where the segment clips a cell's corner,
    /// can make it anything up to 1.)
    #[test]
    fn served_field_is_continuous(
        seed in 0u64..1000,
        start in prop::array::uniform3(0.05..0.95f64),
        direction in prop::array::uniform3(-1.0..1.0f64),
    ) {
        let table = Table::from_vec(common::lattice_table(seed, 1.0)).unwrap();
        let g = *table.grid();
        let Some(adwi_runtime::Payload::V2(archived)) = table.payload() else {
            panic!("a version-2 table");
        };
        let data: adwi_runtime::format::v2::TableData =
            rkyv::deserialize::<_, rkyv::rancor::Error>(archived).unwrap();
        prop_assert_eq!(data.node_sets.len(), 1);
        let [nx, ny, nz] = g.dims.map(|d| d as usize + 1);
        let node = |i: usize, j: usize, k: usize| data.node_errors_mm[i + nx * (j + ny * k)];
        let mut largest_node_difference: f64 = 0.0;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let here = node(i, j, k);
                    for there in [
                        (i + 1 < nx).then(|| node(i + 1, j, k)),
                        (j + 1 < ny).then(|| node(i, j + 1, k)),
                        (k + 1 < nz).then(|| node(i, j, k + 1)),
                    ]
                    .into_iter()
                    .flatten()
                    {
                        let d = ((here[0] - there[0]).powi(2)
                            + (here[1] - there[1]).powi(2)
                            + (here[2] - there[2]).powi(2))
                        .sqrt();
                        // NaN (a node without a value) leaves the maximum as it is.
                        largest_node_difference = largest_node_difference.max(d);
                    }
                }
            }
        }
        let slope = 3f64.sqrt() * largest_node_difference / g.cell_mm;
        let from = [0, 1, 2].map(|a| g.origin_mm[a] + start[a] * g.dims[a] as f64 * g.cell_mm);
        let norm = direction.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-9);
        for step_mm in [0.01f64, 0.1, 1.0] {
            let steps = (20.0 / step_mm).round() as usize;
            let mut previous: Option<[f64; 3]> = None;
            for i in 0..=steps {
                let p = [0, 1, 2].map(|a| from[a] + direction[a] / norm * step_mm * i as f64);
                let c = table.query(p);
                let here = (c.status == Status::Ok).then_some(c.position_error_mm);
                if let (Some(a), Some(b)) = (previous, here) {
                    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                    prop_assert!(
                        d <= slope * step_mm * (1.0 + 1e-9) + 1e-12,
                        "a change of {} mm over {} mm at {:?}, bound {} mm",
                        d,
                        step_mm,
                        p,
                        slope * step_mm
                    );
                }
                previous = here;
            }
        }
    }
}

/// A case with joint angles on every sample, a joint-space screen, and the targets' joint
/// angles: random, not consistent with the positions, which the screen does not need.
fn joint_case() -> impl Strategy<Value = (Case, Vec<[f64; 6]>)> {
    (
        case(),
        prop::collection::vec(prop::array::uniform6(-0.5..0.5f64), 200),
        prop::collection::vec(prop::array::uniform6(-0.5..0.5f64), 60),
        0.05..0.8f64,
    )
        .prop_map(|(mut case, sample_joints, target_joints, radius_rad)| {
            let len = case.samples.len();
            case.samples.joints = Some(adwi_samples::Joints::from_flat(
                6,
                sample_joints[..len].iter().flatten().copied().collect(),
            ));
            case.options.joint_radius_deg = Some(radius_rad.to_degrees());
            (case, target_joints)
        })
}

/// The brute-force hybrid reference, independent of the table: the compiler's own
/// calibrated forward kinematics and the reference over every residual.
struct HybridFixture {
    table: Table<adwi_runtime::AlignedBytes>,
    screened: Table<adwi_runtime::AlignedBytes>,
    calibration: adwi_identify::calibrate::Calibration,
    residuals: Vec<adwi_runtime::format::SampleRecord>,
    joints: adwi_samples::Joints,
    robot: adwi_robot::Robot,
}

const HYBRID_JOINT_RADIUS_DEG: f64 = 12.0;

fn hybrid_fixture() -> &'static HybridFixture {
    static FIXTURE: std::sync::OnceLock<HybridFixture> = std::sync::OnceLock::new();
    FIXTURE.get_or_init(|| {
        let (robot, samples, calibration) = common::kr150_calibration();
        let options = BuildOptions {
            cell_mm: Some(50.0),
            ..BuildOptions::default()
        };
        let build = |options: &BuildOptions| {
            let model = calibration.prepared_model();
            Table::from_vec(common::hybrid_table_bytes(&samples, &model, options)).unwrap()
        };
        let table = build(&options);
        let screened = build(&BuildOptions {
            joint_radius_deg: Some(HYBRID_JOINT_RADIUS_DEG),
            ..options
        });
        let joints = samples.joints.clone().unwrap();
        // Residuals through the compiler's nalgebra model, not the runtime's.
        let mut residual = samples.clone();
        for (i, q) in joints.rows().enumerate() {
            let (p, r) = calibration.predict_error(q);
            for a in 0..3 {
                residual.error_mm[i][a] -= p[a];
                residual.rotation_error_rad.as_mut().unwrap()[i][a] -= r[a];
            }
        }
        HybridFixture {
            table,
            screened,
            residuals: residual.records(),
            calibration,
            joints,
            robot,
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(300)
    ))]

    /// With the joint-space screen on, the table's candidate lists stay a superset (no
    /// dominance pruning) and its answers equal the screened reference's.
    #[test]
    fn joint_screened_table_answers_equal_reference((case, target_joints) in joint_case()) {
        let (bytes, _) = compile(&case.samples, &case.options, &|_| {}).unwrap();
        let table = Table::from_vec(bytes).unwrap();
        let radius_rad = table.joint_radius_rad();
        prop_assert!(radius_rad > 0.0);
        let records = case.samples.records();
        let sample_joints = case.samples.joints.clone().unwrap();
        let params = *table.method();
        for (target, q) in case.targets.iter().zip(&target_joints) {
            let got = table.exact().query_with_joints(target, q);
            if table.grid().cell_of(target.position_mm).is_none() {
                prop_assert_eq!(got.status, Status::OutsideGrid);
                continue;
            }
            let screen = reference::JointScreen {
                samples: &sample_joints,
                target_rad: q,
                radius_rad,
            };
            let want = reference::predict_screened(&records, &params, target, Some(&screen));
            match want {
                Some(want) => {
                    prop_assert_eq!(got.status, Status::Ok, "at {:?}", target);
                    prop_assert_eq!(got.neighbours as usize, want.neighbours.len());
                    for axis in 0..3 {
                        prop_assert!((got.position_error_mm[axis] - want.position_error_mm[axis]).abs() <= 1e-12);
                        prop_assert!((got.orientation_error_rad[axis] - want.orientation_error_rad[axis]).abs() <= 1e-12);
                    }
                }
                None => prop_assert_eq!(got.status, Status::NoAdmissibleNeighbour, "at {:?}", target),
            }
            // Without the target's joints the screen is off: the unscreened reference.
            let unscreened = table.exact().query_target(target);
            let want = reference::predict(&records, &params, target);
            prop_assert_eq!(unscreened.status == Status::Ok, want.is_some());
        }
    }

    /// A hybrid table's runtime answer equals the brute-force hybrid reference (calibrated
    /// model by the compiler's own forward kinematics + reference over the residuals) to
    /// 1e-9, at random poses near the KR150-2 samples, with and without the joint screen.
    #[test]
    fn hybrid_table_answers_equal_reference(
        pick in 0usize..729,
        delta_deg in prop::array::uniform6(-6.0..6.0f64),
    ) {
        let f = hybrid_fixture();
        let q: [f64; 6] = std::array::from_fn(|i| f.joints.row(pick)[i] + delta_deg[i].to_radians());
        let position = f.robot.tcp_pose(&q).translation.vector;
        let target = Target::at([position.x, position.y, position.z]);
        prop_assert_eq!(f.table.query_target(&target).status, Status::MissingJoints);
        // Where the residuals have nothing (outside the grid, no admissible neighbour), the
        // model alone.
        let (model_mm, model_rad) = f.calibration.predict_error(&q);
        let model_alone = |got: &adwi_runtime::Correction| {
            prop_assert_eq!((got.status, got.residual), (Status::Ok, adwi_runtime::Residual::ModelOnly));
            for axis in 0..3 {
                prop_assert!((got.position_error_mm[axis] - model_mm[axis]).abs() <= 1e-9);
                prop_assert!((got.orientation_error_rad[axis] - model_rad[axis]).abs() <= 1e-9);
            }
            Ok(())
        };
        for (table, radius_deg) in [(&f.table, 0.0), (&f.screened, HYBRID_JOINT_RADIUS_DEG)] {
            let got = table.exact().query_with_joints(&target, &q);
            if table.grid().cell_of(target.position_mm).is_none() {
                model_alone(&got)?;
                continue;
            }
            let want = common::hybrid_reference_predict(
                &f.residuals,
                &f.joints,
                table.method(),
                f64::to_radians(radius_deg),
                &f.calibration,
                true,
                &target,
                &q,
            );
            match want {
                Some((p, r)) => {
                    prop_assert_eq!(got.status, Status::Ok);
                    for axis in 0..3 {
                        prop_assert!((got.position_error_mm[axis] - p[axis]).abs() <= 1e-9, "{:?} vs {:?}", got.position_error_mm, p);
                        prop_assert!((got.orientation_error_rad[axis] - r[axis]).abs() <= 1e-9, "{:?} vs {:?}", got.orientation_error_rad, r);
                    }
                }
                None => model_alone(&got)?,
            }
        }
    }
}

/// A hybrid table whose served field turns with the tool (`kriging-tool-axis`) answers, at
/// its nodes, the model plus the direct turning kriging of the residuals with the nominal
/// tool's approach axis at the query's joint values (`nugget_kriging::ResidualGp`), to
/// 1e-9: the compiler's tabulation and the runtime's combination of the four node vectors
/// with the axis hold the prediction, whatever the posture. On the UR5's measurements,
/// whose tool orientation varies from pose to pose.
#[test]
fn a_tool_axis_served_field_answers_the_turning_kriging_at_its_nodes() {
    use adwi_compile::nugget_kriging::ResidualGp;
    use adwi_runtime::format::ServedField;
    use adwi_samples::{read_samples, ColumnMap};
    let columns = ColumnMap::parse(
        "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,j1=joint_1,j2=joint_2,j3=joint_3,\
         j4=joint_4,j5=joint_5,j6=joint_6",
    )
    .unwrap();
    let all = read_samples(
        &common::repo("tables/ur5/measurements/3D_UR5_uncalibrated_grid_cleaned.csv"),
        &columns,
    )
    .unwrap();
    // Every fourth sample keeps the kriging's grid search quick.
    let picked: Vec<usize> = (0..all.len()).step_by(4).collect();
    let samples = all.subset(&picked);
    let robot = adwi_robot::Robot::load(common::repo("tables/ur5/robot.toml")).unwrap();
    let calibration =
        adwi_identify::calibrate::identify(&robot, &samples, &Default::default()).unwrap();
    let model = calibration.prepared_model();
    let options = BuildOptions {
        cell_mm: Some(60.0),
        served_field: ServedField::KrigingToolAxis,
        ..BuildOptions::default()
    };
    let table = Table::from_vec(common::hybrid_table_bytes(&samples, &model, &options)).unwrap();
    assert_eq!(table.header().served_field, ServedField::KrigingToolAxis);
    // The residuals and axes, computed here apart from the compiler.
    let joints = samples.joints.clone().unwrap();
    let axis = |q: &[f64]| {
        let r = model.nominal().tcp_pose(q).unwrap().rotation;
        [r[0][2], r[1][2], r[2][2]]
    };
    let mut inputs = Vec::new();
    let mut values = Vec::new();
    let mut axes = Vec::new();
    for (i, q) in joints.rows().enumerate() {
        let (p, _) = model.error(q).unwrap();
        let residual = [0, 1, 2].map(|a| samples.error_mm[i][a] - p[a]);
        inputs.push(
            (0..3)
                .map(|a| samples.nominal_mm[i][a] + residual[a])
                .collect(),
        );
        values.push(residual.to_vec());
        axes.push(axis(q));
    }
    let gp = ResidualGp::fit_turning(&inputs, &axes, &values).unwrap();
    // The UR5's residuals do turn with the tool: the likelihood gives the part a weight.
    assert!(
        gp.choices().iter().any(|c| c.modulation > 0.0),
        "{:?}",
        gp.choices()
    );
    let grid = *table.grid();
    let mut checked = 0;
    for (n, q) in joints.rows().enumerate() {
        // The node nearest the sample, queried with the sample's joint values (which reach
        // it, within half a cell's diagonal).
        let node = [0, 1, 2].map(|a| {
            let u = (samples.nominal_mm[n][a] - grid.origin_mm[a]) / grid.cell_mm;
            u.round().clamp(0.0, grid.dims[a] as f64)
        });
        let at = [0, 1, 2].map(|a| grid.origin_mm[a] + node[a] * grid.cell_mm);
        let got = table.query_with_joints(&Target::at(at), q);
        // At a node, the node's own value has all the weight: a node without one leaves
        // the model alone.
        if got.status != Status::Ok || got.residual == adwi_runtime::Residual::ModelOnly {
            continue;
        }
        let (p, _) = model.error(q).unwrap();
        let want = gp.predict_at(&at, axis(q)).unwrap();
        for a in 0..3 {
            assert!(
                (got.position_error_mm[a] - p[a] - want[a]).abs() < 1e-9,
                "at {at:?}: {:?} vs {want:?}",
                got.position_error_mm
            );
        }
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} nodes served");
}
