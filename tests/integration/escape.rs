//! Untrusted text reaches the terminal escaped: `mimic info` on a recording whose header
//! strings carry escape codes, control characters and a bidirectional override prints them as
//! `\u{..}` escapes, never as the raw bytes a terminal would act on.

use crate::{mimic, repo, text};
use serde_json::Value;

/// Bytes a terminal acts on: C0 controls but newline, DEL, C1 controls (UTF-8 `C2 80..9F`), and
/// the bidirectional overrides `E2 80 AA..AE`.
fn raw_controls(b: &[u8]) -> usize {
    let c0 = b
        .iter()
        .filter(|&&x| (x < 0x20 && x != b'\n') || x == 0x7f)
        .count();
    let c1 = b
        .windows(2)
        .filter(|w| w[0] == 0xc2 && (0x80..=0x9f).contains(&w[1]))
        .count();
    let bidi = b
        .windows(3)
        .filter(|w| w[0] == 0xe2 && w[1] == 0x80 && (0xaa..=0xae).contains(&w[2]))
        .count();
    c0 + c1 + bidi
}

#[test]
fn info_shows_a_recordings_header_text_escaped() {
    let src = std::fs::read_to_string(repo().join("recordings/openface_test.jsonl")).unwrap();
    let mut lines = src.lines();
    let mut header: Value = serde_json::from_str(lines.next().unwrap()).unwrap();
    let hostile = "\u{1b}[2J\u{1b}]0;owned\u{7}red\u{1b}[31m \u{9b}1m \u{202e}txt.exe\r";
    header["source"] = Value::from(hostile);
    header["description"] = Value::from("line one\nline two\u{7f}");
    header["tracker_note"] = Value::from("\u{1b}[5mblink");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hostile.jsonl");
    let mut body = format!("{header}\n");
    for l in lines {
        body.push_str(l);
        body.push('\n');
    }
    std::fs::write(&path, body).unwrap();
    let out = mimic(&["info", path.to_str().unwrap()]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(
        raw_controls(&out.stdout),
        0,
        "raw control bytes in {stdout:?}"
    );
    assert!(
        stdout.contains(
            "source: \\u{1b}[2J\\u{1b}]0;owned\\u{7}red\\u{1b}[31m \\u{9b}1m \\u{202e}txt.exe\\r\n"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("description: line one\\nline two\\u{7f}\n"),
        "{stdout}"
    );
    assert!(stdout.contains("\\u{1b}[5mblink"), "{stdout}");
    // The shipped recordings, with no such characters, print as before.
    let plain = mimic(&["info", "recordings/openface_test.jsonl"]);
    let (plain_out, _) = text(&plain);
    assert!(
        plain_out
            .contains("source: OpenFace 2.x FeatureExtraction 3D landmarks (OpenFace_Test.csv)\n")
    );
}

#[test]
fn info_errors_show_file_text_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.jsonl");
    // A header naming a unit no reader takes, with an escape code in it.
    std::fs::write(
        &path,
        "{\"format\":\"mimic-recording\",\"version\":1,\"layout\":\"ibug68\",\"units\":\"\\u001b[31mfeet\",\"source\":\"x\",\"rate_hz\":30}\n",
    )
    .unwrap();
    let out = mimic(&["info", path.to_str().unwrap()]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert_eq!(
        raw_controls(&out.stderr),
        0,
        "raw control bytes in {stderr:?}"
    );
    assert!(stderr.contains("bad.jsonl"), "{stderr}");
    assert!(stderr.contains("\\u{1b}[31mfeet"), "{stderr}");
}
