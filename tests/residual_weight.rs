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
