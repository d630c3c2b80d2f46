//! The Stäubli VAL3 reader on arbitrary bytes: the input split at its first NUL byte into a
//! data file (`.dtx`) and a program (`.pgx`). A program whose targets and numbers lie in
//! the data file and are finite (a number the file omits a zero with an empty span), or an
//! error located in the file it names; never a panic.

#![no_main]

use adwi_programs::source::Source;
use libfuzzer_sys::fuzz_target;

#[path = "program_checks.rs"]
mod program_checks;

fuzz_target!(|data: &[u8]| {
    let (dtx, pgx) = match data.iter().position(|b| *b == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &data[..0]),
    };
    let src = Source::new("fuzz.dtx", dtx);
    let program = Source::new("fuzz.pgx", pgx);
    let result = adwi_programs::staubli::read(&src, std::slice::from_ref(&program));
    match result {
        // An error in the program is located in the program.
        Err(adwi_programs::Error::Syntax { ref file, line, .. }) if file == "fuzz.pgx" => {
            assert!(line >= 1 && line <= pgx.split(|b| *b == b'\n').count() + pgx.len());
        }
        result => {
            if let Ok(program) = &result {
                for t in &program.targets {
                    for u in &t.uses {
                        assert!(u.offset <= dtx.len());
                    }
                }
            }
            program_checks::check(&src, result);
        }
    }
});
