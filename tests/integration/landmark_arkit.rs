//! Landmarks to ARKit weights (issue 41, item 3): a landmark recording replayed with
//! `--mode blendshapes` onto a rig with ICT's whole ARKit-style expression set drives many
//! distinct weights, and the server's forwarding fits with the rig's own `[blendshape_fit]`, the
//! same weights the replay writes.

use crate::loopback::Serve;
use crate::repo;
use mimic_trackers::livelink::{curve_index, decode_packet};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// A copy of the shipped ICT rig (configs/rigs/ict-face.toml, paths made absolute) whose morph
/// targets are ICT's whole expression set (configs/meshes/ict-facekit/expressions.shapes) in
/// place of its eight, with `fit` appended (a `[blendshape_fit]` table, or nothing).
fn ict_arkit_rig(dir: &Path, fit: &str) -> (PathBuf, Vec<String>) {
    let shipped = std::fs::read_to_string(repo().join("configs/rigs/ict-face.toml")).unwrap();
    let meshes = repo().join("configs/meshes");
    let head = shipped
        .split("[[morph_targets]]")
        .next()
        .unwrap()
        .replace("name = \"ict-face\"", "name = \"ict-arkit\"")
        .replace("\"../meshes/", &format!("\"{}/", meshes.display()));
    let pack = meshes.join("ict-facekit/expressions.shapes");
    let names: Vec<String> = mimic_assets::load_shape_pack(&pack)
        .unwrap()
        .shapes
        .into_iter()
        .map(|s| s.name)
        .collect();
    let mut text = head;
    for n in &names {
        text.push_str(&format!(
            "[[morph_targets]]\nname = \"{n}\"\nshapes = \"{}\"\n\n",
            pack.display()
        ));
    }
    text.push_str(fit);
    let path = dir.join("ict-arkit.toml");
    std::fs::write(&path, text).unwrap();
    (path, names)
}

/// The weights CSV of `mimic replay RECORDING --rig RIG --mode blendshapes` (first `frames`):
/// its header and rows of numbers (status and label columns left out: NaN).
fn replay_weights(
    recording: &str,
    rig: &Path,
    frames: usize,
    dir: &Path,
) -> (Vec<String>, Vec<Vec<f64>>) {
    let csv = dir.join("w.csv");
    let n = frames.to_string();
    let summary = crate::replay::replay_json(&[
        recording,
        "--rig",
        rig.to_str().unwrap(),
        "--mode",
        "blendshapes",
        "--max-frames",
        &n,
        "--weights",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(summary["rejected"], 0, "{summary}");
    let table = mimic_capture::named_csv::read_named_csv(&csv).unwrap();
    let rows = table
        .rows
        .iter()
        .map(|r| {
            (0..table.header.len())
                .map(|c| r.field(c).parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    (table.header, rows)
}

#[test]
fn a_mediapipe_recording_drives_many_arkit_weights_and_forwarding_fits_with_the_rigs_terms() {
    let tmp = tempfile::tempdir().unwrap();
    // Terms unlike the defaults, so a forwarder that ignored them would send other weights.
    let table = "[blendshape_fit]\nridge = 0.05\nl1 = 0.02\ntemporal = 0.5\nsymmetry = 1.0\n";
    let (rig, names) = ict_arkit_rig(tmp.path(), table);
    assert!(names.len() >= 53, "{} shapes", names.len());
    let recording = "recordings/megamind_mediapipe.jsonl";
    let frames = 120;
    let (header, rows) = replay_weights(recording, &rig, frames, tmp.path());
    let col = |h: &str| header.iter().position(|c| c == h).unwrap();
    // Distinct weights the landmarks drive: targets whose fitted weight reaches 0.1 in some frame.
    let driven: Vec<&String> = names
        .iter()
        .filter(|n| rows.iter().any(|r| r[col(n)] >= 0.1))
        .collect();
    eprintln!(
        "{} of {} weights reach 0.1: {driven:?}",
        driven.len(),
        names.len()
    );
    assert!(
        driven.len() >= 15,
        "{} weights driven: {driven:?}",
        driven.len()
    );

    // The same recording through `mimic serve` with that rig, forwarded to Live Link.
    let ll = UdpSocket::bind("127.0.0.1:0").unwrap();
    ll.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let ll_addr = ll.local_addr().unwrap().to_string();
    let server = Serve::start(&[
        "--rig",
        rig.to_str().unwrap(),
        "--no-udp",
        "--forward-allow",
        &ll_addr,
    ]);
    let rx = mimic_testkit::spawn("livelink-receiver", move || {
        let mut buf = vec![0u8; 65_536];
        (0..frames)
            .map(|_| {
                let len = ll.recv(&mut buf).unwrap();
                decode_packet(&buf[..len]).unwrap()
            })
            .collect::<Vec<_>>()
    });
    let n = frames.to_string();
    let o = crate::mimic(&[
        "send",
        recording,
        "--to",
        &server.tcp,
        "--session",
        "lm",
        "--forward",
        &format!("livelink:{ll_addr}"),
        "--max-frames",
        &n,
        "--speed",
        "4",
    ]);
    let (stdout, stderr) = crate::text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let got = rx.join().unwrap();
    let x = server.wait_for_session("lm", "the end", |x| x["active"] == false);
    assert_eq!(x["forwarded"], frames as u64, "{x}");
    server.stop();
    // The rig without the table (the defaults): what a forwarder ignoring it would send.
    let other = tmp.path().join("defaults");
    std::fs::create_dir(&other).unwrap();
    let (plain, _) = ict_arkit_rig(&other, "");
    let (plain_header, plain_rows) = replay_weights(recording, &plain, frames, &other);
    assert_eq!(plain_header, header);
    // Forwarded curves against the replay's weights (4 decimals in the CSV).
    let (mut off, mut differs) = (0.0f64, 0.0f64);
    for (curve, target) in [
        ("JawOpen", "jawOpen"),
        ("EyeBlinkLeft", "eyeBlink_L"),
        ("EyeBlinkRight", "eyeBlink_R"),
        ("MouthSmileLeft", "mouthSmile_L"),
        ("MouthFunnel", "mouthFunnel"),
    ] {
        let c = curve_index(curve).unwrap();
        for (k, p) in got.iter().enumerate() {
            let want = rows[k][col(target)];
            off = off.max((f64::from(p.curves[c]) - want).abs());
            differs = differs.max((plain_rows[k][col(target)] - want).abs());
        }
    }
    eprintln!("forwarded vs replay: {off:.2e}; the defaults differ by up to {differs:.3}");
    assert!(off <= 0.5e-4 + f64::from(f32::EPSILON), "{off}");
    // The check can tell: the defaults' weights are clearly other ones.
    assert!(differs > 100.0 * 0.5e-4, "{differs}");
}
