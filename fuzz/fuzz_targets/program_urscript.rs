//! The URScript (`.script`) reader on arbitrary bytes: a program whose targets and numbers
//! lie in the input and are finite, or an error located in it; never a panic.

#![no_main]

use adwi_programs::source::Source;
use libfuzzer_sys::fuzz_target;

#[path = "program_checks.rs"]
mod program_checks;

fuzz_target!(|data: &[u8]| {
    let src = Source::new("fuzz.script", data);
    program_checks::check(&src, adwi_programs::urscript::read(&src));
});
