use super::*;
use crate::iso9283::write_path_plan;

/// The standard's test paths of a 600 mm cube at 200 mm/s.
fn plan() -> Vec<CommandPath> {
    let text = write_path_plan([1750.0, 450.0, 1250.0], 600.0, [0.0, 45.0, 0.0], 200.0).unwrap();
    parse_command(text.as_bytes(), "plan.csv").unwrap()
}

fn path(name: &str) -> CommandPath {
    plan().into_iter().find(|p| p.name == name).unwrap()
}

fn quiet(cycles: usize) -> Simulation {
    Simulation {
        speed_factors: vec![1.0; cycles],
        fluctuation: (0.0, 0.0),
        offset_mm: [0.0; 3],
        cycle_spread_mm: 0.0,
        radius_scale: 1.0,
        fillet_mm: 0.0,
        overshoot_mm: 0.0,
        noise_mm: 0.0,
        rate_hz: 250.0,
        dwell_s: 0.5,
        seed: 1,
    }
}

fn reduce(command: &CommandPath, sim: &Simulation) -> PathCharacteristics {
    let text = simulated_stream(command, sim);
    let stream = parse_stream(text.as_bytes(), "stream.csv").unwrap();
    let measured = measured_paths(&stream, std::slice::from_ref(command)).unwrap();
    let report = characteristics(&measured).unwrap();
    report.paths[0].clone()
}

#[test]
fn the_plan_holds_the_standards_paths_in_the_cube() {
    let paths = plan();
    let names: Vec<&str> = paths.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["line", "circle", "small_circle", "rectangle"]);
    let p = crate::iso9283::cube_positions([1750.0, 450.0, 1250.0], 600.0).unwrap();
    let d = |a: [f64; 3], b: [f64; 3]| (V3::from(a) - V3::from(b)).norm();
    // The line is the diagonal P2-P4; the circle's circumference 2π · 240 mm.
    assert!((paths[0].length_mm - d(p[1], p[3])).abs() < 1e-3);
    assert!((paths[1].length_mm - std::f64::consts::TAU * 240.0).abs() < 1e-3);
    // (The file's four decimals.)
    assert!((paths[2].length_mm - std::f64::consts::TAU * 24.0).abs() < 1e-3);
    let rectangle = 2.0 * (d(p[1], p[2]) + d(p[2], p[3]));
    assert!((paths[3].length_mm - rectangle).abs() < 1e-3);
    // Three corners inside the rectangle (its start and end are standstills).
    assert_eq!(paths[3].corners().len(), 3);
    assert!(paths[0].corners().is_empty() && paths[1].corners().is_empty());
}

/// A line run 10 times 0.3 mm off across it (and 0.5 mm along it, which a normal plane
/// does not see), each cycle 0.05 mm to one side or the other in turn: AT_P = 0.3 and
/// RT_P = 0.05 mm exactly; at 0.95 of the speed in every cycle, AV = −5 %.
#[test]
fn a_line_with_a_known_offset_gives_its_accuracy_and_repeatability() {
    let line = path("line");
    let along = line.segments[0].geometry.tangent(0.0);
    let across = along.cross(&V3::z()).normalize();
    let offset = across * 0.3 + along * 0.5;
    let sim = Simulation {
        offset_mm: [offset.x, offset.y, offset.z],
        cycle_spread_mm: 0.05,
        speed_factors: vec![0.95; 10],
        ..quiet(10)
    };
    let c = reduce(&line, &sim);
    assert_eq!((c.n, c.split), (10, Split::Standstills));
    assert!((c.at_p_mm - 0.3).abs() < 1e-6, "{c:?}");
    assert!((c.rt_p_mm - 0.05).abs() < 1e-6, "{c:?}");
    let v = c.velocity.unwrap();
    assert!((v.av_percent + 5.0).abs() < 0.01, "{v:?}");
    assert!(v.rv_percent.abs() < 0.01 && v.fv_mm_s < 0.01, "{v:?}");
}

/// Tracker noise of 0.01 mm per coordinate on the same line: the figures move by about
/// the noise, not more.
#[test]
fn noise_moves_the_line_figures_by_about_the_noise() {
    let line = path("line");
    let across = line.segments[0]
        .geometry
        .tangent(0.0)
        .cross(&V3::z())
        .normalize()
        * 0.3;
    let sim = Simulation {
        offset_mm: [across.x, across.y, across.z],
        noise_mm: 0.01,
        ..quiet(10)
    };
    let c = reduce(&line, &sim);
    assert!((c.at_p_mm - 0.3).abs() < 0.02, "{c:?}");
    // l̄ + 3 S_l of 2-D noise of 0.01 mm is about 0.03 mm; the largest of 1000 planes more.
    assert!(c.rt_p_mm > 0.01 && c.rt_p_mm < 0.08, "{c:?}");
    let v = c.velocity.unwrap();
    assert!(v.av_percent.abs() < 0.1 && v.fv_mm_s < 3.0, "{v:?}");
}

/// A circle attained 0.2 % too large: AT_P = 240 mm · 0.002 = 0.48 mm, less the chord
/// between two points 0.8 mm apart (a sagitta of 0.0003 mm); it runs 0.2 % fast, AV.
#[test]
fn a_circle_with_a_known_radius_error_gives_it_as_its_accuracy() {
    let circle = path("circle");
    let c = reduce(
        &circle,
        &Simulation {
            radius_scale: 1.002,
            ..quiet(3)
        },
    );
    assert!((c.at_p_mm - 0.48).abs() < 1e-3, "{c:?}");
    assert!(c.rt_p_mm < 1e-6, "{c:?}");
    assert!((c.at_mean_mm - 0.48).abs() < 1e-3, "{c:?}");
    assert!(
        (c.velocity.as_ref().unwrap().av_percent - 0.2).abs() < 0.01,
        "{c:?}"
    );
}

/// Corners cut by a 5 mm fillet and overshooting by 0.4 mm after it: CR = 5 (√2 − 1) =
/// 2.0711 mm at each 90° corner, CO = 0.4 mm.
#[test]
fn a_rectangle_with_known_cornering_gives_its_round_off_and_overshoot() {
    let rectangle = path("rectangle");
    let c = reduce(
        &rectangle,
        &Simulation {
            fillet_mm: 5.0,
            overshoot_mm: 0.4,
            rate_hz: 1000.0,
            ..quiet(3)
        },
    );
    assert_eq!(c.corners.len(), 3);
    for corner in &c.corners {
        let cr = 5.0 * (2f64.sqrt() - 1.0);
        assert!((corner.cr_mm - cr).abs() < 1e-3, "{corner:?}");
        assert!((corner.co_mm - 0.4).abs() < 1e-3, "{corner:?}");
        assert!((corner.co_max_mm - 0.4).abs() < 1e-3, "{corner:?}");
    }
    // The sides away from the corners are on the path.
    assert!(c.at_p_mm < 1e-6, "{c:?}");
}

/// Cycles at 0.9, 1.0 and 1.1 of the speed with a 2 Hz fluctuation of 5 mm/s: AV = 0,
/// RV = 3 · 0.1 · 100 = 30 %, FV = 2 · 5 mm/s less the 50 ms window's smoothing,
/// sin(0.1π)/(0.1π) = 0.98363: 9.836 mm/s.
#[test]
fn known_velocity_errors_give_av_rv_and_fv() {
    let line = path("line");
    let c = reduce(
        &line,
        &Simulation {
            speed_factors: vec![0.9, 1.0, 1.1],
            fluctuation: (5.0, 2.0),
            rate_hz: 1000.0,
            ..quiet(3)
        },
    );
    let v = c.velocity.unwrap();
    // The cycles' means carry the part of the sine in their span: within 0.5 %.
    assert!(v.av_percent.abs() < 0.5, "{v:?}");
    assert!((v.rv_percent - 30.0).abs() < 1.0, "{v:?}");
    let fv = 10.0 * (0.1 * std::f64::consts::PI).sin() / (0.1 * std::f64::consts::PI);
    assert!((v.fv_mm_s - fv).abs() < 0.05, "{v:?} against {fv}");
}

/// A cycle column splits the cycles without standstills; a stream that never stands
/// still and has none is refused with the reason.
#[test]
fn cycles_come_from_a_column_or_standstills_or_are_refused_with_the_reason() {
    let circle = path("small_circle");
    let sim = Simulation {
        dwell_s: 0.0,
        ..quiet(4)
    };
    let text = simulated_stream(&circle, &sim);
    let stream = parse_stream(text.as_bytes(), "s.csv").unwrap();
    let e = measured_paths(&stream, std::slice::from_ref(&circle)).unwrap_err();
    let e = e.to_string();
    assert!(
        e.contains("no cycle of path 'small_circle'") && e.contains("cycle column"),
        "{e}"
    );
    // The same points labelled by cycle.
    let per_cycle = stream.samples.len() / 4;
    let mut labelled = String::from("t,x,y,z,cycle\n");
    for (k, line) in text.lines().skip(1).enumerate() {
        labelled.push_str(&format!("{line},{}\n", k / per_cycle + 1));
    }
    let stream = parse_stream(labelled.as_bytes(), "s.csv").unwrap();
    let measured = measured_paths(&stream, std::slice::from_ref(&circle)).unwrap();
    assert_eq!(
        measured[0].cycles.len(),
        4 + usize::from(stream.samples.len() % 4 != 0)
    );
    assert_eq!(measured[0].split, Split::CycleColumn);
}

#[test]
fn malformed_streams_and_commands_are_refused_with_file_line_and_column() {
    let e = parse_stream(&b"t,x,y,z\n0,1,2,3\n0.1,1,2,nan\n"[..], "s.csv").unwrap_err();
    assert_eq!(
        e.to_string(),
        "s.csv:3:4 (column 'z'): 'nan' is not a finite number"
    );
    let e = parse_stream(&b"t,x,y,z\n0,1,2,3\n0,1,2,3\n"[..], "s.csv").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("s.csv:3:1 (column 't'): 0 s is not after"),
        "{e}"
    );
    let e = parse_stream(&b"t,x,y\n0,1,2\n"[..], "s.csv").unwrap_err();
    assert!(e.to_string().contains("no column 'z'"), "{e}");
    let e = parse_command(&b"path,kind,x,y,z\nl,line,0,0,0\n"[..], "c.csv").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("c.csv:2: path 'l' has no start row"),
        "{e}"
    );
    let e = parse_command(
        &b"path,kind,x,y,z\nl,start,0,0,0\nl,jump,1,0,0\n"[..],
        "c.csv",
    )
    .unwrap_err();
    assert!(
        e.to_string().starts_with("c.csv:3:2 (column 'kind')"),
        "{e}"
    );
    let text = b"path,kind,x,y,z,vx,vy,vz\nc,start,0,0,0,,,\nc,arc,2,0,0,1,0,0\n";
    let e = parse_command(&text[..], "c.csv").unwrap_err();
    assert!(e.to_string().contains("lie on one line"), "{e}");
    let e = parse_command(
        &b"path,kind,x,y,z\nl,start,0,0,0\nl,line,0,0,0\n"[..],
        "c.csv",
    )
    .unwrap_err();
    assert!(e.to_string().contains("no length"), "{e}");
}

/// An arc from three points turns through its via point, whichever way round.
#[test]
fn an_arc_passes_through_its_via_point() {
    for via in [V3::new(0.0, 1.0, 0.0), V3::new(0.0, -1.0, 0.0)] {
        let Some(g) = arc(V3::new(1.0, 0.0, 0.0), via, V3::new(-1.0, 0.0, 0.0)) else {
            panic!("an arc")
        };
        assert!((g.length() - std::f64::consts::PI).abs() < 1e-12);
        assert!((g.point(std::f64::consts::FRAC_PI_2) - via).norm() < 1e-12);
        let (s, d) = g.project(&(via * 2.0));
        assert!((s - std::f64::consts::FRAC_PI_2).abs() < 1e-12 && (d - 1.0).abs() < 1e-12);
    }
}

/// A compensation that predicts the offset exactly leaves the path on its command, and
/// the repeatability as it was.
#[test]
fn compensating_the_known_offset_removes_the_accuracy_not_the_repeatability() {
    let line = path("line");
    let across = line.segments[0]
        .geometry
        .tangent(0.0)
        .cross(&V3::z())
        .normalize()
        * 0.3;
    let sim = Simulation {
        offset_mm: [across.x, across.y, across.z],
        cycle_spread_mm: 0.05,
        ..quiet(4)
    };
    let stream = parse_stream(simulated_stream(&line, &sim).as_bytes(), "s.csv").unwrap();
    let measured = measured_paths(&stream, std::slice::from_ref(&line)).unwrap();
    let after = compensated(&measured, |_| Ok([across.x, across.y, across.z])).unwrap();
    let after = characteristics(&after).unwrap().paths[0].clone();
    assert!(after.at_p_mm < 1e-6, "{after:?}");
    assert!((after.rt_p_mm - 0.05).abs() < 1e-6, "{after:?}");
    let e = compensated(&measured, |_| Err("outside the table".into())).unwrap_err();
    assert!(e.to_string().contains("outside the table"), "{e}");
}

/// The speed on a small circle is the arc's, not the chord's: a 24 mm circle run at
/// 200 mm/s reads 200 mm/s (the chord over 50 ms would read 0.7 % slow).
#[test]
fn the_speed_on_a_small_circle_is_not_read_slow_from_the_chord() {
    let circle = path("small_circle");
    let c = reduce(
        &circle,
        &Simulation {
            rate_hz: 1000.0,
            ..quiet(3)
        },
    );
    let v = c.velocity.unwrap();
    assert!(v.av_percent.abs() < 0.01, "{v:?}");
}

/// Bytes that matter to the stream and command readers, and some that do not.
const ALPHABET: &[u8] = b"0123456789.-+eE,#\" \t\r\nxyztpathkindlinearcstartvcycle\xff\x00";

/// Mutates `text` at the places and with the bytes drawn.
fn mutate(text: &str, mutations: &[(f64, u8, usize)]) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    for &(at, op, b) in mutations {
        let i = ((at * bytes.len() as f64) as usize).min(bytes.len());
        match op {
            0 if i < bytes.len() => bytes[i] = ALPHABET[b],
            1 => bytes.insert(i, ALPHABET[b]),
            _ if i < bytes.len() => {
                bytes.remove(i);
            }
            _ => {}
        }
    }
    bytes
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]

    /// Streams and commands mutated byte by byte: reduced, or refused with a reason; never
    /// a panic, never a non-finite figure.
    #[test]
    fn hostile_streams_and_commands_are_refused_or_give_finite_figures(
        stream_mutations in proptest::collection::vec((0.0..1.0f64, 0..3u8, 0..ALPHABET.len()), 0..6),
        command_mutations in proptest::collection::vec((0.0..1.0f64, 0..3u8, 0..ALPHABET.len()), 0..4),
    ) {
        let command = "path,kind,x,y,z,vx,vy,vz,speed\n\
            r,start,1000,0,1000,,,,\n\
            r,line,1100,0,1000,,,,100\n\
            r,arc,1100,100,1000,1150,50,1000,100\n\
            r,line,1000,0,1000,,,,100\n";
        // The stream of the command as written; the reduction against the mutated one.
        let original = parse_command(command.as_bytes(), "c.csv").unwrap();
        let sim = Simulation { rate_hz: 50.0, dwell_s: 0.3, ..quiet(2) };
        let text = simulated_stream(&original[0], &sim);
        let Ok(commands) = parse_command(&mutate(command, &command_mutations)[..], "c.csv") else {
            return Ok(());
        };
        let Ok(stream) = parse_stream(&mutate(&text, &stream_mutations)[..], "s.csv") else {
            return Ok(());
        };
        let Ok(measured) = measured_paths(&stream, &commands) else {
            return Ok(());
        };
        if let Ok(report) = characteristics(&measured) {
            let json = serde_json::to_string(&report).unwrap_or_default();
            proptest::prop_assert!(!json.contains("NaN") && !json.contains("inf") && !json.contains("null,"), "{}", json);
        }
    }
}
