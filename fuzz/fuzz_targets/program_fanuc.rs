//! The Fanuc TP (`.ls`) reader on arbitrary bytes, with user and tool frames given: a
//! program whose targets and numbers lie in the input and are finite, every position's
//! frames finite, or an error located in it; never a panic. The same bytes read as a
//! controller's frame file (`SYSFRAME.VA`): frames within the bounds, or an error located
//! in it.

#![no_main]

use adwi_programs::fanuc::FanucOptions;
use adwi_programs::source::Source;
use libfuzzer_sys::fuzz_target;

#[path = "program_checks.rs"]
mod program_checks;

fuzz_target!(|data: &[u8]| {
    let src = Source::new("fuzz.ls", data);
    let options = FanucOptions {
        user_frames: vec![(1, [1600.0, 250.0, 750.0, 0.0, 0.0, 30.0])],
        tool_frames: vec![(1, [0.0, 0.0, 180.0, 0.0, 0.0, 0.0])],
        frames_file: None,
    };
    let result = adwi_programs::fanuc::read(&src, &options).inspect(|program| {
        for target in &program.targets {
            for u in &target.uses {
                for frame in [u.base, u.tool].into_iter().flatten() {
                    assert!(adwi_programs::bounds::frame_within(&frame));
                }
            }
        }
    });
    program_checks::check(&src, result);
    match adwi_programs::fanuc::read_frames(&src) {
        Ok(frames) => {
            for (_, frame) in frames.user_frames.iter().chain(&frames.tool_frames) {
                assert!(adwi_programs::bounds::option_frame_within(frame));
            }
        }
        Err(e) => program_checks::check(&src, Err(e)),
    }
});
