//! The table options shared by `tablec build` and `tablec eval`: one definition, so a table
//! evaluated by `eval` is built exactly as `build` would build it from the same flags.
// The field docs are clap's help text, where the paper's [λ] and [ζ] read as written.
#![allow(rustdoc::broken_intra_doc_links)]

use adwi_compile::build::BuildOptions;
use adwi_runtime::format::ServedField;
use adwi_runtime::method::MethodParams;

/// The paper's parameters, the defaults of every option below.
const PAPER: MethodParams<()> = MethodParams::paper(());

/// A box's minimum and maximum corners, mm.
type Bounds = ([f64; 3], [f64; 3]);

/// `xmin,ymin,zmin,xmax,ymax,zmax` in one argument (`-500,-500,0,500,500,900`).
fn parse_bounds(text: &str) -> Result<Bounds, String> {
    match crate::parse_number_list(text)?.as_slice() {
        &[x0, y0, z0, x1, y1, z1] => Ok(([x0, y0, z0], [x1, y1, z1])),
        other => Err(format!(
            "six numbers are needed, xmin,ymin,zmin,xmax,ymax,zmax; {} given",
            other.len()
        )),
    }
}

/// Method and grid options of a table.
#[derive(clap::Args, Debug, Clone)]
pub struct TableOptions {
    /// Cell edge length, mm [default: sample spacing / 2].
    #[arg(long, value_name = "MM")]
    pub cell: Option<f64>,
    /// Neighbourhood radius ε, mm [default: 2 × sample spacing].
    #[arg(long, value_name = "MM")]
    pub radius: Option<f64>,
    /// At most this many neighbours.
    #[arg(long, default_value_t = PAPER.max_neighbours)]
    pub k: u32,
    /// ω1, the weight of λ [default: 0.87, or 1 − w2].
    #[arg(long)]
    pub w1: Option<f64>,
    /// ω2, the weight of ζ [default: 0.13, or 1 − w1].
    #[arg(long)]
    pub w2: Option<f64>,
    /// r, the power on λ and ζ (0 to 2).
    #[arg(long, default_value_t = PAPER.power)]
    pub power: f64,
    /// [λ], the admissibility threshold on λ, 1/mm.
    #[arg(long, default_value_t = PAPER.lambda_min_per_mm)]
    pub lambda_min: f64,
    /// [ζ], the admissibility threshold on ζ, 1/mm².
    #[arg(long, default_value_t = PAPER.zeta_min_per_mm2)]
    pub zeta_min: f64,
    /// Skip the consistency screen (40) on neighbour errors.
    #[arg(long)]
    pub no_consistency_screen: bool,
    /// Grid box, mm: xmin,ymin,zmin,xmax,ymax,zmax [default: samples' box grown by ε].
    #[arg(
        long,
        value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
        allow_hyphen_values = true,
        value_parser = parse_bounds
    )]
    pub bounds: Option<Bounds>,
    /// Joint-space screen, degrees: when a query gives the target's joint angles, a sample
    /// is admissible only if each of its joint angles is within this of the target's
    /// (needs samples with j1..jn) [default: off].
    #[arg(long, value_name = "DEG")]
    pub joint_radius: Option<f64>,
    /// What the served field's nodes hold: `method`, the method's own answer (what the
    /// exact tier answers, tabulated), or `kriging`, kriging with a nugget of the samples'
    /// errors (a hybrid table's residuals) in Cartesian distance, which smooths their
    /// measurement noise, or `kriging-tool-axis` (hybrid tables), that kriging with a part
    /// that turns with the nominal tool's approach axis at the query's joint values; the
    /// exact tier answers the method either way.
    #[arg(long, value_name = "FIELD", default_value = "method", value_parser = parse_served_field)]
    pub served_field: ServedField,
}

fn parse_served_field(text: &str) -> Result<ServedField, String> {
    ServedField::from_name(text)
        .ok_or_else(|| format!("'{text}': choose method, kriging or kriging-tool-axis"))
}

impl TableOptions {
    /// The compiler's options.
    pub fn build_options(&self) -> BuildOptions {
        let (w1, w2) = adwi_compile::build::resolve_weights(self.w1, self.w2);
        BuildOptions {
            method: MethodParams {
                radius_mm: self.radius,
                max_neighbours: self.k,
                w1,
                w2,
                power: self.power,
                lambda_min_per_mm: self.lambda_min,
                zeta_min_per_mm2: self.zeta_min,
                consistency_screen: !self.no_consistency_screen,
            },
            cell_mm: self.cell,
            bounds_mm: self.bounds,
            joint_radius_deg: self.joint_radius,
            tuning: None,
            served_field: self.served_field,
        }
    }
}
