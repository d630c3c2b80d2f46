//! The paper's worked example (docs/method.md §7): target P1 = (2000, 700, 1000) mm and
//! eight samples, every intermediate value reproduced to 1e-9, through the reference and
//! end to end through `tablec build` and `tablec query`.

use std::path::{Path, PathBuf};
use std::process::Command;

use adwi_compile::reference;
use adwi_runtime::method::MethodParams;
use adwi_runtime::Target;
use adwi_samples::{read_samples, ColumnMap};

const P1: [f64; 3] = [2000.0, 700.0, 1000.0];
const PREDICTED_MM: [f64; 3] = [0.044584991, 0.995639127, -0.230310237];

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/paper/worked_example_p1.csv")
}

/// The paper's printed columns: distance, angle, area, λ, ζ, q per sample.
fn printed() -> Vec<[f64; 6]> {
    let mut reader = csv::Reader::from_path(example()).unwrap();
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            [7, 8, 9, 10, 11, 12].map(|i| r[i].parse::<f64>().unwrap())
        })
        .collect()
}

fn assert_close(what: &str, got: f64, want: f64, relative: bool) {
    let scale = if relative { want.abs() } else { 1.0 };
    assert!(
        (got - want).abs() <= 1e-9 * scale,
        "{what}: got {got:.12e}, paper {want:.12e}"
    );
}

#[test]
fn reference_reproduces_every_intermediate_value() {
    let samples = read_samples(&example(), &ColumnMap::default()).unwrap();
    let records = samples.records();
    // ε large enough that all eight are admissible, as in the paper.
    let params = MethodParams::paper(200.0);
    let neighbours = reference::neighbours(&records, &params, &Target::at(P1));
    assert_eq!(neighbours.len(), 8);
    let prediction = reference::predict(&records, &params, &Target::at(P1)).unwrap();
    let printed = printed();
    for (n, q) in prediction
        .neighbours
        .as_slice()
        .iter()
        .zip(prediction.weights.as_slice())
    {
        let [distance, angle, area, lambda, zeta, q_paper] = printed[n.sample as usize];
        let d = n.degree;
        let id = n.sample + 1;
        // Printed with 9 decimals (distance, q), 6 decimals (area), 10 significant
        // digits (angle, λ, ζ): compared at 1e-9, absolute or relative accordingly.
        assert_close(&format!("distance {id}"), d.distance_mm, distance, false);
        assert_close(&format!("angle {id}"), d.sin_phi.asin(), angle, true);
        assert_close(&format!("area {id}"), d.area_mm2, area, true);
        assert_close(&format!("lambda {id}"), d.lambda_per_mm, lambda, true);
        assert_close(&format!("zeta {id}"), d.zeta_per_mm2, zeta, true);
        assert_close(&format!("q {id}"), *q, q_paper, false);
    }
    for (got, want) in prediction.position_error_mm.iter().zip(PREDICTED_MM) {
        assert_close("prediction", *got, want, false);
    }
}

#[test]
fn tablec_build_and_query_reproduce_the_prediction() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("p1.tbl");
    let tablec = env!("CARGO_BIN_EXE_tablec");
    let build = Command::new(tablec)
        .args(["build", "--quiet", "-o"])
        .arg(&table)
        .arg(example())
        .output()
        .unwrap();
    assert!(
        build.status.success(),
        "{}",
        String::from_utf8_lossy(&build.stderr)
    );
    let query = Command::new(tablec)
        .arg("query")
        .arg(&table)
        .args(["2000", "700", "1000", "0", "90", "0", "--exact"])
        .output()
        .unwrap();
    assert!(
        query.status.success(),
        "{}",
        String::from_utf8_lossy(&query.stderr)
    );
    let stdout = String::from_utf8(query.stdout).unwrap();
    assert!(
        stdout.contains("status       ok (8 neighbours, exact tier)"),
        "{stdout}"
    );
    let line = stdout.lines().find(|l| l.starts_with("error ")).unwrap();
    let values: Vec<f64> = line
        .split_whitespace()
        .skip(1)
        .take(3)
        .map(|v| v.parse().unwrap())
        .collect();
    for axis in 0..3 {
        assert_close("tablec query", values[axis], PREDICTED_MM[axis], false);
    }
}
