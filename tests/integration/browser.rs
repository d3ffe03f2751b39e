//! The browser viewer (`mimic serve --http`, docs/browser.md): a recording replayed into the
//! server with `mimic send`, `/view/SESSION` opened in headless Chromium (tools/browser-check,
//! playwright-core driving /usr/bin/chromium with WebGL2 on SwiftShader), and the face checked
//! from two screenshots, then its keys and mouse on the same page (paused: number key 1, the heat
//! map and its legend, a drag and the reset); plus the HTTP routes and the token, over raw
//! sockets. The Chromium test skips, saying why, only when Chromium or Node is not installed.

use crate::{mimic, repo, text};
use serde_json::Value;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

/// A `mimic serve --http 127.0.0.1:0` child; killed when dropped.
struct WebServe {
    child: Child,
    _stdout: BufReader<ChildStdout>,
    tcp: String,
    http: String,
}

impl WebServe {
    fn start(args: &[&str]) -> WebServe {
        let mut child = Command::new(env!("CARGO_BIN_EXE_mimic"))
            .args([
                "serve",
                "--rig",
                "ict-face",
                "--listen",
                "127.0.0.1:0",
                "--no-udp",
            ])
            .args(["--http", "127.0.0.1:0"])
            .args(args)
            .current_dir(repo())
            .env_remove("RUST_LOG")
            .env_remove("MIMIC_TOKEN")
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn mimic serve");
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut first = String::new();
        stdout.read_line(&mut first).unwrap();
        // "mimic serve: tcp ADDR udp off rigs [...] http ADDR"
        let words: Vec<&str> = first.split_whitespace().collect();
        let after = |key: &str| {
            let k = words.iter().position(|w| *w == key);
            k.and_then(|k| words.get(k + 1)).map(|s| s.to_string())
        };
        let (Some(tcp), Some(http)) = (after("tcp"), after("http")) else {
            panic!("serve said: {first:?}");
        };
        WebServe {
            child,
            _stdout: stdout,
            tcp,
            http,
        }
    }

    /// `GET path` on the HTTP address: (status, body).
    fn get(&self, path: &str) -> (u16, Vec<u8>) {
        http_get(&self.http, path)
    }
}

impl Drop for WebServe {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One HTTP/1.1 GET with `Connection: close`: (status, body). Generous timeouts: they only
/// guard hangs.
fn http_get(addr: &str, path: &str) -> (u16, Vec<u8>) {
    http_request(
        addr,
        &format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"),
    )
}

fn http_request(addr: &str, request: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut all = Vec::new();
    // A 101 upgrade keeps the connection open: read the head only.
    let mut buf = [0u8; 65536];
    loop {
        let n = s.read(&mut buf).unwrap_or(0);
        if n == 0 {
            break;
        }
        all.extend_from_slice(&buf[..n]);
        if complete(&all) {
            break;
        }
    }
    let head_end = all
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("an HTTP head");
    let head = String::from_utf8_lossy(&all[..head_end]).into_owned();
    let status: u16 = head.split_whitespace().nth(1).unwrap().parse().unwrap();
    let mut body = all[head_end + 4..].to_vec();
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        body = unchunk(&body);
    }
    (status, body)
}

/// Whether `all` holds a whole response: a 101 head (the connection stays open), or a head
/// with a `Content-Length` and that many body bytes (a kept-alive connection does not close).
fn complete(all: &[u8]) -> bool {
    let Some(end) = all.windows(4).position(|w| w == b"\r\n\r\n") else {
        return false;
    };
    if all.starts_with(b"HTTP/1.1 101") {
        return true;
    }
    let head = String::from_utf8_lossy(&all[..end]).to_ascii_lowercase();
    head.lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .and_then(|v| v.trim().parse::<usize>().ok())
        .is_some_and(|len| all.len() >= end + 4 + len)
}

/// A chunked body, joined.
fn unchunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(eol) = b.windows(2).position(|w| w == b"\r\n") {
        let size =
            usize::from_str_radix(std::str::from_utf8(&b[..eol]).unwrap().trim(), 16).unwrap();
        if size == 0 {
            break;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + size]);
        b = &b[eol + 2 + size + 2..];
    }
    out
}

/// `mimic send REC --to ADDR --session S --loop` in the background (killed when dropped).
struct Sender(Child);

impl Sender {
    fn start(rec: &str, to: &str, session: &str, extra: &[&str]) -> Sender {
        let child = Command::new(env!("CARGO_BIN_EXE_mimic"))
            .args(["send", rec, "--to", to, "--session", session])
            .args(extra)
            .current_dir(repo())
            .env_remove("MIMIC_TOKEN")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn mimic send");
        Sender(child)
    }
}

impl Drop for Sender {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Polls `/sessions` until session `name` is live with frames (or fails after a generous wait).
fn wait_live(serve: &WebServe, name: &str, query: &str) -> Value {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let (status, body) = serve.get(&format!("/sessions{query}"));
        assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
        let v: Value = serde_json::from_slice(&body).unwrap();
        let s = v["sessions"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == name && s["active"] == true && s["frames"].as_u64() > Some(0))
            .cloned();
        if let Some(s) = s {
            return s;
        }
        assert!(
            Instant::now() < deadline,
            "session {name} never went live: {v}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Whether Chromium and the Node check are there; prints why the test skips when not.
fn chromium_ready() -> bool {
    let chromium = std::env::var("MIMIC_CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        println!(
            "SKIPPED: no Chromium at {chromium} (Debian: apt-get install chromium chromium-driver)"
        );
        return false;
    }
    match Command::new("node").arg("--version").output() {
        Ok(o) if o.status.success() => {}
        _ => {
            println!("SKIPPED: `node` is not installed (Debian: apt-get install nodejs npm)");
            return false;
        }
    }
    let tools = repo().join("tools/browser-check");
    if !tools.join("node_modules/playwright-core").is_dir() {
        let o = Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund"])
            .current_dir(&tools)
            .output()
            .expect("run npm ci in tools/browser-check");
        assert!(
            o.status.success(),
            "npm ci in tools/browser-check failed: {:?}",
            text(&o)
        );
    }
    true
}

#[test]
fn the_page_draws_the_live_face_and_it_moves() {
    if !chromium_ready() {
        return;
    }
    let serve = WebServe::start(&[]);
    let _send = Sender::start(
        "recordings/a_yn_question.kinect121.jsonl",
        &serve.tcp,
        "web",
        &["--loop"],
    );
    wait_live(&serve, "web", "");
    let out = tempfile::tempdir().unwrap();
    let url = format!("http://{}/view/web", serve.http);
    let o = Command::new("node")
        .arg(repo().join("tools/browser-check/check.mjs"))
        .args(["--url", &url, "--out"])
        .arg(out.path())
        .args(["--frames", "20", "--interact"])
        .output()
        .expect("run node check.mjs");
    let (stdout, stderr) = text(&o);
    let report: Value = serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("check.mjs said no JSON ({e}): {stdout}\n{stderr}"));
    assert!(o.status.success(), "check.mjs failed: {report}\n{stderr}");
    println!("WebGL renderer: {}", report["webgl"]);
    println!("readout: {}", report["readout"]);
    println!("pixels: {}", report["pixels"]);

    // No errors in the browser: console errors and uncaught exceptions.
    assert_eq!(report["console_errors"], serde_json::json!([]), "{report}");
    assert_eq!(report["page_errors"], serde_json::json!([]), "{report}");
    // The readout reports frames received, from the live session on the ict-face rig.
    let state = &report["state"];
    assert!(state["framesReceived"].as_u64().unwrap() > 0, "{state}");
    assert_eq!(state["rig"], "ict-face", "{state}");
    assert_eq!(state["errors"], serde_json::json!([]), "{state}");
    let readout = report["readout"].as_str().unwrap();
    let frames_line = readout.lines().find(|l| l.starts_with("frames ")).unwrap();
    let shown: u64 = frames_line
        .split_whitespace()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!(shown > 0, "{readout}");

    // The face is drawn: the head framed by the page's camera fills a good part of the picture
    // (mimic render's framing: the whole head fits a 30 degree view with a 4% margin; the face
    // alone covers about a fifth of the image). A blank or black canvas has none.
    let px = &report["pixels"];
    let n = px["pixels"].as_f64().unwrap();
    for drawn in px["drawn"].as_array().unwrap() {
        let share = drawn.as_f64().unwrap() / n;
        assert!(
            share > 0.05,
            "only {:.1}% of the pixels differ from the background: {px}",
            share * 100.0
        );
    }
    // It moves: the shots are 20 or more frames apart (2/3 s of a yes/no question, head nods and
    // brows). SwiftShader draws the same scene to the same pixels, so a still face would change
    // none; antialiasing of a moving silhouette and the expression change at least 0.1% of the
    // face's pixels by more than 16 levels.
    let seqs: Vec<u64> = report["shots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["seq"].as_u64().unwrap())
        .collect();
    assert!(seqs[1] >= seqs[0] + 20, "{seqs:?}");
    let face = px["drawn"][0].as_f64().unwrap();
    let changed = px["changed"].as_f64().unwrap();
    assert!(
        changed > 0.001 * face,
        "only {changed} pixels changed between the shots: {px}"
    );

    // The WebSocket viewer was counted in the stats like a TCP viewer.
    let (status, body) = serve.get("/stats");
    assert_eq!(status, 200);
    let stats: Value = serde_json::from_slice(&body).unwrap();
    let web = stats["sessions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == "web")
        .unwrap();
    assert!(web["viewers_total"].as_u64().unwrap() >= 1, "{web}");
    assert!(web["viewer_frames_sent"].as_u64().unwrap() > 0, "{web}");

    the_keys_and_the_mouse_work(&report["interact"], px["pixels"].as_f64().unwrap());
}

/// The rig's `[[morph_targets]]` names, in order, from its TOML file.
fn rig_target_names(rig: &str) -> Vec<String> {
    let path = repo().join(format!("configs/rigs/{rig}.toml"));
    let v: toml::Value = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["morph_targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["name"].as_str().unwrap().to_string())
        .collect()
}

/// What check.mjs `--interact` measured on the paused page (shots: 0 held frame, 1 key `1` in,
/// 2 heat map on, 3 heat map off, 4 key `1` out, 5 after a 100 px drag, 6 after `r`).
fn the_keys_and_the_mouse_work(i: &Value, pixels: f64) {
    println!("interact: {i}");
    let shot = |k: usize, what: &str| i["shots"][k][what].as_f64().unwrap();
    let pair = |a: u64, b: u64| {
        i["pairs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["shots"] == serde_json::json!([a, b]))
            .unwrap()["changed"]
            .as_f64()
            .unwrap()
    };
    // The frame was held: no frame drawn between the first and the last shot.
    assert_eq!(i["frames_shown"][0], i["frames_shown"][1], "{i}");
    let face = shot(0, "drawn");
    assert!(face > 0.05 * pixels, "{i}");
    // The number keys carry the rig's first nine morph targets (ict-face has eight).
    let names = rig_target_names("ict-face");
    let keys: Vec<String> = names.iter().take(9).cloned().collect();
    assert_eq!(i["expression_names"], serde_json::json!(keys), "{i}");
    // ... and each key drives the GLB's target of that name (after the 114 basis columns).
    assert_eq!(i["expression_targets"], serde_json::json!(keys), "{i}");
    // Key 1 (jawOpen: the chin drops by about 2 cm, the mouth opens) changes at least 1% of the
    // face's pixels by more than 16 levels (measured: about 9%).
    assert!(pair(0, 1) > 0.01 * face, "key 1 changed too little: {i}");
    // Blended out again, the same frame draws the same pixels as before (SwiftShader is
    // deterministic; measured: 0 changed); so does the heat map switched off.
    let same = face / 1000.0;
    assert!(
        pair(0, 4) <= same,
        "key 1 out did not restore the face: {i}"
    );
    assert!(
        pair(1, 3) <= same,
        "h off did not restore the lit face: {i}"
    );

    // The heat map: nearly every face pixel has a hue of ramp.wgsl's ramp (the pixel over its
    // largest channel within 0.1 of the ramp's; measured: 99%), none of the lit shots does (the
    // skin's hue is 0.3 or more off the ramp); most of the head is still (the cold fifth of the
    // ramp: measured 84%) and the open jaw is hot (the top fifth: measured 6.5%).
    let heat = shot(2, "drawn");
    assert!(shot(2, "on_ramp") >= 0.9 * heat, "{i}");
    for k in [0, 1, 3, 4] {
        assert!(
            shot(k, "on_ramp") <= 0.01 * shot(k, "drawn"),
            "shot {k}: {i}"
        );
    }
    let hist = |b: usize| i["shots"][2]["ramp_histogram"][b].as_f64().unwrap();
    assert!(hist(0) >= 0.5 * heat, "{i}");
    assert!(hist(4) >= 0.01 * heat, "no hot jaw: {i}");
    assert!(pair(2, 3) > 0.5 * face, "{i}");
    // The legend's bar is the ramp, pixel for pixel, to within two 8-bit levels (the page and
    // the check encode the same linear colours; measured: 0).
    let bar = &i["bar"];
    assert_eq!(bar["samples"], 200, "{i}");
    assert!(bar["max_diff"].as_f64().unwrap() <= 2.0, "legend: {bar}");
    // Its scale: mimic view's default, 5% of the rest mesh's bounding-box diagonal, in cm (the
    // rig's units); the page measured the GLB's vertices in metres, so f32 rounding only.
    let rig = mimic_assets::load_rig(&repo().join("configs/rigs/ict-face.toml")).unwrap();
    assert_eq!(rig.units, "cm");
    let (lo, hi) = rig.mesh.bounds().unwrap();
    let want = 0.05 * f64::from((hi - lo).length());
    let legend = &i["legend"];
    let full: f64 = legend["fullScale"].as_str().unwrap().parse().unwrap();
    let full_cm: f64 = legend["fullScaleCm"].as_str().unwrap().parse().unwrap();
    assert!((full - want).abs() <= 1e-5 * want, "{full} vs {want}");
    assert!((full_cm - want).abs() <= 1e-5 * want, "{full_cm} vs {want}");
    assert!(
        legend["text"].as_str().unwrap().contains("(cm)"),
        "{legend}"
    );

    // The drag turned the view: a 100 px drag at OrbitControls' default speed turns it by
    // 2 pi 100 / 480 = 75 degrees, so most face pixels change and the face's box moves by more
    // than 2.5% of the width (measured: 84% and 41 px; 24 px on a loaded machine, where
    // Chromium coalesces the drag's moves into fewer, so it turns less); `r` brings the framing
    // back exactly.
    assert!(pair(4, 5) > 0.3 * face, "the drag turned nothing: {i}");
    let (b4, b5) = (&i["shots"][4]["bbox"], &i["shots"][5]["bbox"]);
    let moved = (0..4)
        .map(|k| (b4[k].as_f64().unwrap() - b5[k].as_f64().unwrap()).abs())
        .fold(0.0, f64::max);
    assert!(moved > 0.025 * pixels.sqrt(), "{b4} vs {b5}");
    assert!(pair(0, 6) <= same, "r did not reset the view: {i}");
}

#[test]
fn http_routes_serve_the_page_the_glb_and_want_the_token() {
    let serve = WebServe::start(&["--token", "s3cret/+"]);
    let q = "?token=s3cret%2F%2B";
    let _send = Sender::start(
        "recordings/a_yn_question.kinect121.jsonl",
        &serve.tcp,
        "tok",
        &["--loop", "--token", "s3cret/+"],
    );
    wait_live(&serve, "tok", q);
    // Without the token (or with another) every route but /static/ answers 401.
    for path in [
        "/",
        "/sessions",
        "/view/tok",
        "/rig/tok.glb",
        "/stats",
        "/ws/tok",
    ] {
        assert_eq!(serve.get(path).0, 401, "{path}");
        assert_eq!(serve.get(&format!("{path}?token=s3cret")).0, 401, "{path}");
    }
    let (status, page) = serve.get(&format!("/view/tok{q}"));
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&page).contains("/static/view.js"));
    let (status, js) = serve.get("/static/three/three.core.js");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&js[..200]).contains("Three.js Authors"));
    // The GLB: glTF 2.0's binary container, 150 morph targets (38 controls and 12 rigid-part
    // columns, the jaw and both eyeballs, x 3 axes), then the number keys' targets: the rig's
    // first nine `[[morph_targets]]` (ict-face has eight).
    let (status, glb) = serve.get(&format!("/rig/tok.glb{q}"));
    assert_eq!(status, 200);
    assert_eq!(&glb[..4], b"glTF");
    let total = u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize;
    assert_eq!(total, glb.len());
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let gltf: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let names = gltf["meshes"][0]["extras"]["targetNames"]
        .as_array()
        .unwrap();
    let keys = rig_target_names("ict-face");
    let columns = 3 * (38 + 12);
    assert_eq!(names.len(), columns + keys.len().min(9));
    for (j, name) in names[..columns].iter().enumerate() {
        let axis = ["x", "y", "z"][j % 3];
        assert!(name.as_str().unwrap().ends_with(axis), "{j}: {name}");
    }
    assert!(names[3 * 38].as_str().unwrap().starts_with("jaw."));
    for (name, key) in names[columns..].iter().zip(&keys) {
        assert_eq!(name, key);
    }
    // Positions only, as the basis columns (a NORMAL on some targets would make three.js take
    // the rest normal as the others' normal delta).
    for prim in gltf["meshes"][0]["primitives"].as_array().unwrap() {
        let targets = prim["targets"].as_array().unwrap();
        assert_eq!(targets.len(), names.len());
        assert!(targets.iter().all(|t| t.get("NORMAL").is_none()), "{prim}");
    }
    assert_eq!(serve.get(&format!("/rig/nosuch.glb{q}")).0, 404);
    // The WebSocket handshake with the token switches protocols.
    let upgrade = |path: &str| {
        http_request(
            &serve.http,
            &format!(
                "GET {path} HTTP/1.1\r\nHost: {}\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n\
                 Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n",
                serve.http
            ),
        )
        .0
    };
    assert_eq!(upgrade(&format!("/ws/tok{q}")), 101);
    assert_eq!(upgrade("/ws/tok?token=wrong"), 401);
}

#[test]
fn http_beyond_loopback_needs_a_token() {
    let o = mimic(&["serve", "--rig", "ict-face", "--http", "0.0.0.0:0"]);
    assert!(!o.status.success());
    let (_, err) = text(&o);
    assert!(err.contains("HTTP") && err.contains("--token"), "{err}");
}
