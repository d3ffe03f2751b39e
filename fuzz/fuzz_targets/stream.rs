//! Fuzzes the live service's decoders in `mimic_wire`: the first line of a TCP connection
//! (`parse_hello`), a weight frame line (`parse_weight_frame`), an audio chunk line
//! (`parse_audio_chunk`), a UDP frame packet (`decode_udp_frame`) and a viewer message
//! (`decode_viewer_message`, kind byte first). A decoded UDP frame must survive its own encoder
//! unchanged.
//! The body is `mimic_fuzz::stream` (crates/mimic_fuzz), which the workspace tests also run on
//! this target's seed corpus.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimic_fuzz::stream(data));
