//! Fuzzes OpenSeeFace's datagram decoder and the `.osf` capture splitter (`mimic_trackers`). A
//! decoded datagram must re-encode to the same bytes, and its faces convert to frames.
//! The body is `mimic_fuzz::openseeface` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::openseeface(data));
