//! Fuzzes the morph data file reader (`docs/morph-format.md`).
//! The body is `mimic_fuzz::morph` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::morph(data));
