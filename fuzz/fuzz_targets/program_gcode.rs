//! The G-code (`.nc`) reader on arbitrary bytes, with a work offset given and in both A, B,
//! C conventions: a program whose targets and numbers lie in the input and are finite, one
//! arc and one work offset per target, or an error located in it; never a panic.

#![no_main]

use adwi_programs::gcode::{AbcConvention, GcodeOptions};
use adwi_programs::source::Source;
use libfuzzer_sys::fuzz_target;

#[path = "program_checks.rs"]
mod program_checks;

fuzz_target!(|data: &[u8]| {
    let src = Source::new("fuzz.nc", data);
    for abc in [AbcConvention::Kuka, AbcConvention::FixedXyz] {
        let options = GcodeOptions {
            abc,
            work_offsets: vec![(54, [1750.0, 450.0, 1200.0, 0.0, 0.0, 0.0])],
            ..GcodeOptions::default()
        };
        let result = adwi_programs::gcode::read(&src, &options).map(|read| {
            assert_eq!(read.arcs.len(), read.program.targets.len());
            assert_eq!(read.work_offsets.len(), read.program.targets.len());
            for (i, arc) in read.arcs.iter().enumerate() {
                if let Some(arc) = arc {
                    assert!(arc.start_target < i);
                }
            }
            read.program
        });
        program_checks::check(&src, result);
    }
});
