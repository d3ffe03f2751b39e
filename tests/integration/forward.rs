//! `mimic serve --forward vmc:ADDR --forward livelink:ADDR` on loopback: receivers decode every
//! datagram (rosc for VMC's OSC bundles, `mimic_trackers::livelink::decode_packet` for Live
//! Link) and check the names, values and counts against what the tracker sent; the server's
//! `forwarded` count is what they received, `forward_dropped` 0.

use crate::loopback::{Serve, connect, read_json_line};
use mimic_trackers::livelink::{CURVE_NAMES, HEAD_YAW, curve_index, decode_packet};
use rosc::{OscPacket, OscType};
use std::collections::HashMap;
use std::io::{BufReader, Write};
use std::net::{Shutdown, UdpSocket};
use std::time::Duration;

/// A loopback receiver and its address.
fn receiver() -> (UdpSocket, String) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    // Only guards a hang: every expected datagram is counted before the wait ends.
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let a = s.local_addr().unwrap().to_string();
    (s, a)
}

/// One VMC frame: its blend values by name, whether it applied, and the head bone's arguments.
#[derive(Debug, Default)]
struct VmcFrame {
    values: HashMap<String, f32>,
    order: Vec<String>,
    applied: bool,
    head: Vec<f32>,
}

/// Receives `n` VMC datagrams (each one bundle) and decodes them.
fn vmc_frames(s: UdpSocket, n: usize) -> std::thread::JoinHandle<Vec<VmcFrame>> {
    mimic_testkit::spawn("vmc-receiver", move || {
        let mut buf = vec![0u8; 65_536];
        (0..n)
            .map(|_| {
                let len = s.recv(&mut buf).unwrap();
                let (rest, p) = rosc::decoder::decode_udp(&buf[..len]).unwrap();
                assert!(rest.is_empty());
                let OscPacket::Bundle(b) = p else {
                    panic!("a VMC frame is one bundle")
                };
                let mut f = VmcFrame::default();
                for m in b.content {
                    let OscPacket::Message(m) = m else {
                        panic!("nested bundle")
                    };
                    match m.addr.as_str() {
                        "/VMC/Ext/Blend/Val" => {
                            let [OscType::String(name), OscType::Float(v)] = &m.args[..] else {
                                panic!("Blend/Val args {:?}", m.args)
                            };
                            assert!(!f.applied, "a value after the apply");
                            f.order.push(name.clone());
                            f.values.insert(name.clone(), *v);
                        }
                        "/VMC/Ext/Blend/Apply" => f.applied = true,
                        "/VMC/Ext/Bone/Pos" => {
                            assert_eq!(m.args[0], OscType::String("Head".into()));
                            f.head = m.args[1..]
                                .iter()
                                .map(|a| a.clone().float().unwrap())
                                .collect();
                        }
                        other => panic!("unexpected address {other}"),
                    }
                }
                f
            })
            .collect()
    })
}

#[test]
fn a_weights_session_forwards_every_frame_to_vmc_and_live_link() {
    let (vmc, vmc_addr) = receiver();
    let (ll, ll_addr) = receiver();
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--forward",
        &format!("vmc:{vmc_addr}"),
        "--forward",
        &format!("livelink:{ll_addr}"),
    ]);
    let n = 60;
    let vmc_rx = vmc_frames(vmc, n);
    let ll_rx = mimic_testkit::spawn("livelink-receiver", move || {
        let mut buf = vec![0u8; 65_536];
        (0..n)
            .map(|_| {
                let len = ll.recv(&mut buf).unwrap();
                decode_packet(&buf[..len]).unwrap()
            })
            .collect::<Vec<_>>()
    });
    let mut tracker = connect(&server.tcp);
    let mut replies = BufReader::new(tracker.try_clone().unwrap());
    tracker
        .write_all(b"{\"mode\":\"weights\",\"session\":\"fw\"}\n")
        .unwrap();
    assert_eq!(read_json_line(&mut replies)["type"], "welcome");
    // ARKit names the ICT rig has (browInnerUp drives both of its halves) and one it lacks.
    let w = |k: usize, j: usize| ((k * 7 + j * 3) % 11) as f32 / 10.0;
    for k in 0..n {
        let line = serde_json::json!({"t_us": 1000 + 16_667 * k as i64, "weights": {
            "jawOpen": w(k, 0), "mouthSmileLeft": w(k, 1), "browInnerUp": w(k, 2),
            "eyeBlinkRight": w(k, 3), "cheekPuff": 0.5}});
        tracker.write_all(format!("{line}\n").as_bytes()).unwrap();
        // Paced a little: the receivers' socket buffers are bounded.
        std::thread::sleep(Duration::from_millis(2));
    }
    tracker.shutdown(Shutdown::Write).unwrap();
    let vmc = vmc_rx.join().unwrap();
    let ll = ll_rx.join().unwrap();
    let x = server.wait_for_session("fw", "the end", |x| x["active"] == false);
    assert_eq!(x["frames"], n as u64, "{x}");
    assert_eq!(x["forwarded"], 2 * n as u64, "{x}");
    assert_eq!(x["forward_dropped"], 0, "{x}");
    for (k, (v, p)) in vmc.iter().zip(&ll).enumerate() {
        // VMC: the 52 ARKit names in ARKit's spelling, the apply, the head (identity here).
        assert_eq!(v.order.len(), 52, "frame {k}");
        assert!(v.applied);
        assert_eq!(v.head, [0.0, 0.0, 0.0, -0.0, -0.0, 0.0, 1.0]);
        for (name, want) in [
            ("jawOpen", w(k, 0)),
            ("mouthSmileLeft", w(k, 1)),
            ("browInnerUp", w(k, 2)),
            ("eyeBlinkRight", w(k, 3)),
            ("cheekPuff", 0.0),
            ("tongueOut", 0.0),
        ] {
            assert_eq!(v.values[name], want, "frame {k}, {name}");
            let c = curve_index(name).unwrap();
            assert_eq!(p.curves[c], want, "frame {k}, {}", CURVE_NAMES[c]);
        }
        // Live Link: the session's name as subject, 60 fps frame times from the first frame's.
        assert_eq!(p.subject, "fw");
        let t = p.time_us().unwrap();
        assert!((t - 16_667 * k as i64).abs() <= 1, "frame {k}: {t}");
        assert_eq!(&p.curves[HEAD_YAW..HEAD_YAW + 3], &[0.0, 0.0, 0.0]);
    }
    server.stop();
}

#[test]
fn live_link_packets_are_forwarded_to_vmc_with_vrm_names() {
    use mimic_trackers::livelink::{CURVES, LiveLinkPacket, encode_packet};
    let (vmc, vmc_addr) = receiver();
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let intake = format!("127.0.0.1:{port}");
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--livelink",
        &intake,
        "--idle-timeout",
        "1",
        "--forward",
        &format!("vmc:{vmc_addr}"),
        "--forward-vmc-names",
        "configs/namemaps/vrm.toml",
    ]);
    let n = 40;
    let rx = vmc_frames(vmc, n);
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    let jaw = curve_index("JawOpen").unwrap();
    let frown = curve_index("MouthFrownLeft").unwrap();
    let yaw = |i: usize| 0.01 * i as f32;
    for i in 0..n {
        let mut curves = [0.0f32; CURVES];
        curves[jaw] = i as f32 / n as f32;
        // A curve the ICT rig lacks is forwarded all the same (as `Sorrow`).
        curves[frown] = 0.25;
        curves[HEAD_YAW] = yaw(i);
        let p = encode_packet(&LiveLinkPacket {
            device_id: "d".into(),
            subject: "phone".into(),
            frame: 100 + i as i32,
            subframe: 0.0,
            rate_numerator: 60,
            rate_denominator: 1,
            curves,
        });
        udp.send_to(&p, &intake).unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    let frames = rx.join().unwrap();
    let x = server.wait_for_session("livelink-phone", "the idle end", |x| x["active"] == false);
    assert_eq!(x["frames"], n as u64, "{x}");
    assert_eq!(x["forwarded"], n as u64, "{x}");
    for (i, f) in frames.iter().enumerate() {
        assert_eq!(f.values["A"], i as f32 / n as f32, "frame {i}");
        assert_eq!(f.values["Sorrow"], 0.25);
        assert_eq!(f.values["Blink_L"], 0.0);
        // Names the VRM map does not list go under their ARKit names.
        assert!(f.values.contains_key("tongueOut"));
        assert!(!f.values.contains_key("jawOpen"));
        // A yaw psi (right-handed, about +y) is the quaternion (0, -sin(psi/2), 0, cos(psi/2))
        // in Unity's left-handed axes.
        let h = yaw(i) / 2.0;
        let want = [0.0, 0.0, 0.0, 0.0, -h.sin(), 0.0, h.cos()];
        for (g, w) in f.head.iter().zip(want) {
            assert!((g - w).abs() <= 1e-6, "frame {i}: {:?}", f.head);
        }
    }
    server.stop();
}

#[test]
fn a_landmark_session_forwards_its_blendshape_fit_where_its_hello_asks() {
    let (ll, ll_addr) = receiver();
    // A tracker's own target must be allowed by address and port (docs/reliability.md).
    let server = Serve::start(&["--rig", "ict-face", "--no-udp", "--forward-allow", &ll_addr]);
    let n = 100;
    let rx = mimic_testkit::spawn("livelink-receiver", move || {
        let mut buf = vec![0u8; 65_536];
        (0..n)
            .map(|_| {
                let len = ll.recv(&mut buf).unwrap();
                decode_packet(&buf[..len]).unwrap()
            })
            .collect::<Vec<_>>()
    });
    let n_text = n.to_string();
    let o = crate::mimic(&[
        "send",
        "recordings/a_yn_question.jsonl",
        "--to",
        &server.tcp,
        "--session",
        "lm",
        "--forward",
        &format!("livelink:{ll_addr}"),
        "--max-frames",
        &n_text,
        "--speed",
        "4",
    ]);
    let (stdout, stderr) = crate::text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let got = rx.join().unwrap();
    let x = server.wait_for_session("lm", "the end", |x| x["active"] == false);
    assert_eq!(x["frames"], n as u64, "{x}");
    assert_eq!(x["forwarded"], n as u64, "{x}");
    // The same fit offline: `mimic replay --mode blendshapes --weights` (same pipeline and fit
    // settings, 4 decimals).
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("w.csv");
    let summary = crate::replay::replay_json(&[
        "recordings/a_yn_question.jsonl",
        "--rig",
        "ict-face",
        "--mode",
        "blendshapes",
        "--max-frames",
        &n_text,
        "--weights",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(summary["rejected"], 0, "{summary}");
    let table = mimic_capture::named_csv::read_named_csv(&csv).unwrap();
    let col = |h: &str| table.header.iter().position(|c| c == h).unwrap();
    let jaw = curve_index("JawOpen").unwrap();
    let t0: i64 = table.rows[0].field(col("t_us")).parse().unwrap();
    let mut opened = 0.0f32;
    for (k, (p, row)) in got.iter().zip(&table.rows).enumerate() {
        let want: f32 = row.field(col("jawOpen")).parse().unwrap();
        assert!(
            (p.curves[jaw] - want).abs() <= 0.5e-4 + f32::EPSILON,
            "frame {k}"
        );
        // Frame times from the first forwarded frame, at 60 fps (to a microsecond).
        let t: i64 = row.field(col("t_us")).parse().unwrap();
        assert!((p.time_us().unwrap() - (t - t0)).abs() <= 1, "frame {k}");
        opened = opened.max(p.curves[jaw]);
    }
    assert_eq!(got[0].subject, "lm");
    assert!(opened > 0.0, "the fit moves: jawOpen max {opened}");
    // A hello may not make the server an open relay: beyond loopback, refused.
    let mut t = connect(&server.tcp);
    let mut r = BufReader::new(t.try_clone().unwrap());
    t.write_all(b"{\"mode\":\"weights\",\"forward\":\"vmc:192.0.2.1:39539\"}\n")
        .unwrap();
    let refusal = read_json_line(&mut r);
    assert_eq!(refusal["code"], "bad_hello", "{refusal}");
    assert!(
        refusal["message"]
            .as_str()
            .unwrap()
            .contains("--forward-allow"),
        "{refusal}"
    );
    server.stop();
}
