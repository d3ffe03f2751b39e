//! The shipped real recordings, and the importers on the shared source data when it is present.

use mimic_capture::{RecordingReader, summarize};
use mimic_trackers::gfe::import_gfe;
use mimic_trackers::openface::{OpenFaceTiming, import_openface};
use std::path::{Path, PathBuf};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `../shared/data` beside the repository, if this checkout has it.
fn shared_data() -> Option<PathBuf> {
    let d = repo_root().join("../shared/data");
    if d.is_dir() {
        Some(d)
    } else {
        println!(
            "note: {} not found; skipping the checks against the source files",
            d.display()
        );
        None
    }
}

/// (name, data rows, depth-0 entries, positive targets): rows and positives from the dataset's
/// description file, depth-0 entries counted with awk over the z columns of the source files.
const GFE: [(&str, usize, usize, usize); 3] = [
    ("a_affirmative", 1062, 3157, 414),
    ("a_doubt_question", 1312, 5370, 491),
    ("a_yn_question", 1390, 2600, 532),
];

#[test]
fn shipped_gfe_recordings_read_strictly_with_the_right_counts() {
    for (name, rows, zeros, positives) in GFE {
        let path = repo_root().join(format!("recordings/{name}.jsonl"));
        let s = summarize(&path, Some(100)).unwrap();
        assert_eq!(s.header.layout, "kinect-gfe100");
        assert_eq!(s.frames, rows, "{name}");
        assert_eq!(s.invalid_points, zeros, "{name}");
        assert_eq!(
            (s.labelled_frames, s.positive_labels),
            (rows, positives),
            "{name}"
        );
        assert_eq!(s.rejected.total(), 0);
        assert_eq!(s.lost_tracking_frames, 0);
        // ~16 fps per the dataset notes: mean interval about 63 ms.
        let rate = s.mean_rate_hz.unwrap();
        assert!((14.0..17.0).contains(&rate), "{name}: {rate} Hz");
        // Valid points lie at the observed depths, 801..1578 mm (SOURCE.md), i.e. z in [-1.578, -0.801] m.
        let reader = RecordingReader::open(&path, Some(100)).unwrap();
        let mut last = i64::MIN;
        for f in reader {
            let f = f.unwrap().frame;
            assert!(f.timestamp_us > last);
            last = f.timestamp_us;
            for i in 0..100 {
                if f.is_valid(i) {
                    let z = f.points[i].z;
                    assert!((-1.5785..=-0.8005).contains(&z), "{name} point {i}: z {z}");
                } else {
                    assert!(f.points[i].is_nan());
                }
            }
        }
    }
}

#[test]
fn gfe_import_of_the_source_files_matches_the_raw_rows() {
    let Some(data) = shared_data() else { return };
    for (name, rows, zeros, positives) in GFE {
        let dp = data.join(format!("kinect-gfe-libras/{name}_datapoints.txt"));
        let tg = data.join(format!("kinect-gfe-libras/{name}_targets.txt"));
        let imp = import_gfe(&dp, Some(&tg), None).unwrap();
        assert_eq!(imp.frames.len(), rows);
        assert!(
            imp.frames
                .windows(2)
                .all(|w| w[0].frame.timestamp_us < w[1].frame.timestamp_us),
            "{name}"
        );
        assert_eq!(imp.invalid_points(), zeros);
        assert_eq!(
            imp.frames.iter().filter(|f| f.label == Some(1)).count(),
            positives
        );
        // Independent check against the raw text: each point is invalid exactly where its z token is 0,
        // and a valid point's z is -depth/1000 (f32 rounding: 1 ulp of ~1.5 is 1.2e-7).
        let raw = std::fs::read_to_string(&dp).unwrap();
        for (line, f) in raw.lines().skip(1).zip(&imp.frames) {
            let tok: Vec<&str> = line.split_whitespace().collect();
            for i in 0..100 {
                let depth: f64 = tok[3 + 3 * i].parse().unwrap();
                assert_eq!(
                    f.frame.valid[i],
                    depth != 0.0,
                    "{name} t {} point {i}",
                    f.frame.timestamp_us
                );
                if depth != 0.0 {
                    assert!((f64::from(f.frame.points[i].z) + depth / 1000.0).abs() < 2e-7);
                }
            }
        }
        // The shipped recording is this import written with six significant digits.
        let shipped: Vec<_> = RecordingReader::open(
            &repo_root().join(format!("recordings/{name}.jsonl")),
            Some(100),
        )
        .unwrap()
        .map(|f| f.unwrap())
        .collect();
        assert_eq!(shipped.len(), imp.frames.len());
        for (a, b) in imp.frames.iter().zip(&shipped) {
            assert_eq!(a.frame.timestamp_us, b.frame.timestamp_us);
            assert_eq!(a.frame.valid, b.frame.valid);
            assert_eq!(a.label, b.label);
            for (p, q) in a.frame.points.iter().zip(&b.frame.points) {
                if p.is_finite() {
                    // 6 significant digits: |error| <= 0.5e-5 |x| + f32 rounding.
                    assert!((*p - *q).abs().cmple(p.abs() * 5.1e-6).all(), "{p} vs {q}");
                }
            }
        }
    }
}

#[test]
fn shipped_openface_recording_has_100_frames_of_68_points_in_range() {
    let path = repo_root().join("recordings/openface_test.jsonl");
    let s = summarize(&path, Some(68)).unwrap();
    assert_eq!(s.header.layout, "ibug68");
    assert_eq!(
        (s.frames, s.invalid_points, s.lost_tracking_frames),
        (100, 0, 0)
    );
    // Re-timed at 30 Hz: 99 intervals of 1/30 s = 3.3 s (rounded to whole µs per frame).
    assert!((s.duration_s - 3.3).abs() < 1e-6, "{}", s.duration_s);
    // Observed OpenFace ranges (SOURCE.md): X -65..89, Y -21..119, Z 560..665 mm; y and z flip sign.
    for f in RecordingReader::open(&path, Some(68)).unwrap() {
        for p in f.unwrap().frame.points {
            assert!((-0.0655..=0.0895).contains(&p.x), "{p}");
            assert!((-0.1195..=0.0215).contains(&p.y), "{p}");
            assert!((-0.6655..=-0.5595).contains(&p.z), "{p}");
        }
    }
}

#[test]
fn openface_import_of_the_source_file_keeps_or_retimes_timestamps() {
    let Some(data) = shared_data() else { return };
    let csv = data.join("openface-68pt-3d-sequence/OpenFace_Test.csv");
    let kept = import_openface(&csv, OpenFaceTiming::FileTimestamps, None).unwrap();
    // The file's clock steps by 1 ms: frame k at k ms.
    let t: Vec<i64> = kept.frames.iter().map(|f| f.frame.timestamp_us).collect();
    assert_eq!(t, (0..100).map(|k| k * 1000).collect::<Vec<_>>());
    let retimed = import_openface(&csv, OpenFaceTiming::Rate(30.0), None).unwrap();
    assert_eq!(retimed.frames.len(), 100);
    assert_eq!(retimed.frames[99].frame.timestamp_us, 3_300_000);
    assert_eq!(kept.frames[7].frame.points, retimed.frames[7].frame.points);
    // Row 1, point 0 read independently by column name from the raw text.
    let raw = std::fs::read_to_string(&csv).unwrap();
    let mut lines = raw.lines();
    // The header separates with ", ", the data rows with ",".
    let names: Vec<&str> = lines.next().unwrap().split(", ").collect();
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| -> f64 {
        row[names.iter().position(|c| *c == n).unwrap()]
            .parse()
            .unwrap()
    };
    let p = retimed.frames[0].frame.points[0];
    let want = [
        col("X_0") / 1000.0,
        -col("Y_0") / 1000.0,
        -col("Z_0") / 1000.0,
    ];
    for (got, want) in p.to_array().into_iter().zip(want) {
        assert!((f64::from(got) - want).abs() < 1e-7, "{got} vs {want}");
    }
}
