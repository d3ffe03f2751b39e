//! `mimic send`: a tracker simulator that replays a recording (or a CSV of named blendshape
//! weights, as a weights session) into `mimic serve` over TCP; the sending is
//! `mimic_stream::send`, this command parses the arguments and prints what was sent.

use anyhow::Context;
use mimic_stream::send::{
    DEFAULT_SUBJECT, SendOptions, TakeSender, TcpSent, recording_bye, send_audio, send_openseeface,
    send_recording, send_take_udp, send_weights, weights_bye,
};
use mimic_types::parse::parse_factor;
use serde_json::Value;
use std::path::PathBuf;

/// Arguments of `mimic send`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (v1 JSON Lines) to send.
    #[arg(required_unless_present_any = ["weights", "audio"], conflicts_with_all = ["weights", "audio"])]
    pub recording: Option<PathBuf>,
    /// Send speech (a WAV) as an audio session: paced 20 ms chunks the server lip-syncs live.
    #[arg(long, conflicts_with_all = ["weights", "openseeface"])]
    pub audio: Option<PathBuf>,
    /// Send named weights instead, as a weights session: a CSV with a header of names (e.g.
    /// `replay --mode blendshapes --weights` output or an ARKit export); a `t_us` column gives
    /// the times, else frames are `1/--rate` apart. `frame`, `status`, `label`, `timecode` and
    /// `blendshapecount` columns are not sent.
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Send the recording (an `openseeface68` one, e.g. from `mimic import openseeface`) as
    /// OpenSeeFace UDP datagrams to this address (a `mimic serve --openseeface` port), at its
    /// pace, instead of to `--to`.
    #[arg(long, value_name = "ADDR", conflicts_with = "weights")]
    pub openseeface: Option<std::net::SocketAddr>,
    /// Send a Live Link Face take (`--weights TAKE.csv`) as the app's UDP packets to this
    /// address (a `mimic serve --livelink` port), at the take's pace, instead of to `--to`; the
    /// subject name is `--session` (default `mimic-send`).
    #[arg(long, value_name = "ADDR", requires = "weights")]
    pub livelink: Option<std::net::SocketAddr>,
    /// Name map for a Live Link Face take's names (default: configs/namemaps/arkit.toml).
    #[arg(long, value_name = "TOML")]
    pub namemap: Option<PathBuf>,
    /// Frame rate of a weights CSV without a `t_us` column.
    #[arg(long, default_value_t = 60.0, value_parser = parse_factor)]
    pub rate: f64,
    /// Server address (host:port of `mimic serve`).
    #[arg(long, default_value = mimic_stream::DEFAULT_LISTEN)]
    pub to: String,
    /// Session name to open (default: the server makes one up).
    #[arg(long)]
    pub session: Option<String>,
    /// Token of a server started with one (default: the MIMIC_TOKEN environment variable).
    #[arg(long)]
    pub token: Option<String>,
    /// Rig the session drives (default: the server's).
    #[arg(long)]
    pub rig: Option<String>,
    /// Speed factor of the recorded pace (2 is twice as fast).
    #[arg(long, default_value_t = 1.0, value_parser = parse_factor)]
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
    /// Ask the server to forward this session's frames too (`vmc:HOST:PORT` or
    /// `livelink:HOST:PORT`; a loopback address unless the server's `--forward-allow` lists it):
    /// the hello's `"forward"` (docs/protocol.md).
    #[arg(long, value_name = "KIND:ADDR")]
    pub forward: Option<mimic_stream::forward::ForwardTarget>,
}

/// Exit status of `mimic send` when the server ended the session (its `bye`, e.g. `shutdown`,
/// is printed) before everything was sent.
pub const EXIT_SERVER_ENDED: u8 = 3;

/// Runs `mimic send`.
pub fn run(args: Args) -> anyhow::Result<()> {
    mimic_stream::send::ignore_sigpipe();
    let o = SendOptions {
        to: args.to.clone(),
        session: args.session.clone(),
        token: mimic_stream::token_or_env(args.token.as_deref()),
        rig: args.rig.clone(),
        forward: args.forward,
        rate: args.rate,
        speed: args.speed,
        fast: args.fast,
        looping: args.looping,
        max_frames: args.max_frames,
        on_reply: |line| eprintln!("server: {line}"),
    };
    if let Some(wav) = &args.audio {
        return report(send_audio(wav, &o)?, "audio chunks", &o.to, weights_bye);
    }
    match &args.weights {
        None => recording(&args, &o),
        Some(csv) if !mimic_trackers::take::is_take_file(csv)? => {
            anyhow::ensure!(
                args.livelink.is_none(),
                "{}: --livelink sends Live Link Face takes (a `Timecode` and `BlendShapeCount` header)",
                csv.display()
            );
            let r = send_weights(csv, &o)?;
            report(r, "weight frames", &o.to, weights_bye)
        }
        Some(csv) => take(&args, csv, &o),
    }
}

/// A recording, over TCP or as OpenSeeFace datagrams.
fn recording(args: &Args, o: &SendOptions) -> anyhow::Result<()> {
    let recording = args.recording.clone().context("no recording given")?;
    let Some(addr) = args.openseeface else {
        let r = send_recording(&recording, o)?;
        return report(r, "frames", &o.to, recording_bye);
    };
    let u = send_openseeface(&recording, addr, o)?;
    println!(
        "{}",
        u.said("OpenSeeFace datagrams", addr, "recording", args.speed)
    );
    Ok(())
}

/// A Live Link Face take, as a weights session or as the app's UDP packets.
fn take(args: &Args, csv: &std::path::Path, o: &SendOptions) -> anyhow::Result<()> {
    if let Some(addr) = args.livelink {
        let u = send_take_udp(csv, addr, o)?;
        let subject = args.session.as_deref().unwrap_or(DEFAULT_SUBJECT);
        let what = format!("Live Link packets (subject `{subject}`)");
        println!("{}", u.said(&what, addr, "take", args.speed));
        return Ok(());
    }
    let take = TakeSender::open(csv, args.namemap.as_deref(), o)?;
    if let Some(line) = take.lacking_line() {
        println!("{line}");
    }
    let t = take.send()?;
    println!("{}", t.said(csv));
    if let Some(b) = &t.tcp.bye {
        println!("server: {}", weights_bye(b));
    }
    ended_early(t.tcp)
}

/// Prints what a TCP session's send did (`server` words its `bye`), then [`ended_early`].
fn report(r: TcpSent, frames: &str, to: &str, server: fn(&Value) -> String) -> anyhow::Result<()> {
    if let Some(line) = r.said(frames, to, server) {
        println!("{line}");
    }
    ended_early(r)
}

/// After the sending stopped: a write error after the server's `bye` came is reported as that
/// `bye` (its reason, exit status [`EXIT_SERVER_ENDED`]); one without a `bye` as itself.
fn ended_early(r: TcpSent) -> anyhow::Result<()> {
    match (r.write_failed, r.bye) {
        (None, _) => Ok(()),
        (Some(_), Some(b)) => {
            let reason = b["reason"].as_str().unwrap_or("unknown");
            eprintln!(
                "error: the server ended the session ({reason}) while frames were still being sent"
            );
            std::process::exit(i32::from(EXIT_SERVER_ENDED));
        }
        (Some(e), None) => Err(e.into()),
    }
}
