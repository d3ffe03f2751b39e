//! `mimic import gfe` and `mimic import openface` on small files built here, and their errors.

use crate::{mimic, text};

/// A GFE file: the 301-token header, then rows with x = 320 + p px, y = 240 px, depth 1000 mm
/// except point 0 of the first row (depth 0).
fn gfe_text() -> String {
    let labels: Vec<String> = (0..300)
        .map(|k| format!("{}{}", k / 3, ["x", "y", "z"][k % 3]))
        .collect();
    let mut text = format!("0.0 {}\r\n", labels.join(" "));
    for (r, t) in ["100.9", "100.10", "100.110"].iter().enumerate() {
        let mut row = vec![t.to_string()];
        for p in 0..100 {
            row.extend([
                format!("{}", 320 + p),
                "240".into(),
                if r == 0 && p == 0 {
                    "0".into()
                } else {
                    "1000".into()
                },
            ]);
        }
        text.push_str(&row.join(" "));
        text.push_str("\r\n");
    }
    text
}

#[test]
fn gfe_import_writes_a_readable_recording_and_a_summary_line() {
    let dir = tempfile::tempdir().unwrap();
    let (dp, tg, out) = (
        dir.path().join("x_datapoints.txt"),
        dir.path().join("x_targets.txt"),
        dir.path().join("x.jsonl"),
    );
    std::fs::write(&dp, gfe_text()).unwrap();
    std::fs::write(&tg, "0\r\n1\r\n1").unwrap();
    let o = mimic(&[
        "import",
        "gfe",
        dp.to_str().unwrap(),
        "--targets",
        tg.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--raw-depth",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    // Times 100 s + 9, 10, 110 ms: 0.101 s from first to last.
    assert_eq!(
        stdout.trim_end(),
        format!(
            "{}: 3 frames (0 lost tracking), 1 invalid points, 0.1 s, layout kinect-gfe100",
            out.display()
        )
    );
    let s = mimic_capture::summarize(&out, Some(100)).unwrap();
    assert_eq!((s.frames, s.invalid_points, s.positive_labels), (3, 1, 2));
    assert_eq!(
        (s.first_t_us, s.last_t_us),
        (Some(100_009_000), Some(100_110_000))
    );
    // Point 1 at (321, 240) px, 1000 mm: x = 1000 / 531.15 mm; written with 6 significant digits.
    let second = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .nth(1)
        .unwrap()
        .to_string();
    assert!(
        second.starts_with(r#"{"t_us":100009000,"points":[null,[0.00188271,0,-1],"#),
        "{second}"
    );
    // Without --raw-depth the hole is filled (docs/gate.md): every point at 1000 mm, the plane
    // of the other 99, so point 0 gets (0, 0, -1) m at its pixel (320, 240).
    let o = mimic(&[
        "import",
        "gfe",
        dp.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stdout.starts_with(
            "depth repaired: 1 holes filled, 0 off-face depths replaced, 0 frames kept as measured\n"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("3 frames (0 lost tracking), 0 invalid points"),
        "{stdout}"
    );
    let second = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .nth(1)
        .unwrap()
        .to_string();
    assert!(
        second.starts_with(r#"{"t_us":100009000,"points":[[0,0,-1],[0.00188271,0,-1],"#),
        "{second}"
    );
}

#[test]
fn gfe_import_errors_name_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let dp = dir.path().join("bad.txt");
    let out = dir.path().join("bad.jsonl");
    std::fs::write(&dp, gfe_text().replacen(" 1000 ", " -5 ", 1)).unwrap();
    let o = mimic(&[
        "import",
        "gfe",
        dp.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(!o.status.success());
    assert_eq!(
        stderr.trim_end(),
        format!("error: {}:2: point 1: negative depth -5 mm", dp.display())
    );
    let tg = dir.path().join("t.txt");
    std::fs::write(&dp, gfe_text()).unwrap();
    std::fs::write(&tg, "0\n1\n").unwrap();
    let o = mimic(&[
        "import",
        "gfe",
        dp.to_str().unwrap(),
        "--targets",
        tg.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert_eq!(
        stderr.trim_end(),
        format!("error: {}: 2 labels for 3 data rows", tg.display())
    );
}

#[test]
fn openface_import_retimes_at_the_given_rate_and_marks_lost_frames() {
    let mut header = vec![
        "frame".to_string(),
        "timestamp".into(),
        "confidence".into(),
        "success".into(),
    ];
    for axis in ["X", "Y", "Z"] {
        header.extend((0..68).map(|i| format!("{axis}_{i}")));
    }
    let mut csv = header.join(", ");
    for (k, success) in [1, 0, 1, 1].iter().enumerate() {
        let mut row = vec![
            format!("{}", k + 1),
            format!("{}", k as f64 * 0.001),
            "0.9".into(),
            format!("{success}"),
        ];
        row.extend((0..68).map(|i| format!("{}", i)));
        row.extend((0..68).map(|_| "10".to_string()));
        row.extend((0..68).map(|_| "600".to_string()));
        csv.push('\n');
        csv.push_str(&row.join(","));
    }
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("of.csv"), dir.path().join("of.jsonl"));
    std::fs::write(&input, csv).unwrap();
    let o = mimic(&[
        "import",
        "openface",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--rate",
        "25",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    // 4 rows at 25 Hz: 3 intervals of 40 ms.
    assert_eq!(
        stdout.trim_end(),
        format!(
            "{}: 4 frames (1 lost tracking), 0 invalid points, 0.1 s, layout ibug68",
            out.display()
        )
    );
    let s = mimic_capture::summarize(&out, Some(68)).unwrap();
    assert_eq!(
        (s.frames, s.lost_tracking_frames, s.last_t_us),
        (4, 1, Some(120_000))
    );
    let o = mimic(&[
        "import",
        "openface",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--keep-timestamps",
    ]);
    assert!(o.status.success());
    assert_eq!(
        mimic_capture::summarize(&out, Some(68)).unwrap().last_t_us,
        Some(3_000)
    );
}
