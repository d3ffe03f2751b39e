//! Fuzzes the MediaPipe dump reader and, for every line it accepts, the conversion to metres:
//! the line's landmarks (whatever their count) are repeated up to 478 so that short inputs
//! reach `to_camera_space` too.
//! The body is `mimic_fuzz::mediapipe` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::mediapipe(data));
