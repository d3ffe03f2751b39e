//! Fuzzes the v1 recording reader: header, then every frame line until the end.
//! The body is `mimic_fuzz::recording` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::recording(data));
