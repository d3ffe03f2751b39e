//! Crash loss (docs/reliability.md): under `mimic serve --record DIR` a frame reaches viewers
//! only once it is written to the OS (with `--record-sync`, once it is on disk), so a `kill -9`
//! in the middle of a flood leaves every frame any viewer saw in the recording.

use crate::loopback::{Serve, frame_lines, header_with_session, viewer};
use mimic_stream::wire::{ViewerMessage, decode_viewer_message};
use serde_json::Value;
use std::io::{Read, Write};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Timestamps of the frames a viewer receives until its connection ends (however it ends: a
/// killed server may cut a message short).
fn frame_times(mut s: std::net::TcpStream, seen: &AtomicUsize) -> Vec<i64> {
    let mut times = Vec::new();
    loop {
        let mut len = [0u8; 4];
        if s.read_exact(&mut len).is_err() {
            return times;
        }
        let mut body = vec![0u8; u32::from_le_bytes(len) as usize];
        if s.read_exact(&mut body).is_err() || body.is_empty() {
            return times;
        }
        if let Ok(ViewerMessage::Frame(f)) = decode_viewer_message(body[0], &body[1..]) {
            times.push(f.timestamp_us);
            seen.fetch_add(1, Ordering::Relaxed);
        }
    }
}

#[test]
fn kill_9_during_a_flood_under_record_sync_loses_no_frame_a_viewer_saw() {
    kill_9_during_a_flood_loses_no_frame_a_viewer_saw(&["--record-sync"]);
}

#[test]
fn kill_9_during_a_flood_with_plain_record_loses_no_frame_a_viewer_saw() {
    kill_9_during_a_flood_loses_no_frame_a_viewer_saw(&[]);
}

/// Floods a recording server started with `mode` flags, kills it with SIGKILL once a viewer has
/// seen 200 frames, and checks the recording holds every frame the viewer saw, in order.
fn kill_9_during_a_flood_loses_no_frame_a_viewer_saw(mode: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let rec_dir = dir.path().to_str().unwrap();
    let mut args = vec!["--rig", "candide3", "--record", rec_dir];
    args.extend_from_slice(mode);
    args.extend_from_slice(&["--viewer-queue", "100000"]);
    let server = Serve::start(&args);
    let v = viewer(&server.tcp, "k", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let seen = Arc::new(AtomicUsize::new(0));
    let reader = {
        let seen = seen.clone();
        mimic_testkit::spawn("viewer k", move || frame_times(v, &seen))
    };
    // A flood: 3000 frames, 1 ms apart in tracker time, written as fast as the socket takes them.
    let rec = "recordings/openface_test.jsonl";
    let base = frame_lines(rec);
    let mut flood = header_with_session(rec, "k");
    for k in 0..3000 {
        let mut f: Value = serde_json::from_str(base[k % base.len()].trim()).unwrap();
        f["t_us"] = Value::from(k as i64 * 1000);
        flood.push_str(&format!("{f}\n"));
    }
    let mut t = crate::loopback::connect(&server.tcp);
    let tracker = mimic_testkit::spawn("tracker k", move || {
        // Fails once the server is killed.
        let _ = t.write_all(flood.as_bytes());
    });
    let deadline = Instant::now() + Duration::from_secs(60);
    while seen.load(Ordering::Relaxed) < 200 {
        assert!(Instant::now() < deadline, "the viewer saw too few frames");
        std::thread::sleep(Duration::from_millis(2));
    }
    let pid = server.pid().to_string();
    assert!(
        Command::new("kill")
            .args(["-KILL", &pid])
            .status()
            .unwrap()
            .success()
    );
    let shown = reader.join().unwrap();
    tracker.join().unwrap();
    drop(server);
    // The recording: the header, then frame lines; a torn last line (cut by the kill) is no frame.
    let files: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let text = std::fs::read_to_string(&files[0]).unwrap();
    let recorded: Vec<i64> = text
        .split_inclusive('\n')
        .skip(1)
        .filter(|l| l.ends_with('\n'))
        .map(|l| {
            let f: Value = serde_json::from_str(l).unwrap();
            f["t_us"].as_i64().unwrap()
        })
        .collect();
    assert!(shown.len() >= 200 && shown.len() < 3000, "{}", shown.len());
    assert!(
        recorded.len() >= shown.len(),
        "viewer saw {} frames, the recording holds {}",
        shown.len(),
        recorded.len()
    );
    assert_eq!(recorded[..shown.len()], shown[..]);
    eprintln!(
        "kill -9 ({mode:?}): viewer saw {} frames, recording holds {}",
        shown.len(),
        recorded.len()
    );
}
