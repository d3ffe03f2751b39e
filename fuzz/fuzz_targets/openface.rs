//! Fuzzes the OpenFace CSV importer with both timing modes.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use mimic_capture::openface::{OpenFaceTiming, parse_csv};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.csv");
    let _ = parse_csv(text, path, OpenFaceTiming::FileTimestamps);
    let _ = parse_csv(text, path, OpenFaceTiming::Rate(30.0));
});
