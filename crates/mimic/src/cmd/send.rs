//! `mimic send`: a tracker simulator that replays a recording (or a CSV of named blendshape
//! weights, as a weights session) into `mimic serve` over TCP.

use anyhow::Context;
use mimic_capture::{
    FileSource, Pace, RecordedFrame, RecordingReader, RecordingWriter, Replay, ReplayOptions,
};
use mimic_stream::pace::Pacer;
use serde_json::Value;
use std::io::{BufRead, BufReader, Read};
use std::net::{Shutdown, TcpStream};
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `mimic send`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (v1 JSON Lines) to send.
    #[arg(required_unless_present = "weights", conflicts_with = "weights")]
    pub recording: Option<PathBuf>,
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
    #[arg(long, default_value_t = 60.0, value_parser = parse_rate)]
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
    #[arg(long, default_value_t = 1.0, value_parser = parse_speed)]
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

/// Longest reply line read from the server (its replies are short JSON lines); a longer one is
/// reported and the replies are no longer read.
const MAX_REPLY_BYTES: usize = 64 * 1024;

/// Exit status of `mimic send` when the server ended the session (its `bye`, e.g. `shutdown`,
/// is printed) before everything was sent.
pub const EXIT_SERVER_ENDED: u8 = 3;

/// Parses a positive factor or rate in [1e-3, 1e6].
fn parse_factor(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number"))?;
    if !(1e-3..=1e6).contains(&v) {
        return Err(format!("{text} is out of range: 0.001 to 1000000"));
    }
    Ok(v)
}

/// `--speed`: a factor in [1e-3, 1e6].
fn parse_speed(text: &str) -> Result<f64, String> {
    parse_factor(text)
}

/// `--rate`: frames per second in [1e-3, 1e6].
fn parse_rate(text: &str) -> Result<f64, String> {
    parse_factor(text)
}

/// Runs `mimic send`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Socket writes after the server closed must come back as errors (to report its `bye`),
    // not kill the process: main restores SIGPIPE's default for stdout pipes.
    #[cfg(unix)]
    // SAFETY: setting a signal disposition before this command starts any thread.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
    if let Some(csv) = &args.weights {
        if is_live_link_take(csv)? {
            if let Some(addr) = args.livelink {
                return send_take_udp(&args, csv, addr);
            }
            return send_take(&args, csv);
        }
        anyhow::ensure!(
            args.livelink.is_none(),
            "{}: --livelink sends Live Link Face takes (a `Timecode` and `BlendShapeCount` header)",
            csv.display()
        );
        return send_weights(&args, csv);
    }
    let recording = args.recording.clone().context("no recording given")?;
    if let Some(addr) = args.openseeface {
        return send_openseeface(&args, &recording, addr);
    }
    let recording_reader = RecordingReader::open(&recording, None)?;
    let mut header = recording_reader.header().clone();
    if let Some(s) = &args.session {
        header
            .extra
            .insert("session".into(), Value::from(s.as_str()));
    }
    if let Some(r) = &args.rig {
        header.extra.insert("rig".into(), Value::from(r.as_str()));
    }
    if let Some(f) = &args.forward {
        header
            .extra
            .insert("forward".into(), Value::from(f.to_string()));
    }
    if let Some(t) = crate::cmd::setup::token_or_env(args.token.as_deref()) {
        header.extra.insert("token".into(), Value::from(t));
    }
    let (stream, reader) = connect(&args.to, None)?;
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
    let mut replay = Replay::new(FileSource::from_reader(recording_reader), options)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let mut sent = 0usize;
    let mut write_failed = None;
    let result = runtime.block_on(async {
        while let Some(item) = replay.next().await {
            let f = item?;
            if let Err(e) = writer.write(&RecordedFrame {
                frame: f.frame,
                label: f.label,
            }) {
                write_failed = Some(anyhow::Error::from(e).context("sending a frame"));
                break;
            }
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
    match &bye {
        Some(b) => println!(
            "sent {sent} frames to {}; server: {} frames retargeted, {} late, {} malformed ({})",
            args.to, b["frames"], b["late"], b["malformed"], b["reason"]
        ),
        None if write_failed.is_none() => println!(
            "sent {sent} frames to {}; no reply from the server",
            args.to
        ),
        None => {}
    }
    ended_early(write_failed, bye.as_ref())
}

/// `mimic send --openseeface`: the recording's frames as OpenSeeFace datagrams (face 0 of a
/// 640 x 480 image), each sent when its time comes.
fn send_openseeface(
    args: &Args,
    recording: &std::path::Path,
    addr: std::net::SocketAddr,
) -> anyhow::Result<()> {
    use mimic_trackers::openseeface::encode_packet;
    use mimic_trackers::osf_frames::{LAYOUT, to_face};
    let rec = mimic_capture::read_recording(recording, None)?;
    anyhow::ensure!(
        rec.header.layout == LAYOUT,
        "{}: layout `{}`; --openseeface sends `{LAYOUT}` recordings (mimic import openseeface)",
        recording.display(),
        rec.header.layout
    );
    let bind = if addr.ip().is_loopback() {
        "127.0.0.1:0"
    } else {
        "0.0.0.0:0"
    };
    let socket = std::net::UdpSocket::bind(bind).context("binding a UDP socket")?;
    let first_t = rec.frames.first().map_or(0, |f| f.frame.timestamp_us);
    let pace = Pacer::new(args.speed, args.fast);
    let mut sent = 0usize;
    for f in &rec.frames {
        pace.wait(f.frame.timestamp_us - first_t);
        let packet = encode_packet(&[to_face(&f.frame, 0, 640.0, 480.0)]);
        socket
            .send_to(&packet, addr)
            .with_context(|| format!("sending datagram {sent} to {addr}"))?;
        sent += 1;
        if args.max_frames.is_some_and(|m| sent >= m) {
            break;
        }
    }
    let span = rec
        .frames
        .last()
        .map_or(0, |f| f.frame.timestamp_us - first_t);
    println!(
        "sent {sent} OpenSeeFace datagrams to {addr} in {:.3} s (recording {:.3} s, speed {})",
        pace.elapsed_s(),
        span as f64 * 1e-6,
        args.speed
    );
    Ok(())
}

/// After the sending stopped: a write error after the server's `bye` came is reported as that
/// `bye` (its reason, exit status [`EXIT_SERVER_ENDED`]); one without a `bye` as itself.
fn ended_early(write_failed: Option<anyhow::Error>, bye: Option<&Value>) -> anyhow::Result<()> {
    match (write_failed, bye) {
        (None, _) => Ok(()),
        (Some(_), Some(b)) => {
            let reason = b["reason"].as_str().unwrap_or("unknown");
            eprintln!(
                "error: the server ended the session ({reason}) while frames were still being sent"
            );
            std::process::exit(i32::from(EXIT_SERVER_ENDED));
        }
        (Some(e), None) => Err(e),
    }
}

/// Columns of a weights CSV that are not weights.
const NOT_WEIGHTS: [&str; 6] = [
    "frame",
    "t_us",
    "status",
    "label",
    "timecode",
    "blendshapecount",
];

/// The weight frames of a weights CSV: each row's time and its `weights` object.
type WeightRows = Vec<(i64, serde_json::Map<String, Value>)>;

/// Weight frames (`t_us` and the `weights` object of a frame line) of a weights CSV.
fn weight_lines(csv: &std::path::Path, rate: f64) -> anyhow::Result<WeightRows> {
    let table = mimic_capture::named_csv::read_named_csv(csv)?;
    let header: Vec<&str> = table.header.iter().map(String::as_str).collect();
    let time_col = header.iter().position(|h| h.eq_ignore_ascii_case("t_us"));
    let sent: Vec<usize> = (0..header.len())
        .filter(|&c| {
            !NOT_WEIGHTS
                .iter()
                .any(|n| header[c].eq_ignore_ascii_case(n))
        })
        .collect();
    anyhow::ensure!(!sent.is_empty(), "{}: no weight columns", csv.display());
    anyhow::ensure!(rate > 0.0 && rate.is_finite(), "--rate must be positive");
    let mut out = Vec::new();
    for row in &table.rows {
        let at = |c: usize| row.field(c);
        let t_us = match time_col {
            Some(c) => at(c).parse::<i64>().with_context(|| {
                format!(
                    "{}:{}: `t_us` `{}` is not an integer",
                    csv.display(),
                    row.line,
                    at(c)
                )
            })?,
            None => (out.len() as f64 * 1e6 / rate).round() as i64,
        };
        let mut weights = serde_json::Map::new();
        for &c in &sent {
            let v: f64 = at(c)
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .with_context(|| {
                    format!(
                        "{}:{}: column `{}`: `{}` is not a number",
                        csv.display(),
                        row.line,
                        header[c],
                        at(c)
                    )
                })?;
            weights.insert(header[c].to_string(), Value::from(v));
        }
        out.push((t_us, weights));
    }
    Ok(out)
}

/// `mimic send --weights`: a weights session fed from a CSV.
fn send_weights(args: &Args, csv: &std::path::Path) -> anyhow::Result<()> {
    use std::io::Write;
    let lines = weight_lines(csv, args.rate)?;
    let mut hello =
        serde_json::json!({"mode": "weights", "source": "mimic send", "rate_hz": args.rate});
    if let Some(s) = &args.session {
        hello["session"] = Value::from(s.as_str());
    }
    if let Some(r) = &args.rig {
        hello["rig"] = Value::from(r.as_str());
    }
    if let Some(f) = &args.forward {
        hello["forward"] = Value::from(f.to_string());
    }
    if let Some(t) = crate::cmd::setup::token_or_env(args.token.as_deref()) {
        hello["token"] = Value::from(t);
    }
    let (mut stream, reader) = connect(&args.to, None)?;
    stream.write_all(format!("{hello}\n").as_bytes())?;
    let pace = Pacer::new(args.speed, args.fast);
    let first_t = lines.first().map_or(0, |(t, _)| *t);
    let last_t = lines.last().map_or(0, |(t, _)| *t);
    // `--loop` shifts each pass by one frame interval: the mean of the CSV's, else 1 / --rate.
    let gap = if lines.len() >= 2 {
        ((last_t - first_t) / (lines.len() as i64 - 1)).max(1)
    } else {
        (1e6 / args.rate).round().max(1.0) as i64
    };
    let (sent, _, write_failed) =
        send_weight_frames(&mut stream, &pace, args, &lines, first_t, gap);
    let _ = stream.shutdown(Shutdown::Write);
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let bye = reader.join().ok().flatten();
    match &bye {
        Some(b) => println!(
            "sent {sent} weight frames to {}; server: {} frames, {} late, {} malformed, {} unknown weight names ({})",
            args.to, b["frames"], b["late"], b["malformed"], b["unknown_weights"], b["reason"]
        ),
        None if write_failed.is_none() => println!(
            "sent {sent} weight frames to {}; no reply from the server",
            args.to
        ),
        None => {}
    }
    ended_early(write_failed, bye.as_ref())
}

/// Sends weight frames (`t_us`, `weights`) paced from `origin_us`, again and again under
/// `--loop` (each pass's times shifted past the previous pass by `gap_us`, so none is late),
/// up to `--max-frames`; returns the frames sent, the last frame's due time (s) and the write
/// error that stopped it, if any.
fn send_weight_frames(
    stream: &mut TcpStream,
    pace: &Pacer,
    args: &Args,
    frames: &[(i64, serde_json::Map<String, Value>)],
    origin_us: i64,
    gap_us: i64,
) -> (usize, f64, Option<anyhow::Error>) {
    use std::io::Write;
    let span = match (frames.first(), frames.last()) {
        (Some(a), Some(b)) => b.0 - a.0,
        _ => 0,
    };
    let (mut sent, mut last_due, mut offset) = (0usize, 0.0f64, 0i64);
    loop {
        for (t, weights) in frames {
            let t_us = t.saturating_add(offset);
            last_due = pace.wait(t_us.saturating_sub(origin_us));
            let mut line = serde_json::json!({"t_us": t_us, "weights": weights}).to_string();
            line.push('\n');
            if let Err(e) = stream.write_all(line.as_bytes()) {
                let e = anyhow::Error::from(e).context("sending a weight frame");
                return (sent, last_due, Some(e));
            }
            sent += 1;
            if args.max_frames.is_some_and(|m| sent >= m) {
                return (sent, last_due, None);
            }
        }
        if !args.looping || frames.is_empty() {
            return (sent, last_due, None);
        }
        offset = offset.saturating_add(span + gap_us);
    }
}

/// Whether a weights CSV is a Live Link Face take (`Timecode` and `BlendShapeCount` columns).
fn is_live_link_take(csv: &std::path::Path) -> anyhow::Result<bool> {
    Ok(mimic_trackers::take::is_take_file(csv)?)
}

/// `mimic send --weights TAKE.csv` for a Live Link Face take: its tracked rows through the name
/// map, paced by the take's `Timecode`; only the targets the session's rig has are sent, and the
/// names it lacks are reported once, in one line.
fn send_take(args: &Args, csv: &std::path::Path) -> anyhow::Result<()> {
    use std::io::Write;
    let take = mimic_trackers::take::read_take(csv)?;
    let map_path = args.namemap.clone().unwrap_or_else(|| {
        mimic_assets::ConfigDirs::locate(None)
            .root
            .join("namemaps/arkit.toml")
    });
    let map = mimic_trackers::namemap::NameMap::load(&map_path)?;
    let tw = mimic_trackers::take::take_weights(&take, &map);
    let rate = take.sample_rate_hz();
    let mut hello = serde_json::json!({"mode": "weights", "rate_hz": rate,
        "source": format!("Live Link Face take {} (mimic send)", csv.display())});
    if let Some(s) = &args.session {
        hello["session"] = Value::from(s.as_str());
    }
    if let Some(r) = &args.rig {
        hello["rig"] = Value::from(r.as_str());
    }
    if let Some(f) = &args.forward {
        hello["forward"] = Value::from(f.to_string());
    }
    if let Some(t) = crate::cmd::setup::token_or_env(args.token.as_deref()) {
        hello["token"] = Value::from(t);
    }
    let (welcome_tx, welcome_rx) = std::sync::mpsc::sync_channel(1);
    let (mut stream, reader) = connect(&args.to, Some(welcome_tx))?;
    stream.write_all(format!("{hello}\n").as_bytes())?;
    let welcome = welcome_rx
        .recv_timeout(Duration::from_secs(30))
        .context("no welcome from the server")?;
    let rig_targets: Vec<String> = welcome["targets"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|t| t.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();
    let rig_map = mimic_retarget::WeightMap::new(&rig_targets);
    let mut scratch = vec![0.0f32; rig_targets.len()];
    let (kept, lacking): (Vec<usize>, Vec<usize>) = (0..tw.targets.len())
        .partition(|&k| rig_map.apply([(tw.targets[k].as_str(), 0.0)], &mut scratch) == 0);
    if !lacking.is_empty() {
        let names: Vec<&str> = lacking.iter().map(|&k| tw.targets[k].as_str()).collect();
        println!(
            "rig `{}` has no morph target for {} of the take's {} names (not sent): {}",
            welcome["rig"].as_str().unwrap_or("?"),
            names.len(),
            tw.targets.len(),
            names.join(", ")
        );
    }
    let pace = Pacer::new(args.speed, args.fast);
    let frames: WeightRows = tw
        .frames
        .iter()
        .map(|(_, t, w)| {
            let weights = kept
                .iter()
                .map(|&k| (tw.targets[k].clone(), Value::from(f64::from(w[k]))))
                .collect();
            (*t, weights)
        })
        .collect();
    // `--loop` shifts each pass by one frame of the take's rate.
    let gap = (1e6 / rate).round().max(1.0) as i64;
    let (sent, last_due, write_failed) =
        send_weight_frames(&mut stream, &pace, args, &frames, 0, gap);
    let paced = pace.elapsed_s();
    let _ = stream.shutdown(Shutdown::Write);
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let bye = reader.join().ok().flatten();
    println!(
        "take {}: {} rows ({} with no face, not sent), {:.3} s at {} fps timecode; sent {sent} weight frames in {paced:.3} s (due {last_due:.3} s)",
        csv.display(),
        take.rows.len(),
        tw.untracked,
        take.duration_s(),
        take.timecode_rate
    );
    if let Some(b) = &bye {
        println!(
            "server: {} frames, {} late, {} malformed, {} unknown weight names ({})",
            b["frames"], b["late"], b["malformed"], b["unknown_weights"], b["reason"]
        );
    }
    ended_early(write_failed, bye.as_ref())
}

/// `mimic send --weights TAKE.csv --livelink ADDR`: the take's tracked rows as Live Link Face
/// packets (all 61 curves, 60 fps frame times from the take's start), each sent when it is due.
fn send_take_udp(
    args: &Args,
    csv: &std::path::Path,
    addr: std::net::SocketAddr,
) -> anyhow::Result<()> {
    use mimic_trackers::livelink::{LiveLinkPacket, encode_packet};
    let take = mimic_trackers::take::read_take(csv)?;
    let bind = if addr.ip().is_loopback() {
        "127.0.0.1:0"
    } else {
        "0.0.0.0:0"
    };
    let socket = std::net::UdpSocket::bind(bind).context("binding a UDP socket")?;
    let subject = args.session.clone().unwrap_or_else(|| "mimic-send".into());
    let pace = Pacer::new(args.speed, args.fast);
    let mut sent = 0usize;
    for row in take.rows.iter().filter(|r| r.tracked) {
        pace.wait(row.t_us);
        let frames = row.t_us as f64 * 60.0 / 1e6;
        let packet = encode_packet(&LiveLinkPacket {
            device_id: "00000000-0000-4000-8000-6d696d696373".into(),
            subject: subject.clone(),
            frame: frames.floor() as i32,
            subframe: frames.fract() as f32,
            rate_numerator: 60,
            rate_denominator: 1,
            curves: row.curves,
        });
        socket
            .send_to(&packet, addr)
            .with_context(|| format!("sending packet {sent} to {addr}"))?;
        sent += 1;
        if args.max_frames.is_some_and(|m| sent >= m) {
            break;
        }
    }
    println!(
        "sent {sent} Live Link packets (subject `{subject}`) to {addr} in {:.3} s (take {:.3} s, speed {})",
        pace.elapsed_s(),
        take.duration_s(),
        args.speed
    );
    Ok(())
}

/// Connects to a server as a tracker; its replies (welcome, errors, bye) are read on their own
/// thread, errors reported on stderr, the welcome handed to `welcome` (if given), and the
/// thread returns the `bye` message, if one came.
fn connect(
    to: &str,
    welcome: Option<std::sync::mpsc::SyncSender<Value>>,
) -> anyhow::Result<(TcpStream, std::thread::JoinHandle<Option<Value>>)> {
    let stream = TcpStream::connect(to).with_context(|| format!("connecting to {to}"))?;
    stream.set_nodelay(true)?;
    let replies = stream.try_clone()?;
    let reader = std::thread::Builder::new()
        .name("mimic-send-replies".into())
        .spawn(move || {
            let mut bye = None;
            let mut replies = BufReader::new(replies);
            let mut buf = Vec::new();
            loop {
                buf.clear();
                // At most one byte over the cap is read: a line that long is not a reply.
                let cap = u64::try_from(MAX_REPLY_BYTES + 1).unwrap_or(u64::MAX);
                match (&mut replies).take(cap).read_until(b'\n', &mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {}
                }
                if buf.len() > MAX_REPLY_BYTES {
                    eprintln!(
                        "server: a reply line over {MAX_REPLY_BYTES} bytes; no longer reading replies"
                    );
                    break;
                }
                let line = String::from_utf8_lossy(&buf);
                let line = line.trim_end_matches(['\n', '\r']);
                let v: Value = serde_json::from_str(line).unwrap_or(Value::Null);
                match v["type"].as_str() {
                    Some("welcome") => {
                        tracing::info!("{line}");
                        if let Some(w) = &welcome {
                            let _ = w.try_send(v.clone());
                        }
                    }
                    Some("bye") => bye = Some(v),
                    _ => eprintln!("server: {line}"),
                }
            }
            bye
        })?;
    Ok((stream, reader))
}
