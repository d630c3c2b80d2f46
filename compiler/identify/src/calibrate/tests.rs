use super::model::{loaded, loaded_with_terms, Model, Walk};
use super::*;
use adwi_robot::error_model::{transform_pose_error, MdhParameter};
use adwi_robot::model::URAD_PER_NM;
use adwi_robot::model::{shipped_file, shipped_robot_path};
use adwi_samples::Joints;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn kr150() -> Robot {
    Robot::load(shipped_robot_path("kr150-2")).unwrap()
}

fn iiwa() -> Robot {
    Robot::load(shipped_file("iiwa14", "robot.urdf")).unwrap()
}

/// The iiwa with its flange turned and moved off the last joint's frame (as a URDF's
/// `tool0` may lie) and a tool on it: the tool's parameters move the TCP along and about
/// the flange's axes, not the last joint's.
fn iiwa_on_a_turned_flange() -> Robot {
    use adwi_robot::model::transform_from_xyz_rpy;
    let r = iiwa();
    Robot::with_flange_at(
        "iiwa on a turned flange".into(),
        r.geometry().clone(),
        r.joints().to_vec(),
        r.base(),
        transform_from_xyz_rpy([10.0, -5.0, 60.0], [0.3, -1.2, 0.7]),
        transform_from_xyz_rpy([20.0, 30.0, 150.0], [0.1, 0.2, -0.3]),
        r.home().to_vec(),
    )
    .unwrap()
}

/// Random joint values inside 80 % of the limits.
fn poses(robot: &Robot, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            (0..robot.joint_count())
                .map(|i| {
                    let [lo, hi] = robot.sampling_range(i);
                    rng.gen_range(lo * 0.8..hi * 0.8)
                })
                .collect()
        })
        .collect()
}

/// Samples of a robot whose true parameters are `truth`, simulated with the exact
/// forward kinematics (nominal positions from the nominal model), with Gaussian noise of
/// σ `noise_mm` per position axis drawn from `seed`.
fn simulate(
    robot: &Robot,
    truth: &DVector<f64>,
    q: &[Vec<f64>],
    orientation: bool,
    noise_mm: f64,
    seed: u64,
) -> SampleSet {
    simulate_model(
        &Model::new(robot, false, 0),
        truth,
        q,
        orientation,
        noise_mm,
        seed,
    )
}

/// As [`simulate`], of any model (one with compliances among them): the measured poses
/// are the runtime chain's deflected poses ([`Chain::loaded_tcp_pose`]) of the true
/// robot.
fn simulate_model(
    model: &Model,
    truth: &DVector<f64>,
    q: &[Vec<f64>],
    orientation: bool,
    noise_mm: f64,
    seed: u64,
) -> SampleSet {
    let robot = &model.robot;
    let state = model.state(truth).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut set = SampleSet {
        rotation_error_rad: orientation.then(Vec::new),
        joints: Some(Joints::new(robot.joint_count())),
        ..SampleSet::default()
    };
    for (i, q) in q.iter().enumerate() {
        let nominal = robot.tcp_pose(q).translation.vector;
        let e = model.error(&state, q);
        let mut noise = || {
            // Box-Muller.
            let (u, v): (f64, f64) = (1.0 - rng.gen::<f64>(), rng.gen());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos() * noise_mm
        };
        set.nominal_mm.push([nominal.x, nominal.y, nominal.z]);
        set.error_mm
            .push([e[0] + noise(), e[1] + noise(), e[2] + noise()]);
        if let Some(r) = &mut set.rotation_error_rad {
            r.push([e[3], e[4], e[5]]);
        }
        set.joints.as_mut().unwrap().push(q);
        set.lines.push(i as u64 + 2);
    }
    set
}

/// Realistic deviations on the given columns: 0.5 mm for lengths, 1 mrad for angles.
fn deviations_on(parameters: &[Parameter], columns: &[usize], seed: u64) -> DVector<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut x = DVector::zeros(parameters.len());
    for &c in columns {
        let m = if parameters[c].is_length() { 0.5 } else { 1e-3 };
        x[c] = rng.gen_range(-m..m);
    }
    x
}

fn columns_of(c: &Calibration) -> Vec<usize> {
    c.identified
        .iter()
        .map(|p| c.parameters.iter().position(|q| q == p).unwrap())
        .collect()
}

#[test]
fn parameters_of_mdh_and_chain_robots() {
    let mdh = Parameter::all_of(&kr150());
    assert_eq!(mdh.len(), 42);
    assert_eq!(mdh[3].to_string(), "Δtheta1");
    assert_eq!(mdh[41], Parameter::BaseRotation(2));
    // The iiwa from URDF: joint 1 has its offset only, joints 2-7 offset and origin.
    let chain = Parameter::all_of(&iiwa());
    assert_eq!(chain.len(), 1 + 6 * 7 + 12);
    assert_eq!(chain[1].to_string(), "Δoffset2");
    assert_eq!(chain[2].to_string(), "Δx2");
    assert_eq!(chain[7].to_string(), "Δrz2");
    assert!(chain[2].is_length() && !chain[7].is_length());
}

/// Every analytic column equals central differences of the exact model, at a state
/// away from nominal, for an MD-H robot and a URDF chain.
#[test]
fn jacobian_matches_finite_differences_of_the_exact_model() {
    for robot in [kr150(), iiwa(), iiwa_on_a_turned_flange()] {
        let model = Model::new(&robot, false, 0);
        let all: Vec<usize> = (0..model.len()).collect();
        let x = deviations_on(&model.parameters, &all, 3);
        let state = model.state(&x).unwrap();
        let q = &poses(&robot, 1, 5)[0];
        let j = model.jacobian(&x, &state, q);
        let h = 1e-6;
        for c in 0..model.len() {
            let mut d = DVector::zeros(model.len());
            d[c] = h;
            let plus = model.error(&model.state(&model.step(&x, &d)).unwrap(), q);
            let minus = model.error(&model.state(&model.step(&x, &(-&d))).unwrap(), q);
            let numeric = (plus - minus) / (2.0 * h);
            let scale = j.column(c).norm().max(1.0);
            for a in 0..3 {
                assert!(
                    (numeric[a] - j[(a, c)]).abs() < 1e-6 * scale,
                    "{}: {} row {a}: {} vs {}",
                    robot.name,
                    model.parameters[c],
                    numeric[a],
                    j[(a, c)]
                );
                // log(R_actual R_nominalᵀ) differs from the rotation perturbation by
                // the inverse left Jacobian of SO(3): I + O(|δ|), here |δ| ≈ 1e-2.
                assert!(
                    (numeric[a + 3] - j[(a + 3, c)]).abs() < 2e-2 * scale,
                    "{}: {} row {}: {} vs {}",
                    robot.name,
                    model.parameters[c],
                    a + 3,
                    numeric[a + 3],
                    j[(a + 3, c)]
                );
            }
        }
    }
}

fn ur5() -> Robot {
    Robot::load(shipped_robot_path("ur5")).unwrap()
}

/// Realistic deviations on the given columns, as [`deviations_on`], and compliances of
/// 5 to 40 µrad/(N·m) (stiffnesses of 2.5·10⁴ to 2·10⁵ N·m/rad, a UR5's range).
fn compliant_deviations_on(parameters: &[Parameter], columns: &[usize], seed: u64) -> DVector<f64> {
    let mut x = deviations_on(parameters, columns, seed);
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000);
    for &c in columns {
        if parameters[c].is_compliance() {
            x[c] = rng.gen_range(5.0..40.0);
        }
    }
    x
}

/// With compliance, every column against central differences of the exact model: a
/// compliance column exactly (the torques do not depend on the compliances); a
/// geometric column exactly when the torques are held at the state's (the Jacobian's
/// definition, module docs), and to the neglected torque term, `c · ∂τ/∂x`, when they
/// follow the geometry as the model does.
#[test]
fn compliance_jacobian_matches_finite_differences() {
    for robot in [ur5(), iiwa()] {
        let model = Model::new(&robot, true, 0);
        let all: Vec<usize> = (0..model.len()).collect();
        let x = compliant_deviations_on(&model.parameters, &all, 3);
        let state = model.state(&x).unwrap();
        let chain = state.robot.chain();
        let q = &poses(&robot, 1, 5)[0];
        let held_joints = chain.loaded_joints(q).unwrap();
        let held_joints = &held_joints[..robot.joint_count()];
        // The pose error of x + d with the torques held at the state's: each joint
        // deflected as at x, plus the compliance deviation's own turn.
        let torques = chain
            .gravity_torques(q, chain.compliance.as_ref().unwrap())
            .unwrap();
        let held = |d: &DVector<f64>| {
            let s = model.state(&model.step(&x, d)).unwrap();
            let mut joints = held_joints.to_vec();
            for (k, &joint) in model.compliance_joints.iter().enumerate() {
                joints[joint] += d[model.first_compliance() + k] * URAD_PER_NM * torques[joint];
            }
            transform_pose_error(
                &robot.tcp_transform(q),
                &s.robot.chain().tcp_pose(&joints).unwrap(),
            )
        };
        let exact = |d: &DVector<f64>| model.error(&model.state(&model.step(&x, d)).unwrap(), q);
        let j = model.jacobian(&x, &state, q);
        let mut largest_neglected: f64 = 0.0;
        for c in 0..model.len() {
            let compliance = model.parameters[c].is_compliance();
            let h = if compliance { 1e-3 } else { 1e-6 };
            let mut d = DVector::zeros(model.len());
            d[c] = h;
            let held_numeric = (held(&d) - held(&(-&d))) / (2.0 * h);
            let numeric = (exact(&d) - exact(&(-&d))) / (2.0 * h);
            let scale = j.column(c).norm().max(1.0);
            if compliance {
                // The same deflection, summed in another order.
                assert!((held_numeric - numeric).norm() < 1e-9 * scale);
            }
            for a in 0..3 {
                assert!(
                    (held_numeric[a] - j[(a, c)]).abs() < 1e-6 * scale,
                    "{}: {} row {a}: {} vs {}",
                    robot.name,
                    model.parameters[c],
                    held_numeric[a],
                    j[(a, c)]
                );
                // As in the test without compliance: the orientation rows differ by
                // the inverse left Jacobian of SO(3).
                assert!((held_numeric[a + 3] - j[(a + 3, c)]).abs() < 2e-2 * scale);
                largest_neglected = largest_neglected.max((numeric[a] - j[(a, c)]).abs() / scale);
            }
        }
        // The deflections are a few mrad at most (compliances of ≤ 40 µrad/(N·m),
        // torques of ≤ 100 N·m): the torques' dependence on the geometry changes a
        // column by that fraction of it at most.
        println!(
            "{}: torque term left out of the Jacobian ≤ {largest_neglected:.2e} of a column",
            robot.name
        );
        assert!(largest_neglected < 5e-3, "{largest_neglected}");
    }
}

/// Noise-free data from a robot with known geometric deviations and known joint
/// compliances, simulated as the runtime chain deflects: the compliances come back to
/// 1e-6 of their values, the geometry to 1e-6 mm or rad, and the stored model predicts
/// the deflected poses.
#[test]
fn recovers_known_compliances_from_noise_free_data() {
    for robot in [ur5(), iiwa()] {
        let model = Model::new(&robot, true, 0);
        let q = poses(&robot, 120, 1);
        let options = CalibrateOptions {
            compliance: true,
            ..CalibrateOptions::default()
        };
        let p = model.len();
        let zero = simulate_model(&model, &DVector::zeros(p), &q, false, 0.0, 0);
        let structure = identify(&robot, &zero, &options).unwrap();
        let columns = columns_of(&structure);
        let compliances: Vec<usize> = columns
            .iter()
            .copied()
            .filter(|&c| model.parameters[c].is_compliance())
            .collect();
        // Joint 1 turns about gravity and carries no torque: not seen. The others are.
        assert!(compliances.len() >= 3, "{:?}", structure.identified);
        let truth = compliant_deviations_on(&model.parameters, &columns, 2);
        let samples = simulate_model(&model, &truth, &q, false, 0.0, 0);
        let c = identify(&robot, &samples, &options).unwrap();
        assert!(c.converged, "not converged after {}", c.iterations);
        assert_eq!(c.identified, structure.identified);
        for i in 0..p {
            let parameter = c.parameters[i];
            let gap = (c.deviations[i] - truth[i]).abs();
            let tolerance = if parameter.is_compliance() {
                1e-6 * truth[i].abs()
            } else {
                1e-6
            };
            assert!(
                gap <= tolerance,
                "{}, {parameter}: identified {} true {}",
                robot.name,
                c.deviations[i],
                truth[i]
            );
        }
        for &k in &compliances {
            let r = &c.report[k];
            assert_eq!(r.status, ParameterStatus::Identified);
            assert_eq!(r.parameter.unit(), "µrad/(N·m)");
        }
        assert!(c.position_rms_mm < 1e-9, "{}", c.position_rms_mm);
        let truth_state = model.state(&truth).unwrap();
        let stored = c.prepared_model();
        for q in poses(&robot, 10, 9) {
            let expected = model.error(&truth_state, &q);
            let got = stored.error(&q).unwrap();
            for a in 0..3 {
                assert!((expected[a] - got.0[a]).abs() < 1e-6);
            }
        }
        println!(
            "{}: compliances {:?} µrad/(N·m) recovered",
            robot.name,
            compliances
                .iter()
                .map(|&k| (c.parameters[k].to_string(), c.deviations[k]))
                .collect::<Vec<_>>()
        );
    }
}

/// Compliance needs link masses; a compliance beyond 100 µrad/(N·m) or a determined
/// negative one is held at nominal with its reason.
#[test]
fn implausible_compliances_are_held_and_massless_robots_refused() {
    let options = CalibrateOptions {
        compliance: true,
        ..CalibrateOptions::default()
    };
    let robot = kr150();
    let q = poses(&robot, 60, 4);
    let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
    let error = identify(&robot, &samples, &options).unwrap_err();
    assert!(matches!(error, CalibrateError::NoLinkMasses { .. }));
    assert!(
        error.to_string().contains("gives no link masses"),
        "{error}"
    );

    let robot = ur5();
    let model = Model::new(&robot, true, 0);
    let q = poses(&robot, 120, 4);
    let column = |joint| {
        model
            .parameters
            .iter()
            .position(|p| *p == Parameter::Compliance { joint })
            .unwrap()
    };
    for (value, negative) in [(-20.0, true), (400.0, false)] {
        let mut truth = DVector::zeros(model.len());
        truth[column(1)] = value;
        truth[column(2)] = 15.0;
        let samples = simulate_model(&model, &truth, &q, false, 0.01, 3);
        let c = identify(&robot, &samples, &options).unwrap();
        let report = &c.report[column(1)];
        match report.status {
            ParameterStatus::Held {
                reason: HoldReason::NegativeCompliance { value, .. },
                ..
            } if negative => assert!(value < 0.0),
            ParameterStatus::Held {
                reason: HoldReason::Implausible { bound, .. },
                ..
            } if !negative => assert_eq!(bound, 100.0),
            status => panic!("{value}: {status:?}"),
        }
        assert!(
            report.reason().contains("µrad/(N·m)"),
            "{}",
            report.reason()
        );
        assert_eq!(c.value(Parameter::Compliance { joint: 1 }), 0.0);
    }
}

/// Noise-free data from a known model: the identifiable deviations come back to 1e-6.
fn recovers(robot: &Robot, samples: usize) -> f64 {
    let q = poses(robot, samples, 1);
    let mut largest: f64 = 0.0;
    for orientation in [true, false] {
        // Which parameters these poses identify: a fit of error-free data.
        let p = Parameter::all_of(robot).len();
        let zero = simulate(robot, &DVector::zeros(p), &q, orientation, 0.0, 0);
        let structure = identify(robot, &zero, &CalibrateOptions::default()).unwrap();
        let truth = deviations_on(&structure.parameters, &columns_of(&structure), 2);
        let samples = simulate(robot, &truth, &q, orientation, 0.0, 0);
        let c = identify(robot, &samples, &CalibrateOptions::default()).unwrap();
        assert!(c.converged, "not converged after {}", c.iterations);
        assert_eq!(c.identified, structure.identified);
        for i in 0..p {
            let gap = (c.deviations[i] - truth[i]).abs();
            largest = largest.max(gap);
            assert!(
                gap < 1e-6,
                "{}, orientation {orientation}, {}: identified {} true {}",
                robot.name,
                c.parameters[i],
                c.deviations[i],
                truth[i]
            );
        }
        assert!(c.position_rms_mm < 1e-9, "{}", c.position_rms_mm);
        assert!(c.initial_position_rms_mm > 0.1);
        // Predictions at unseen poses equal the simulated errors.
        let model = Model::new(robot, false, 0);
        let truth_state = model.state(&truth).unwrap();
        for q in poses(robot, 10, 9) {
            let expected = model.error(&truth_state, &q);
            let (got, _) = c.predict_error(&q);
            for a in 0..3 {
                assert!((expected[a] - got[a]).abs() < 1e-6);
            }
        }
        println!(
            "{}: orientation {orientation}: {} of {} parameters identified, largest \
             recovery error {largest:.2e}",
            robot.name,
            c.identified.len(),
            p
        );
    }
    largest
}

#[test]
fn recovers_known_deviations_from_noise_free_data() {
    recovers(&kr150(), 60);
}

/// The seven-axis iiwa read from URDF, parameterised by origin perturbations and
/// offsets: every parameter the data identify comes back to 1e-6 (mm, rad).
#[test]
fn recovers_a_seven_axis_urdf_robot_from_noise_free_data() {
    let largest = recovers(&iiwa(), 120);
    println!("iiwa 14 (URDF): largest recovery error {largest:.2e} (mm or rad)");
}

/// The standard errors are what repeated noisy measurements spread the estimates by:
/// over 40 noise draws, each parameter's empirical spread agrees with the mean reported
/// standard error to within 35 %.
#[test]
fn standard_errors_match_the_spread_over_noise_draws() {
    let robot = kr150();
    let q = poses(&robot, 60, 4);
    let p = Parameter::all_of(&robot).len();
    let zero = simulate(&robot, &DVector::zeros(p), &q, false, 0.0, 0);
    // Every parameter the pivoting keeps, trusted or not: the spread of each is compared.
    let options = CalibrateOptions {
        hold_untrustworthy: false,
        ..CalibrateOptions::default()
    };
    let structure = identify(&robot, &zero, &options).unwrap();
    let truth = deviations_on(&structure.parameters, &columns_of(&structure), 5);
    let draws = 40;
    let mut estimates = Vec::new();
    let mut reported = DVector::<f64>::zeros(p);
    for seed in 0..draws {
        let samples = simulate(&robot, &truth, &q, false, 0.02, 100 + seed);
        let c = identify(&robot, &samples, &options).unwrap();
        assert_eq!(c.identified, structure.identified);
        assert!(
            (c.residual_sigma_mm - 0.02).abs() < 0.005,
            "{}",
            c.residual_sigma_mm
        );
        for k in 0..p {
            reported[k] += c.standard_errors[k].unwrap_or(0.0) / draws as f64;
        }
        estimates.push(c.deviations);
    }
    for k in columns_of(&structure) {
        let mean = estimates.iter().map(|e| e[k]).sum::<f64>() / draws as f64;
        let spread = (estimates.iter().map(|e| (e[k] - mean).powi(2)).sum::<f64>()
            / (draws - 1) as f64)
            .sqrt();
        let ratio = spread / reported[k];
        assert!(
            (0.65..1.35).contains(&ratio),
            "{}: spread {spread:.3e}, reported {:.3e}",
            structure.parameters[k],
            reported[k]
        );
    }
    // Unidentified parameters have none.
    for (parameter, _) in &structure.unidentifiable {
        assert_eq!(structure.standard_error(*parameter), None);
    }
}

/// The trust rules (module docs, "Trust"): with noise and no deviation at all, the
/// parameters whose estimates are noise are held at nominal as undetermined, every one
/// left passes the rules, and the reports carry value, SE and strongest correlation.
/// A deviation far beyond its plausible bound is held as implausible. Of exactly
/// redundant joint and tool parameters, the tool's is kept.
#[test]
fn untrustworthy_parameters_are_held_with_a_reason() {
    let robot = kr150();
    let q = poses(&robot, 80, 6);
    let p = Parameter::all_of(&robot).len();
    let truth = {
        let zero = simulate(&robot, &DVector::zeros(p), &q, false, 0.0, 0);
        let structure = identify(&robot, &zero, &CalibrateOptions::default()).unwrap();
        deviations_on(&structure.parameters, &columns_of(&structure), 8)
    };
    // Half of the deviations zero, so that noise alone makes their estimates.
    let mut sparse = truth.clone();
    for c in (0..p).step_by(2) {
        sparse[c] = 0.0;
    }
    let samples = simulate(&robot, &sparse, &q, false, 0.05, 11);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    let held = c.held();
    assert!(!held.is_empty());
    for r in &held {
        let ParameterStatus::Held { estimate, reason } = r.status else {
            unreachable!()
        };
        let HoldReason::Undetermined {
            value,
            standard_error,
        } = reason
        else {
            panic!("{}: {reason:?}", r.parameter)
        };
        assert_eq!(value, estimate);
        assert!(value.abs() <= 3.0 * standard_error);
        assert_eq!(c.value(r.parameter), 0.0);
        assert!(r.reason().starts_with("undetermined"), "{}", r.reason());
    }
    for r in &c.report {
        if r.status == ParameterStatus::Identified {
            let se = r.standard_error.unwrap();
            assert!(r.value.abs() > 3.0 * se || se <= r.parameter.negligible_standard_error());
            assert!(r.value.abs() <= r.parameter.plausible_bound());
            let (partner, rho) = r.strongest_correlation.unwrap();
            assert_ne!(partner, r.parameter);
            assert!(rho.abs() <= 1.0 + 1e-9);
            assert!(c.identified.contains(&r.parameter));
        }
    }
    // The held parameters' deviations were zero in truth: holding them loses nothing,
    // the fit leaves the noise (RMS norm √3 σ).
    let noise_rms = 0.05 * 3f64.sqrt();
    assert!(
        c.position_rms_mm < 1.05 * noise_rms,
        "{}",
        c.position_rms_mm
    );

    // A joint angle 10° off: implausible, held, and the reason says so.
    let theta2 = Parameter::Mdh {
        joint: 1,
        parameter: MdhParameter::Theta,
    };
    let column = c.parameters.iter().position(|p| *p == theta2).unwrap();
    let mut absurd = truth.clone();
    absurd[column] = 10f64.to_radians();
    let samples = simulate(&robot, &absurd, &q, false, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    let report = &c.report[column];
    assert!(
        matches!(
            report.status,
            ParameterStatus::Held {
                reason: HoldReason::Implausible { .. },
                ..
            }
        ),
        "{report:?}"
    );
    assert!(
        report.reason().contains("beyond ±87.2665 mrad"),
        "{}",
        report.reason()
    );
    assert_eq!(c.value(theta2), 0.0);

    // On the UR5, Δd of the last joint moves the TCP exactly as the tool's z does: the
    // tool keeps it.
    let robot = Robot::load(shipped_robot_path("ur5")).unwrap();
    let q = poses(&robot, 80, 6);
    let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    assert!(c.identified.contains(&Parameter::ToolTranslation(2)));
    let d6 = Parameter::Mdh {
        joint: 5,
        parameter: MdhParameter::D,
    };
    let status = c.report[c.parameters.iter().position(|p| *p == d6).unwrap()].status;
    assert!(
        matches!(
            status,
            ParameterStatus::Unidentifiable {
                most_like: Some(Parameter::ToolTranslation(2)),
                ..
            }
        ),
        "{status:?}"
    );
}

/// Known redundancies are found: Δd1 moves the TCP exactly like the base z
/// translation, Δθ1 like the base rotation about z; without orientation data the tool
/// rotation cannot be seen at all.
#[test]
fn structural_redundancies_are_reported_unidentifiable() {
    let robot = kr150();
    let q = poses(&robot, 60, 4);
    let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    let dropped: Vec<Parameter> = c.unidentifiable.iter().map(|(p, _)| *p).collect();
    for axis in 0..3 {
        assert!(dropped.contains(&Parameter::ToolRotation(axis)));
    }
    let either = |a: Parameter, b: Parameter| dropped.contains(&a) || dropped.contains(&b);
    let d1 = Parameter::Mdh {
        joint: 0,
        parameter: MdhParameter::D,
    };
    let theta1 = Parameter::Mdh {
        joint: 0,
        parameter: MdhParameter::Theta,
    };
    assert!(either(d1, Parameter::BaseTranslation(2)));
    assert!(either(theta1, Parameter::BaseRotation(2)));
    assert!(c.condition_number.is_finite() && c.condition_number < 1e4);

    // A URDF chain: the rotation of an origin about its joint's own axis (z for every
    // iiwa joint) is the joint's offset, and of the two equal columns the offset comes
    // first: the rotation is never the one kept. The rest of the redundancies (an
    // offset is also a constant turn between two joints, which the next origin's
    // perturbation holds) leave the minimal count.
    let robot = iiwa();
    let q = poses(&robot, 120, 4);
    let p = Parameter::all_of(&robot).len();
    let samples = simulate(&robot, &DVector::zeros(p), &q, true, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    for joint in 1..7 {
        assert!(!c
            .identified
            .contains(&Parameter::OriginRotation { joint, axis: 2 }));
    }
    // 4 per revolute joint and 6 for base and tool: the minimal parameter count of a
    // serial chain measured in position and orientation (Everett, Driels, Mooring).
    assert_eq!(c.identified.len(), 4 * 7 + 6, "{:?}", c.identified);
    assert_eq!(c.unidentifiable.len(), p - 34);
    assert!(c.condition_number.is_finite() && c.condition_number < 1e4);
    // Without orientation the tool's rotation is not seen (three fewer), and since the
    // measured point, the flange centre, lies on axis 7, which way that axis points is
    // not seen either (two fewer).
    let samples = simulate(&robot, &DVector::zeros(p), &q, false, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    assert_eq!(c.identified.len(), 4 * 7 + 6 - 3 - 2, "{:?}", c.identified);
}

/// Data that excite almost nothing are refused, and data without joints too.
#[test]
fn refuses_data_that_cannot_identify_the_model() {
    let robot = kr150();
    // Only joint 1 turns: a circle, far too little for the parameters it excites
    // when there are only four samples.
    let q: Vec<Vec<f64>> = (0..4)
        .map(|i| vec![0.2 * f64::from(i), -1.0, 1.2, 0.0, 0.5, 0.0])
        .collect();
    let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
    let error = identify(&robot, &samples, &CalibrateOptions::default()).unwrap_err();
    assert!(
        matches!(
            error,
            CalibrateError::TooFewMeasurements {
                measurements: 12,
                ..
            }
        ),
        "{error}"
    );
    let mut no_joints = samples.clone();
    no_joints.joints = None;
    assert_eq!(
        identify(&robot, &no_joints, &CalibrateOptions::default()).unwrap_err(),
        CalibrateError::MissingJoints
    );
    // Joint values of another robot.
    let error = identify(&iiwa(), &samples, &CalibrateOptions::default()).unwrap_err();
    assert_eq!(
        error,
        CalibrateError::JointCount {
            robot: 7,
            samples: 6
        }
    );
    // Many samples on that circle: identification runs, but a circular arc has only
    // seven degrees of freedom (centre 3, axis 2, radius 1, phase 1), so at most seven
    // parameters are identified and the rest are reported unidentifiable.
    let q: Vec<Vec<f64>> = (0..40)
        .map(|i| vec![0.05 * f64::from(i), -1.0, 1.2, 0.0, 0.5, 0.0])
        .collect();
    let samples = simulate(&robot, &DVector::zeros(42), &q, false, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    assert!(c.identified.len() <= 7, "{:?}", c.identified);
    assert_eq!(c.unidentifiable.len(), 42 - c.identified.len());
    let dropped = |p| c.unidentifiable.iter().any(|(q, _)| *q == p);
    // Joint 2 never turns: its angle offset cannot be told from the base rotation.
    assert!(dropped(Parameter::Mdh {
        joint: 1,
        parameter: MdhParameter::Theta
    }));
}

/// The stored model reproduces the identification's predictions through the runtime's
/// model, and the residuals it leaves are the identification's.
#[test]
fn stored_model_agrees_with_the_identification() {
    let dir = shipped_robot_path("kr150-2");
    let robot = Robot::load(&dir).unwrap();
    let samples = adwi_samples::read_samples(
        &dir.parent().unwrap().join("samples.csv"),
        &adwi_samples::ColumnMap::default(),
    )
    .unwrap();
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    let model = c.prepared_model();
    let joints = samples.joints.as_ref().unwrap();
    for q in joints.rows().step_by(37) {
        assert_eq!(model.error(q).unwrap(), c.predict_error(q));
    }
    let residual = adwi_compile::hybrid::residual_samples(&samples, &model).unwrap();
    let rms = (residual
        .error_mm
        .iter()
        .map(|e| e.iter().map(|v| v * v).sum::<f64>())
        .sum::<f64>()
        / residual.len() as f64)
        .sqrt();
    assert!(
        (rms - c.position_rms_mm).abs() < 1e-9,
        "{rms} vs {}",
        c.position_rms_mm
    );

    // With compliance identified, the stored calibrated chain carries it and predicts
    // the same deflected poses.
    let robot = ur5();
    let model = Model::new(&robot, true, 0);
    let q = poses(&robot, 80, 12);
    let all: Vec<usize> = (0..model.len()).collect();
    let truth = compliant_deviations_on(&model.parameters, &all, 4);
    let samples = simulate_model(&model, &truth, &q, false, 0.01, 5);
    let options = CalibrateOptions {
        compliance: true,
        ..CalibrateOptions::default()
    };
    let c = identify(&robot, &samples, &options).unwrap();
    let model = c.prepared_model();
    let stored = model.calibrated().compliance.unwrap();
    for joint in 1..3 {
        let identified = c.value(Parameter::Compliance { joint });
        assert!(identified > 0.0);
        assert_eq!(stored.compliance[joint], identified * URAD_PER_NM);
    }
    for q in &q {
        assert_eq!(model.error(q).unwrap(), c.predict_error(q));
    }
    let residual = adwi_compile::hybrid::residual_samples(&samples, &model).unwrap();
    let rms = (residual
        .error_mm
        .iter()
        .map(|e| e.iter().map(|v| v * v).sum::<f64>())
        .sum::<f64>()
        / residual.len() as f64)
        .sqrt();
    assert!((rms - c.position_rms_mm).abs() < 1e-9);
}

/// A seven-joint robot is identified and stored as its chains.
#[test]
fn seven_joint_robots_are_stored_as_chains() {
    let robot = iiwa();
    let q = poses(&robot, 60, 6);
    let p = Parameter::all_of(&robot).len();
    let x = deviations_on(&Parameter::all_of(&robot), &[0, 3, 9], 1);
    let samples = simulate(&robot, &x, &q, true, 0.0, 0);
    let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
    assert_eq!(c.parameters.len(), p);
    let model = c.prepared_model();
    assert_eq!(model.joint_count(), 7);
    for q in &q[..5] {
        assert_eq!(model.error(q).unwrap(), c.predict_error(q));
    }
}

/// The calibrated robot written as a robot file and as URDF, read again, has the
/// calibrated forward kinematics to 1e-9 mm: for an MD-H robot and a URDF chain.
#[test]
fn written_calibrated_robots_reproduce_the_calibrated_model() {
    for robot in [
        kr150(),
        iiwa(),
        Robot::load(shipped_file("ur10", "robot.urdf")).unwrap(),
    ] {
        let q = poses(&robot, 80, 7);
        let p = Parameter::all_of(&robot).len();
        let all: Vec<usize> = (0..p).collect();
        let truth = deviations_on(&Parameter::all_of(&robot), &all, 8);
        let samples = simulate(&robot, &truth, &q, true, 0.0, 0);
        let c = identify(&robot, &samples, &CalibrateOptions::default()).unwrap();
        let calibrated = c.calibrated_robot();
        let dir = tempfile_dir();
        let toml_path = dir.join(format!("{}.toml", robot.joint_count()));
        std::fs::write(&toml_path, calibrated.to_toml_string(&["test".into()])).unwrap();
        let urdf_path = dir.join(format!("{}.urdf", robot.joint_count()));
        std::fs::write(
            &urdf_path,
            calibrated.to_urdf_string(&["test".into()]).unwrap(),
        )
        .unwrap();
        let from_toml = Robot::load(&toml_path).unwrap();
        let from_urdf = Robot::load_with(
            &urdf_path,
            &adwi_robot::urdf::LinkNames {
                base_link: None,
                tip_link: Some(adwi_robot::urdf::TCP_LINK.into()),
                flange_link: None,
            },
        )
        .unwrap();
        let mut largest: f64 = 0.0;
        for q in poses(&robot, 200, 10) {
            let want = calibrated.tcp_pose(&q);
            for back in [&from_toml, &from_urdf] {
                let got = back.tcp_pose(&q);
                largest = largest.max((got.translation.vector - want.translation.vector).norm());
                assert!(got.rotation.angle_to(&want.rotation) < 1e-12);
            }
        }
        println!(
            "{}: written calibrated robot files agree to {largest:.2e} mm",
            robot.name
        );
        assert!(largest < 1e-9, "{}: {largest} mm", robot.name);
        std::fs::remove_dir_all(dir).unwrap();
    }

    // With compliance identified, the robot file carries it: read again, it deflects
    // as the calibrated model does, and so does the file read a second time.
    for robot in [ur5(), iiwa()] {
        let model = Model::new(&robot, true, 0);
        let q = poses(&robot, 120, 7);
        let all: Vec<usize> = (0..model.len()).collect();
        let truth = compliant_deviations_on(&model.parameters, &all, 8);
        let samples = simulate_model(&model, &truth, &q, false, 0.0, 0);
        let options = CalibrateOptions {
            compliance: true,
            ..CalibrateOptions::default()
        };
        let c = identify(&robot, &samples, &options).unwrap();
        let calibrated = c.calibrated_robot();
        let text = calibrated.to_toml_string(&["test".into()]);
        assert!(text.contains("compliance_urad_per_nm = "), "{text}");
        let back = Robot::from_toml_str(&text).unwrap();
        assert_eq!(
            back.gravity_model().unwrap().compliance,
            calibrated.gravity_model().unwrap().compliance
        );
        let mut largest: f64 = 0.0;
        for q in poses(&robot, 200, 10) {
            let want = loaded(calibrated, &q);
            let got = loaded(&back, &q);
            largest = largest.max(
                (Vector3::from(got.translation_mm) - Vector3::from(want.translation_mm)).norm(),
            );
            // The deflection is there: the loaded pose is not the commanded one.
            let still = calibrated.tcp_transform(&q);
            assert!(
                (Vector3::from(still.translation_mm) - Vector3::from(want.translation_mm)).norm()
                    > 1e-3
            );
        }
        println!(
            "{}: written calibrated robot file with compliances agrees to {largest:.2e} mm",
            robot.name
        );
        assert!(largest < 1e-9, "{}: {largest} mm", robot.name);
        // A calibration from that file starts from its compliances: errors that are
        // the deflection alone are what its nominal model already predicts.
        let mut deflections = samples.clone();
        for (i, q) in q.iter().enumerate() {
            let e = transform_pose_error(&back.tcp_transform(q), &loaded(&back, q));
            deflections.error_mm[i] = [e[0], e[1], e[2]];
        }
        let again = identify(&back, &deflections, &CalibrateOptions::default()).unwrap();
        assert!(
            again.initial_position_rms_mm < 1e-9,
            "{}",
            again.initial_position_rms_mm
        );
    }
}

/// A fresh folder under the system's temporary folder.
fn tempfile_dir() -> std::path::PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "adwi-robot-test-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Values no robot has are refused before iterating, naming the sample and its line: an
/// error beyond a metre (a tracker's frame, another unit), a joint beyond ten turns, a
/// non-finite value; a model that is not finite is found at its first sample and column.
#[test]
fn implausible_samples_are_refused_before_iterating() {
    let robot = kr150();
    let q = poses(&robot, 60, 4);
    let samples = simulate(&robot, &DVector::zeros(42), &q, true, 0.0, 0);
    let options = CalibrateOptions::default();
    let start = std::time::Instant::now();
    let mut far = samples.clone();
    far.error_mm[5] = [5e5, 0.0, 0.0];
    assert_eq!(
        identify(&robot, &far, &options).unwrap_err().to_string(),
        "sample 5 (line 7): a position error of 500000 mm, more than the 1000 mm any \
         calibration explains: are the measured poses in another frame (a tracker's) or \
         another unit?"
    );
    let mut turned = samples.clone();
    turned.rotation_error_rad.as_mut().unwrap()[3] = [0.0, 2.0, 0.0];
    assert!(identify(&robot, &turned, &options)
        .unwrap_err()
        .to_string()
        .starts_with("sample 3 (line 5): an orientation error of 2 rad"));
    let mut spun = samples.clone();
    let mut joints = Joints::new(6);
    for (i, q) in q.iter().enumerate() {
        let mut q = q.clone();
        if i == 9 {
            q[2] = 1e300;
        }
        joints.push(&q);
    }
    spun.joints = Some(joints);
    assert!(identify(&robot, &spun, &options)
        .unwrap_err()
        .to_string()
        .starts_with("sample 9 (line 11): joint 3: a joint value (deg) is 5.7295779513082"));
    let mut nan = samples.clone();
    nan.error_mm[0][1] = f64::NAN;
    assert_eq!(
        identify(&robot, &nan, &options).unwrap_err(),
        CalibrateError::NonFinite {
            index: 0,
            line: Some(2)
        }
    );
    assert!(start.elapsed().as_secs_f64() < 1.0);

    let r = DVector::from_vec(vec![0.0; 6]);
    let mut j = DMatrix::zeros(6, 4);
    assert_eq!(first_non_finite(&r, &j), None);
    j[(4, 2)] = f64::INFINITY;
    j[(5, 1)] = f64::NAN;
    assert_eq!(first_non_finite(&r, &j), Some((4, Some(2))));
    let mut r = r;
    r[5] = f64::NAN;
    assert_eq!(first_non_finite(&r, &j), Some((5, None)));
}

/// Realistic joint-space terms on the term columns among `columns`: 0.2-0.5 mrad, sign
/// at random; the rest as [`deviations_on`].
fn terms_on(parameters: &[Parameter], columns: &[usize], seed: u64) -> DVector<f64> {
    let mut x = deviations_on(parameters, columns, seed);
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 2000);
    for &c in columns {
        if parameters[c].is_joint_term() {
            let m = rng.gen_range(2e-4..5e-4);
            x[c] = if rng.gen::<bool>() { m } else { -m };
        }
    }
    x
}

/// The walk a linearisation reads its error from is the exact model's loaded TCP to the
/// bit (an MD-H robot, one with compliance, a URDF chain; with joint-space terms), at
/// states away from nominal: the error and the Jacobian share it, and the fit's
/// residuals must not move by it.
#[test]
fn a_walk_ends_at_the_loaded_tcp_to_the_bit() {
    let bits = |t: &adwi_runtime::kinematics::Transform| {
        let mut out: Vec<u64> = t.rotation.iter().flatten().map(|v| v.to_bits()).collect();
        out.extend(t.translation_mm.iter().map(|v| v.to_bits()));
        out
    };
    for (robot, compliance) in [(kr150(), false), (ur5(), true), (iiwa(), false)] {
        let model = Model::new(&robot, compliance, 2);
        let all: Vec<usize> = (0..model.len()).collect();
        let x = terms_on(&model.parameters, &all, 5);
        let state = model.state(&x).unwrap();
        for q in poses(&robot, 200, 9) {
            let walked = Walk::of(&state, &q).tcp;
            let exact = loaded_with_terms(&state.robot, &state.terms, &q);
            assert_eq!(bits(&walked), bits(&exact), "{} at {q:?}", robot.name);
        }
    }
}

/// Every joint-space term column against central differences of the exact model, whose
/// joints the terms move before the chain (and gravity) acts.
#[test]
fn joint_term_jacobian_matches_finite_differences() {
    for (robot, compliance) in [(kr150(), false), (ur5(), true), (iiwa(), false)] {
        let model = Model::new(&robot, compliance, 2);
        let all: Vec<usize> = (0..model.len()).collect();
        let x = terms_on(&model.parameters, &all, 3);
        let state = model.state(&x).unwrap();
        assert!(!state.terms.is_none());
        let q = &poses(&robot, 1, 5)[0];
        let j = model.jacobian(&x, &state, q);
        let h = 1e-7;
        for c in model.first_term()..model.len() {
            let mut d = DVector::zeros(model.len());
            d[c] = h;
            let plus = model.error(&model.state(&model.step(&x, &d)).unwrap(), q);
            let minus = model.error(&model.state(&model.step(&x, &(-&d))).unwrap(), q);
            let numeric = (plus - minus) / (2.0 * h);
            let scale = j.column(c).norm().max(1.0);
            // With compliance the torques follow the moved joints, which the column
            // leaves out (as for the geometry's columns): c·∂τ/∂q, about 1e-4 here.
            let tolerance = if compliance { 1e-3 } else { 1e-6 } * scale;
            for a in 0..6 {
                // log(R_actual R_nominalᵀ) differs from the rotation perturbation by the
                // inverse left Jacobian of SO(3), as for every column.
                let tolerance = if a < 3 { tolerance } else { 2e-2 * scale };
                assert!(
                    (numeric[a] - j[(a, c)]).abs() < tolerance,
                    "{}: {} row {a}: {} vs {}",
                    robot.name,
                    model.parameters[c],
                    numeric[a],
                    j[(a, c)]
                );
            }
        }
    }
}

/// Joint-space terms simulated on the exact model are recovered from noise-free data,
/// every one the data see identified, and the stored model (the runtime's, with its
/// terms) predicts the true robot's error.
#[test]
fn recovers_known_joint_terms_from_noise_free_data() {
    for robot in [kr150(), iiwa()] {
        let model = Model::new(&robot, false, 2);
        let q = poses(&robot, 300, 1);
        let options = CalibrateOptions {
            harmonics: 2,
            ..CalibrateOptions::default()
        };
        let p = model.len();
        let zero = simulate_model(&model, &DVector::zeros(p), &q, true, 0.0, 0);
        // What the poses can separate: nothing is held for want of evidence.
        let everything = CalibrateOptions {
            hold_untrustworthy: false,
            ..options
        };
        let structure = identify(&robot, &zero, &everything).unwrap();
        let columns = columns_of(&structure);
        let terms = columns
            .iter()
            .filter(|&&c| model.parameters[c].is_joint_term())
            .count();
        assert!(terms >= 8, "{}: {:?}", robot.name, structure.identified);
        let truth = terms_on(&model.parameters, &columns, 2);
        let samples = simulate_model(&model, &truth, &q, true, 0.0, 0);
        let c = identify(&robot, &samples, &options).unwrap();
        assert_eq!(c.identified, structure.identified, "{}", robot.name);
        for i in 0..p {
            let gap = (c.deviations[i] - truth[i]).abs();
            assert!(
                gap <= 1e-6,
                "{}, {}: identified {} true {}",
                robot.name,
                c.parameters[i],
                c.deviations[i],
                truth[i]
            );
        }
        assert!(!c.joint_terms().is_none());
        let truth_state = model.state(&truth).unwrap();
        let stored = c.prepared_model();
        for q in poses(&robot, 10, 9) {
            let expected = model.error(&truth_state, &q);
            let (position, rotation) = stored.error(&q).unwrap();
            let at = stored.at(&q).unwrap();
            for a in 0..3 {
                assert!((expected[a] - position[a]).abs() < 1e-6);
                assert!((expected[a + 3] - rotation[a]).abs() < 1e-9);
                assert!((at.position_mm[a] - position[a]).abs() < 1e-9);
                assert!((at.rotation_rad[a] - rotation[a]).abs() < 1e-12);
                let (predicted, _) = c.predict_error(&q);
                assert!((predicted[a] - position[a]).abs() < 1e-9);
            }
        }
    }
}

/// Terms the data carry no trace of are held, each with the information criterion's
/// reason, and the model is the one without them; terms as large as a gear's are kept.
#[test]
fn joint_terms_without_support_are_held_by_the_information_criterion() {
    let robot = kr150();
    let model = Model::new(&robot, false, 2);
    let q = poses(&robot, 400, 1);
    let options = CalibrateOptions {
        harmonics: 2,
        ..CalibrateOptions::default()
    };
    let p = model.len();
    let zero = simulate_model(&model, &DVector::zeros(p), &q, false, 0.0, 0);
    let columns = columns_of(&identify(&robot, &zero, &options).unwrap());
    // Geometry only, and 0.05 mm of noise: no term is in the data.
    let mut truth = deviations_on(&model.parameters, &columns, 4);
    for c in model.first_term()..p {
        truth[c] = 0.0;
    }
    let samples = simulate_model(&model, &truth, &q, false, 0.05, 7);
    let c = identify(&robot, &samples, &options).unwrap();
    let identified_terms: Vec<_> = c.identified.iter().filter(|p| p.is_joint_term()).collect();
    // At 400 × 3 coordinates, sqrt(ln m) = 2.7, below the significance of 3: the terms
    // are held as undetermined or unsupported, and none survives by chance here.
    assert!(identified_terms.is_empty(), "{identified_terms:?}");
    assert!(c.held().iter().any(|r| r.parameter.is_joint_term()));
    assert!(c.joint_terms().is_none());
    // Joint 2's first harmonic as large as a gear's: identified.
    let sin_q2 = model
        .parameters
        .iter()
        .position(|p| {
            *p == Parameter::JointTerm {
                joint: 1,
                harmonic: 1,
                cosine: false,
            }
        })
        .unwrap();
    truth[sin_q2] = 3e-4;
    let samples = simulate_model(&model, &truth, &q, false, 0.05, 7);
    let c = identify(&robot, &samples, &options).unwrap();
    let r = &c.report[sin_q2];
    assert_eq!(r.status, ParameterStatus::Identified, "{}", r.reason());
    let se = r.standard_error.unwrap();
    assert!((r.value - 3e-4).abs() < 4.0 * se, "{} ± {se}", r.value);
    assert_eq!(r.parameter.to_string(), "sin q2");
}

/// The threshold of the information criterion and its hold reason in words.
#[test]
fn the_information_criterion_threshold_is_the_root_of_ln_m() {
    assert!((super::trust::bic_threshold(3000) - 3000f64.ln().sqrt()).abs() < 1e-15);
    let reason = HoldReason::Unsupported {
        value: 2e-5,
        standard_error: 1e-5,
        threshold: 2.83,
    };
    let parameter = Parameter::JointTerm {
        joint: 2,
        harmonic: 2,
        cosine: true,
    };
    assert_eq!(parameter.to_string(), "cos 2q3");
    let text = reason.describe(parameter);
    assert!(
        text.contains("+0.0200 mrad") && text.contains("2.0 standard errors"),
        "{text}"
    );
    assert!(text.contains("BIC") && text.contains("2.8"), "{text}");
}
