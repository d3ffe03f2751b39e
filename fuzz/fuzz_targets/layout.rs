//! Fuzzes the landmark layout TOML loader.
//! The body is `mimic_fuzz::layout` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::layout(data));
