//! Fuzzes the MediaPipe dump reader and, for every line it accepts, the conversion to metres:
//! the line's landmarks (whatever their count) are repeated up to 478 so that short inputs
//! reach `to_camera_space` too.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use mimic_capture::mediapipe::{
    DEFAULT_FOV_DEG, DumpFrame, POINT_COUNT, convert_dump, parse_dump_line, to_camera_space,
};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = convert_dump(text, Path::new("fuzz.jsonl"), DEFAULT_FOV_DEG, "fuzz");
    let mut out = Vec::new();
    for line in text.lines() {
        // The per-line checks without the count check: any landmarks, tiled to a full frame.
        let Ok(value) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        let _ = parse_dump_line(line);
        let Some(lm) = value.get("landmarks").and_then(|l| l.as_array()) else {
            continue;
        };
        let pts: Vec<[f64; 3]> = lm
            .iter()
            .filter_map(|p| {
                let a = p.as_array()?;
                Some([a.first()?.as_f64()?, a.get(1)?.as_f64()?, a.get(2)?.as_f64()?])
            })
            .collect();
        if pts.is_empty() {
            continue;
        }
        let frame = DumpFrame {
            t_us: 0,
            image_size: Some([
                (data.len() as u32 % 4096) + 1,
                (line.len() as u32 % 4096) + 1,
            ]),
            landmarks: pts.iter().cycle().take(POINT_COUNT).copied().collect(),
        };
        let fov = 1.0 + (line.len() % 178) as f64;
        if let Some(d) = to_camera_space(&frame, fov, &mut out) {
            assert!(d.is_finite() && out.len() == POINT_COUNT);
        }
    }
});
