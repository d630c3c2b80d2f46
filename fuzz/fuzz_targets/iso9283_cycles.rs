//! The ISO 9283 cycles reader and characteristics on arbitrary bytes: figures that are all
//! finite, or an error; never a panic. The bounded in-tree run of the same check is
//! `adwi_measure`'s `hostile_cycles_are_refused_or_give_finite_figures`.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(rows) = adwi_measure::iso9283::parse_cycles(data) else {
        return;
    };
    if let Ok(report) = adwi_measure::iso9283::characteristics(&rows) {
        let json = serde_json::to_string(&report).expect("a report serialises");
        assert!(!json.contains("NaN") && !json.contains("inf"), "{json}");
    }
});
