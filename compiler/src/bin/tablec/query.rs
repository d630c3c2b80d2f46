//! `tablec query`.

use std::io::Write;
use std::path::{Path, PathBuf};

use adwi_compiler::pose;
use adwi_compiler::samples::ColumnMap;
use adwi_runtime::{Status, Target};
use anyhow::{bail, Context};

#[derive(clap::Args)]
pub struct Args {
    /// The table.
    table: PathBuf,
    /// Target X Y Z (mm, base frame), optionally A B C (KUKA degrees).
    #[arg(allow_negative_numbers = true, num_args = 0..=6)]
    pose: Vec<f64>,
    /// Inverse-kinematics configuration of the target.
    #[arg(long)]
    config: Option<u8>,
    /// The joint angles the controller will use for the target, degrees: J1,...,J6.
    /// Needed by a hybrid table (built with --hybrid); applies a table's joint screen.
    #[arg(
        long,
        value_name = "DEG",
        value_delimiter = ',',
        allow_negative_numbers = true,
        conflicts_with = "targets"
    )]
    joints: Option<Vec<f64>>,
    /// A CSV of targets (columns x,y,z, optionally config) instead of one pose.
    #[arg(long, conflicts_with = "pose")]
    targets: Option<PathBuf>,
    /// Column mapping for the targets CSV, as for `tablec build`.
    #[arg(long, value_name = "MAP", requires = "targets")]
    columns: Option<String>,
    /// Output CSV for --targets [default: standard output].
    #[arg(short, long, requires = "targets")]
    output: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let table = crate::open_table(&args.table)?;
    if let Some(targets) = &args.targets {
        return run_batch(
            &table,
            targets,
            args.columns.as_deref(),
            args.output.as_deref(),
        );
    }
    let (position, abc) = match args.pose.as_slice() {
        [x, y, z] => ([*x, *y, *z], None),
        [x, y, z, a, b, c] => ([*x, *y, *z], Some([*a, *b, *c])),
        _ => bail!("give a target as X Y Z or X Y Z A B C, or --targets FILE"),
    };
    let target = Target {
        position_mm: position,
        config: args.config,
    };
    let joints_rad: Option<[f64; 6]> = match args.joints.as_deref() {
        None => None,
        Some(&[a, b, c, d, e, f]) => Some([a, b, c, d, e, f].map(f64::to_radians)),
        Some(_) => bail!("--joints takes six angles in degrees: J1,J2,J3,J4,J5,J6"),
    };
    let c = match &joints_rad {
        Some(q) => table.query_with_joints(&target, q),
        None => table.query_target(&target),
    };
    println!(
        "target       {:.6} {:.6} {:.6} mm",
        position[0], position[1], position[2]
    );
    println!(
        "status       {} ({} neighbours)",
        c.status.as_str(),
        c.neighbours
    );
    if c.status != Status::Ok {
        return Ok(());
    }
    let e = c.position_error_mm;
    println!("error        {:.9} {:.9} {:.9} mm", e[0], e[1], e[2]);
    if table.has_orientation() {
        let r = c.orientation_error_rad;
        println!("orientation  {:.9} {:.9} {:.9} rad", r[0], r[1], r[2]);
    }
    if joints_rad.is_some() {
        // The fixed-point compensation re-queries at moved positions, whose joint angles
        // only the controller's inverse kinematics knows: print the first-order command.
        let p = [0, 1, 2].map(|a| position[a] - e[a]);
        println!(
            "command      {:.6} {:.6} {:.6} mm (first order: target − error)",
            p[0], p[1], p[2]
        );
        return Ok(());
    }
    let comp = table.compensate(&target, 1e-6, 50);
    let p = comp.command_position_mm;
    println!(
        "command      {:.6} {:.6} {:.6} mm ({} after {} iterations, residual {:.2e} mm)",
        p[0],
        p[1],
        p[2],
        if comp.converged {
            "converged"
        } else {
            "not converged"
        },
        comp.iterations,
        comp.residual_mm
    );
    if let Some(abc) = abc {
        let target_rotation = pose::rotation_from_kuka_abc_deg(abc);
        let command = pose::rotation_from_vector(comp.command_rotation_rad) * target_rotation;
        let [a, b, c] = pose::kuka_abc_deg_from_rotation(&command);
        println!("command abc  {a:.6} {b:.6} {c:.6} deg");
    }
    Ok(())
}

fn run_batch(
    table: &adwi_runtime::Table<memmap2::Mmap>,
    targets: &Path,
    columns: Option<&str>,
    output: Option<&Path>,
) -> anyhow::Result<()> {
    let columns = ColumnMap::parse(columns.unwrap_or("")).map_err(anyhow::Error::msg)?;
    let targets = adwi_compiler::samples::read_targets(targets, &columns)?;
    let mut out: Box<dyn Write> = match output {
        Some(path) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("cannot create {}", path.display()))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout().lock())),
    };
    writeln!(out, "x,y,z,dx,dy,dz,rx,ry,rz,neighbours,status")?;
    let orientation = table.has_orientation();
    for row in &targets {
        // Rows with joint angles serve hybrid tables and the joint-space screen.
        let c = match &row.joints_rad {
            Some(q) => table.query_with_joints(&row.target, q),
            None => table.query_target(&row.target),
        };
        let p = row.target.position_mm;
        write!(out, "{},{},{}", p[0], p[1], p[2])?;
        if c.status == Status::Ok {
            let e = c.position_error_mm;
            write!(out, ",{:.9},{:.9},{:.9}", e[0], e[1], e[2])?;
        } else {
            write!(out, ",,,")?;
        }
        if c.status == Status::Ok && orientation {
            let r = c.orientation_error_rad;
            write!(out, ",{:.12},{:.12},{:.12}", r[0], r[1], r[2])?;
        } else {
            write!(out, ",,,")?;
        }
        writeln!(out, ",{},{}", c.neighbours, c.status.as_str())?;
    }
    out.flush()?;
    Ok(())
}
