//! `mimic serve --record DIR` records weights sessions and Live Link Face UDP sessions as weights
//! CSVs (`t_us,<rig morph targets>...`, docs/recording-format.md): the file read back holds every
//! accepted frame with its values (as the session applied them), and nothing it refused.

use crate::loopback::{Serve, connect, read_json_line};
use crate::{mimic, repo, text};
use mimic_capture::named_csv::{NamedCsv, read_named_csv};
use serde_json::Value;
use std::io::{BufReader, Write};
use std::net::Shutdown;
use std::path::Path;

/// The single `*.weights.csv` of `dir`, parsed.
fn the_recording(dir: &Path) -> NamedCsv {
    let found: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".weights.csv"))
        .collect();
    assert_eq!(found.len(), 1, "{found:?}");
    read_named_csv(&found[0]).unwrap()
}

/// Row `r`'s value in column `name`.
fn cell(t: &NamedCsv, r: usize, name: &str) -> f32 {
    let c = t.header.iter().position(|h| h == name).unwrap();
    t.rows[r].field(c).parse().unwrap()
}

#[test]
fn a_weights_session_is_recorded_frame_by_frame_and_sent_back() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rec");
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--record",
        dir.to_str().unwrap(),
        "--record-queue",
        "1",
    ]);
    let mut tracker = connect(&server.tcp);
    let mut replies = BufReader::new(tracker.try_clone().unwrap());
    tracker
        .write_all(b"{\"mode\":\"weights\",\"session\":\"w\"}\n")
        .unwrap();
    let welcome = read_json_line(&mut replies);
    let names: Vec<String> = welcome["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap().to_string())
        .collect();
    // 300 frames of pseudo-random weights (some outside [0, 1]: the session clamps them), one
    // late frame (refused, not recorded) and one unknown name (ignored).
    let mut rng = mimic_testkit::Lcg::new(18);
    let mut sent: Vec<(i64, Vec<f32>)> = Vec::new();
    let mut lines = String::new();
    for k in 0..300i64 {
        let t = 1000 + 16_667 * k;
        let w: Vec<f32> = names.iter().map(|_| rng.next_f32() * 1.4 - 0.2).collect();
        let mut weights = serde_json::Map::new();
        for (n, v) in names.iter().zip(&w) {
            weights.insert(n.clone(), Value::from(f64::from(*v)));
        }
        weights.insert("tongueOut".into(), Value::from(0.5));
        lines.push_str(&serde_json::json!({"t_us": t, "weights": weights}).to_string());
        lines.push('\n');
        if k == 150 {
            lines.push_str("{\"t_us\":5,\"weights\":{\"jawOpen\":0.9}}\n");
        }
        sent.push((t, w.iter().map(|v| v.clamp(0.0, 1.0)).collect()));
    }
    tracker.write_all(lines.as_bytes()).unwrap();
    tracker.shutdown(Shutdown::Write).unwrap();
    let bye = loop {
        let l = read_json_line(&mut replies);
        if l["type"] == "bye" {
            break l;
        }
    };
    assert_eq!(bye["frames"], 300, "{bye}");
    assert_eq!(bye["late"], 1, "{bye}");
    assert_eq!(bye["recorded"], 300, "{bye}");
    let x = server.wait_for_session("w", "the end", |x| x["active"] == false);
    assert_eq!(x["record_lost"], 0, "{x}");
    let table = the_recording(&dir);
    let mut header = vec!["t_us".to_string()];
    header.extend(names.iter().cloned());
    assert_eq!(table.header, header);
    assert_eq!(table.rows.len(), sent.len());
    for (r, (t, w)) in sent.iter().enumerate() {
        assert_eq!(table.rows[r].field(0).parse::<i64>().unwrap(), *t);
        for (n, v) in names.iter().zip(w) {
            // JSON carries the f64 of each f32; the session's f32 is written exactly.
            assert_eq!(cell(&table, r, n), *v, "row {r}, {n}");
        }
    }
    // `mimic send --weights` reads the recording back, at its times.
    let path = std::fs::read_dir(&dir)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let o = mimic(&[
        "send",
        "--weights",
        path.to_str().unwrap(),
        "--to",
        &server.tcp,
        "--session",
        "again",
        "--fast",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("server: 300 frames, 0 late, 0 malformed, 0 unknown weight names"),
        "{stdout}"
    );
    server.stop();
}

#[test]
fn a_live_link_udp_session_is_recorded_with_record_sync() {
    use mimic_trackers::livelink::{CURVE_NAMES, LiveLinkPacket, curve_index, encode_packet};
    let take = mimic_trackers::take::read_take(&repo().join("tests/data/livelinkface/S07-001.csv"))
        .unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rec");
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--livelink",
        &addr,
        "--idle-timeout",
        "1",
        "--record",
        dir.to_str().unwrap(),
        "--record-sync",
    ]);
    let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let rows: Vec<_> = take.rows.iter().filter(|r| r.tracked).take(200).collect();
    for (i, row) in rows.iter().enumerate() {
        let p = encode_packet(&LiveLinkPacket {
            device_id: "9A1B7D4E-0000-4000-8000-000000000001".into(),
            subject: "iPhone".into(),
            frame: 500 + i as i32,
            subframe: 0.0,
            rate_numerator: 60,
            rate_denominator: 1,
            curves: row.curves,
        });
        udp.send_to(&p, &addr).unwrap();
        // Paced a little, so the bounded UDP socket buffer never overflows on a loaded machine.
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let x = server.wait_for_session("livelink-iPhone", "the idle end", |x| x["active"] == false);
    let frames = x["frames"].as_u64().unwrap() as usize;
    // Every packet is counted; what was accepted is on disk, nothing lost.
    assert_eq!(
        frames as u64 + x["late"].as_u64().unwrap(),
        rows.len() as u64,
        "{x}"
    );
    assert_eq!(x["recorded"].as_u64().unwrap() as usize, frames, "{x}");
    assert_eq!(x["record_lost"], 0, "{x}");
    let table = the_recording(&dir);
    assert_eq!(table.rows.len(), frames);
    assert_eq!(table.header[0], "t_us");
    // Each rig target from its ARKit curve (`configs/namemaps/arkit.toml`: gain 1, offset 0,
    // clamp [0, 1]; ICT's `browInnerUp_L`/`_R` both from `BrowInnerUp`), packet i at frame
    // 500 + i of 60 fps, timed from the first.
    assert_eq!(frames, rows.len(), "no packet late on loopback: {x}");
    for (r, row) in rows.iter().enumerate() {
        let t: i64 = table.rows[r].field(0).parse().unwrap();
        assert!(
            (t as f64 - r as f64 / 60.0 * 1e6).abs() <= 1.0,
            "row {r}: {t}"
        );
        for name in &table.header[1..] {
            let base = name.trim_end_matches("_L").trim_end_matches("_R");
            let k = curve_index(base).unwrap_or_else(|| panic!("{name}: no curve"));
            let want = row.curves[k].clamp(0.0, 1.0);
            assert_eq!(
                cell(&table, r, name),
                want,
                "row {r}, {name} ({})",
                CURVE_NAMES[k]
            );
        }
    }
    server.stop();
}
