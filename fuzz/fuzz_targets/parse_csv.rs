//! The sample CSV reader on arbitrary bytes, with the default column names and with a
//! column mapping taken from the input's first line: it must return a sample set or an
//! error, never panic.

#![no_main]

use std::path::Path;

use adwi_compile::samples::{parse_samples, ColumnMap};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.csv");
    if let Ok(set) = parse_samples(path, data, &ColumnMap::default()) {
        let _ = set.records();
        let _ = set.spacing_mm();
        let _ = set.nominal_bounds_mm();
        let _ = set.source_hash();
    }
    // A mapping spec from the first line, the CSV from the rest.
    let split = data.iter().position(|&b| b == b'\n').unwrap_or(data.len());
    if let Ok(spec) = std::str::from_utf8(&data[..split]) {
        if let Ok(columns) = ColumnMap::parse(spec) {
            let _ = parse_samples(path, data.get(split + 1..).unwrap_or(&[]), &columns);
        }
    }
});
