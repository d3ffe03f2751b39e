//! Outside trackers' packets and files (`mimic_trackers`): OpenSeeFace and Live Link Face.

use std::path::Path;

use mimic_trackers::livelink::{
    decode_packet as decode_livelink, encode_packet as encode_livelink,
};
use mimic_trackers::openseeface::{decode_packet, encode_packet, parse_capture};
use mimic_trackers::osf_frames::{POINT_COUNT, to_frame};
use mimic_trackers::take::parse_take;

/// OpenSeeFace's datagram decoder and the `.osf` capture splitter: a decoded datagram re-encodes
/// to the same bytes, and its faces convert to frames.
pub fn openseeface(data: &[u8]) {
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
}

/// Live Link Face's UDP packet decoder and the CSV take reader: a decoded packet re-encodes to
/// the same bytes, a take's rows come in time order.
pub fn livelink(data: &[u8]) {
    if let Ok(p) = decode_livelink(data) {
        assert_eq!(encode_livelink(&p), data, "byte-exact round trip");
        let _ = p.time_us();
    }
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(take) = parse_take(text, Path::new("fuzz.csv"))
    {
        assert!(take.rows.windows(2).all(|w| w[0].t_us <= w[1].t_us));
    }
}
