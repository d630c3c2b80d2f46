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
    /// Also print the candidate list and centre base weights of the cell holding X Y Z.
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_negative_numbers = true)]
    cell: Option<Vec<f64>>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let table = crate::open_table(&args.table)?;
    let h = table.header();
    let m = h.method;
    let g = h.grid;
    let data = table
        .data()
        .ok_or_else(|| anyhow::anyhow!("table bytes changed after validation"))?;
    let size = HEADER_LEN as u64 + h.payload_len;
    println!("file            {} ({size} bytes)", args.table.display());
    println!(
        "format          version {}, rkyv flags {:#x}",
        h.version, h.rkyv_flags
    );
    println!(
        "payload         {} bytes, checksum {:#018x}",
        h.payload_len, h.payload_checksum
    );
    println!("source hash     {:#018x}", h.source_hash);
    let mut content = vec!["positions"];
    for (flag, name) in [
        (CONTENT_ORIENTATION, "orientations"),
        (CONTENT_CONFIG, "configurations"),
        (CONTENT_JOINTS, "joint angles"),
        (
            CONTENT_MODEL,
            "kinematic model: hybrid table, query with joint angles",
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
    println!("method          {}", crate::describe_method(&m));
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
    let cells = data.cells.len();
    let lists: std::collections::HashSet<(u32, u32)> = data
        .cells
        .iter()
        .map(|c| (c.list_start.to_native(), c.list_len.to_native()))
        .collect();
    let covered: Vec<usize> = data
        .cells
        .iter()
        .map(|c| c.list_len.to_native() as usize)
        .filter(|&n| n > 0)
        .collect();
    let mean = covered.iter().sum::<usize>() as f64 / covered.len().max(1) as f64;
    println!(
        "cells           {cells}, {} covered ({:.1} %)",
        covered.len(),
        100.0 * covered.len() as f64 / cells.max(1) as f64
    );
    println!(
        "candidates      {} distinct lists, {} entries; per covered cell mean {mean:.1}, max {}",
        lists.len(),
        data.list_samples.len(),
        covered.iter().max().copied().unwrap_or(0)
    );
    println!(
        "sizes           samples {} B, cells {} B, lists {} B, base weights {} B",
        data.samples.len() * std::mem::size_of::<adwi_runtime::format::ArchivedSampleRecord>(),
        cells * std::mem::size_of::<adwi_runtime::format::ArchivedCellRecord>(),
        data.list_samples.len() * 4,
        (cells + 1) * 4 + data.centre_samples.len() * 12
    );
    if let Some(p) = args.cell {
        let p = [p[0], p[1], p[2]];
        let Some(cell) = g.cell_of(p) else {
            println!(
                "cell            ({}, {}, {}) is outside the grid",
                p[0], p[1], p[2]
            );
            return Ok(());
        };
        let [ix, iy, iz] = g.cell_coords(cell);
        let record = &data.cells[cell];
        let start = record.list_start.to_native() as usize;
        let list: Vec<u32> = data.list_samples[start..start + record.list_len.to_native() as usize]
            .iter()
            .map(|i| i.to_native())
            .collect();
        println!("cell            #{cell} ({ix}, {iy}, {iz}), candidates {list:?}");
        let c0 = data.centre_offsets[cell].to_native() as usize;
        let c1 = data.centre_offsets[cell + 1].to_native() as usize;
        for i in c0..c1 {
            println!(
                "  centre weight sample {:>6}  q {:.9}",
                data.centre_samples[i].to_native(),
                data.centre_weights[i].to_native()
            );
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
