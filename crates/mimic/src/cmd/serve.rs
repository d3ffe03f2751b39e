//! `mimic serve`: live sessions over sockets (see docs/protocol.md).

use crate::cmd::setup::{PipelineArgs, RigArgs, parse_seconds};
use anyhow::Context;
use mimic_stream::launch::{self, Listeners};
use mimic_stream::{DEFAULT_LISTEN, RecordMode, Server, ServerSettings, check_binds};
use mimic_types::parse::parse_listen_addr;
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// Arguments of `mimic serve`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Further rigs a tracker's hello may name (`"rig": NAME`); `--rig` is the default.
    #[arg(long = "also-rig")]
    pub also_rig: Vec<String>,
    /// TCP address for trackers, viewers and stats (loopback unless another address is given).
    #[arg(long, default_value = DEFAULT_LISTEN)]
    pub listen: SocketAddr,
    /// UDP address for binary tracker frames (default: the TCP address and port).
    #[arg(long)]
    pub udp: Option<SocketAddr>,
    /// Do not listen for UDP frames.
    #[arg(long)]
    pub no_udp: bool,
    /// Also receive OpenSeeFace's UDP datagrams on this address (its default port is
    /// 127.0.0.1:11573): one session `openseeface-<face id>` per face, `openseeface68` layout,
    /// the `--rig` rig (docs/trackers.md).
    #[arg(long, value_name = "ADDR")]
    pub openseeface: Option<SocketAddr>,
    /// Also receive Live Link Face's UDP packets on this address (the app's default port is
    /// 11111): one weights session `livelink-<subject>` per subject, driving the `--rig` rig's
    /// morph targets through `--namemap` (docs/trackers.md).
    #[arg(long, value_name = "ADDR")]
    pub livelink: Option<SocketAddr>,
    /// Also serve the browser viewer on this address (`PORT` alone means 127.0.0.1:PORT): the
    /// sessions at `/`, a session in 3D at `/view/SESSION` (three.js, shipped in the binary),
    /// its rig at `/rig/SESSION.glb`, frames over the WebSocket `/ws/SESSION` (docs/browser.md).
    /// Off without this flag; beyond loopback it needs `--token` like every listener.
    #[arg(long, value_name = "ADDR", value_parser = parse_listen_addr)]
    pub http: Option<SocketAddr>,
    /// A host name (besides loopback names and the listener's addresses) the browser endpoint
    /// answers in a request's `Host` (repeatable, or comma-separated); others get 421.
    #[arg(long, value_name = "NAME", value_delimiter = ',')]
    pub http_host: Vec<String>,
    /// An origin (`http://name:port`) besides the served page's own whose pages may use the
    /// browser endpoint, its WebSockets included (repeatable, or comma-separated); others get 403.
    #[arg(long, value_name = "ORIGIN", value_delimiter = ',')]
    pub http_origin: Vec<String>,
    /// Browser endpoint connections at once (kept below the open-file limit, with room for the
    /// TCP slots and recordings); more are answered 503 and closed.
    #[arg(long, default_value_t = mimic_stream::HttpSettings::default().max_connections)]
    pub http_max_connections: usize,
    /// Browser endpoint connections at once from one IP address.
    #[arg(long, default_value_t = mimic_stream::HttpSettings::default().max_connections_per_peer)]
    pub http_max_connections_per_peer: usize,
    /// Seconds a browser endpoint connection has for a whole request head (also between
    /// requests of a kept-alive connection).
    #[arg(long, default_value_t = mimic_stream::HttpSettings::default().header_timeout.as_secs_f64(), value_parser = parse_seconds)]
    pub http_header_timeout: f64,
    /// Name map for Live Link curves (default: configs/namemaps/arkit.toml); its inverse also
    /// reads the rig's weights back as ARKit curves for `--forward`.
    #[arg(long, value_name = "TOML")]
    pub namemap: Option<PathBuf>,
    /// Forward every session's frames (ARKit weights and head rotation) to a VMC receiver
    /// (`vmc:HOST:PORT`, OSC over UDP, e.g. VSeeFace's 127.0.0.1:39539) or a Live Link Face
    /// receiver (`livelink:HOST:PORT`, e.g. Unreal's 127.0.0.1:11111); repeatable. Any address
    /// the operator names here is used (warned about beyond loopback); docs/protocol.md.
    #[arg(long, value_name = "KIND:ADDR")]
    pub forward: Vec<mimic_stream::forward::ForwardTarget>,
    /// An address and port besides the `--forward` targets' that a tracker's own `"forward"`
    /// may name (repeatable, or comma-separated); trackers may forward nowhere else.
    #[arg(long, value_name = "ADDR:PORT", value_delimiter = ',')]
    pub forward_allow: Vec<SocketAddr>,
    /// Name map from ARKit names to the names VMC receives (e.g.
    /// configs/namemaps/vrm.toml for VRM presets); default: ARKit's names.
    #[arg(long, value_name = "TOML")]
    pub forward_vmc_names: Option<PathBuf>,
    /// Maximum tracker sessions at once.
    #[arg(long, default_value_t = ServerSettings::default().max_sessions)]
    pub max_sessions: usize,
    /// Maximum sessions of the UDP tracker intakes (OpenSeeFace faces, Live Link subjects) at
    /// once, within --max-sessions: TCP trackers always have the rest.
    #[arg(long, default_value_t = ServerSettings::default().max_udp_sessions)]
    pub max_udp_sessions: usize,
    /// Source addresses the UDP tracker intakes (--openseeface, --livelink) take datagrams from
    /// (repeatable, or comma-separated); required when one listens beyond loopback.
    #[arg(long, value_name = "ADDR", value_delimiter = ',')]
    pub udp_allow: Vec<std::net::IpAddr>,
    /// Maximum viewers at once.
    #[arg(long, default_value_t = ServerSettings::default().max_viewers)]
    pub max_viewers: usize,
    /// Maximum connections at once from one IP address (any kind, also before their hello);
    /// past it a connection is answered `too_many_connections` and closed.
    #[arg(long, default_value_t = ServerSettings::default().max_connections_per_peer)]
    pub max_connections_per_peer: usize,
    /// Connection slots kept for stats requests when all others are taken (a stats hello
    /// within 2 s).
    #[arg(long, default_value_t = ServerSettings::default().stats_slots)]
    pub stats_slots: usize,
    /// Seconds a viewer may wait without a message while its session has no tracker; then it
    /// is closed with `idle_timeout`.
    #[arg(long, default_value_t = ServerSettings::default().viewer_idle_timeout.as_secs_f64(), value_parser = parse_seconds)]
    pub viewer_idle_timeout: f64,
    /// Seconds of silence on a connection before TCP keepalive probes start (a vanished peer is
    /// dropped about 30 s later).
    #[arg(long, default_value_t = ServerSettings::default().tcp_keepalive.as_secs_f64(), value_parser = parse_seconds)]
    pub tcp_keepalive: f64,
    /// Maximum message (line) size in bytes.
    #[arg(long, default_value_t = ServerSettings::default().max_message_bytes)]
    pub max_message_bytes: usize,
    /// Seconds of silence after which a tracker connection is closed.
    #[arg(long, default_value_t = ServerSettings::default().idle_timeout.as_secs_f64(), value_parser = parse_seconds)]
    pub idle_timeout: f64,
    /// Frames each viewer's queue holds before the oldest is dropped.
    #[arg(long, default_value_t = ServerSettings::default().viewer_queue_frames)]
    pub viewer_queue: usize,
    /// Malformed messages in a row after which a tracker connection is closed.
    #[arg(long, default_value_t = ServerSettings::default().max_errors_in_a_row)]
    pub max_errors: u32,
    /// Seconds a viewer's socket may take to accept one message before it is disconnected.
    #[arg(long, default_value_t = ServerSettings::default().viewer_write_timeout.as_secs_f64(), value_parser = parse_seconds)]
    pub viewer_write_timeout: f64,
    /// Seconds a frame's timestamp may run ahead of the last accepted frame's, beyond the time
    /// between their arrivals; further ahead it is refused (`future_timestamp`).
    #[arg(long, default_value_t = ServerSettings::default().max_time_jump.as_secs_f64(), value_parser = parse_seconds)]
    pub max_time_jump: f64,
    /// Record every session's accepted frames in this folder (created if missing), one file per
    /// session, flushed per frame: a v1 recording for landmark sessions
    /// (`<session>-<id>-<peer>-<UTC time>.jsonl`), a weights CSV (`t_us` and the rig's
    /// morph-target weights, `...weights.csv`, which `mimic send --weights` reads) for weights and
    /// Live Link sessions.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// With --record: a frame reaches viewers only after it is also synced to disk (one
    /// fdatasync per frame), so a power loss loses no frame a viewer saw either. By default a
    /// frame reaches viewers once written to the OS, which a kill -9 of the server cannot undo
    /// (docs/reliability.md, "Crash loss").
    #[arg(long, requires = "record", conflicts_with = "record_queued")]
    pub record_sync: bool,
    /// With --record: broadcast each frame at once and write it behind through the queue, the
    /// fastest mode; a kill -9 loses the frames still queued (up to --record-queue + 1 a
    /// session), which viewers may have seen.
    #[arg(long, requires = "record")]
    pub record_queued: bool,
    /// Accepted frames queued per session for its recording; when full the session waits for
    /// the disk (no frame is dropped).
    #[arg(long, default_value_t = ServerSettings::default().record_queue_frames)]
    pub record_queue: usize,
    /// Seconds viewers get after Ctrl-C to receive what was accepted.
    #[arg(long, default_value_t = ServerSettings::default().shutdown_grace.as_secs_f64(), value_parser = parse_seconds)]
    pub shutdown_grace: f64,
    /// Shared secret every hello (tracker, viewer, stats) must present (default: the
    /// MIMIC_TOKEN environment variable). Without one, only loopback addresses may be listened
    /// on (protected mode).
    #[arg(long)]
    pub token: Option<String>,
    /// Place landmark sessions on `mimic worker`s through the NATS server at this URL (e.g.
    /// nats://127.0.0.1:4222) instead of retargeting them here; viewers here also get sessions
    /// hosted by other front doors (docs/cluster.md).
    #[arg(long, value_name = "URL", conflicts_with = "record_sync")]
    pub nats: Option<String>,
    /// Print the final counters as JSON on exit.
    #[arg(long)]
    pub json: bool,
}

fn seconds(s: f64, what: &str) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s).with_context(|| format!("{what}: {s} is not a duration"))
}

/// Runs `mimic serve` until Ctrl-C.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Protected mode first: no rig is loaded for a server that may not start.
    let token = mimic_stream::token_or_env(args.token.as_deref());
    let t = token.as_deref();
    let udp = (!args.no_udp).then(|| args.udp.unwrap_or(args.listen));
    // The trackers' own protocols carry no token: beyond loopback they need one all the same
    // (an operator's explicit choice), and are warned about when bound.
    let more = [
        ("OpenSeeFace UDP", args.openseeface),
        ("Live Link Face UDP", args.livelink),
        ("HTTP", args.http),
    ];
    check_binds(args.listen, udp, &more, t)?;
    let (catalog, rig_paths) = crate::cmd::setup::build_catalog(&args.rig, &args.also_rig)?;
    let web = mimic_stream::HttpSettings {
        skin: mimic_render::SKIN_ALBEDO,
        rig_paths,
        hosts: args.http_host.clone(),
        origins: args.http_origin.clone(),
        max_connections: args.http_max_connections,
        max_connections_per_peer: args.http_max_connections_per_peer,
        header_timeout: seconds(args.http_header_timeout, "--http-header-timeout")?,
        ..Default::default()
    };
    let settings = settings(&args, token)?;
    if !args.listen.ip().is_loopback() {
        tracing::warn!(addr = %args.listen, "listening beyond loopback with a token: every hello must present it");
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let stats = runtime.block_on(async {
        let udp = (!args.no_udp).then_some(args.udp);
        let bound = Listeners::bind(args.listen, udp, args.http).await?;
        // Connected to NATS (and its buckets) before the ready line.
        let (placement, nats) = match &args.nats {
            Some(url) => {
                let tcp = bound.tcp.local_addr()?;
                let cluster = mimic_cluster::Cluster::connect(url, Default::default()).await?;
                let p = mimic_cluster::NatsPlacement::new(cluster, &format!("front-{tcp}"));
                (Some(p), format!(" nats {}", mimic_cluster::redact(url)))
            }
            None => (None, String::new()),
        };
        // The first stdout line says where to connect (tests and scripts read it).
        println!(
            "{}",
            bound.ready_line(&settings, &catalog.rig_names(), &nats)?
        );
        std::io::stdout().flush()?;
        let catalog = Arc::new(catalog);
        let server = match placement {
            None => Server::new(catalog, settings),
            Some(p) => Server::with_placement(catalog, settings, Arc::new(p)),
        };
        let ctrl_c = || async {
            let _ = tokio::signal::ctrl_c().await;
        };
        anyhow::Ok(launch::serve(server, bound, web, ctrl_c).await)
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&stats)?);
        return Ok(());
    }
    println!("{}", stats.summary());
    if let Some(dir) = &args.record {
        println!("{}", stats.record_summary(dir));
    }
    Ok(())
}

/// The server's settings from the arguments (the tracker sockets bound, the record folder
/// checked, the name maps read).
fn settings(args: &Args, token: Option<String>) -> anyhow::Result<ServerSettings> {
    let root = args.rig.config_dirs().root;
    let namemap = args
        .namemap
        .clone()
        .unwrap_or_else(|| root.join("namemaps/arkit.toml"));
    Ok(ServerSettings {
        max_sessions: args.max_sessions,
        max_viewers: args.max_viewers,
        max_message_bytes: args.max_message_bytes,
        max_connections_per_peer: args.max_connections_per_peer.max(1),
        stats_slots: args.stats_slots,
        viewer_idle_timeout: seconds(args.viewer_idle_timeout, "--viewer-idle-timeout")?,
        tcp_keepalive: seconds(args.tcp_keepalive, "--tcp-keepalive")?,
        idle_timeout: seconds(args.idle_timeout, "--idle-timeout")?,
        viewer_queue_frames: args.viewer_queue,
        max_errors_in_a_row: args.max_errors.max(1),
        shutdown_grace: seconds(args.shutdown_grace, "--shutdown-grace")?,
        viewer_write_timeout: seconds(args.viewer_write_timeout, "--viewer-write-timeout")?,
        max_time_jump: seconds(args.max_time_jump, "--max-time-jump")?,
        record_dir: launch::record_dir(args.record.as_deref())?,
        token,
        record_queue_frames: args.record_queue.max(1),
        record_mode: RecordMode::from_flags(args.record_sync, args.record_queued),
        retarget: args.pipeline.settings(),
        openseeface: launch::bind_tracker_udp(args.openseeface, "--openseeface", &args.udp_allow)?,
        livelink: launch::livelink_intake(
            launch::bind_tracker_udp(args.livelink, "--livelink", &args.udp_allow)?,
            &namemap,
        )?,
        forward: launch::forward_settings(
            args.forward.clone(),
            args.forward_allow.clone(),
            &namemap,
            args.forward_vmc_names.as_deref(),
        )?,
        max_udp_sessions: args.max_udp_sessions,
        udp_allow: args.udp_allow.clone(),
        ..ServerSettings::default()
    })
}
