//! The KUKA KRL (`.src`, `.dat`) reader on arbitrary bytes, with a partner file when the
//! first byte is odd (the input split in two at its middle): a program whose targets and
//! numbers lie in the input and are finite, or an error located in it; never a panic.

#![no_main]

use adwi_programs::source::Source;
use libfuzzer_sys::fuzz_target;

#[path = "program_checks.rs"]
mod program_checks;

fuzz_target!(|data: &[u8]| {
    let (program, partner) = match data.first() {
        Some(b) if b & 1 == 1 => data.split_at(data.len() / 2),
        _ => (data, &[][..]),
    };
    let src = Source::new("fuzz.src", program);
    let partner = (!partner.is_empty()).then(|| Source::new("fuzz.dat", partner));
    program_checks::check(&src, adwi_programs::krl::read(&src, partner.as_ref()));
});
