//! Fuzzes the GFE (Kinect grammatical facial expressions) importer: header check, datapoints, targets.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use mimic_capture::gfe::{check_header, parse_datapoints, parse_targets};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz_datapoints.txt");
    let _ = check_header(text.lines().next().unwrap_or(""), path);
    if let Ok(frames) = parse_datapoints(text, path) {
        for f in &frames {
            assert_eq!(f.frame.points.len(), f.frame.valid.len());
            for (p, &ok) in f.frame.points.iter().zip(&f.frame.valid) {
                assert!(!ok || p.is_finite(), "a valid point that is not finite");
            }
        }
    }
    let _ = parse_targets(text, Path::new("fuzz_targets.txt"));
});
