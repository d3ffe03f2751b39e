//! Fuzzes the avatar file reader (glTF / GLB / VRM).
//! The body is `mimic_fuzz::avatar` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::avatar(data));
