//! Fuzzes OpenSeeFace's datagram decoder and the `.osf` capture splitter (`mimic_trackers`). A
//! decoded datagram must re-encode to the same bytes, and its faces convert to frames.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mimic_trackers::openseeface::{decode_packet, encode_packet, parse_capture};
use mimic_trackers::osf_frames::{POINT_COUNT, to_frame};

fuzz_target!(|data: &[u8]| {
    if let Ok(faces) = decode_packet(data) {
        assert_eq!(encode_packet(&faces), data, "byte-exact round trip");
        for f in &faces {
            let frame = to_frame(f, 0);
            assert!(frame.points.is_empty() || frame.points.len() == POINT_COUNT);
            assert_eq!(frame.points.len(), frame.valid.len());
        }
    }
    if let Ok(records) = parse_capture(data) {
        for r in &records {
            let _ = decode_packet(&r.datagram);
        }
    }
});
