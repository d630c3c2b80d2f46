//! Structured mutation of robot-file and scenario text, for the mutation tests
//! (`adwi-simulate`'s and the end-to-end tests through `tablec`): the edits a hostile user
//! makes, so that every range check, every parser limit and every message bound is reached.
//! Not part of the supported API.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Byte ranges of the numbers in `text`: maximal runs of number characters holding a
/// digit.
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let is_number = |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'e' | b'E');
        if is_number(bytes[i]) && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric()) {
            let start = i;
            while i < bytes.len() && is_number(bytes[i]) {
                i += 1;
            }
            if bytes[start..i].iter().any(u8::is_ascii_digit) {
                out.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    out
}

/// A value a hostile user would write for a number.
fn hostile_number(current: &str, rng: &mut ChaCha8Rng) -> String {
    const VALUES: [&str; 22] = [
        "0", "-0", "0.0", "1e308", "-1e308", "1e-308", "5e-324", "nan", "NaN", "inf", "-inf",
        "1e999", "1e16", "-5", "-1", "1", "360", "1e6", "1000001", "", "1e300", "1e-300",
    ];
    match rng.gen_range(0..4) {
        0 => {
            // The current value scaled by a power of ten, so that units go wrong.
            let v: f64 = current.parse().unwrap_or(1.0);
            let k = rng.gen_range(-12..=12);
            format!("{:e}", v * 10f64.powi(k))
        }
        1 => format!("{}", rng.gen::<f64>() * 2e3 - 1e3),
        _ => VALUES[rng.gen_range(0..VALUES.len())].to_owned(),
    }
}

/// One structured mutation of robot-file (`urdf`: URDF) or scenario text, drawn from
/// `rng`: a number replaced by a hostile one (three times in four), lines deleted,
/// repeated or swapped, a block (a joint) repeated, deep nesting inserted, names, kinds
/// and keys swapped, the text truncated, or garbage inserted.
pub fn mutate(text: &mut String, urdf: bool, rng: &mut ChaCha8Rng) {
    let lines: Vec<&str> = text.lines().collect();
    match rng.gen_range(0..10) {
        // A number, three times in four: the fields are what a range check must catch.
        0..=3 => {
            let spans = numbers(text);
            if let Some(&(start, end)) = spans.get(rng.gen_range(0..spans.len().max(1))) {
                let value = hostile_number(&text[start..end], rng);
                text.replace_range(start..end, &value);
            }
        }
        // Lines deleted, duplicated many times or swapped.
        4 => {
            if !lines.is_empty() {
                let i = rng.gen_range(0..lines.len());
                let mut out: Vec<&str> = lines.clone();
                match rng.gen_range(0..3) {
                    0 => {
                        out.remove(i);
                    }
                    1 => {
                        let times = [1, 7, 50][rng.gen_range(0..3)];
                        for _ in 0..times {
                            out.insert(i, lines[i]);
                        }
                    }
                    _ => out.swap(i, rng.gen_range(0..lines.len())),
                }
                *text = out.join("\n");
            }
        }
        // A block (an element or a [[joints]] table) repeated.
        5 => {
            let marker = if urdf { "<joint " } else { "[[joints]]" };
            let starts: Vec<usize> = text.match_indices(marker).map(|(i, _)| i).collect();
            if let Some(&start) = starts.get(rng.gen_range(0..starts.len().max(1))) {
                let end = text[start + 1..]
                    .find(marker)
                    .map_or(text.len(), |k| start + 1 + k);
                let block = text[start..end].to_owned();
                let times = [1, 12, 13, 200][rng.gen_range(0..4)];
                text.insert_str(end, &block.repeat(times));
            }
        }
        // Deep nesting.
        6 => {
            let depth = [10, 63, 64, 65, 1000, 30_000, 200_000][rng.gen_range(0..7)];
            let at = rng.gen_range(0..=text.len());
            let at = (0..=at)
                .rev()
                .find(|&i| text.is_char_boundary(i))
                .unwrap_or(0);
            let nested = if urdf {
                format!("{}{}", "<a>".repeat(depth), "</a>".repeat(depth))
            } else {
                format!("\nx = {}{}\n", "[".repeat(depth), "]".repeat(depth))
            };
            text.insert_str(at, &nested);
        }
        // Names and kinds swapped: duplicate names, other joint types, other keys.
        7 => {
            let swaps: &[(&str, &str)] = if urdf {
                &[
                    ("type=\"revolute\"", "type=\"prismatic\""),
                    ("type=\"revolute\"", "type=\"continuous\""),
                    ("type=\"revolute\"", "type=\"fixed\""),
                    ("type=\"fixed\"", "type=\"floating\""),
                    (
                        "name=\"shoulder_lift_joint\"",
                        "name=\"shoulder_pan_joint\"",
                    ),
                    ("name=\"joint_a2\"", "name=\"joint_a1\""),
                    ("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 0 0\"/>"),
                    ("<limit ", "<limit lower=\"1\" "),
                    ("link=\"", "link=\"x"),
                ]
            } else {
                &[
                    ("a_mm", "d_mm"),
                    ("alpha_deg", "beta_deg"),
                    ("limits_deg", "limits_mm"),
                    ("mass_kg", "com_mm"),
                    ("name =", "urdf ="),
                    ("[tool]", "[payload]"),
                    ("delta_a_mm", "delta_xyz_mm"),
                    ("stiffness_nm_per_rad", "gear_phase_deg"),
                    ("[[joints]]", "[[link_masses]]"),
                ]
            };
            let (from, to) = swaps[rng.gen_range(0..swaps.len())];
            *text = text.replacen(from, to, rng.gen_range(1..3));
        }
        // Truncated.
        8 => {
            let at = rng.gen_range(0..=text.len());
            let at = (0..=at)
                .rev()
                .find(|&i| text.is_char_boundary(i))
                .unwrap_or(0);
            text.truncate(at);
        }
        // Garbage inserted.
        _ => {
            let garbage: String = (0..rng.gen_range(1..20))
                .map(|_| {
                    let c = [
                        '<', '>', '"', '=', '[', ']', '\n', '#', 'é', '\0', '1', ' ', '/', '&',
                    ];
                    c[rng.gen_range(0..c.len())]
                })
                .collect();
            let at = rng.gen_range(0..=text.len());
            let at = (0..=at)
                .rev()
                .find(|&i| text.is_char_boundary(i))
                .unwrap_or(0);
            text.insert_str(at, &garbage);
        }
    }
}
