//! The Yaskawa INFORM (`.jbi`) reader on arbitrary bytes, with tools, a user frame and
//! pulses per degree given and without: a program whose targets and numbers lie in the
//! input and are finite, or an error located in it; never a panic.

#![no_main]

use adwi_programs::source::Source;
use adwi_programs::yaskawa::YaskawaOptions;
use libfuzzer_sys::fuzz_target;

#[path = "program_checks.rs"]
mod program_checks;

fuzz_target!(|data: &[u8]| {
    let src = Source::new("fuzz.jbi", data);
    let given = YaskawaOptions {
        tools: vec![(1, [0.0, 0.0, 180.0, 0.0, 0.0, 0.0])],
        users: vec![(1, [1600.0, 250.0, 750.0, 0.0, 0.0, 30.0])],
        pulses_per_deg: Some(vec![1456.356, 1456.356, 1350.0, 910.222, 910.222, 555.556]),
    };
    for options in [YaskawaOptions::default(), given] {
        let result = adwi_programs::yaskawa::read(&src, &options);
        if let Ok(program) = &result {
            for t in &program.targets {
                for u in &t.uses {
                    assert!(u.offset <= data.len());
                }
            }
        }
        program_checks::check(&src, result);
    }
});
