//! Hostile sample files: each is read or refused with an error, without panicking and in
//! bounded time (the bounds are generous: they catch quadratic blow-ups, not slow machines).

use std::path::Path;
use std::time::{Duration, Instant};

use adwi_samples::{parse_samples, ColumnMap, SampleSet};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const BOUND: Duration = Duration::from_secs(20);

/// Parses `bytes`, checking the time bound; returns the result's error message, if any.
fn parse(name: &str, bytes: &[u8]) -> Result<SampleSet, String> {
    let start = Instant::now();
    let result = parse_samples(Path::new(name), bytes, &ColumnMap::default());
    let elapsed = start.elapsed();
    assert!(elapsed < BOUND, "{name}: {elapsed:?}");
    result.map_err(|e| e.to_string())
}

#[test]
fn a_huge_field_is_refused() {
    let mut csv = b"x,y,z,dx,dy,dz\n1,2,".to_vec();
    csv.extend(std::iter::repeat_n(b'9', 16 << 20));
    csv.extend_from_slice(b",0.1,0.2,0.3\n");
    let err = parse("huge_field.csv", &csv).unwrap_err();
    // 16 million nines parse as infinity, refused as not finite, on line 2.
    assert!(err.starts_with("huge_field.csv:2:"), "{err}");
}

#[test]
fn a_huge_quoted_field_with_newlines_is_refused() {
    let mut csv = b"x,y,z,dx,dy,dz\n\"".to_vec();
    for _ in 0..(1 << 20) {
        csv.extend_from_slice(b"a\n");
    }
    csv.extend_from_slice(b"\",2,3,0.1,0.2,0.3\n");
    assert!(parse("quoted.csv", &csv).is_err());
}

#[test]
fn random_garbage_is_refused() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for size in [1usize, 10, 1_000, 1 << 20] {
        let bytes: Vec<u8> = (0..size).map(|_| rng.gen()).collect();
        assert!(parse("garbage.csv", &bytes).is_err(), "size {size}");
    }
    // Garbage after a valid header and row.
    let mut csv = b"x,y,z,dx,dy,dz\n1,2,3,0.1,0.2,0.3\n".to_vec();
    csv.extend((0..1 << 20).map(|_| rng.gen::<u8>()));
    assert!(parse("tail.csv", &csv).is_err());
}

#[test]
fn deeply_nested_quotes_and_separators_are_refused() {
    let mut csv = b"x,y,z,dx,dy,dz\n".to_vec();
    csv.extend(std::iter::repeat_n(b'"', 1 << 20));
    csv.extend(std::iter::repeat_n(b',', 1 << 20));
    csv.extend(std::iter::repeat_n(b'\n', 1 << 20));
    assert!(parse("quotes.csv", &csv).is_err());
}

#[test]
fn non_utf8_fields_are_refused_naming_the_line() {
    let csv = b"x,y,z,dx,dy,dz\n1,2,3,0.1,0.2,0.3\n4,\xff\xfe,6,0.1,0.2,0.3\n";
    let err = parse("latin.csv", csv).unwrap_err();
    assert!(err.starts_with("latin.csv:3:"), "{err}");
    let header = b"x,y,\xc3\x28,dx,dy,dz\n1,2,3,0.1,0.2,0.3\n";
    assert!(parse("header.csv", header).is_err());
}

#[test]
fn a_million_columns_are_read_or_refused_quickly() {
    const COLUMNS: usize = 1_000_000;
    let mut header = String::from("x,y,z,dx,dy,dz");
    let mut row = String::from("1,2,3,0.1,0.2,0.3");
    for i in 0..COLUMNS - 6 {
        header += &format!(",c{i}");
        row += ",0";
    }
    let csv = format!("{header}\n{row}\n");
    // Extra columns are ignored: one sample.
    match parse("wide.csv", csv.as_bytes()) {
        Ok(set) => assert_eq!(set.len(), 1),
        Err(e) => assert!(e.contains("wide.csv"), "{e}"),
    }
    // A million unnamed columns on a row of a narrow file.
    let csv = format!("x,y,z,dx,dy,dz\n{}\n", vec!["1"; COLUMNS].join(","));
    match parse("ragged.csv", csv.as_bytes()) {
        Ok(set) => assert_eq!(set.len(), 1),
        Err(e) => assert!(e.contains("ragged.csv"), "{e}"),
    }
}

#[test]
fn many_rows_of_nothing_are_refused() {
    let csv = "\n".repeat(1 << 20) + &",".repeat(1 << 16);
    assert!(parse("empty_rows.csv", csv.as_bytes()).is_err());
    let comments = "# comment\n".repeat(1 << 18);
    assert!(parse("comments.csv", comments.as_bytes()).is_err());
}

/// A million rows at one position: repeats of one pose fold into one sample, a million
/// orientations there stay a million samples with no spacing — each in bounded time.
#[test]
fn a_million_rows_at_one_position_are_read_quickly() {
    const ROWS: usize = 1_000_000;
    let csv = format!("x,y,z,dx,dy,dz\n{}", "1,2,3,0.1,0.2,0.3\n".repeat(ROWS));
    let set = parse("repeats.csv", csv.as_bytes()).unwrap();
    assert_eq!(set.len(), 1);
    assert_eq!(set.repeats.as_ref().unwrap().rows, ROWS);
    let mut csv = String::from("x,y,z,dx,dy,dz,a,b,c\n");
    for i in 0..ROWS {
        csv += &format!("1,2,3,0.1,0.2,0.3,0,0,{}\n", i as f64 * 1e-4);
    }
    let set = parse("orientations.csv", csv.as_bytes()).unwrap();
    assert_eq!(set.len(), ROWS);
    let start = Instant::now();
    assert_eq!(set.spacing_mm(), None);
    assert!(start.elapsed() < BOUND, "{:?}", start.elapsed());
}
