//! `mimic send`: a tracker simulator that replays a recording into `mimic serve` over TCP.

use anyhow::Context;
use mimic_capture::{Pace, RecordedFrame, RecordingReader, RecordingWriter, Replay, ReplayOptions};
use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::net::{Shutdown, TcpStream};
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `mimic send`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (v1 JSON Lines) to send.
    pub recording: PathBuf,
    /// Server address (host:port of `mimic serve`).
    #[arg(long, default_value = mimic_stream::DEFAULT_LISTEN)]
    pub to: String,
    /// Session name to open (default: the server makes one up).
    #[arg(long)]
    pub session: Option<String>,
    /// Rig the session drives (default: the server's).
    #[arg(long)]
    pub rig: Option<String>,
    /// Speed factor of the recorded pace (2 is twice as fast).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Send as fast as the connection takes frames, ignoring the recorded pace.
    #[arg(long)]
    pub fast: bool,
    /// Start again from the beginning after the last frame (until interrupted).
    #[arg(long = "loop")]
    pub looping: bool,
    /// Stop after this many frames.
    #[arg(long)]
    pub max_frames: Option<usize>,
}

/// Runs `mimic send`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut header = RecordingReader::open(&args.recording, None)?
        .header()
        .clone();
    if let Some(s) = &args.session {
        header
            .extra
            .insert("session".into(), Value::from(s.as_str()));
    }
    if let Some(r) = &args.rig {
        header.extra.insert("rig".into(), Value::from(r.as_str()));
    }
    let stream =
        TcpStream::connect(&args.to).with_context(|| format!("connecting to {}", args.to))?;
    stream.set_nodelay(true)?;
    let replies = stream.try_clone()?;
    // Replies (welcome, errors, bye) are read on their own thread and reported on stderr.
    let reader = std::thread::spawn(move || {
        let mut bye = None;
        for line in BufReader::new(replies).lines() {
            let Ok(line) = line else { break };
            let v: Value = serde_json::from_str(&line).unwrap_or(Value::Null);
            match v["type"].as_str() {
                Some("welcome") => tracing::info!("{line}"),
                Some("bye") => bye = Some(v),
                _ => eprintln!("server: {line}"),
            }
        }
        bye
    });
    let mut writer = RecordingWriter::new(&stream, &header)?.flush_each_frame(true);
    let options = ReplayOptions {
        pace: if args.fast {
            Pace::AsFastAsPossible
        } else {
            Pace::Recorded { speed: args.speed }
        },
        looping: args.looping,
        ..ReplayOptions::default()
    };
    let mut replay = Replay::open(&args.recording, None, options)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let mut sent = 0usize;
    let result = runtime.block_on(async {
        while let Some(item) = replay.next().await {
            let f = item?;
            writer
                .write(&RecordedFrame {
                    frame: f.frame,
                    label: f.label,
                })
                .context("sending a frame")?;
            sent += 1;
            if args.max_frames.is_some_and(|m| sent >= m) {
                break;
            }
        }
        anyhow::Ok(())
    });
    let _ = stream.shutdown(Shutdown::Write);
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let bye = reader.join().ok().flatten();
    result?;
    match bye {
        Some(b) => println!(
            "sent {sent} frames to {}; server: {} frames retargeted, {} late, {} malformed ({})",
            args.to, b["frames"], b["late"], b["malformed"], b["reason"]
        ),
        None => println!(
            "sent {sent} frames to {}; no reply from the server",
            args.to
        ),
    }
    Ok(())
}
