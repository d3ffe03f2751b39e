//! Fuzzes Live Link Face's UDP packet decoder and the CSV take reader (`mimic_trackers`). A
//! decoded packet must re-encode to the same bytes.
//! The body is `mimic_fuzz::livelink` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::livelink(data));
