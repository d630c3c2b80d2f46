//! A simulated tracker stream of the standard's test paths with known errors, to check
//! `tablec iso9283 --path` against:
//!
//! ```sh
//! tablec iso9283 --cube 1750,450,1250,600 --path-plan --speed 200 -o paths.csv
//! cargo run --release -p adwi-measure --example path_stream -- paths.csv stream.csv
//! tablec iso9283 --path stream.csv --command paths.csv
//! ```
//!
//! It prints the figures the reduction should find.

use adwi_measure::path::{parse_command, simulated_stream, Simulation};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, command, output] = &args[..] else {
        return Err("usage: path_stream COMMAND.csv STREAM.csv".into());
    };
    let paths = parse_command(std::fs::File::open(command)?, command)?;
    let quiet = Simulation {
        speed_factors: vec![1.0; 10],
        fluctuation: (0.0, 0.0),
        offset_mm: [0.0; 3],
        cycle_spread_mm: 0.0,
        radius_scale: 1.0,
        fillet_mm: 0.0,
        overshoot_mm: 0.0,
        noise_mm: 0.01,
        rate_hz: 1000.0,
        dwell_s: 0.5,
        seed: 1,
    };
    let mut out = String::from("t,x,y,z,path\n");
    let mut t0 = 0.0;
    for path in &paths {
        let sim = match path.name.as_str() {
            "line" => {
                // Across the line (horizontal, perpendicular to it) 0.3 mm, along it 0.5 mm.
                let s = path.point_at(0.0);
                let e = path.point_at(path.length_mm);
                let d = [e[0] - s[0], e[1] - s[1], e[2] - s[2]];
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let along = d.map(|v| v / n);
                let h = (along[0] * along[0] + along[1] * along[1]).sqrt();
                let across = [along[1] / h, -along[0] / h, 0.0];
                eprintln!(
                    "line: AT_P 0.3 mm (+ noise), RT_P 0.05 mm (+ noise), AV -5 %, RV 3.162 %, \
                     FV 9.836 mm/s (+ noise)"
                );
                Simulation {
                    offset_mm: [0, 1, 2].map(|a| 0.3 * across[a] + 0.5 * along[a]),
                    cycle_spread_mm: 0.05,
                    speed_factors: (0..10)
                        .map(|j| 0.95 + if j % 2 == 0 { 0.01 } else { -0.01 })
                        .collect(),
                    fluctuation: (5.0, 2.0),
                    ..quiet.clone()
                }
            }
            "circle" | "small_circle" => {
                let radius = path.length_mm / std::f64::consts::TAU;
                eprintln!(
                    "{}: AT_P {:.4} mm (0.2 % of the radius, + noise), AV 0.2 %",
                    path.name,
                    0.002 * radius
                );
                Simulation {
                    radius_scale: 1.002,
                    ..quiet.clone()
                }
            }
            "rectangle" => {
                eprintln!(
                    "rectangle: CR {:.4} mm, CO 0.4 mm at each corner (+ noise)",
                    5.0 * (2f64.sqrt() - 1.0)
                );
                Simulation {
                    fillet_mm: 5.0,
                    overshoot_mm: 0.4,
                    ..quiet.clone()
                }
            }
            _ => quiet.clone(),
        };
        let text = simulated_stream(path, &sim);
        let mut last = t0;
        for line in text.lines().skip(1) {
            let (t, rest) = line.split_once(',').ok_or("a stream row")?;
            last = t0 + t.parse::<f64>()?;
            out.push_str(&format!("{last:.6},{rest},{}\n", path.name));
        }
        t0 = last + 1.0;
    }
    std::fs::write(output, out)?;
    Ok(())
}
