//! Fuzzes the v1 recording reader: header, then every frame line until the end.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mimic_capture::{RecordingReader, parse_frame_line};

fuzz_target!(|data: &[u8]| {
    // Whole file through the reader, with and without a caller-side point count.
    for expected in [None, Some(100)] {
        if let Ok(mut reader) = RecordingReader::new(data, "fuzz.jsonl", expected) {
            let (mut ok, mut bad) = (0usize, 0usize);
            while let Some(item) = reader.next_frame() {
                assert!(ok + bad <= data.len(), "more frames than bytes");
                let Ok(f) = item else {
                    bad += 1;
                    continue;
                };
                ok += 1;
                let f = f.frame;
                assert_eq!(f.points.len(), f.valid.len());
                if let Some(p) = reader.expected_points() {
                    assert!(
                        !f.tracked || p == f.points.len(),
                        "a frame with the wrong point count passed"
                    );
                }
                for (p, &valid) in f.points.iter().zip(&f.valid) {
                    assert!(!valid || p.is_finite(), "a valid point that is not finite");
                }
            }
            // Exact accounting: every frame handed out is counted once, as accepted or rejected.
            assert_eq!(reader.stats().accepted, ok);
            assert_eq!(reader.stats().rejected.total(), bad);
        }
    }
    // The same bytes as one live frame line (what mimic serve does with a socket line).
    let _ = parse_frame_line(data, true, None, "fuzz");
    let _ = parse_frame_line(data, false, Some(38), "fuzz");
});
