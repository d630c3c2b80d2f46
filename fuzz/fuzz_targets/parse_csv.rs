//! The sample CSV reader on arbitrary bytes, with the default column names, with a column
//! mapping taken from the input's first line, with reading options chosen by the input's
//! first byte, and as measurements: it must return a sample set (or measurements) or an
//! error, never panic.

#![no_main]

use std::path::Path;

use adwi_samples::{
    parse_measurements, parse_samples, parse_samples_with, AngleUnit, ColumnMap, Decimal,
    Delimiter, LengthUnit, ReadOptions,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.csv");
    if let Ok(set) = parse_samples(path, data, &ColumnMap::default()) {
        let _ = set.records();
        let _ = set.spacing_mm();
        let _ = set.nominal_bounds_mm();
        let _ = set.source_hash();
    }
    // Reading options from the first byte's bits.
    let bits = data.first().copied().unwrap_or(0);
    let options = ReadOptions {
        delimiter: [
            None,
            Some(Delimiter::Comma),
            Some(Delimiter::Semicolon),
            Some(Delimiter::Tab),
        ][usize::from(bits & 3)],
        decimal: [None, Some(Decimal::Point), Some(Decimal::Comma), None]
            [usize::from(bits >> 2 & 3)],
        length_unit: if bits & 16 == 0 {
            LengthUnit::Millimetre
        } else {
            LengthUnit::Metre
        },
        angle_unit: if bits & 32 == 0 {
            AngleUnit::Degree
        } else {
            AngleUnit::Radian
        },
        prismatic_joints: u64::from(bits >> 6 & 1),
    };
    if let Ok(set) = parse_samples_with(path, data, &ColumnMap::default(), &options) {
        let _ = set.spacing_mm();
    }
    if let Ok(m) = parse_measurements(path, data, &ColumnMap::default(), &options) {
        let _ = m.to_samples();
    }
    // A mapping spec from the first line, the CSV from the rest.
    let split = data.iter().position(|&b| b == b'\n').unwrap_or(data.len());
    if let Ok(spec) = std::str::from_utf8(&data[..split]) {
        if let Ok(columns) = ColumnMap::parse(spec) {
            let _ = parse_samples(path, data.get(split + 1..).unwrap_or(&[]), &columns);
        }
    }
});
