//! Fuzzes the GFE (Kinect grammatical facial expressions) importer: header check, datapoints, targets.
//! The body is `mimic_fuzz::gfe` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::gfe(data));
