//! `tablec iso9283`: the ISO 9283 job ([`adwi_jobs::Iso9283Job`]), its characteristics
//! printed as a table per position and per distance.

use adwi_jobs::{Iso9283Args, Iso9283Job};
use adwi_measure::iso9283::{Report, ISO_CYCLES};
use adwi_measure::path::PathReport;

/// ISO 9283:1998 pose characteristics of measured cycles: pose accuracy AP and
/// repeatability RP per position, distance accuracy AD and repeatability RD between the
/// standard's P2 and P4 or the pairs named (as text, --json and an HTML page, --report);
/// the path characteristics of a tracker stream (--path with --command: AT, RT, CR, CO,
/// AV, RV, FV); or the standard's five cube positions as a plan (--cube), or its test
/// paths (--cube --path-plan).
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    job: Iso9283Args,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let path_plan = args.job.path_plan;
    let result = Iso9283Job::new(args.job)?.run()?;
    if let Some(report) = &result.report {
        print_report(report);
    }
    if let Some(report) = &result.compensated {
        println!();
        println!("compensated by the table (each attained pose less the predicted error at its command):");
        print_report(report);
    }
    if let Some(report) = &result.path {
        print_path_report(report);
    }
    if let Some(report) = &result.path_compensated {
        println!();
        println!("compensated by the table (each point less the predicted error at its commanded point):");
        print_path_report(report);
    }
    if result.report.is_none() && result.path.is_none() {
        if path_plan {
            println!(
                "plan           paths line (P2 to P4), circle and small_circle (about P1), \
                 rectangle (P2, P3, P4, P5); a, b, c are KUKA A, B, C degrees, \
                 R = Rz(a)·Ry(b)·Rx(c)"
            );
        } else {
            println!(
                "plan           each cycle P1, P5, P4, P3, P2 (ISO 9283); a, b, c are KUKA A, B, \
                 C degrees, R = Rz(a)·Ry(b)·Rx(c) (the standard's a, b, c about x, y, z are c, \
                 b, a)"
            );
        }
    }
    for path in &result.written {
        println!("wrote          {}", path.display());
    }
    Ok(())
}

/// Per path AT and RT, per corner CR and CO, and the velocity figures.
fn print_path_report(report: &PathReport) {
    println!(
        "{:<14} {:>4} {:>10} {:>6} {:>9} {:>9} {:>9}",
        "path", "n", "length mm", "planes", "AT_P mm", "mean AT", "RT_P mm"
    );
    for p in &report.paths {
        println!(
            "{:<14} {:>4} {:>10.3} {:>6} {:>9.4} {:>9.4} {:>9.4}",
            p.name, p.n, p.length_mm, p.planes, p.at_p_mm, p.at_mean_mm, p.rt_p_mm
        );
    }
    if report.paths.iter().any(|p| !p.corners.is_empty()) {
        println!(
            "{:<14} {:>6} {:>9} {:>9} {:>9} {:>9}",
            "corner", "", "CR mm", "CR max", "CO mm", "CO max"
        );
        for p in &report.paths {
            for c in &p.corners {
                println!(
                    "{:<14} {:>6} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
                    p.name, c.corner, c.cr_mm, c.cr_max_mm, c.co_mm, c.co_max_mm
                );
            }
        }
    }
    if report.paths.iter().any(|p| p.velocity.is_some()) {
        println!(
            "{:<14} {:>10} {:>10} {:>9} {:>9} {:>9}",
            "velocity", "v_c mm/s", "mean mm/s", "AV %", "RV ±%", "FV mm/s"
        );
        for p in &report.paths {
            if let Some(v) = &p.velocity {
                println!(
                    "{:<14} {:>10.3} {:>10.4} {:>9.4} {:>9.4} {:>9.4}",
                    p.name, v.commanded_mm_s, v.mean_mm_s, v.av_percent, v.rv_percent, v.fv_mm_s
                );
            }
        }
    }
    for note in &report.notes {
        println!("note           {note}");
    }
}

/// Per position AP and RP (mm; orientation degrees when measured), then AD and RD.
fn print_report(report: &Report) {
    let oriented = report.positions.iter().any(|p| p.ap_a_deg.is_some());
    print!(
        "{:<10} {:>4} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "position", "n", "AP_P mm", "AP_x mm", "AP_y mm", "AP_z mm", "RP_l mm"
    );
    if oriented {
        print!(
            " {:>8} {:>8} {:>8} {:>9} {:>9} {:>9}",
            "AP_a °", "AP_b °", "AP_c °", "RP_a ±°", "RP_b ±°", "RP_c ±°"
        );
    }
    println!();
    for p in &report.positions {
        print!(
            "{:<10} {:>4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
            p.name, p.n, p.ap_p_mm, p.ap_x_mm, p.ap_y_mm, p.ap_z_mm, p.rp_l_mm
        );
        let angles = [
            p.ap_a_deg, p.ap_b_deg, p.ap_c_deg, p.rp_a_deg, p.rp_b_deg, p.rp_c_deg,
        ];
        if let [Some(a), Some(b), Some(c), Some(ra), Some(rb), Some(rc)] = angles {
            print!(" {a:>8.4} {b:>8.4} {c:>8.4} {ra:>9.4} {rb:>9.4} {rc:>9.4}");
        }
        println!();
    }
    if !report.distance.is_empty() {
        println!(
            "{:<21} {:>4} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "distance", "n", "D_c mm", "AD_P mm", "AD_x mm", "AD_y mm", "AD_z mm", "RD ±mm"
        );
        for d in &report.distance {
            println!(
                "{:<21} {:>4} {:>10.3} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
                format!("{} - {}", d.from, d.to),
                d.n,
                d.commanded_mm,
                d.ad_p_mm,
                d.ad_x_mm,
                d.ad_y_mm,
                d.ad_z_mm,
                d.rd_mm
            );
        }
    }
    let fewest = report.positions.iter().map(|p| p.n).min().unwrap_or(0);
    if fewest < ISO_CYCLES as usize {
        println!("note           {fewest} cycles at the fewest: ISO 9283 asks for {ISO_CYCLES}");
    }
    if let Some(convention) = report.orientation_convention {
        println!("orientation    {convention}");
    }
    for note in &report.notes {
        println!("note           {note}");
    }
}
