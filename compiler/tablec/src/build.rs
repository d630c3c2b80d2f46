//! `tablec build`: the build job ([`adwi_jobs::BuildJob`]), with a progress bar and the
//! summary of what was built.

use adwi_jobs::{BuildArgs, BuildJob, Built, CalibrationSummary, RegistrationSummary};
use adwi_runtime::format::ServedField;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: BuildArgs,
    /// No progress bar or summary.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let job = BuildJob::new(args.job)?;
    let bar = crate::progress::Bar::new(args.quiet);
    let built = job.run(&bar)?;
    bar.finish();
    if !args.quiet {
        print_summary(&built);
    }
    crate::warn(&built.warnings);
    Ok(())
}

/// What was built: the plan as derived, the candidate lists, the method and the file.
fn print_summary(built: &Built) {
    let report = &built.report;
    let plan = &report.plan;
    let derived = |yes| if yes { " (derived: default)" } else { "" };
    let spacing = plan
        .spacing_mm
        .map_or("n/a".to_string(), |s| format!("{s:.3} mm"));
    let g = plan.grid;
    let m = plan.params;
    let sources: Vec<String> = built
        .sources
        .iter()
        .map(|s| s.display().to_string())
        .collect();
    println!(
        "samples        {} from {}",
        plan.samples,
        sources.join(", ")
    );
    if let Some(r) = &built.repeats {
        let orientation = match (r.orientation_max_mrad, r.orientation_rms_mrad) {
            (Some(max), Some(rms)) => format!("; orientation max {max:.4} mrad, RMS {rms:.4} mrad"),
            _ => String::new(),
        };
        println!(
            "repeats        {} poses on {} rows (at most {} of one pose), each averaged into one \
             sample; errors about their means: max {:.4} mm, RMS {:.4} mm{orientation}",
            r.poses, r.rows, r.max_rows_per_pose, r.position_max_mm, r.position_rms_mm
        );
    }
    if let Some(h) = &built.harmonics {
        print_harmonics_choice(h);
    }
    if let Some(t) = &built.tuning {
        print_tuning(t);
    }
    if let Some(c) = built.served_field.as_ref().and_then(|d| d.evidence()) {
        print_served_choice(c);
    }
    println!("spacing        {spacing} (median nearest-neighbour distance, or the volume per sample of clustered samples)");
    println!(
        "radius ε       {:.3} mm{}",
        m.radius_mm,
        derived(plan.radius_derived)
    );
    println!(
        "cell           {:.3} mm{}",
        g.cell_mm,
        derived(plan.cell_derived)
    );
    println!(
        "grid           {} × {} × {} cells from ({:.3}, {:.3}, {:.3}) to ({:.3}, {:.3}, {:.3}) mm",
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.origin_mm[0],
        g.origin_mm[1],
        g.origin_mm[2],
        g.max_mm()[0],
        g.max_mm()[1],
        g.max_mm()[2]
    );
    println!(
        "candidates     {} distinct lists, {} of {} cells covered, mean {:.1}, max {} per cell",
        report.distinct_lists,
        report.cells_covered,
        plan.cells(),
        report.mean_list_len,
        report.max_list_len
    );
    let registration =
        (built.registration.as_ref()).map(|(r, refined)| RegistrationSummary::of(r, Some(refined)));
    if let Some(r) = &registration {
        print!("{}", r.text());
    }
    for (i, r) in built.series_registrations.iter().enumerate() {
        print!("{}", RegistrationSummary::of(r, None).series_text(i + 2));
    }
    if let Some((c, residual_rms_mm)) = &built.calibration {
        print!("{}", CalibrationSummary::of(c).text(Some(*residual_rms_mm)));
        if let Some(r) = &registration {
            print!("{}", r.refined_text());
        }
    }
    println!("method         {}", crate::describe_method(&m));
    println!(
        "joint screen   {}",
        crate::describe_joint_screen(plan.joint_radius_rad)
    );
    println!("served field   {}", describe_served_field(built));
    println!("posture term   {}", describe_posture(built));
    if !report.residual_joint_range_rad.is_empty() {
        let degrees = adwi_jobs::inspect::ranges_deg(&report.residual_joint_range_rad);
        println!("residual joints {}", crate::describe_joint_ranges(&degrees));
    }
    println!(
        "wrote          {} ({} bytes) in {:.2} s",
        built.output.display(),
        report.table_bytes,
        built.seconds
    );
}

/// Whether the table has a posture term, its parameters and the evidence.
fn describe_posture(built: &adwi_jobs::build::Built) -> String {
    let choice = (built.served_field.as_ref())
        .and_then(|d| d.evidence())
        .and_then(|c| c.posture)
        .or(built.tuning.as_ref().and_then(|t| t.posture));
    let evidence = choice.map_or(String::new(), |c| {
        let mean = |m: Option<f64>| m.map_or("—".to_string(), |m| format!("{m:.4} mm"));
        format!(
            "; cross-validated served mean {} without, {} with (added when at least {} % and \
             {} mm lower)",
            mean(c.without_mm),
            mean(c.with_mm),
            100.0 * adwi_jobs::choice::POSTURE_MIN_GAIN_FRACTION,
            adwi_jobs::choice::POSTURE_MIN_GAIN_MM
        )
    });
    match &built.report.posture {
        Some(p) => format!(
            "on: R {:.1} mm, ℓ_q {} rad, W0 {} (leave-one-out mean {:.4} mm without, {:.4} mm \
             with); {} cells, at most {} samples a cell{evidence}",
            p.params.radius_mm,
            p.params.length_rad,
            p.params.floor,
            p.loo_without_mm,
            p.loo_with_mm,
            p.cells,
            p.max_list_len
        ),
        None => format!("off{evidence}"),
    }
}

/// What the served field's nodes hold, with a kriging's hyperparameters per component.
fn describe_served_field(built: &Built) -> String {
    let report = &built.report;
    if report.node_sets == 0 {
        return "none (the exact tier answers)".to_string();
    }
    let name = crate::served_field_name(report.plan.served_field);
    if report.served_kriging.is_empty() {
        return name.to_string();
    }
    const COMPONENTS: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];
    let turning = report.plan.served_field == ServedField::KrigingToolAxis;
    let choices: Vec<String> = report
        .served_kriging
        .iter()
        .zip(COMPONENTS)
        .map(|(c, component)| {
            let weight = if turning {
                format!(", w {}", c.modulation)
            } else {
                String::new()
            };
            format!(
                "{component} ℓ {:.1} mm, vertical ×{}, λ {}{weight}",
                c.length_scale, c.vertical_scale, c.relative_nugget
            )
        })
        .collect();
    let legend = if turning {
        ", weight w of the part turning with the tool"
    } else {
        ""
    };
    format!(
        "{name}; by likelihood (length scale ℓ, vertical distances × a scale, nugget λ per sill{legend}): {}",
        choices.join("; ")
    )
}

/// Every candidate of --tune with its cross-validated mean, the chosen one marked.
fn print_tuning(report: &adwi_jobs::choice::TuneReport) {
    println!(
        "tuning         {}-fold cross-validation of `{}` on the samples alone:",
        report.folds,
        report.method.name()
    );
    for (i, c) in report.candidates.iter().enumerate() {
        let mean = c
            .cv_mean_mm
            .map_or("—".to_string(), |m| format!("{m:.4} mm mean"));
        println!(
            "  {} k {:>2}, ε {:>9.3} mm: {mean}, {} missed",
            if i == report.chosen { "*" } else { " " },
            c.k,
            c.radius_mm,
            c.missed
        );
    }
    if let Some(chosen) = report.candidates.get(report.chosen) {
        let parameters = format!("k {}, ε {:.3} mm", chosen.k, chosen.radius_mm);
        print_served_candidates(&report.served, report.options.served_field, &parameters);
    }
}

/// The harmonic count chosen by default: each count's held-out mean of the model alone,
/// the chosen one marked.
fn print_harmonics_choice(choice: &adwi_jobs::choice::HarmonicsChoice) {
    println!(
        "harmonics      chosen by {}, the model alone (fewer terms unless more lower the \
         mean by more than its noise):",
        choice.held_out.describe(choice.folds)
    );
    if let Some(reach) = &choice.series_reach {
        let (within, poses) = (reach.within_range, reach.held_out_poses);
        if reach.judges() {
            println!(
                "  scored at the {within} of the {poses} held-out poses whose joints lie within \
                 the angles the other series span"
            );
        } else {
            println!(
                "  not by the series held out, which cannot judge the terms: {within} of their \
                 {poses} poses lie within the joint angles the other series span"
            );
        }
    }
    for c in &choice.candidates {
        let mean = c
            .cv_mean_mm
            .map_or("not identified".to_string(), |m| format!("{m:.4} mm mean"));
        let noise = c
            .noise_mm
            .filter(|n| *n > 0.0)
            .map_or(String::new(), |n| format!(" (noise ±{n:.4} mm)"));
        println!(
            "  {} harmonics {}: {mean}{noise}, {} missed",
            if c.harmonics == choice.chosen {
                "*"
            } else {
                " "
            },
            c.harmonics,
            c.missed
        );
    }
}

/// The served field chosen by default: each field's cross-validated mean, the chosen one
/// marked.
fn print_served_choice(auto: &adwi_jobs::choice::AutoServedField) {
    let exact = auto
        .exact_cv_mean_mm
        .map_or("—".to_string(), |m| format!("{m:.4} mm mean"));
    println!(
        "served field   chosen by {} on {} of the samples alone (the exact tier: {exact}):",
        auto.choice.held_out.describe(auto.choice.folds),
        auto.samples
    );
    print_served_candidates(&auto.choice.candidates, auto.choice.field(), "the build's");
    if let Some(reach) = &auto.series_reach {
        let (within, poses) = (reach.within_range, reach.held_out_poses);
        let what = if reach.judges() {
            "the figures count every held-out pose, those beyond included"
        } else {
            "the figures are the model's extrapolation to other joint angles, not what poses \
             within the samples' angles see"
        };
        println!(
            "  {within} of the {poses} held-out poses lie within the joint angles the other \
             series span: {what}"
        );
    }
    if let Some(w) = &auto.residual_weight {
        let held_out = if w.by_series {
            format!("{} series, each predicted from the others", w.splits)
        } else {
            format!(
                "{} spatial blocks, each predicted from the others",
                w.splits
            )
        };
        // Said of the weight as printed: one that rounds to 1.000 keeps the whole field.
        let why = if w.weight < 0.9995 {
            "the field is faded toward the model alone where it does not carry"
        } else {
            "the whole field carries"
        };
        println!(
            "residual weight {:.3}: held-out mean {:.4} mm with it, {:.4} mm with the model \
             alone, {:.4} mm with the whole field ({} points of {held_out}): {why}",
            w.weight, w.weighted_mm, w.model_mm, w.full_mm, w.points
        );
    }
}

fn print_served_candidates(
    candidates: &[adwi_jobs::choice::ServedCandidate],
    chosen: ServedField,
    parameters: &str,
) {
    for c in candidates {
        let mean = c
            .cv_mean_mm
            .map_or("—".to_string(), |m| format!("{m:.4} mm mean"));
        println!(
            "  {} served field {:<24} ({parameters}): {mean}, {} missed",
            if c.field == chosen { "*" } else { " " },
            crate::served_field_name(c.field),
            c.missed
        );
    }
}
