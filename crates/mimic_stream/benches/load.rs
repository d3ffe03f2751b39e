//! Load benchmark of the live service: N simulated trackers at 60 frames/s on the ICT rig, one
//! d-only viewer each, everything over 127.0.0.1 in this process.
//!
//! `cargo bench -p mimic_stream --bench load` runs 100 sessions for 10 s after a warm-up
//! (`MIMIC_LOAD_SESSIONS`, `MIMIC_LOAD_SECS`, `MIMIC_LOAD_WORKERS` (default 2),
//! `MIMIC_LOAD_POSITIONS=1` for viewers that take full positions); without `--bench` (as `cargo
//! test --benches` runs it) it smoke-runs 2 sessions for 1 s. It prints the server's
//! arrival-to-broadcast latency (p50, p99, max) over the measured window, the frames dropped
//! anywhere, and the process CPU time. Not a criterion bench: the quantity is a latency
//! distribution under a fixed offered load, not the time of one call.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use mimic_assets::{ConfigDirs, load_rig};
use mimic_stream::wire::{KIND_END, KIND_FRAME};
use mimic_stream::{Catalog, RigEntry, Server, ServerSettings};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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
    // Fields after the command name (which is in parentheses): utime is the 12th, stime the 13th.
    let after = stat.rsplit(')').next().unwrap_or_default();
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let sessions: usize = if full {
        env_or("MIMIC_LOAD_SESSIONS", 100)
    } else {
        2
    };
    let secs: f64 = if full {
        env_or("MIMIC_LOAD_SECS", 10.0)
    } else {
        1.0
    };
    let workers: usize = env_or("MIMIC_LOAD_WORKERS", 2);
    let positions = env_or("MIMIC_LOAD_POSITIONS", 0) == 1;
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dirs = ConfigDirs::locate(Some(&repo.join("configs")));
    let rig = load_rig(&dirs.rig_path("ict-face")).expect("ict-face rig");
    let basis = mimic_solve::build_basis(&rig, &rig.solver).expect("basis");
    let mut catalog = Catalog::new(RigEntry::new(rig, basis).expect("rig entry"));
    catalog.add_layout(
        dirs.load_layout_named("kinect-gfe100")
            .expect("kinect-gfe100"),
    );
    // Frame lines of a real recording, re-timed to 60 frames/s as they are sent.
    let text =
        std::fs::read_to_string(repo.join("recordings/a_affirmative.jsonl")).expect("recording");
    let mut lines = text.lines();
    let header: serde_json::Value =
        serde_json::from_str(lines.next().expect("header")).expect("header json");
    let bodies: Arc<Vec<String>> = Arc::new(
        lines
            .filter_map(|l| l.split_once(',').map(|(_, rest)| rest.to_string()))
            .collect(),
    );
    let settings = ServerSettings {
        max_sessions: sessions + 8,
        max_viewers: sessions + 8,
        ..ServerSettings::default()
    };
    let server = Server::new(Arc::new(catalog), settings);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(workers)
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async move {
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
        let addr = listener.local_addr().expect("addr");
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let srv = server.clone();
        let serving = tokio::spawn(async move {
            srv.run(listener, None, async {
                let _ = stop_rx.await;
            })
            .await
        });
        let received = Arc::new(AtomicU64::new(0));
        let gaps = Arc::new(AtomicU64::new(0));
        let mut viewers = Vec::new();
        for i in 0..sessions {
            let mut s = TcpStream::connect(addr).await.expect("viewer connect");
            let hello = format!(
                "{{\"type\":\"viewer\",\"session\":\"load{i}\",\"positions\":{positions}}}\n"
            );
            s.write_all(hello.as_bytes()).await.expect("viewer hello");
            let (received, gaps) = (received.clone(), gaps.clone());
            viewers.push(tokio::spawn(async move {
                let mut next_seq = 0u64;
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
                            let seq = u64::from_le_bytes(buf[1..9].try_into().expect("seq"));
                            if seq != next_seq {
                                gaps.fetch_add(seq - next_seq, Ordering::Relaxed);
                            }
                            next_seq = seq + 1;
                            received.fetch_add(1, Ordering::Relaxed);
                        }
                        Some(&KIND_END) => break,
                        _ => {}
                    }
                }
            }));
        }
        while server.stats().viewers_active < sessions as u64 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let running = Arc::new(AtomicBool::new(true));
        let mut trackers = Vec::new();
        let period = Duration::from_micros(16_667);
        for i in 0..sessions {
            let mut h = header.clone();
            h["session"] = serde_json::Value::from(format!("load{i}"));
            let (bodies, running) = (bodies.clone(), running.clone());
            // Starts spread over one frame period, so sessions do not all send at once.
            let offset = period.mul_f64(i as f64 / sessions as f64);
            trackers.push(tokio::spawn(async move {
                tokio::time::sleep(offset).await;
                let mut s = TcpStream::connect(addr).await.expect("tracker connect");
                s.set_nodelay(true).expect("nodelay");
                s.write_all(format!("{h}\n").as_bytes())
                    .await
                    .expect("tracker hello");
                let mut tick = tokio::time::interval(period);
                tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
                let mut k = 0usize;
                let mut line = String::new();
                while running.load(Ordering::Relaxed) {
                    tick.tick().await;
                    line.clear();
                    let t_us = k as u64 * 16_667;
                    line.push_str(&format!("{{\"t_us\":{t_us},"));
                    line.push_str(&bodies[k % bodies.len()]);
                    line.push('\n');
                    if s.write_all(line.as_bytes()).await.is_err() {
                        break;
                    }
                    k += 1;
                }
                let _ = s.shutdown().await;
                k
            }));
        }
        // Warm-up: every session past its neutral (5 frames and the source-to-target fit).
        let warm = Instant::now();
        loop {
            let st = server.stats();
            let ready = st.sessions.iter().filter(|s| s.tracked > 0).count();
            if ready >= sessions || warm.elapsed() > Duration::from_secs(120) {
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let warm_s = warm.elapsed().as_secs_f64();
        tokio::time::sleep(Duration::from_secs(1)).await;
        server.reset_latency();
        let before = server.stats();
        let (cpu0, t0) = (cpu_seconds(), Instant::now());
        tokio::time::sleep(Duration::from_secs_f64(secs)).await;
        let after = server.stats();
        let (cpu1, wall) = (cpu_seconds(), t0.elapsed().as_secs_f64());
        running.store(false, Ordering::Relaxed);
        let mut sent = 0;
        for t in trackers {
            sent += t.await.unwrap_or(0);
        }
        // Let the sessions read what the trackers sent before asking the server to stop.
        tokio::time::sleep(Duration::from_millis(300)).await;
        let _ = stop_tx.send(());
        let last = serving.await.expect("server");
        for v in viewers {
            let _ = v.await;
        }
        let frames = |s: &mimic_stream::ServerStats| s.sessions.iter().map(|x| x.frames).sum::<u64>();
        let sum = |f: fn(&mimic_stream::SessionSnapshot) -> u64| -> u64 { last.sessions.iter().map(f).sum() };
        let window_frames = frames(&after) - frames(&before);
        println!(
            "load: {sessions} sessions x 60 frames/s on ict-face ({} viewers, {workers} runtime workers), warm-up {warm_s:.1} s, measured {wall:.1} s",
            if positions { "positions" } else { "d-only" }
        );
        println!(
            "  frames retargeted in the window: {window_frames} ({:.0}/s, offered {:.0}/s)",
            window_frames as f64 / wall,
            sessions as f64 * 60.0
        );
        println!(
            "  arrival -> broadcast latency: p50 {} us, p99 {} us, max {} us ({} frames)",
            after.latency.p50_us, after.latency.p99_us, after.latency.max_us, after.latency.count
        );
        println!(
            "  in the window: late {}, viewer queue drops {}",
            after.sessions.iter().map(|s| s.late).sum::<u64>()
                - before.sessions.iter().map(|s| s.late).sum::<u64>(),
            after.viewer_frames_dropped - before.viewer_frames_dropped
        );
        println!(
            "  whole run (warm-up included): sent {sent}, retargeted {}, late {}, malformed {}, viewer queue drops {}, gaps seen by viewers {}, frames received by viewers {}",
            frames(&last),
            sum(|s| s.late),
            sum(|s| s.malformed),
            last.viewer_frames_dropped,
            gaps.load(Ordering::Relaxed),
            received.load(Ordering::Relaxed)
        );
        println!(
            "  process CPU in the window: {:.2} s per s of wall time (server, trackers and viewers together)",
            (cpu1 - cpu0) / wall
        );
    });
}
