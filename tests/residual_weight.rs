//! A hybrid table's residual weight learned from held-out regions (`--residual-weight
//! auto`): the build says which weight it chose and on what evidence, and the weight is
//! one the held-out points can justify.

use crate::common::{repo, tablec, ur5_grid, UR5_MAP};

/// The number after `label` in `text`.
fn number_after(text: &str, label: &str) -> f64 {
    let start = text
        .find(label)
        .unwrap_or_else(|| panic!("no '{label}' in:\n{text}"))
        + label.len();
    let rest = &text[start..];
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(rest.len());
    rest[..end].parse().unwrap()
}

#[test]
fn a_learned_residual_weight_is_printed_with_its_held_out_evidence() {
    let dir = tempfile::tempdir().unwrap();
    let grid = ur5_grid();
    let robot = repo("tables/ur5/robot.toml");
    let o = tablec(
        &[
            "build",
            grid.to_str().unwrap(),
            "--columns",
            UR5_MAP,
            "--robot",
            robot.to_str().unwrap(),
            "--served-field",
            "method",
            "--posture",
            "off",
            "--cell",
            "30",
            "--residual-weight",
            "auto",
            "-o",
            "weighted.tbl",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let weight = number_after(&stdout, "residual weight ");
    assert!((0.0..=1.0).contains(&weight), "{stdout}");
    // Every choice is made on the same held-out regions, the served field's too.
    assert!(
        stdout.contains(
            "served field   chosen by 5 spatial blocks, each predicted from the others on 1000"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("spatial blocks, each predicted from the others"),
        "{stdout}"
    );
    // The weight chosen leaves no more on the held-out regions than either end does.
    let with = number_after(&stdout, "held-out mean ");
    let model = number_after(&stdout, "mm with it, ");
    let full = number_after(&stdout, "mm with the model alone, ");
    assert!(with <= model + 5e-5 && with <= full + 5e-5, "{stdout}");
    assert!(dir.path().join("weighted.tbl").exists());
}

/// Given two series, every choice of the build is made by predicting each series from the
/// other, as the next series will be predicted: the served field's figures and the
/// residual weight's alike.
#[test]
fn with_two_series_the_build_chooses_by_leaving_each_series_out() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(ur5_grid()).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let rows: Vec<&str> = lines.collect();
    let (first, second) = rows.split_at(rows.len() / 2);
    for (name, half) in [("first.csv", first), ("second.csv", second)] {
        let mut file = format!("{header}\n");
        for row in half {
            file.push_str(row);
            file.push('\n');
        }
        std::fs::write(dir.path().join(name), file).unwrap();
    }
    let robot = repo("tables/ur5/robot.toml");
    let o = tablec(
        &[
            "build",
            "first.csv",
            "second.csv",
            "--columns",
            UR5_MAP,
            "--robot",
            robot.to_str().unwrap(),
            "--posture",
            "off",
            "--cell",
            "30",
            "--residual-weight",
            "auto",
            "--harmonics",
            "auto",
            "-o",
            "two.tbl",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("served field   chosen by 2 series, each predicted from the others"),
        "{stdout}"
    );
    // The harmonic count, when asked for by `auto`, is chosen first, on the same splits.
    assert!(
        stdout.contains("harmonics      chosen by 2 series, each predicted from the others"),
        "{stdout}"
    );
    assert!(
        stdout.contains("2 series, each predicted from the others): "),
        "{stdout}"
    );
}
