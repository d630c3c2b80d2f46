//! Several series trained together: refused when one is another given twice, or when one
//! is in another length unit than the rest.
//!
//! A series given twice reads without complaint and doubles every pose: each is then a
//! repeated pose with a spread of 0 mm, and the repeatability reported is 0. A series in
//! metres among series in millimetres puts its samples a thousand times too close to the
//! base. Neither is a measurement: both are refused by name before any work.

use std::path::{Path, PathBuf};

/// How far apart two series' position scales may lie before one is taken for another
/// unit: a hundredfold (series of one robot lie within its reach, their median distances
/// from the origin a few times apart at most; a metre is a thousand millimetres).
pub const MAX_SERIES_SCALE_RATIO: f64 = 100.0;

/// The median distances from the origin a robot's positions plausibly have, mm: 5 cm to
/// 50 m (of the base for base-frame positions, of a tracker for its own).
const ROBOT_DISTANCE_MM: std::ops::RangeInclusive<f64> = 50.0..=50_000.0;

/// One series as the check sees it.
#[derive(Debug, Clone, Copy)]
pub struct SeriesRows<'a, T> {
    /// What messages call it.
    pub name: &'a Path,
    /// Its file, when it is one (not text in memory).
    pub file: Option<&'a Path>,
    /// What it holds, compared whole with the other series'.
    pub content: &'a T,
    /// Its positions, mm as read: nominal ones in the base frame, measured ones in a
    /// tracker's.
    pub positions_mm: &'a [[f64; 3]],
}

/// Series that cannot be trained together.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SeriesConflict {
    /// One file named twice.
    #[error(
        "{} is given twice (series {first} and {again}): every pose would count as repeated, \
         with a repeatability of 0 mm; give each series once",
        path.display()
    )]
    SameFile {
        /// The file.
        path: PathBuf,
        /// Its first position among the series (1-based).
        first: usize,
        /// Its second.
        again: usize,
    },
    /// Two series with the same rows (a copy of a file).
    #[error(
        "{} holds the same rows as {} (series {again} and {first}): every pose would count as \
         repeated, with a repeatability of 0 mm; give each series once",
        again_name.display(),
        first_name.display()
    )]
    SameRows {
        /// The first series.
        first_name: PathBuf,
        /// Its position among the series (1-based).
        first: usize,
        /// The series that repeats it.
        again_name: PathBuf,
        /// Its position.
        again: usize,
    },
    /// One series' positions on another scale than the others'.
    #[error(
        "series {series} ({}) has positions {} times {} those of the other series (median \
         distance from the origin {} mm against {} mm){}",
        name.display(),
        ratio_text(*ratio),
        if *ratio < 1.0 { "smaller than" } else { "larger than" },
        number(*distance_mm),
        number(*others_mm),
        unit_text(*ratio)
    )]
    Scale {
        /// The series, as messages call it.
        name: PathBuf,
        /// Its position among the series (1-based).
        series: usize,
        /// Its positions' median distance from the origin, mm as read.
        distance_mm: f64,
        /// The other series' (the median of theirs), mm as read.
        others_mm: f64,
        /// `distance_mm / others_mm`.
        ratio: f64,
    },
}

fn number(value: f64) -> String {
    crate::plausible::number(value)
}

/// The ratio as a factor: "about 1000" either way.
fn ratio_text(ratio: f64) -> String {
    let factor = if ratio < 1.0 { 1.0 / ratio } else { ratio };
    format!("about {}", number(factor))
}

/// The unit a ratio suggests: a thousand is metres among millimetres, or the reverse.
fn unit_text(ratio: f64) -> &'static str {
    let thousand = |r: f64| (300.0..=3000.0).contains(&r);
    if thousand(1.0 / ratio) {
        ": it looks like metres read as millimetres among series in millimetres; convert it \
         to millimetres (series trained together are read with one column map)"
    } else if thousand(ratio) {
        ": it looks like millimetres among series in metres read as millimetres, or \
         micrometres; convert it to the others' unit (series trained together are read with \
         one column map)"
    } else {
        ": series of one robot lie within its reach; is it another robot's, or in another \
         unit?"
    }
}

/// The median distance of `positions` from the origin, mm as read.
fn median_distance_mm(positions: &[[f64; 3]]) -> f64 {
    let mut d: Vec<f64> = positions
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// Checks series to be trained together (module docs): no file twice, no two series with
/// the same rows, no series whose positions' median distance from the origin is more than
/// [`MAX_SERIES_SCALE_RATIO`] times the other series' (their median).
///
/// # Errors
///
/// The first [`SeriesConflict`] found, naming the series.
pub fn check_series<T: PartialEq>(series: &[SeriesRows<'_, T>]) -> Result<(), SeriesConflict> {
    // Files compared by what they are, not how they are named (`./a.csv`, a link).
    let identity = |path: &Path| std::fs::canonicalize(path).unwrap_or_else(|_| path.into());
    let files: Vec<Option<PathBuf>> = series.iter().map(|s| s.file.map(identity)).collect();
    for (again, s) in series.iter().enumerate() {
        for first in 0..again {
            if files[again].is_some() && files[again] == files[first] {
                return Err(SeriesConflict::SameFile {
                    path: s.name.to_path_buf(),
                    first: first + 1,
                    again: again + 1,
                });
            }
            if s.content == series[first].content {
                return Err(SeriesConflict::SameRows {
                    first_name: series[first].name.to_path_buf(),
                    first: first + 1,
                    again_name: s.name.to_path_buf(),
                    again: again + 1,
                });
            }
        }
    }
    if series.len() < 2 {
        return Ok(());
    }
    let distances: Vec<f64> = series
        .iter()
        .map(|s| median_distance_mm(s.positions_mm))
        .collect();
    let odd: Vec<(usize, f64, f64)> = (0..series.len())
        .filter_map(|i| {
            let mut others: Vec<f64> = (0..series.len())
                .filter(|&j| j != i)
                .map(|j| distances[j])
                .collect();
            others.sort_by(f64::total_cmp);
            let others_mm = others[others.len() / 2];
            let ratio = distances[i] / others_mm;
            let apart = !(1.0 / MAX_SERIES_SCALE_RATIO..=MAX_SERIES_SCALE_RATIO).contains(&ratio);
            (apart && others_mm > 0.0).then_some((i, distances[i], others_mm))
        })
        .collect();
    // Two series apart from each other: the one no robot's positions look like, else the
    // later one.
    let named = odd
        .iter()
        .find(|(_, d, _)| !ROBOT_DISTANCE_MM.contains(d))
        .or(odd.last());
    match named {
        Some(&(i, distance_mm, others_mm)) => Err(SeriesConflict::Scale {
            name: series[i].name.to_path_buf(),
            series: i + 1,
            distance_mm,
            others_mm,
            ratio: distance_mm / others_mm,
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows<'a>(name: &'a str, content: &'a Vec<[f64; 3]>) -> SeriesRows<'a, Vec<[f64; 3]>> {
        SeriesRows {
            name: Path::new(name),
            file: None,
            content,
            positions_mm: content,
        }
    }

    fn lattice(scale: f64, shift: f64) -> Vec<[f64; 3]> {
        (0..27)
            .map(|i| {
                [
                    400.0 + shift + (i % 3) as f64 * 100.0,
                    -200.0 + (i / 3 % 3) as f64 * 100.0,
                    300.0 + (i / 9) as f64 * 100.0,
                ]
                .map(|v| v * scale)
            })
            .collect()
    }

    #[test]
    fn a_series_in_metres_among_series_in_millimetres_is_named() {
        let (a, b, c) = (lattice(1.0, 0.0), lattice(1.0, 50.0), lattice(1e-3, 25.0));
        assert_eq!(check_series(&[rows("a", &a), rows("b", &b)]), Ok(()));
        let e = check_series(&[rows("a", &a), rows("c", &c), rows("b", &b)]).unwrap_err();
        let SeriesConflict::Scale { series, ratio, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!(*series, 2);
        assert!((ratio * 1000.0 - 1.0).abs() < 0.2, "{ratio}");
        assert!(
            e.to_string()
                .contains("looks like metres read as millimetres"),
            "{e}"
        );
        // Two series: the one no robot's positions look like is named, first or second.
        for pair in [[&a, &c], [&c, &a]] {
            let e = check_series(&[rows("x", pair[0]), rows("y", pair[1])]).unwrap_err();
            let expected = if std::ptr::eq(pair[0], &c) { "x" } else { "y" };
            assert!(
                matches!(&e, SeriesConflict::Scale { name, .. } if name == Path::new(expected)),
                "{e}"
            );
        }
    }

    #[test]
    fn a_series_given_twice_is_refused() {
        let (a, b) = (lattice(1.0, 0.0), lattice(1.0, 50.0));
        let copy = a.clone();
        let e = check_series(&[rows("a", &a), rows("b", &b), rows("copy", &copy)]).unwrap_err();
        assert_eq!(
            e,
            SeriesConflict::SameRows {
                first_name: "a".into(),
                first: 1,
                again_name: "copy".into(),
                again: 3
            }
        );
        // One file named two ways is refused by its path, whatever it holds.
        let dir = std::env::temp_dir().join(format!("adwi-series-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("s.csv"), "x,y,z,dx,dy,dz\n").unwrap();
        let (plain, dotted) = (dir.join("s.csv"), dir.join(".").join("s.csv"));
        let series = [(&plain, &a), (&dotted, &b)].map(|(path, content)| SeriesRows {
            name: path.as_path(),
            file: Some(path.as_path()),
            content,
            positions_mm: content,
        });
        let e = check_series(&series).unwrap_err();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            matches!(
                e,
                SeriesConflict::SameFile {
                    first: 1,
                    again: 2,
                    ..
                }
            ),
            "{e}"
        );
    }
}
