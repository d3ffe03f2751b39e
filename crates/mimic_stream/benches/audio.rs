//! CPU cost of live audio sessions (issue 42 item 3; docs/audio.md "Live"): N audio sessions on
//! the ICT rig, each fed speech-like audio (a 120 Hz buzz in syllables of 150-300 ms with 100-400
//! ms silences and a hiss now and then, 16-bit mono at `MIMIC_AUDIO_RATE`, default 22,050 Hz) in
//! 20 ms chunks at the real-time pace, one d-only viewer each, everything over 127.0.0.1 in this
//! process; then the same chunks through the parser and the lip sync alone on one thread.
//!
//! `cargo bench -p mimic_stream --bench audio` runs 20 sessions for 10 s (`MIMIC_AUDIO_SESSIONS`,
//! `MIMIC_AUDIO_SECS`); without `--bench` (as `cargo test --benches` runs it) 2 sessions for 1 s.
//! It prints the process CPU per second of audio per session (server, senders and viewers
//! together, so an upper bound), the chunk-arrival-to-broadcast latency (p50, p99, max) and the
//! single-thread cost of parsing and lip-syncing a second of audio.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use mimic_assets::{ConfigDirs, load_morph_targets, load_rig};
use mimic_audio::live::LiveLipSync;
use mimic_audio::visemes::VisemeTable;
use mimic_stream::wire::{
    AudioFormat, KIND_END, KIND_FRAME, encode_audio_chunk, parse_audio_chunk,
};
use mimic_stream::{Catalog, RigEntry, Server, ServerSettings};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// User + system CPU seconds of this process so far (Linux /proc; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let after = stat.rsplit(')').next().unwrap_or_default();
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

/// `secs` of speech-like audio at `rate` (deterministic).
fn speechlike(rate: u32, secs: f64) -> Vec<f32> {
    let n = (secs * f64::from(rate)) as usize;
    let mut out = Vec::with_capacity(n);
    let mut lcg = 7u32;
    let mut rnd = || {
        lcg = lcg.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (lcg >> 8) as f32 / (1u32 << 24) as f32
    };
    while out.len() < n {
        let syllable = ((0.15 + 0.15 * rnd()) * rate as f32) as usize;
        let hiss = rnd() < 0.25;
        for i in 0..syllable {
            let t = i as f32 / rate as f32;
            let env = (std::f32::consts::PI * i as f32 / syllable as f32).sin();
            let x = if hiss {
                (rnd() - 0.5) * 0.4
            } else {
                (1..=12)
                    .map(|h| (std::f32::consts::TAU * 120.0 * h as f32 * t).sin() / h as f32)
                    .sum::<f32>()
                    * 0.15
            };
            out.push(env * x);
        }
        let quiet = ((0.1 + 0.3 * rnd()) * rate as f32) as usize;
        out.extend(std::iter::repeat_n(0.0, quiet));
    }
    out.truncate(n);
    out
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let sessions: usize = if full {
        env_or("MIMIC_AUDIO_SESSIONS", 20)
    } else {
        2
    };
    let secs: f64 = if full {
        env_or("MIMIC_AUDIO_SECS", 10.0)
    } else {
        1.0
    };
    let rate: u32 = env_or("MIMIC_AUDIO_RATE", 22_050);
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dirs = ConfigDirs::locate(Some(&repo.join("configs")));
    let path = dirs.rig_path("ict-face");
    let rig = load_rig(&path).expect("ict-face rig");
    let targets = load_morph_targets(&path, &rig).expect("morph targets");
    let basis = mimic_solve::build_basis(&rig, &rig.solver).expect("basis");
    let entry = RigEntry::new(rig, basis)
        .expect("rig entry")
        .with_morph_targets(targets)
        .expect("targets");
    let settings = ServerSettings {
        max_sessions: sessions + 8,
        max_viewers: sessions + 8,
        // Every tracker and viewer comes from 127.0.0.1.
        max_connections_per_peer: 2 * sessions + 8,
        ..ServerSettings::default()
    };
    let server = Server::new(Arc::new(Catalog::new(entry)), settings);
    let audio = Arc::new(speechlike(rate, secs));
    let chunk = rate as usize / 50;
    let lines: Arc<Vec<String>> = Arc::new(
        audio
            .chunks(chunk)
            .enumerate()
            .map(|(k, c)| encode_audio_chunk((k * chunk) as i64 * 1_000_000 / i64::from(rate), c))
            .collect(),
    );
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let srv = server.clone();
    let sent = lines.clone();
    let (cpu, wall, received) = runtime.block_on(async move {
        let lines = sent;
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
        let addr = listener.local_addr().expect("addr");
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let serving = tokio::spawn(async move {
            srv.run(listener, None, async {
                let _ = stop_rx.await;
            })
            .await
        });
        let received = Arc::new(AtomicU64::new(0));
        let mut viewers = Vec::new();
        for i in 0..sessions {
            let mut s = TcpStream::connect(addr).await.expect("viewer");
            let hello = format!("{{\"type\":\"viewer\",\"session\":\"a{i}\"}}\n");
            s.write_all(hello.as_bytes()).await.expect("viewer hello");
            let received = received.clone();
            viewers.push(tokio::spawn(async move {
                let mut buf = Vec::new();
                loop {
                    let mut len = [0u8; 4];
                    if s.read_exact(&mut len).await.is_err() {
                        break;
                    }
                    buf.resize(u32::from_le_bytes(len) as usize, 0);
                    if s.read_exact(&mut buf).await.is_err() {
                        break;
                    }
                    match buf.first() {
                        Some(&KIND_FRAME) => {
                            received.fetch_add(1, Ordering::Relaxed);
                        }
                        Some(&KIND_END) => break,
                        _ => {}
                    }
                }
            }));
        }
        let (cpu0, t0) = (cpu_seconds(), Instant::now());
        let mut senders = Vec::new();
        for i in 0..sessions {
            let lines = lines.clone();
            let offset = Duration::from_millis(20).mul_f64(i as f64 / sessions as f64);
            senders.push(tokio::spawn(async move {
                tokio::time::sleep(offset).await;
                let mut s = TcpStream::connect(addr).await.expect("tracker");
                s.set_nodelay(true).expect("nodelay");
                let hello =
                    format!("{{\"mode\":\"audio\",\"session\":\"a{i}\",\"sample_rate\":{rate}}}\n");
                s.write_all(hello.as_bytes()).await.expect("hello");
                let mut tick = tokio::time::interval(Duration::from_millis(20));
                for l in lines.iter() {
                    tick.tick().await;
                    s.write_all(l.as_bytes()).await.expect("chunk");
                }
                let _ = s.shutdown().await;
            }));
        }
        for s in senders {
            s.await.expect("sender");
        }
        for v in viewers {
            let _ = v.await;
        }
        let (cpu, wall) = (cpu_seconds() - cpu0, t0.elapsed().as_secs_f64());
        let _ = stop_tx.send(());
        serving.await.expect("server");
        (cpu, wall, received.load(Ordering::Relaxed))
    });
    let st = server.stats();
    let audio_s = audio.len() as f64 / f64::from(rate);
    println!(
        "audio: {sessions} sessions x {audio_s:.1} s of {rate} Hz speech-like audio in 20 ms chunks, paced, on ict-face (one d-only viewer each); {wall:.1} s"
    );
    println!(
        "  frames broadcast {} (viewers got {received}, expected {}), late {}, malformed {}",
        st.sessions.iter().map(|s| s.frames).sum::<u64>(),
        sessions as u64 * (audio_s * 60.0).floor() as u64,
        st.sessions.iter().map(|s| s.late).sum::<u64>(),
        st.sessions.iter().map(|s| s.malformed).sum::<u64>()
    );
    println!(
        "  chunk arrival -> broadcast: p50 {} us, p99 {} us, max {} us",
        st.latency.p50_us, st.latency.p99_us, st.latency.max_us
    );
    println!(
        "  process CPU: {:.1} ms per second of audio per session ({:.2} % of a core each; server, senders and viewers together)",
        cpu / (sessions as f64 * audio_s) * 1e3,
        cpu / (sessions as f64 * audio_s) * 100.0
    );
    // The per-session audio work alone, one thread: parse (JSON, base64, mix-down) + lip sync.
    let table = VisemeTable::shipped().unwrap();
    let format = AudioFormat {
        sample_rate: rate,
        channels: 1,
    };
    let (mut scratch, mut mono) = (Vec::new(), Vec::new());
    let reps = if full { 20 } else { 1 };
    let t = Instant::now();
    let mut frames = 0u64;
    for _ in 0..reps {
        let mut live = LiveLipSync::new(rate, &table).unwrap();
        for l in lines.iter() {
            parse_audio_chunk(l.trim_end().as_bytes(), format, &mut scratch, &mut mono).unwrap();
            live.push(&mono, |_, _| frames += 1);
        }
    }
    let per_s = t.elapsed().as_secs_f64() / (reps as f64 * audio_s);
    println!(
        "  one thread, parse + lip sync: {:.0} us per second of audio ({frames} frames)",
        per_s * 1e6
    );
}
