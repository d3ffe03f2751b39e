//! Fuzzes the landmark layout TOML loader.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = mimic_assets::parse_layout(Path::new("fuzz_layout.toml"), text);
});
