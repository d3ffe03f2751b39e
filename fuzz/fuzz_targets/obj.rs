//! Fuzzes the OBJ mesh parser.
//! The body is `mimic_fuzz::obj` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::obj(data));
