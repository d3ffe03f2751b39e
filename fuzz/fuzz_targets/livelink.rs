//! Fuzzes Live Link Face's UDP packet decoder and the CSV take reader (`mimic_trackers`). A
//! decoded packet must re-encode to the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mimic_trackers::livelink::{decode_packet, encode_packet};
use mimic_trackers::take::parse_take;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(p) = decode_packet(data) {
        assert_eq!(encode_packet(&p), data, "byte-exact round trip");
        let _ = p.time_us();
    }
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(take) = parse_take(text, Path::new("fuzz.csv"))
    {
        assert!(take.rows.windows(2).all(|w| w[0].t_us <= w[1].t_us));
    }
});
