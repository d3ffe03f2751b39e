//! Fuzzes the morph data file reader (`docs/morph-format.md`).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(targets) = mimic_assets::read_morph_file(data, Path::new("fuzz.morph.txt")) {
        for t in &targets {
            assert_eq!(
                t.position_deltas.len(),
                t.normal_deltas.len(),
                "position and normal deltas differ in count"
            );
        }
    }
});
