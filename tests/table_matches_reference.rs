//! The compiled table's answer equals the brute-force reference's, for random sample
//! clouds, random parameters and targets chosen where a cell table is most likely to go
//! wrong: inside cells, on cell faces and corners, exactly on samples, and collinear with a
//! sample through the base origin.

use adwi_compiler::build::{compile, BuildOptions};
use adwi_compiler::reference;
use adwi_compiler::samples::SampleSet;
use adwi_runtime::{Status, Table, Target};
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
                max_neighbours: k,
                power,
                w1,
                w2: 1.0 - w1,
                consistency_screen: screen,
                lambda_min_per_mm: lambda,
                zeta_min_per_mm2: zeta,
                radius_mm: radius,
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
            let pad = options.radius_mm.unwrap_or(60.0);
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
