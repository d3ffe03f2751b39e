//! Capture importers: the v1 recording reader, GFE, OpenFace and MediaPipe dumps.

use std::path::Path;

use mimic_capture::{RecordingReader, parse_frame_line};
use mimic_trackers::gfe::{check_header, parse_datapoints, parse_targets};
use mimic_trackers::mediapipe::{
    DEFAULT_FOV_DEG, DumpFrame, POINT_COUNT, convert_dump, parse_dump_line, to_camera_space,
};
use mimic_trackers::openface::{OpenFaceTiming, parse_csv};

/// The v1 recording reader: header, then every frame line until the end, and the same bytes as
/// one live frame line (what `mimic serve` does with a socket line).
pub fn recording(data: &[u8]) {
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
    let _ = parse_frame_line(data, true, None, "fuzz");
    let _ = parse_frame_line(data, false, Some(38), "fuzz");
}

/// The GFE (Kinect grammatical facial expressions) importer: header check, datapoints, targets.
pub fn gfe(data: &[u8]) {
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
}

/// The OpenFace CSV importer with both timing modes.
pub fn openface(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.csv");
    let _ = parse_csv(text, path, OpenFaceTiming::FileTimestamps);
    let _ = parse_csv(text, path, OpenFaceTiming::Rate(30.0));
}

/// The MediaPipe dump reader and, for every line it accepts, the conversion to metres: the line's
/// landmarks (whatever their count) are repeated up to 478 so that short inputs reach
/// `to_camera_space` too.
pub fn mediapipe(data: &[u8]) {
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
                Some([
                    a.first()?.as_f64()?,
                    a.get(1)?.as_f64()?,
                    a.get(2)?.as_f64()?,
                ])
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
}
