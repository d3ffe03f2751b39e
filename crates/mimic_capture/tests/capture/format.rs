//! The v1 reader and writer: round trips and every rejection reason, with exact counts.

use glam::Vec3;
use mimic_capture::{
    FrameProblem, RecordedFrame, RecordingError, RecordingHeader, RecordingReader, RecordingWriter,
};
use mimic_types::LandmarkFrame;
use std::io::Cursor;

/// Header of a 121-point layout; `header(n)` is the same with `n` points.
const HEADER_121: &str = r#"{"format":"mimic-recording","version":1,"layout":"kinect121","units":"m","source":"test","rate_hz":30.0,"point_count":121}"#;

/// A frame line with `n` points at (i, 0.5, -1) mm-ish values.
fn frame_line(t_us: i64, n: usize) -> String {
    let pts: Vec<String> = (0..n)
        .map(|i| format!("[{},0.5,-1]", i as f64 * 0.001))
        .collect();
    format!(
        r#"{{"t_us":{t_us},"points":[{}],"tracked":true}}"#,
        pts.join(",")
    )
}

fn header(n: usize) -> String {
    HEADER_121.replace(r#""point_count":121"#, &format!(r#""point_count":{n}"#))
}

fn read_all(
    text: &str,
    expected: Option<usize>,
) -> (
    Vec<RecordedFrame>,
    Vec<String>,
    RecordingReader<Cursor<Vec<u8>>>,
) {
    let mut r =
        RecordingReader::new(Cursor::new(text.as_bytes().to_vec()), "x.jsonl", expected).unwrap();
    let (mut ok, mut bad) = (Vec::new(), Vec::new());
    for item in r.by_ref() {
        match item {
            Ok(f) => ok.push(f),
            Err(e) => bad.push(e.to_string()),
        }
    }
    (ok, bad, r)
}

#[test]
fn writer_output_reads_back_within_six_significant_digits() {
    let mut header = RecordingHeader::new("tiny", "unit test", 16.0, Some(3));
    header.description = Some("round trip".into());
    header
        .extra
        .insert("operator".into(), serde_json::json!("nobody"));
    let mut a = LandmarkFrame::new(
        10,
        vec![
            Vec3::new(0.012_345_68, -0.836, 1.5),
            Vec3::new(-2.0, 1e-7, 0.0),
            Vec3::ONE,
        ],
    );
    a.valid[1] = false;
    let lost = LandmarkFrame {
        timestamp_us: 20,
        points: vec![],
        valid: vec![],
        tracked: false,
    };
    let c = LandmarkFrame::new(
        30,
        vec![
            Vec3::new(123.456_79, f32::NAN, 0.1),
            Vec3::ZERO,
            Vec3::NEG_ONE,
        ],
    );
    let mut w = RecordingWriter::new(Vec::new(), &header)
        .unwrap()
        .flush_each_frame(true);
    w.write_frame(&a, Some(1)).unwrap();
    w.write_frame(&lost, None).unwrap();
    w.write_frame(&c, Some(0)).unwrap();
    // Writing time backwards or a wrong point count is refused.
    assert!(
        w.write_frame(&LandmarkFrame::new(30, vec![Vec3::ZERO; 3]), None)
            .is_err()
    );
    assert!(
        w.write_frame(&LandmarkFrame::new(40, vec![Vec3::ZERO; 2]), None)
            .is_err()
    );
    let bytes = w.finish().unwrap();
    let text = String::from_utf8(bytes).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4);
    assert_eq!(
        lines[1],
        r#"{"t_us":10,"points":[[0.0123457,-0.836,1.5],null,[1,1,1]],"invalid":[1],"tracked":true,"label":1}"#
    );
    assert_eq!(lines[2], r#"{"t_us":20,"points":[],"tracked":false}"#);

    let (ok, bad, r) = read_all(&text, None);
    assert!(bad.is_empty(), "{bad:?}");
    assert_eq!(r.header(), &header);
    assert_eq!(ok.len(), 3);
    assert_eq!(
        (ok[0].label, ok[1].label, ok[2].label),
        (Some(1), None, Some(0))
    );
    assert_eq!(r.stats().lost_tracking, 1);
    // Invalid: point 1 of frame 10 and the NaN point 0 of frame 30.
    assert_eq!(r.stats().invalid_points, 2);
    assert!(!ok[1].frame.tracked && ok[1].frame.points.is_empty());
    assert!(!ok[2].frame.is_valid(0) && ok[2].frame.is_valid(1));
    // Six significant digits: relative error at most 0.5e-5 plus one f32 rounding (6e-8).
    for (orig, back) in [(&a, &ok[0].frame), (&c, &ok[2].frame)] {
        for i in 0..3 {
            if !orig.is_valid(i) {
                assert!(!back.is_valid(i));
                continue;
            }
            for (x, y) in orig.points[i]
                .to_array()
                .into_iter()
                .zip(back.points[i].to_array())
            {
                assert!((x - y).abs() <= x.abs() * (0.5e-5 + 6e-8), "{x} vs {y}");
            }
        }
    }
}

#[test]
fn truncated_last_line_keeps_every_frame_before_it() {
    let text = format!(
        "{HEADER_121}\n{}\n{}\n{}\n{{\"t_us\":40,\"points\":[[0.1,0.2",
        frame_line(10, 121),
        frame_line(20, 121),
        frame_line(30, 121)
    );
    let (ok, bad, r) = read_all(&text, None);
    assert_eq!(
        ok.iter().map(|f| f.frame.timestamp_us).collect::<Vec<_>>(),
        vec![10, 20, 30]
    );
    assert_eq!(
        bad,
        vec!["x.jsonl:5: truncated JSON (EOF while parsing a list)".to_string()]
    );
    assert_eq!(r.stats().rejected.truncated, 1);
    assert_eq!(r.stats().rejected.total(), 1);
    assert_eq!(r.stats().accepted, 3);
}

#[test]
fn wrong_point_count_is_rejected_counted_and_reading_goes_on() {
    let text = format!(
        "{HEADER_121}\n{}\n{}\n{}\n{}\n",
        frame_line(10, 121),
        frame_line(20, 120),
        frame_line(30, 121),
        frame_line(40, 122)
    );
    let (ok, bad, r) = read_all(&text, Some(121));
    assert_eq!(
        ok.iter().map(|f| f.frame.timestamp_us).collect::<Vec<_>>(),
        vec![10, 30]
    );
    assert_eq!(
        bad,
        vec![
            "x.jsonl:3: frame has 120 points; layout kinect121 has 121".to_string(),
            "x.jsonl:5: frame has 122 points; layout kinect121 has 121".to_string()
        ]
    );
    assert_eq!(r.stats().rejected.point_count, 2);
    assert_eq!(r.stats().rejected.total(), 2);
}

#[test]
fn point_count_from_first_good_frame_when_header_has_none() {
    let header = HEADER_121.replace(r#","point_count":121"#, "");
    let text = format!(
        "{header}\n{}\n{}\n{}\n",
        frame_line(10, 5),
        frame_line(20, 4),
        frame_line(30, 5)
    );
    let (ok, bad, r) = read_all(&text, None);
    assert_eq!(ok.len(), 2);
    assert_eq!(
        bad,
        vec!["x.jsonl:3: frame has 4 points; layout kinect121 has 5".to_string()]
    );
    assert_eq!(r.expected_points(), Some(5));
}

#[test]
fn nan_and_null_coordinates_are_rejected_unless_listed_invalid() {
    let good = frame_line(10, 4);
    let null_coord = r#"{"t_us":20,"points":[[0,0,0],[0,0,0],[0,0,0],[1,null,2]]}"#;
    let null_point = r#"{"t_us":30,"points":[[0,0,0],null,[0,0,0],[0,0,0]]}"#;
    let listed = r#"{"t_us":40,"points":[[0,0,0],null,[0,0,0],[1,null,2]],"invalid":[1,3]}"#;
    let literal_nan = r#"{"t_us":50,"points":[[0,0,0],[NaN,0,0],[0,0,0],[0,0,0]]}"#;
    let overflow = r#"{"t_us":60,"points":[[0,0,0],[0,0,0],[1e39,0,0],[0,0,0]]}"#;
    let bad_index = r#"{"t_us":70,"points":[[0,0,0],[0,0,0],[0,0,0],[0,0,0]],"invalid":[4]}"#;
    let header = header(4);
    let text = format!(
        "{header}\n{good}\n{null_coord}\n{null_point}\n{listed}\n{literal_nan}\n{overflow}\n{bad_index}\n"
    );
    let (ok, bad, r) = read_all(&text, None);
    assert_eq!(
        ok.iter().map(|f| f.frame.timestamp_us).collect::<Vec<_>>(),
        vec![10, 40]
    );
    assert_eq!(ok[1].frame.valid, vec![true, false, true, false]);
    assert!(ok[1].frame.points[1].is_nan());
    assert_eq!(bad.len(), 5);
    assert_eq!(
        bad[0],
        "x.jsonl:3: point 3 has a NaN coordinate (null or out of range) but is not listed invalid"
    );
    assert!(
        bad[1].starts_with("x.jsonl:4: point 1 has a NaN coordinate"),
        "{}",
        bad[1]
    );
    assert!(
        bad[2].starts_with("x.jsonl:6: invalid JSON at column"),
        "{}",
        bad[2]
    );
    // 1e39 overflows f32 (max 3.4e38).
    assert!(
        bad[3].starts_with("x.jsonl:7: point 2 has a NaN coordinate"),
        "{}",
        bad[3]
    );
    assert_eq!(
        bad[4],
        "x.jsonl:8: `invalid` lists point 4, but the frame has 4 points"
    );
    let c = &r.stats().rejected;
    assert_eq!(
        (c.bad_coordinate, c.bad_json, c.bad_invalid_index, c.total()),
        (3, 1, 1, 5)
    );
    assert_eq!(r.stats().invalid_points, 2);
}

#[test]
fn time_going_backwards_or_standing_still_is_rejected() {
    let header = header(2);
    let t = [10, 20, 15, 20, 30, 25, 40];
    let lines: Vec<String> = t.iter().map(|&t| frame_line(t, 2)).collect();
    let text = format!("{header}\n{}\n", lines.join("\n"));
    let (ok, bad, r) = read_all(&text, None);
    assert_eq!(
        ok.iter().map(|f| f.frame.timestamp_us).collect::<Vec<_>>(),
        vec![10, 20, 30, 40]
    );
    assert_eq!(
        bad[0],
        "x.jsonl:4: timestamp 15 us is not after the previous frame's 20 us"
    );
    assert_eq!(
        bad[1],
        "x.jsonl:5: timestamp 20 us is not after the previous frame's 20 us"
    );
    assert_eq!(
        bad[2],
        "x.jsonl:7: timestamp 25 us is not after the previous frame's 30 us"
    );
    assert_eq!(r.stats().rejected.time_not_increasing, 3);
}

#[test]
fn garbage_in_the_middle_is_bad_json_and_blank_lines_are_ignored() {
    let header = header(1);
    let text = format!(
        "{header}\n{}\n{{oops\n\n{}\r\n",
        frame_line(10, 1),
        frame_line(20, 1)
    );
    let (ok, bad, r) = read_all(&text, None);
    assert_eq!(ok.len(), 2);
    assert_eq!(
        bad,
        vec!["x.jsonl:3: invalid JSON at column 2 (key must be a string)".to_string()]
    );
    assert_eq!(r.stats().rejected.bad_json, 1);
    assert_eq!(r.line(), 5);
}

#[test]
fn bad_headers_are_fatal_and_name_line_one() {
    let cases = [
        ("", "x.jsonl:1: empty file: no header line"),
        (
            "not json\n",
            "x.jsonl:1: header is not a valid recording header",
        ),
        (
            &HEADER_121.replace("mimic-recording", "other"),
            "x.jsonl:1: format is `other`, expected `mimic-recording`",
        ),
        (
            &HEADER_121.replace(r#""version":1"#, r#""version":2"#),
            "x.jsonl:1: format version 2 is not supported",
        ),
        (
            &HEADER_121.replace(r#""units":"m""#, r#""units":"mm""#),
            "x.jsonl:1: units are `mm`",
        ),
        (&HEADER_121.replace("30.0", "0"), "x.jsonl:1: rate_hz is 0"),
        (
            &HEADER_121.replace(r#""layout":"kinect121","#, ""),
            "x.jsonl:1: header is not a valid recording header",
        ),
    ];
    for (text, want) in cases {
        let err = RecordingReader::new(Cursor::new(text.as_bytes().to_vec()), "x.jsonl", None)
            .err()
            .unwrap();
        assert!(matches!(err, RecordingError::Header { .. }));
        assert!(err.to_string().starts_with(want), "{err} vs {want}");
    }
    let err = RecordingReader::new(
        Cursor::new(HEADER_121.as_bytes().to_vec()),
        "x.jsonl",
        Some(100),
    )
    .err()
    .unwrap();
    assert_eq!(
        err.to_string(),
        "x.jsonl:1: header says 121 points per frame but layout kinect121 is expected to have 100"
    );
}

#[test]
fn summarize_strict_fails_on_the_first_problem_and_lenient_counts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.jsonl");
    let header = header(2);
    let lost = r#"{"t_us":2000000,"points":[],"tracked":false}"#;
    let labelled = r#"{"t_us":3000000,"points":[[0,0,0],null],"invalid":[1],"label":1}"#;
    let text = format!(
        "{header}\n{}\n{lost}\n{labelled}\n{}\n{}\n",
        frame_line(1_000_000, 2),
        frame_line(2_500_000, 2),
        frame_line(5_000_000, 2)
    );
    std::fs::write(&path, text).unwrap();
    let err = mimic_capture::summarize(&path, None).unwrap_err();
    let p = path.display();
    assert_eq!(
        err.to_string(),
        format!("{p}:5: timestamp 2500000 us is not after the previous frame's 3000000 us")
    );
    assert!(
        matches!(err, RecordingError::Frame(ref e) if matches!(e.problem, FrameProblem::TimeNotIncreasing { .. }))
    );
    let s = mimic_capture::summarize_lenient(&path, None).unwrap();
    assert_eq!(
        (s.frames, s.lost_tracking_frames, s.invalid_points),
        (4, 1, 1)
    );
    assert_eq!((s.labelled_frames, s.positive_labels), (1, 1));
    assert_eq!(s.rejected.time_not_increasing, 1);
    // 4 frames over 1 s .. 5 s: duration 4 s, mean rate 3 / 4 Hz, largest gap 2 s.
    assert_eq!(s.duration_s, 4.0);
    assert_eq!(s.mean_rate_hz, Some(0.75));
    assert_eq!(s.max_gap_s, 2.0);
    assert_eq!(
        s.first_problem.as_deref(),
        Some(
            format!("{p}:5: timestamp 2500000 us is not after the previous frame's 3000000 us")
                .as_str()
        )
    );
    let json = serde_json::to_value(&s).unwrap();
    assert_eq!(json["header"]["layout"], "kinect121");
    // A missing file is an Open error naming it.
    let missing = dir.path().join("none.jsonl");
    assert!(
        mimic_capture::summarize(&missing, None)
            .unwrap_err()
            .to_string()
            .starts_with(&format!("{}: cannot open", missing.display()))
    );
}

#[test]
fn compact_coordinates_have_six_significant_digits() {
    use mimic_capture::recording::format_coordinate as f;
    assert_eq!(f(0.0), "0");
    assert_eq!(f(-0.0), "0");
    assert_eq!(f(1.0), "1");
    assert_eq!(f(-0.836), "-0.836");
    assert_eq!(f(0.012_345_68), "0.0123457");
    assert_eq!(f(123.456_79), "123.457");
    assert_eq!(f(1234567.0), "1234567");
    assert_eq!(f(f32::NAN), "null");
}

#[test]
fn overlong_lines_are_skipped_without_buffering_them() {
    let text = format!(
        "{}\n{}\n{}\n{}\n",
        header(2),
        frame_line(10, 2),
        frame_line(20, 200),
        frame_line(30, 2)
    );
    // frame_line(_, 2) is about 50 bytes; the 200-point line is about 2.6 kB.
    let mut r = RecordingReader::new(Cursor::new(text.into_bytes()), "x.jsonl", None)
        .unwrap()
        .with_max_line_bytes(1000);
    let items: Vec<_> = r.by_ref().collect();
    assert_eq!(items.len(), 3);
    assert_eq!(items[0].as_ref().unwrap().frame.timestamp_us, 10);
    assert_eq!(
        items[1].as_ref().unwrap_err().to_string(),
        "x.jsonl:3: line longer than 1000 bytes"
    );
    assert_eq!(items[2].as_ref().unwrap().frame.timestamp_us, 30);
    assert_eq!(
        (r.stats().rejected.too_long, r.stats().rejected.total()),
        (1, 1)
    );
}

#[test]
fn read_all_keeps_accepted_frames_and_counts_the_rest() {
    let header = HEADER_121.replace(r#","point_count":121"#, "");
    let text = format!(
        "{header}\n{}\n{}\nnot json\n{}\n",
        frame_line(10, 3),
        frame_line(20, 4),
        frame_line(30, 3)
    );
    let mut r = RecordingReader::new(Cursor::new(text.into_bytes()), "x.jsonl", None).unwrap();
    // The count is set after the header was read, as a command does once it has the layout.
    r.expect_points(3).unwrap();
    let all = r.read_all();
    assert_eq!(all.header.layout, "kinect121");
    let times: Vec<i64> = all.frames.iter().map(|f| f.frame.timestamp_us).collect();
    assert_eq!(times, vec![10, 30]);
    assert_eq!(all.stats.accepted, 2);
    assert_eq!(all.stats.rejected.point_count, 1);
    assert_eq!(all.stats.rejected.bad_json, 1);
}

#[test]
fn expect_points_refuses_a_count_the_header_contradicts() {
    let text = format!("{}\n{}\n", header(5), frame_line(10, 5));
    let mut r = RecordingReader::new(Cursor::new(text.into_bytes()), "x.jsonl", None).unwrap();
    let e = r.expect_points(6).unwrap_err();
    assert!(
        e.to_string()
            .contains("header says 5 points per frame but layout kinect121 is expected to have 6"),
        "{e}"
    );
    r.expect_points(5).unwrap();
    assert_eq!(r.read_all().frames.len(), 1);
}
