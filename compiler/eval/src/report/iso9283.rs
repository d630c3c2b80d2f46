//! The ISO 9283 pose characteristics as a report page (`tablec iso9283 ... --report
//! DIR`): per position the pose accuracy AP and repeatability RP, per motion the distance
//! accuracy AD and repeatability RD, and with a table the same figures as its compensation
//! would attain them beside the measured ones. Every figure is the one `--json` writes,
//! at four decimals.

use std::fmt::Write as _;

use adwi_measure::iso9283::{PoseCharacteristics, Report, ISO_CYCLES};
use adwi_measure::path::PathReport;

use super::{escape, head};

/// `v` at four decimals, `—` when absent.
fn cell(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.4}"))
}

/// The page: `measured` the characteristics of the cycles as measured, `compensated` those
/// the table's compensation would give (with `--table`), `command` the command line that
/// produced them.
pub fn html(measured: &Report, compensated: Option<&Report>, command: &str) -> String {
    let mut page = head("ISO 9283 pose characteristics");
    let _ = writeln!(page, "<p>Command: <code>{}</code></p>", escape(command));
    page.push_str(
        "<p>ISO 9283:1998 pose characteristics of measured cycles: position accuracy \
         AP<sub>P</sub> (the barycentre's distance to the commanded position, 7.2.1) and \
         repeatability RP<sub>l</sub> (l̄ + 3 S<sub>l</sub>, 7.2.2) per position; distance \
         accuracy AD and repeatability RD between the standard's P2 and P4 or the pairs \
         named (7.4). Lengths in mm, base frame. docs/measure.md has the formulas.</p>\n",
    );
    if let Some(convention) = measured.orientation_convention {
        let _ = writeln!(page, "<p>Orientation: {}.</p>", escape(convention));
    }
    for note in &measured.notes {
        let _ = writeln!(page, "<p>Note: {}</p>", escape(note));
    }
    let _ = writeln!(page, "<h2>Pose accuracy and repeatability</h2>");
    positions_table(&mut page, measured);
    if let Some(c) = compensated {
        let _ = writeln!(
            page,
            "<h2>Before and after compensation</h2>\n<p>The cycles as the table's \
             compensation would attain them: each attained pose less the table's predicted \
             error at its commanded pose. On real data this is a prediction, not a \
             measurement (docs/measure.md).</p>"
        );
        before_after_table(&mut page, measured, c);
        let _ = writeln!(page, "<h3>Compensated, every characteristic</h3>");
        positions_table(&mut page, c);
    }
    if !measured.distance.is_empty() {
        let _ = writeln!(page, "<h2>Distance accuracy and repeatability</h2>");
        distance_table(&mut page, measured, "measured");
        if let Some(c) = compensated {
            distance_table(&mut page, c, "compensated");
        }
    }
    let fewest = measured.positions.iter().map(|p| p.n).min().unwrap_or(0);
    if fewest < ISO_CYCLES as usize {
        let _ = writeln!(
            page,
            "<p>Note: {fewest} cycles at the fewest; ISO 9283 asks for {ISO_CYCLES}.</p>"
        );
    }
    page.push_str("</body>\n</html>\n");
    page
}

fn oriented(report: &Report) -> bool {
    report.positions.iter().any(|p| p.ap_a_deg.is_some())
}

/// One row per position: n, the commanded position, AP and RP (and orientation figures
/// when measured).
fn positions_table(page: &mut String, report: &Report) {
    let angles = oriented(report);
    page.push_str(
        "<table>\n<tr><th>position</th><th>n</th><th>commanded x, y, z mm</th>\
         <th>AP<sub>P</sub> mm</th><th>AP<sub>x</sub> mm</th><th>AP<sub>y</sub> mm</th>\
         <th>AP<sub>z</sub> mm</th><th>RP<sub>l</sub> mm</th>",
    );
    if angles {
        page.push_str(
            "<th>AP<sub>a</sub> °</th><th>AP<sub>b</sub> °</th><th>AP<sub>c</sub> °</th>\
             <th>RP<sub>a</sub> ±°</th><th>RP<sub>b</sub> ±°</th><th>RP<sub>c</sub> ±°</th>",
        );
    }
    page.push_str("</tr>\n");
    for p in &report.positions {
        let [x, y, z] = p.commanded_mm;
        let _ = write!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{x:.3}, {y:.3}, {z:.3}</td><td>{:.4}</td>\
             <td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td>",
            escape(&p.name),
            p.n,
            p.ap_p_mm,
            p.ap_x_mm,
            p.ap_y_mm,
            p.ap_z_mm,
            p.rp_l_mm
        );
        if angles {
            for v in orientation_figures(p) {
                let _ = write!(page, "<td>{}</td>", cell(v));
            }
        }
        page.push_str("</tr>\n");
    }
    page.push_str("</table>\n");
}

fn orientation_figures(p: &PoseCharacteristics) -> [Option<f64>; 6] {
    [
        p.ap_a_deg, p.ap_b_deg, p.ap_c_deg, p.rp_a_deg, p.rp_b_deg, p.rp_c_deg,
    ]
}

/// AP and RP of each position as measured and as compensated, side by side.
fn before_after_table(page: &mut String, measured: &Report, compensated: &Report) {
    page.push_str(
        "<table>\n<tr><th>position</th><th>AP<sub>P</sub> mm measured</th>\
         <th>AP<sub>P</sub> mm compensated</th><th>RP<sub>l</sub> mm measured</th>\
         <th>RP<sub>l</sub> mm compensated</th></tr>\n",
    );
    for m in &measured.positions {
        let c = compensated.positions.iter().find(|c| c.name == m.name);
        let _ = writeln!(
            page,
            "<tr><td>{}</td><td>{:.4}</td><td>{}</td><td>{:.4}</td><td>{}</td></tr>",
            escape(&m.name),
            m.ap_p_mm,
            cell(c.map(|c| c.ap_p_mm)),
            m.rp_l_mm,
            cell(c.map(|c| c.rp_l_mm))
        );
    }
    page.push_str("</table>\n");
}

fn distance_table(page: &mut String, report: &Report, which: &str) {
    let _ = write!(
        page,
        "<table>\n<tr><th>distance ({which})</th><th>n</th><th>D<sub>c</sub> mm</th>\
         <th>AD<sub>P</sub> mm</th><th>AD<sub>x</sub> mm</th><th>AD<sub>y</sub> mm</th>\
         <th>AD<sub>z</sub> mm</th><th>RD ±mm</th></tr>\n"
    );
    for d in &report.distance {
        let _ = writeln!(
            page,
            "<tr><td>{} – {}</td><td>{}</td><td>{:.3}</td><td>{:.4}</td><td>{:.4}</td>\
             <td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>",
            escape(&d.from),
            escape(&d.to),
            d.n,
            d.commanded_mm,
            d.ad_p_mm,
            d.ad_x_mm,
            d.ad_y_mm,
            d.ad_z_mm,
            d.rd_mm
        );
    }
    page.push_str("</table>\n");
}

/// The path characteristics as a page (`tablec iso9283 --path ... --report DIR`): per path
/// AT_P and RT_P, per corner CR and CO, the velocity figures; with a table the same as its
/// compensation would attain them beside the measured ones.
pub fn path_html(measured: &PathReport, compensated: Option<&PathReport>, command: &str) -> String {
    let mut page = head("ISO 9283 path characteristics");
    let _ = writeln!(page, "<p>Command: <code>{}</code></p>", escape(command));
    page.push_str(
        "<p>ISO 9283:1998 path characteristics of a tracker stream (clause 8): path accuracy \
         AT<sub>P</sub> (the largest distance of a normal plane's barycentre to the commanded \
         point) and repeatability RT<sub>P</sub> (the largest l̄ + 3 S<sub>l</sub>), cornering \
         round-off CR and overshoot CO, path velocity accuracy AV, repeatability RV and \
         fluctuation FV. Lengths in mm, base frame. docs/measure.md has the formulas.</p>\n",
    );
    let reports: Vec<(&str, &PathReport)> = std::iter::once(("measured", measured))
        .chain(compensated.map(|c| ("compensated", c)))
        .collect();
    page.push_str(
        "<h2>Path accuracy and repeatability</h2>\n<table>\n<tr><th>path</th><th></th>\
         <th>n</th><th>length mm</th><th>planes</th><th>AT<sub>P</sub> mm</th><th>at s mm</th>\
         <th>mean AT mm</th><th>RT<sub>P</sub> mm</th><th>at s mm</th></tr>\n",
    );
    for (label, r) in &reports {
        for p in &r.paths {
            let _ = writeln!(
                page,
                "<tr><td>{}</td><td>{label}</td><td>{}</td><td>{:.3}</td><td>{}</td>\
                 <td>{:.4}</td><td>{:.1}</td><td>{:.4}</td><td>{:.4}</td><td>{:.1}</td></tr>",
                escape(&p.name),
                p.n,
                p.length_mm,
                p.planes,
                p.at_p_mm,
                p.at_p_at_mm,
                p.at_mean_mm,
                p.rt_p_mm,
                p.rt_p_at_mm
            );
        }
    }
    page.push_str("</table>\n");
    if measured.paths.iter().any(|p| !p.corners.is_empty()) {
        page.push_str(
            "<h2>Cornering</h2>\n<table>\n<tr><th>path</th><th></th><th>corner</th>\
             <th>x, y, z mm</th><th>CR mm</th><th>CR max mm</th><th>CO mm</th>\
             <th>CO max mm</th></tr>\n",
        );
        for (label, r) in &reports {
            for p in &r.paths {
                for c in &p.corners {
                    let [x, y, z] = c.point_mm;
                    let _ = writeln!(
                        page,
                        "<tr><td>{}</td><td>{label}</td><td>{}</td><td>{x:.3}, {y:.3}, {z:.3}</td>\
                         <td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>",
                        escape(&p.name),
                        c.corner,
                        c.cr_mm,
                        c.cr_max_mm,
                        c.co_mm,
                        c.co_max_mm
                    );
                }
            }
        }
        page.push_str("</table>\n");
    }
    if measured.paths.iter().any(|p| p.velocity.is_some()) {
        page.push_str(
            "<h2>Path velocity</h2>\n<table>\n<tr><th>path</th><th></th><th>v<sub>c</sub> \
             mm/s</th><th>v̄ mm/s</th><th>AV %</th><th>RV ±%</th><th>FV mm/s</th></tr>\n",
        );
        for (label, r) in &reports {
            for p in &r.paths {
                if let Some(v) = &p.velocity {
                    let _ = writeln!(
                        page,
                        "<tr><td>{}</td><td>{label}</td><td>{:.3}</td><td>{:.4}</td>\
                         <td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>",
                        escape(&p.name),
                        v.commanded_mm_s,
                        v.mean_mm_s,
                        v.av_percent,
                        v.rv_percent,
                        v.fv_mm_s
                    );
                }
            }
        }
        page.push_str("</table>\n");
    }
    if compensated.is_some() {
        page.push_str(
            "<p>Compensated: each point of a cycle less the table's predicted error at the \
             commanded point it is tracked to. On real data this is a prediction, not a \
             measurement (docs/measure.md).</p>\n",
        );
    }
    for note in &measured.notes {
        let _ = writeln!(page, "<p>Note: {}</p>", escape(note));
    }
    page.push_str("</body>\n</html>\n");
    page
}

#[cfg(test)]
mod tests {
    use super::*;
    use adwi_measure::iso9283::{characteristics_between, CycleRow, Report};

    /// The characteristics with the distance between the two positions.
    fn characteristics(rows: &[CycleRow]) -> Result<Report, adwi_measure::iso9283::Iso9283Error> {
        characteristics_between(rows, &[("P1".into(), "P<2>".into())])
    }

    /// Two positions, three cycles, attained positions off by known amounts.
    fn cycles(offset_mm: f64, orientation: bool) -> Vec<CycleRow> {
        let mut rows = Vec::new();
        for cycle in 1..=3u32 {
            for (name, commanded) in [("P1", [0.0, 0.0, 0.0]), ("P<2>", [100.0, 0.0, 0.0])] {
                let wobble = f64::from(cycle) * 0.01;
                rows.push(CycleRow {
                    position: name.to_string(),
                    cycle,
                    commanded_mm: commanded,
                    attained_mm: [
                        commanded[0] + offset_mm + wobble,
                        commanded[1],
                        commanded[2],
                    ],
                    orientation_abc_deg: orientation
                        .then_some([[0.0, 45.0, 0.0], [0.1 * f64::from(cycle), 45.0, 0.0]]),
                    line: 0,
                });
            }
        }
        rows
    }

    /// The page carries every figure the JSON carries, at four decimals, and escapes the
    /// positions' names.
    #[test]
    fn the_page_holds_the_figures_of_the_json() {
        for orientation in [false, true] {
            let measured = characteristics(&cycles(0.3, orientation)).unwrap();
            let compensated = characteristics(&cycles(0.05, orientation)).unwrap();
            let page = html(
                &measured,
                Some(&compensated),
                "tablec iso9283 c.csv --table t.tbl",
            );
            let json = serde_json::to_value(&measured).unwrap();
            let mut checked = 0;
            for p in json["positions"].as_array().unwrap() {
                for key in [
                    "ap_p_mm", "ap_x_mm", "ap_y_mm", "ap_z_mm", "rp_l_mm", "ap_a_deg", "rp_a_deg",
                ] {
                    if let Some(v) = p[key].as_f64() {
                        assert!(page.contains(&format!("<td>{v:.4}</td>")), "{key} {v}");
                        checked += 1;
                    }
                }
            }
            for d in json["distance"].as_array().unwrap() {
                for key in ["ad_p_mm", "ad_x_mm", "rd_mm"] {
                    let v = d[key].as_f64().unwrap();
                    assert!(page.contains(&format!("<td>{v:.4}</td>")), "{key} {v}");
                    checked += 1;
                }
            }
            assert_eq!(checked, if orientation { 17 } else { 13 });
            for p in &compensated.positions {
                assert!(page.contains(&format!("<td>{:.4}</td>", p.ap_p_mm)));
            }
            assert!(page.contains("Before and after compensation"));
            assert!(page.contains("P&lt;2&gt;") && !page.contains("P<2>"));
            assert!(page.contains("3 cycles at the fewest"));
            assert_eq!(page.contains("AP<sub>a</sub>"), orientation);
            assert_eq!(
                page.contains("rotations about the base x, y, z"),
                orientation
            );
        }
        let alone = html(
            &characteristics(&cycles(0.3, false)).unwrap(),
            None,
            "tablec iso9283 c.csv",
        );
        assert!(!alone.contains("Before and after"));
    }
}
