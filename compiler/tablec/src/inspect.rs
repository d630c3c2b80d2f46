//! `tablec inspect`.

use std::path::PathBuf;

use adwi_runtime::format::{
    CONTENT_CONFIG, CONTENT_JOINTS, CONTENT_MODEL, CONTENT_ORIENTATION, HEADER_LEN,
};
use adwi_runtime::Target;

#[derive(clap::Args)]
pub struct Args {
    /// The table.
    table: PathBuf,
    /// Also print the cell holding X Y Z: its candidates, its node values and the exact
    /// method's neighbours and weights at the point.
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_negative_numbers = true)]
    cell: Option<Vec<f64>>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let table = crate::open_table(&args.table)?;
    let h = table.header();
    let g = h.grid;
    let summary = adwi_compile::inspect::summary(&table)
        .ok_or_else(|| anyhow::anyhow!("table bytes changed after validation"))?;
    let size = HEADER_LEN as u64 + h.payload_len;
    println!("file            {} ({size} bytes)", args.table.display());
    println!(
        "format          version {}, rkyv flags {:#x}",
        h.version, h.rkyv_flags
    );
    if h.version == 1 {
        println!("                version 1: answered by the exact tier (no served field)");
    }
    println!(
        "payload         {} bytes, checksum {:#018x}",
        h.payload_len, h.payload_checksum
    );
    println!("source hash     {:#018x}", h.source_hash);
    let mut content = vec!["positions"];
    for (flag, name) in [
        (CONTENT_ORIENTATION, "orientations"),
        (CONTENT_CONFIG, "configurations"),
        (CONTENT_JOINTS, "joint values"),
        (
            CONTENT_MODEL,
            "kinematic model: hybrid table, query with joint values",
        ),
    ] {
        if h.content_flags & flag != 0 {
            content.push(name);
        }
    }
    println!(
        "samples         {} ({})",
        h.sample_count,
        content.join(", ")
    );
    if let Some(n) = table.joint_count() {
        println!("joints          {n}");
    }
    if let Some(c) = table.model().and_then(|m| m.calibrated().compliance) {
        let n = table.joint_count().unwrap_or(0);
        let values: Vec<String> = c.compliance[..n]
            .iter()
            .map(|v| format!("{:.4}", v / adwi_robot::model::URAD_PER_NM))
            .collect();
        println!(
            "compliance      {} µrad/(N·m), joints 1 to {n} (the calibrated model deflects under gravity)",
            values.join(", ")
        );
        if c.payload_kg > 0.0 {
            let [x, y, z] = c.payload_com_mm;
            println!(
                "load at flange  {} kg, centre of mass ({x:.1}, {y:.1}, {z:.1}) mm in the tool frame",
                c.payload_kg
            );
        }
    }
    if let Some(terms) = table
        .model()
        .map(|m| m.joint_terms())
        .filter(|t| !t.is_none())
    {
        let n = table.joint_count().unwrap_or(0);
        for (j, (c, [lo, hi])) in terms.coefficients_rad[..n]
            .iter()
            .zip(terms.range_rad)
            .enumerate()
            .filter(|(_, (c, _))| c.iter().any(|&v| v != 0.0))
        {
            println!(
                "joint terms     joint {}: {:+.4} sin q {:+.4} cos q {:+.4} sin 2q {:+.4} cos 2q mrad, held beyond [{:.1}, {:.1}]°",
                j + 1,
                c[0] * 1e3,
                c[1] * 1e3,
                c[2] * 1e3,
                c[3] * 1e3,
                lo.to_degrees(),
                hi.to_degrees()
            );
        }
    }
    print_evidence(&h.evidence, h.version);
    println!("method          {}", crate::describe_method(&h.method));
    match h.tuning {
        Some(t) => println!(
            "cross-validated {}-fold on the samples alone: the method {:.4} mm mean{}",
            t.folds,
            t.cv_mean_mm,
            t.served_cv_mean_mm.map_or(String::new(), |m| format!(
                "; served field {} chosen by the same folds: {m:.4} mm mean",
                crate::served_field_name(h.served_field)
            ))
        ),
        None => println!("cross-validated no (parameters and served field given)"),
    }
    match table.posture() {
        Some(p) => println!(
            "posture term    on: R {} mm, ℓ_q {} rad, W0 {}{}",
            p.radius_mm,
            p.length_rad,
            p.floor,
            h.tuning
                .and_then(|t| t.posture_cv_mean_mm)
                .map_or(String::new(), |m| format!(
                    "; served field with the term, by the same folds: {m:.4} mm mean"
                ))
        ),
        None if table.is_hybrid() => println!("posture term    off"),
        None => {}
    }
    println!(
        "joint screen    {}",
        crate::describe_joint_screen(h.joint_radius_rad)
    );
    let max = g.max_mm();
    println!(
        "grid            {} × {} × {} cells of {} mm, ({}, {}, {}) to ({}, {}, {}) mm",
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.cell_mm,
        g.origin_mm[0],
        g.origin_mm[1],
        g.origin_mm[2],
        max[0],
        max[1],
        max[2]
    );
    let percent = |n: usize| 100.0 * n as f64 / summary.cells.max(1) as f64;
    println!(
        "exact tier      {} of {} cells with candidates ({:.1} %); per cell mean {:.1}, max {}; {} lists stored apart",
        summary.covered,
        summary.cells,
        percent(summary.covered),
        summary.mean_candidates,
        summary.max_candidates,
        summary.lists_apart
    );
    match summary.served_cells {
        Some(served) => println!(
            "served tier     {served} of {} cells served ({:.1} %), {} node set(s): {}; nodes hold {}",
            summary.cells,
            percent(served),
            summary.node_sets.len(),
            summary
                .node_sets
                .iter()
                .map(|&c| if c == u8::MAX {
                    "any configuration".to_string()
                } else {
                    format!("configuration {c}")
                })
                .collect::<Vec<_>>()
                .join(", "),
            match h.served_field {
                adwi_runtime::format::ServedField::Method => "the method's answer",
                adwi_runtime::format::ServedField::Kriging =>
                    "kriging with a nugget of the samples' errors (--served-field kriging)",
                adwi_runtime::format::ServedField::KrigingToolAxis =>
                    "kriging with a nugget of the samples' errors, turning with the tool's approach axis (--served-field kriging on a hybrid table)",
            }
        ),
        None if h.joint_radius_rad > 0.0 => {
            println!("served tier     none (a joint screen): queries answer from the exact tier")
        }
        None => println!("served tier     none: queries answer from the exact tier"),
    }
    let sections: Vec<String> = summary
        .sections
        .iter()
        .map(|(name, bytes)| format!("{name} {bytes} B"))
        .collect();
    println!("sizes           {}", sections.join(", "));
    if let Some(p) = args.cell {
        let p = [p[0], p[1], p[2]];
        let Some(cell) = adwi_compile::inspect::cell(&table, p) else {
            println!(
                "cell            ({}, {}, {}) is outside the grid",
                p[0], p[1], p[2]
            );
            return Ok(());
        };
        let [ix, iy, iz] = cell.coords;
        println!(
            "cell            #{} ({ix}, {iy}, {iz}), candidates {:?}",
            cell.index, cell.candidates
        );
        for (corner, node) in cell.nodes_mm.iter().enumerate() {
            let at = [corner & 1, corner >> 1 & 1, corner >> 2 & 1];
            match node {
                Some(e) => println!(
                    "  node {at:?}    error {:.9} {:.9} {:.9} mm",
                    e[0], e[1], e[2]
                ),
                None => println!("  node {at:?}    no admissible sample: cell not served"),
            }
        }
        if let Ok(pred) = table.explain(&Target::at(p)) {
            for (n, q) in pred
                .neighbours
                .as_slice()
                .iter()
                .zip(pred.weights.as_slice())
            {
                println!(
                    "  at target     sample {:>6}  distance {:.6} mm  λ {:.9e}  ζ {:.9e}  q {:.9}",
                    n.sample,
                    n.degree.distance_mm,
                    n.degree.lambda_per_mm,
                    n.degree.zeta_per_mm2,
                    q
                );
            }
        }
    }
    Ok(())
}

/// What the samples span beyond their positions (format version 4): the answers beyond it
/// carry the evidence flag.
fn print_evidence(e: &adwi_runtime::format::EvidenceRecord, version: u16) {
    if version < 4 {
        println!(
            "evidence        not recorded (format version {version}): answers are never flagged"
        );
        return;
    }
    match e.approach {
        Some(cone) => {
            let [x, y, z] = cone.axis;
            println!(
                "evidence        tool approach axes within {:.2}° of ({x:.4}, {y:.4}, {z:.4}), base frame; \
                 answers beyond that and {:.0}° more are flagged `orientation`",
                cone.spread_rad.to_degrees(),
                adwi_runtime::format::ORIENTATION_MARGIN_RAD.to_degrees()
            );
        }
        None => println!("evidence        the samples' orientations are not known: not checked"),
    }
    match e.point_in_flange {
        Some(p) => {
            let [x, y, z] = p.translation_mm;
            println!(
                "                measured point ({x:.3}, {y:.3}, {z:.3}) mm in the flange frame: \
                 a query may name another TCP"
            );
        }
        None => println!(
            "                measured point on the flange not recorded: a named TCP is flagged `tcp`"
        ),
    }
}
