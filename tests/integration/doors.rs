//! The network doors (docs/reliability.md, "Doors") under attack on loopback: idle sockets on
//! the browser endpoint under a 1 024 file limit, foreign `Host` and `Origin` headers, random
//! datagrams and many faces on the OpenSeeFace intake, a second source injecting into a face,
//! and a tracker aiming forwarding at a local service.
//!
//! "Addresses" are loopback source addresses: on Linux all of 127.0.0.0/8 reaches a server on
//! 127.0.0.1, each its own peer.

use crate::loopback::{
    Serve, connect, connect_from, frame_lines, header_with_session, read_json_line,
};
use mimic_trackers::openseeface::{OsfFace, decode_packet, encode_packet, read_capture};
use std::io::{BufReader, Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::time::{Duration, Instant};

/// Sends 30 frames of the shipped recording as session `name` from `from` and waits until the
/// server has taken all 30 (a tracker admitted and served); returns its connection.
fn tracker_is_served(server: &Serve, from: &str, name: &str) -> TcpStream {
    let rec = "recordings/openface_test.jsonl";
    let mut t = connect_from(from, &server.tcp);
    t.write_all(header_with_session(rec, name).as_bytes())
        .unwrap();
    for l in &frame_lines(rec)[..30] {
        t.write_all(l.as_bytes()).unwrap();
    }
    server.wait_for_session(name, "the tracker's 30 frames", |x| x["frames"] == 30);
    t
}

/// One raw HTTP/1.1 request on a new connection: (status, the whole answer as text).
fn http(addr: &str, request: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut all = Vec::new();
    let mut buf = [0u8; 65536];
    loop {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => all.extend_from_slice(&buf[..n]),
        }
        // A 101 keeps the connection open: its head is all there is to read.
        if all.starts_with(b"HTTP/1.1 101") && all.windows(4).any(|w| w == b"\r\n\r\n") {
            break;
        }
    }
    let text = String::from_utf8_lossy(&all).into_owned();
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, text)
}

#[test]
fn idle_http_sockets_under_a_1024_file_limit_leave_trackers_and_stats_answering() {
    let server = Serve::start_with_file_limit(
        &[
            "--rig",
            "candide3",
            "--no-udp",
            "--http",
            "127.0.0.1:0",
            "--http-header-timeout",
            "15",
        ],
        Some(1024),
    );
    let http_addr = server.http.clone().unwrap();
    // 1 100 idle sockets from 40 addresses (28 each, within the per-address cap of 32): past
    // the budget the server answers 503 and closes; the admitted ones say nothing.
    let started = Instant::now();
    let mut held = Vec::new();
    for k in 0..1100 {
        let from = format!("127.0.0.{}", 10 + k % 40);
        held.push(connect_from(&from, &http_addr));
    }
    let s = server.wait_for("the idle sockets seen", |s| {
        s["http_refused"].as_u64().unwrap_or(0) + s["http_connections"].as_u64().unwrap_or(0)
            >= 1100
    });
    let open = s["http_connections"].as_u64().unwrap();
    // Under 1 024 descriptors the budget is 1 024 - (400 + 4 + 256 + 128 + 64) = 172.
    assert!(open <= 172, "{s}");
    assert!(s["http_refused"].as_u64().unwrap() >= 1100 - 172, "{s}");
    // A TCP tracker is admitted and served, and the stats answer, while the sockets are held.
    let tracker = tracker_is_served(&server, "127.0.0.2", "beside-the-idle");
    let mut g = connect(&server.tcp);
    g.write_all(b"GET /stats HTTP/1.0\r\n\r\n").unwrap();
    let mut reply = String::new();
    g.read_to_string(&mut reply).unwrap();
    assert!(reply.starts_with("HTTP/1.0 200 OK"), "{reply}");
    // The idle ones are closed after the header timeout, and the endpoint answers again.
    let s = server.wait_for("the idle sockets closed", |s| s["http_connections"] == 0);
    assert!(started.elapsed() >= Duration::from_secs(15), "{s}");
    drop(tracker);
    let (status, body) = http(
        &http_addr,
        &format!("GET /stats HTTP/1.1\r\nHost: {http_addr}\r\nConnection: close\r\n\r\n"),
    );
    assert_eq!(status, 200, "{body}");
    // Past the per-address cap (32): refused with a 503 naming it, whatever the budget.
    drop(held);
    server.wait_for("the sockets gone", |s| s["http_connections"] == 0);
    let mut mine: Vec<TcpStream> = (0..32)
        .map(|_| connect_from("127.0.0.99", &http_addr))
        .collect();
    server.wait_for("32 from one address", |s| s["http_connections"] == 32);
    let mut extra = connect_from("127.0.0.99", &http_addr);
    let mut answer = String::new();
    let _ = extra.read_to_string(&mut answer);
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(
        answer.contains("at most 32 connections from 127.0.0.99"),
        "{answer}"
    );
    mine.clear();
    server.stop();
}

#[test]
fn a_foreign_host_or_origin_is_refused_and_the_right_ones_accepted() {
    let server = Serve::start(&[
        "--rig",
        "candide3",
        "--no-udp",
        "--http",
        "127.0.0.1:0",
        "--http-host",
        "face.lan",
        "--http-origin",
        "http://studio.example:3000",
    ]);
    let addr = server.http.clone().unwrap();
    let get = |path: &str, host: &str, extra: &str| {
        http(
            &addr,
            &format!("GET {path} HTTP/1.1\r\nHost: {host}\r\n{extra}Connection: close\r\n\r\n"),
        )
    };
    let ws = "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
    let upgrade = |host: &str, origin: &str| {
        http(
            &addr,
            &format!("GET /ws/s HTTP/1.1\r\nHost: {host}\r\nOrigin: {origin}\r\n{ws}\r\n"),
        )
    };
    // DNS rebinding: a page of attacker.example that now resolves to 127.0.0.1.
    let (status, body) = get("/stats", "attacker.example", "");
    assert_eq!(status, 421, "{body}");
    assert!(
        body.contains("Host `attacker.example` does not name this server"),
        "{body}"
    );
    let (status, body) = upgrade("attacker.example:80", "http://attacker.example");
    assert_eq!(status, 421, "{body}");
    // A foreign page's WebSocket to the right host.
    let (status, body) = upgrade(&addr, "http://evil.example");
    assert_eq!(status, 403, "{body}");
    assert!(
        body.contains("Origin `http://evil.example` is not this server's page"),
        "{body}"
    );
    let (status, body) = get("/sessions", &addr, "Origin: http://evil.example\r\n");
    assert_eq!(status, 403, "{body}");
    // The right ones: the served page's own origin, a listed one, a listed host name.
    let (status, body) = upgrade(&addr, &format!("http://{addr}"));
    assert_eq!(status, 101, "{body}");
    let (status, body) = upgrade(&addr, "http://studio.example:3000");
    assert_eq!(status, 101, "{body}");
    let (status, body) = get("/stats", "face.lan:8080", "");
    assert_eq!(status, 200, "{body}");
    let (status, body) = get("/", "localhost", "");
    assert_eq!(status, 200, "{body}");
    let s = server.stats();
    assert_eq!(s["http_refused"], 4, "{s}");
    server.stop();
}

/// The capture's faces (each datagram of `megamind.osf` holds one).
fn capture_faces() -> Vec<OsfFace> {
    let osf = crate::repo().join("tests/data/openseeface/megamind.osf");
    read_capture(&osf)
        .unwrap()
        .iter()
        .flat_map(|r| decode_packet(&r.datagram).unwrap())
        .collect()
}

/// A free loopback UDP port's address.
fn free_udp() -> String {
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("127.0.0.1:{port}")
}

#[test]
fn random_datagrams_and_many_faces_leave_a_tcp_tracker_admitted() {
    let osf = free_udp();
    let server = Serve::start(&["--rig", "candide3", "--no-udp", "--openseeface", &osf]);
    let faces = capture_faces();
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    // Random bytes, whole faces' worth (the 6 datagrams opened every session slot).
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = |n: usize| -> Vec<u8> {
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x as u8
            })
            .collect()
    };
    for k in 0..200 {
        udp.send_to(&random(1785 * (1 + k % 20)), &osf).unwrap();
    }
    // 300 faces that each send 3 valid packets: 16 sessions (--max-udp-sessions) open.
    for id in 0..300 {
        for f in &faces[..3] {
            let mut face = f.clone();
            face.face_id = id;
            udp.send_to(&encode_packet(&[face]), &osf).unwrap();
        }
        if id % 50 == 49 {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let s = server.wait_for("the faces counted", |s| {
        s["sessions_active"] == 16 && s["udp_refused"].as_u64().unwrap_or(0) > 0
    });
    assert!(s["sessions"].as_array().unwrap().len() <= 16, "{s}");
    // The intake never took more than its budget: a TCP tracker is admitted.
    let tracker = tracker_is_served(&server, "127.0.0.1", "after-the-flood");
    let s = server.stats();
    assert_eq!(s["sessions_active"], 17, "{s}");
    drop(tracker);
    server.stop();
}

#[test]
fn a_second_source_cannot_inject_into_a_face_session() {
    let osf = free_udp();
    let server = Serve::start(&["--rig", "candide3", "--no-udp", "--openseeface", &osf]);
    let faces = capture_faces();
    let tracker = UdpSocket::bind("127.0.0.1:0").unwrap();
    let intruder = UdpSocket::bind("127.0.0.1:0").unwrap();
    for (k, f) in faces[..20].iter().enumerate() {
        tracker
            .send_to(&encode_packet(std::slice::from_ref(f)), &osf)
            .unwrap();
        if k >= 5 && k % 3 == 0 {
            // The same face from another process, while the tracker is live.
            let mut fake = faces[100 + k].clone();
            fake.face_id = f.face_id;
            intruder.send_to(&encode_packet(&[fake]), &osf).unwrap();
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let s = server.wait_for("every packet counted", |s| {
        let x = Serve::session(s, "openseeface-0", 0);
        let n = |k: &str| x[k].as_u64().unwrap_or(0);
        n("frames") + n("late") + n("future") + n("malformed") == 20 && s["udp_wrong_source"] == 5
    });
    let x = Serve::session(&s, "openseeface-0", 0);
    assert_eq!(x["late"], 0, "{x}");
    assert_eq!(x["restarts"], 0, "{x}");
    server.stop();
}

#[test]
fn a_tracker_may_not_aim_forwarding_at_a_local_service() {
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--forward-allow",
        "127.0.0.1:39539",
    ]);
    for target in [
        "vmc:127.0.0.2:53",
        "livelink:127.0.0.1:22",
        "vmc:127.0.0.1:39540",
    ] {
        let mut t = connect(&server.tcp);
        let mut r = BufReader::new(t.try_clone().unwrap());
        t.write_all(format!("{{\"mode\":\"weights\",\"forward\":\"{target}\"}}\n").as_bytes())
            .unwrap();
        let refusal = read_json_line(&mut r);
        assert_eq!(refusal["code"], "bad_hello", "{refusal}");
        let m = refusal["message"].as_str().unwrap();
        assert!(
            m.contains(&format!(
                "forward to {}",
                &target[target.find(':').unwrap() + 1..]
            )) && m.contains("--forward-allow"),
            "{refusal}"
        );
    }
    // The allowed address and port is taken.
    let mut t = connect(&server.tcp);
    let mut r = BufReader::new(t.try_clone().unwrap());
    t.write_all(b"{\"mode\":\"weights\",\"forward\":\"vmc:127.0.0.1:39539\"}\n")
        .unwrap();
    let welcome = read_json_line(&mut r);
    assert_eq!(welcome["type"], "welcome", "{welcome}");
    drop(t);
    server.stop();
}
