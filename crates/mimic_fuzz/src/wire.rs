//! The live service's decoders in `mimic_wire`.

use mimic_wire::{
    decode_udp_frame, decode_viewer_message, encode_udp_frame, parse_hello, parse_weight_frame,
};

/// The first line of a TCP connection (`parse_hello`), a weight frame line
/// (`parse_weight_frame`), a UDP frame packet (`decode_udp_frame`) and a viewer message
/// (`decode_viewer_message`, kind byte first). A decoded UDP frame survives its own encoder.
pub fn stream(data: &[u8]) {
    let _ = parse_hello(data);
    let _ = parse_weight_frame(data);
    if let Ok(f) = decode_udp_frame(data) {
        assert_eq!(f.frame.points.len(), f.frame.valid.len());
        let again = decode_udp_frame(&encode_udp_frame(f.session_id, f.key, &f.frame));
        assert!(again.is_ok(), "a decoded packet re-encodes to a valid one");
        if let Ok(again) = again {
            assert_eq!((again.session_id, again.key), (f.session_id, f.key));
            assert_eq!(again.frame.timestamp_us, f.frame.timestamp_us);
            assert_eq!(again.frame.tracked, f.frame.tracked);
            assert_eq!(again.frame.valid, f.frame.valid);
            for (i, (a, b)) in again.frame.points.iter().zip(&f.frame.points).enumerate() {
                assert!(
                    !f.frame.valid[i] || a == b,
                    "point {i} changed in a round trip"
                );
            }
        }
    }
    if let Some((&kind, payload)) = data.split_first() {
        let _ = decode_viewer_message(kind, payload);
    }
}
