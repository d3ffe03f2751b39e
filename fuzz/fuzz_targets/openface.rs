//! Fuzzes the OpenFace CSV importer with both timing modes.
//! The body is `mimic_fuzz::openface` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::openface(data));
