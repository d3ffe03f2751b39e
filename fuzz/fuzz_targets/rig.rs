//! Fuzzes the rig TOML loader; the rig's mesh resolves in a scratch folder holding `tri.obj`.
//! The body is `mimic_fuzz::rig` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::rig(data));
