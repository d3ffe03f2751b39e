//! Fault tests of `mimic serve` on loopback (docs/reliability.md, "Faults survived"): trackers
//! cut off mid-line, reconnecting, flooding, sending timestamps from the past and the future;
//! viewers stalling, leaving and coming back; Ctrl-C mid-session with `--record` on. Every count
//! of accepted, dropped and refused frames is asserted exactly; every wait is for a stats
//! condition (generous deadline), never a sleep.

use crate::loopback::{
    Serve, connect, frame_lines, header_with_session, read_json_line, read_message, read_session,
    viewer,
};
use crate::{mimic, repo, text};
use mimic_capture::{RecordedFrame, RecordingReader};
use mimic_stream::wire::ViewerMessage;
use serde_json::Value;
use std::io::{BufReader, Write};
use std::net::{Shutdown, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};

const REC: &str = "recordings/openface_test.jsonl";

/// A raw tracker connection: its socket and a reader of the server's reply lines.
struct Tracker {
    s: TcpStream,
    replies: BufReader<TcpStream>,
    welcome: Value,
}

impl Tracker {
    /// Opens session `name` with `REC`'s header and reads the welcome line.
    fn open(server: &Serve, name: &str) -> Tracker {
        let mut s = connect(&server.tcp);
        s.write_all(header_with_session(REC, name).as_bytes())
            .unwrap();
        let mut replies = BufReader::new(s.try_clone().unwrap());
        let welcome = read_json_line(&mut replies);
        assert_eq!(welcome["type"], "welcome", "{welcome}");
        Tracker {
            s,
            replies,
            welcome,
        }
    }

    fn send(&mut self, bytes: &[u8]) {
        self.s.write_all(bytes).unwrap();
    }

    fn send_lines(&mut self, lines: &[String]) {
        self.send(lines.concat().as_bytes());
    }

    fn reply(&mut self) -> Value {
        read_json_line(&mut self.replies)
    }
}

/// The shipped recording's frames, as the recording reader gives them.
fn shipped() -> Vec<RecordedFrame> {
    RecordingReader::open(&repo().join(REC), None)
        .unwrap()
        .map(Result::unwrap)
        .collect()
}

/// Every `.jsonl` the server wrote in `dir`, oldest session first.
fn recordings_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<(u64, PathBuf)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "jsonl"))
        .map(|p| {
            let r = RecordingReader::open(&p, None).unwrap();
            (r.header().extra["session_id"].as_u64().unwrap(), p)
        })
        .collect();
    files.sort();
    files.into_iter().map(|(_, p)| p).collect()
}

/// A recording's frames; every line must be a frame (nothing rejected).
fn read_back(path: &Path) -> Vec<RecordedFrame> {
    let mut r = RecordingReader::open(path, None).unwrap();
    let frames: Vec<_> = r.by_ref().map(Result::unwrap).collect();
    assert_eq!(r.stats().rejected.total(), 0, "{}", path.display());
    frames
}

/// Bit-exact equality of two frames: time, tracking flag, validity, every valid coordinate's bits.
fn assert_same_frames(got: &[RecordedFrame], want: &[RecordedFrame], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: frame count");
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        let (g, w) = (&g.frame, &w.frame);
        assert_eq!(g.timestamp_us, w.timestamp_us, "{what}: frame {k}");
        assert_eq!(g.tracked, w.tracked, "{what}: frame {k}");
        assert_eq!(g.valid, w.valid, "{what}: frame {k}");
        for (i, (a, b)) in g.points.iter().zip(&w.points).enumerate() {
            if w.valid[i] {
                let bits = |p: &glam::Vec3| p.to_array().map(f32::to_bits);
                assert_eq!(bits(a), bits(b), "{what}: frame {k} point {i}");
            }
        }
    }
}

/// A frame line of `REC` moved to time `t_us`.
fn retimed(line: &str, t_us: i64) -> String {
    let mut v: Value = serde_json::from_str(line).unwrap();
    v["t_us"] = Value::from(t_us);
    format!("{v}\n")
}

#[test]
fn a_recorded_session_holds_exactly_the_accepted_frames_and_replays_like_the_original() {
    let dir = tempfile::tempdir().unwrap();
    let rec_dir = dir.path().join("rec");
    // A one-frame recording queue: the session often waits for the writer thread.
    let server = Serve::start(&[
        "--rig",
        "candide3",
        "--viewer-queue",
        "100000",
        "--record",
        rec_dir.to_str().unwrap(),
        "--record-queue",
        "1",
    ]);
    let mut v = viewer(&server.tcp, "r", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tv = mimic_testkit::spawn("viewer v", move || read_session(&mut v));
    // The 100 shipped frames with, between them, a repeat of an old frame (late), garbage
    // (bad_json), a frame an hour ahead (future_timestamp) and a blank line (ignored).
    let lines = frame_lines(REC);
    let last_t = |k: usize| -> i64 {
        serde_json::from_str::<Value>(&lines[k]).unwrap()["t_us"]
            .as_i64()
            .unwrap()
    };
    let mut sent = Vec::new();
    for (k, l) in lines.iter().enumerate() {
        sent.push(l.clone());
        if k % 10 == 5 {
            sent.push(lines[k - 3].clone());
            sent.push("{\"t_us\":\n".to_string());
            sent.push(retimed(l, last_t(k) + 3_600_000_000));
            sent.push("\n".to_string());
        }
    }
    let mut t = Tracker::open(&server, "r");
    t.send_lines(&sent);
    t.s.shutdown(Shutdown::Write).unwrap();
    let seen = tv.join().unwrap();
    let end = seen.end.clone().unwrap();
    assert_eq!(
        (
            end["frames"].as_u64(),
            end["late"].as_u64(),
            end["future"].as_u64(),
            end["malformed"].as_u64()
        ),
        (Some(100), Some(10), Some(10), Some(10)),
        "{end}"
    );
    // The replies: one error per garbage line and per future frame, then bye with the count
    // recorded.
    let mut codes = Vec::new();
    let bye = loop {
        let r = t.reply();
        if r["type"] == "bye" {
            break r;
        }
        codes.push(r["code"].as_str().unwrap().to_string());
    };
    assert_eq!(codes.iter().filter(|c| *c == "bad_json").count(), 10);
    assert_eq!(
        codes.iter().filter(|c| *c == "future_timestamp").count(),
        10
    );
    assert_eq!(codes.len(), 20);
    assert_eq!(bye["recorded"], 100);

    // The recording: exactly the accepted frames (the shipped ones, labels included) ...
    let files = recordings_in(&rec_dir);
    assert_eq!(files.len(), 1);
    let name = files[0].file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with("r-1-127.0.0.1_"), "{name}");
    let got = read_back(&files[0]);
    let want = shipped();
    assert_same_frames(&got, &want, "recording");
    assert!(got.iter().zip(&want).all(|(g, w)| g.label == w.label));
    // ... in the order and at the times the viewer got them ...
    assert_eq!(seen.frames.len(), 100);
    for (k, (f, g)) in seen.frames.iter().zip(&got).enumerate() {
        assert_eq!((f.seq, f.timestamp_us), (k as u64, g.frame.timestamp_us));
    }
    let stats = server.stats();
    let s = Serve::session(&stats, "r", 0);
    assert_eq!(
        (s["recorded"].as_u64(), s["record_lost"].as_u64()),
        (Some(100), Some(0))
    );
    assert_eq!(s["recording"].as_str(), Some(files[0].to_str().unwrap()));
    let rest = server.stop();
    assert!(rest.contains("100 frames recorded"), "{rest}");

    // ... so `mimic replay` of the recording computes what it computes for the original.
    let controls = |input: &Path, out: &str| {
        let csv = dir.path().join(out);
        let o = mimic(&[
            "replay",
            input.to_str().unwrap(),
            "--rig",
            "candide3",
            "--controls",
            csv.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o).1);
        std::fs::read_to_string(csv).unwrap()
    };
    let original = controls(&repo().join(REC), "original.csv");
    assert_eq!(original.lines().count(), 101);
    assert_eq!(controls(&files[0], "recorded.csv"), original);
}

#[test]
fn a_tracker_cut_off_mid_line_then_back_under_the_same_name_loses_only_the_half_line() {
    let dir = tempfile::tempdir().unwrap();
    let server = Serve::start(&[
        "--rig",
        "candide3",
        "--viewer-queue",
        "100000",
        "--record",
        dir.path().to_str().unwrap(),
    ]);
    let mut v = viewer(&server.tcp, "t", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let lines = frame_lines(REC);
    let mut a = Tracker::open(&server, "t");
    let first_id = a.welcome["session_id"].as_u64().unwrap();
    a.send_lines(&lines[..30]);
    a.send(&lines[30].as_bytes()[..lines[30].len() / 2]);
    // The tracker goes away without a newline or a goodbye (both directions closed).
    drop(a);
    let s = server.wait_for("the cut-off session to end", |s| {
        Serve::session(s, "t", first_id)["active"] == false
    });
    let s = Serve::session(&s, "t", first_id);
    // The half line is counted as malformed (`truncated`), never as a frame.
    assert_eq!(
        (
            s["frames"].as_u64(),
            s["malformed"].as_u64(),
            s["late"].as_u64()
        ),
        (Some(30), Some(1), Some(0)),
        "{s}"
    );
    assert_eq!(s["end_reason"], "closed");
    assert_eq!(s["recorded"], 30);

    // Back under the same name: a new session (new id) carries on from the cut.
    let mut b = Tracker::open(&server, "t");
    let second_id = b.welcome["session_id"].as_u64().unwrap();
    assert_ne!(second_id, first_id);
    b.send_lines(&lines[30..]);
    b.s.shutdown(Shutdown::Write).unwrap();
    assert_eq!(b.reply()["frames"], 70);

    // The viewer stayed: it saw both sessions, each whole, with END counts.
    let one = read_session(&mut v);
    let two = read_session(&mut v);
    assert_eq!(one.session.as_ref().unwrap()["session_id"], first_id);
    assert_eq!(two.session.as_ref().unwrap()["session_id"], second_id);
    assert!(two.rig.is_some());
    let end = one.end.clone().unwrap();
    assert_eq!(
        (end["frames"].as_u64(), end["malformed"].as_u64()),
        (Some(30), Some(1))
    );
    assert_eq!(two.end.as_ref().unwrap()["frames"], 70);
    let seqs = |s: &crate::loopback::Seen| s.frames.iter().map(|f| f.seq).collect::<Vec<_>>();
    assert_eq!(seqs(&one), (0..30).collect::<Vec<_>>());
    assert_eq!(seqs(&two), (0..70).collect::<Vec<_>>());
    assert_eq!(server.stats()["viewer_frames_dropped"], 0);
    server.stop();
    // Two recordings that together are the shipped recording.
    let files = recordings_in(dir.path());
    assert_eq!(files.len(), 2);
    let mut all = read_back(&files[0]);
    assert_eq!(all.len(), 30);
    all.extend(read_back(&files[1]));
    assert_same_frames(&all, &shipped(), "both recordings");
}

#[test]
fn a_flood_is_taken_in_full_and_a_stalled_viewer_drops_exactly_all_but_its_queue() {
    // ICT rig: its RIG message (~5 MB, mostly the basis) is larger than loopback socket buffers
    // take for a peer that never reads, so the stalled viewer's writer is stuck on it and every
    // frame goes through the viewer's 10-frame queue: exactly 90 of 100 are dropped, oldest first.
    let queue = 10;
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--viewer-queue",
        &queue.to_string(),
        "--viewer-write-timeout",
        "600",
    ]);
    let mut stalled = viewer(&server.tcp, "f", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    // The whole recording three times over in one write (passes 2 and 3 are late: 200 frames),
    // then 5 frames an hour ahead and 5 from long before: far more than 100x the recording's
    // 30 Hz. TCP does not drop: the server reads it all at its own pace.
    let lines = frame_lines(REC);
    let mut flood: Vec<String> = lines.iter().cycle().take(300).cloned().collect();
    let t_last = serde_json::from_str::<Value>(&lines[99]).unwrap()["t_us"]
        .as_i64()
        .unwrap();
    for (k, l) in (0i64..).zip(&lines[..5]) {
        flood.push(retimed(l, t_last + 3_600_000_000 + k));
        flood.push(retimed(l, -1_000_000 - k));
    }
    let mut t = Tracker::open(&server, "f");
    t.send_lines(&flood);
    let s = server.wait_for_session("f", "the flood to be read", |s| {
        s["frames"].as_u64().unwrap() + s["late"].as_u64().unwrap() + s["future"].as_u64().unwrap()
            == 310
    });
    assert_eq!(
        (
            s["frames"].as_u64(),
            s["late"].as_u64(),
            s["future"].as_u64(),
            s["malformed"].as_u64()
        ),
        (Some(100), Some(205), Some(5), Some(0)),
        "{s}"
    );
    let sv = &s["viewers"][0];
    assert_eq!(
        sv["frames_sent"], 0,
        "the stalled viewer's socket took the whole rig message; this test needs it stuck there: {sv}"
    );
    assert_eq!(
        (sv["frames_dropped"].as_u64(), sv["queued"].as_u64()),
        (Some(100 - queue), Some(queue))
    );
    t.s.shutdown(Shutdown::Write).unwrap();
    let bye = loop {
        let r = t.reply();
        if r["type"] == "bye" {
            break r;
        }
        assert_eq!(r["code"], "future_timestamp", "{r}");
    };
    assert_eq!(
        (bye["frames"].as_u64(), bye["future"].as_u64()),
        (Some(100), Some(5))
    );
    // The viewer now reads: the rig, then exactly the newest `queue` frames, in order, then END.
    let seen = read_session(&mut stalled);
    assert!(seen.rig.is_some());
    let seqs: Vec<u64> = seen.frames.iter().map(|f| f.seq).collect();
    assert_eq!(seqs, (100 - queue..100).collect::<Vec<_>>());
    assert_eq!(seen.end.unwrap()["frames"], 100);
    let s = server.wait_for_session("f", "the viewer to finish", |s| {
        s["viewers"][0]["frames_sent"] == queue
    });
    assert_eq!(s["viewers"][0]["frames_dropped"], 100 - queue);
    server.stop();
}

#[test]
fn a_viewer_that_leaves_and_comes_back_gets_the_rig_again_and_every_frame_from_then_on() {
    let server = Serve::start(&["--rig", "candide3", "--viewer-queue", "100000"]);
    let lines = frame_lines(REC);
    let mut first = viewer(&server.tcp, "v", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let mut t = Tracker::open(&server, "v");
    t.send_lines(&lines[..20]);
    let mut frames = 0;
    while frames < 20 {
        match read_message(&mut first) {
            Some(ViewerMessage::Frame(f)) => {
                assert_eq!(f.seq, frames);
                frames += 1;
            }
            Some(ViewerMessage::Session(_) | ViewerMessage::Rig(_)) => {}
            other => panic!("{other:?}"),
        }
    }
    drop(first);
    server.wait_for("the viewer to leave", |s| s["viewers_active"] == 0);
    // Frames while nobody watches are retargeted and counted, not queued anywhere.
    t.send_lines(&lines[20..50]);
    server.wait_for_session("v", "50 frames", |s| s["frames"] == 50);
    let mut again = viewer(&server.tcp, "v", false);
    server.wait_for_session("v", "the viewer back", |s| {
        s["viewers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|v| v["connected"] == true)
    });
    t.send_lines(&lines[50..]);
    t.s.shutdown(Shutdown::Write).unwrap();
    let seen = read_session(&mut again);
    assert_eq!(seen.session.unwrap()["session"], "v");
    assert!(seen.rig.is_some());
    let seqs: Vec<u64> = seen.frames.iter().map(|f| f.seq).collect();
    assert_eq!(seqs, (50..100).collect::<Vec<_>>());
    assert_eq!(seen.end.unwrap()["frames"], 100);
    let s = Serve::session(&server.stats(), "v", 0);
    let viewers = s["viewers"].as_array().unwrap();
    assert_eq!(viewers.len(), 2);
    assert_eq!(
        (
            viewers[0]["frames_sent"].as_u64(),
            viewers[0]["connected"].as_bool()
        ),
        (Some(20), Some(false))
    );
    assert_eq!(viewers[1]["frames_sent"], 50);
    assert!(viewers.iter().all(|v| v["frames_dropped"] == 0));
    server.stop();
}

#[test]
fn ctrl_c_mid_session_leaves_every_accepted_frame_in_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let server = Serve::start(&[
        "--rig",
        "candide3",
        "--record",
        dir.path().to_str().unwrap(),
        "--record-queue",
        "1",
    ]);
    let lines = frame_lines(REC);
    let mut t = Tracker::open(&server, "c");
    t.send_lines(&lines[..30]);
    server.wait_for_session("c", "30 TCP frames", |s| s["frames"] == 30);
    // Then 7 UDP frames at full f32 precision (not the recording's 6 digits), one at a time.
    let id = t.welcome["session_id"].as_u64().unwrap() as u32;
    let key = t.welcome["udp_key"].as_u64().unwrap() as u32;
    let mut want: Vec<RecordedFrame> = shipped().into_iter().take(30).collect();
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    for k in 30..37 {
        let mut f = shipped()[k].frame.clone();
        for p in &mut f.points {
            *p = glam::Vec3::from_array(p.to_array().map(|c| f32::from_bits(c.to_bits() ^ 0x55)));
        }
        udp.send_to(
            &mimic_stream::wire::encode_udp_frame(id, key, &f),
            &server.udp,
        )
        .unwrap();
        server.wait_for_session("c", "the UDP frame", |s| s["frames"] == k + 1);
        want.push(RecordedFrame::unlabelled(f));
    }
    let rest = server.stop();
    assert!(rest.contains("37 frames recorded"), "{rest}");
    let bye = loop {
        let r = t.reply();
        if r["type"] == "bye" {
            break r;
        }
    };
    assert_eq!(
        (
            bye["reason"].as_str(),
            bye["frames"].as_u64(),
            bye["recorded"].as_u64()
        ),
        (Some("shutdown"), Some(37), Some(37))
    );
    let files = recordings_in(dir.path());
    assert_eq!(files.len(), 1);
    assert_same_frames(&read_back(&files[0]), &want, "recording after Ctrl-C");
}
