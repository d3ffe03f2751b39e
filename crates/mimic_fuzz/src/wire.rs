//! The live service's decoders in `mimic_wire`.

use mimic_wire::{
    AudioFormat, decode_udp_frame, decode_viewer_message, encode_udp_frame, parse_audio_chunk,
    parse_hello, parse_weight_frame,
};

/// The first line of a TCP connection (`parse_hello`), a weight frame line
/// (`parse_weight_frame`), an audio chunk line (`parse_audio_chunk`, mono at 8 kHz and stereo at
/// 48 kHz: at most the chunk limit of samples, each in -1..1), a UDP frame packet (`decode_udp_frame`) and a viewer message
/// (`decode_viewer_message`, kind byte first). A decoded UDP frame survives its own encoder.
pub fn stream(data: &[u8]) {
    let _ = parse_hello(data);
    let _ = parse_weight_frame(data);
    let (mut scratch, mut mono) = (Vec::new(), Vec::new());
    for (sample_rate, channels) in [(8_000, 1), (48_000, 2)] {
        let format = AudioFormat {
            sample_rate,
            channels,
        };
        if parse_audio_chunk(data, format, &mut scratch, &mut mono).is_ok() {
            assert!(!mono.is_empty() && mono.len() <= format.max_chunk_samples());
            assert!(mono.iter().all(|x| (-1.0..=1.0).contains(x)));
        }
    }
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
