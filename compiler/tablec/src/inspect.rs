//! `tablec inspect`: the inspect job ([`adwi_jobs::InspectJob`]), printed field by field.

use adwi_jobs::inspect::CellAt;
use adwi_jobs::{InspectArgs, InspectJob, Inspected};
use adwi_runtime::format::{Header, ServedField, CONTENT_MODEL, TCP_MARGIN_MM};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: InspectArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let t = InspectJob::new(args.job)?.run()?;
    print_file(&t);
    print_model(&t);
    print_evidence(&t.header);
    print_method(&t);
    print_tiers(&t);
    if let Some(cell) = &t.cell {
        print_cell(cell);
    }
    Ok(())
}

/// The file, its format and what its samples carry.
fn print_file(t: &Inspected) {
    let h = &t.header;
    println!(
        "file            {} ({} bytes)",
        t.file.display(),
        t.size_bytes
    );
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
    println!(
        "samples         {} ({})",
        h.sample_count,
        t.content.join(", ")
    );
    if let Some(voxel_mm) = h.merge_voxel_mm {
        println!(
            "merged          the measured samples averaged within {voxel_mm:.4} mm voxels (one per \
             voxel and configuration): both tiers answer from these {} averages",
            h.sample_count
        );
    }
}

/// The robot's joints, and the calibrated model's compliance and joint-space terms.
fn print_model(t: &Inspected) {
    if let Some(n) = t.joints {
        println!("joints          {n}");
    }
    if let Some(c) = &t.compliance {
        let values: Vec<String> = c.urad_per_nm.iter().map(|v| format!("{v:.4}")).collect();
        println!(
            "compliance      {} µrad/(N·m), joints 1 to {} (the calibrated model deflects under gravity)",
            values.join(", "),
            c.urad_per_nm.len()
        );
        if c.payload_kg > 0.0 {
            let [x, y, z] = c.payload_com_mm;
            println!(
                "load at flange  {} kg, centre of mass ({x:.1}, {y:.1}, {z:.1}) mm in the tool frame",
                c.payload_kg
            );
        }
    }
    for term in &t.joint_terms {
        let c = term.coefficients_mrad;
        let [lo, hi] = term.range_deg;
        println!(
            "joint terms     joint {}: {:+.4} sin q {:+.4} cos q {:+.4} sin 2q {:+.4} cos 2q mrad, held beyond [{lo:.1}, {hi:.1}]°",
            term.joint, c[0], c[1], c[2], c[3],
        );
    }
    if let Some(ranges) = &t.residual_joint_range_deg {
        println!("residual joints {}", crate::describe_joint_ranges(ranges));
    }
}

/// What the samples span beyond their positions (format version 4): the answers beyond it
/// carry the evidence flag.
fn print_evidence(h: &Header) {
    let (e, version) = (&h.evidence, h.version);
    if version < 4 {
        println!(
            "evidence        not recorded (format version {version}): orientations are not \
             checked, a named TCP is flagged `tcp`"
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
            // As the runtime flags a named TCP (docs/runtime.md, "Another TCP").
            let margin = TCP_MARGIN_MM;
            let hybrid = h.content_flags & CONTENT_MODEL != 0;
            let tcp = match (h.turns_measured_lever(), hybrid) {
                (true, _) => "a query may name another TCP, whose lever the model turns".into(),
                (false, true) => format!(
                    "no orientation error is served (the samples measured position alone, \
                     which does not determine the model's), and a named TCP more than \
                     {margin} mm from it is carried unturned and flagged `tcp`"
                ),
                (false, false) => format!(
                    "a named TCP more than {margin} mm from it is flagged `tcp`: no model \
                     turns its lever"
                ),
            };
            println!(
                "                measured point ({x:.3}, {y:.3}, {z:.3}) mm in the flange frame: \
                 {tcp}"
            );
        }
        None => println!(
            "                measured point on the flange not recorded: a named TCP is flagged `tcp`"
        ),
    }
}

/// The method's parameters, how they were chosen, the posture term and the joint screen.
fn print_method(t: &Inspected) {
    let h = &t.header;
    println!("method          {}", crate::describe_method(&h.method));
    match h.tuning {
        Some(tuning) => println!(
            "cross-validated {}-fold on the samples alone: the method {:.4} mm mean{}",
            tuning.folds,
            tuning.cv_mean_mm,
            tuning.served_cv_mean_mm.map_or(String::new(), |m| format!(
                "; served field {} chosen by the same folds: {m:.4} mm mean",
                crate::served_field_name(h.served_field)
            ))
        ),
        None => println!("cross-validated no (parameters and served field given)"),
    }
    match t.posture {
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
        None if t.hybrid => println!("posture term    off"),
        None => {}
    }
    println!(
        "joint screen    {}",
        crate::describe_joint_screen(h.joint_radius_rad)
    );
}

/// The grid, both tiers' coverage and the sections' sizes.
fn print_tiers(t: &Inspected) {
    let h = &t.header;
    let g = h.grid;
    let summary = &t.summary;
    let max = g.max_mm();
    println!(
        "grid            {} × {} × {} cells of {:.3} mm, ({:.3}, {:.3}, {:.3}) to ({:.3}, {:.3}, {:.3}) mm",
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
                ServedField::Method => "the method's answer",
                ServedField::Kriging =>
                    "kriging with a nugget of the samples' errors (--served-field kriging)",
                ServedField::KrigingToolAxis =>
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
}

/// The cell asked for: its candidates, its node values and the exact method's neighbours
/// and weights at the point.
fn print_cell(at: &CellAt) {
    let p = at.at_mm;
    let Some(cell) = &at.detail else {
        println!(
            "cell            ({}, {}, {}) is outside the grid",
            p[0], p[1], p[2]
        );
        return;
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
    for n in &at.neighbours {
        println!(
            "  at target     sample {:>6}  distance {:.6} mm  λ {:.9e}  ζ {:.9e}  q {:.9}",
            n.sample, n.distance_mm, n.lambda_per_mm, n.zeta_per_mm2, n.weight
        );
    }
}
