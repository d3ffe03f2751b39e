//! `mimic serve`: live sessions over sockets (see docs/protocol.md).

use crate::cmd::setup::{PipelineArgs, RigArgs, parse_seconds};
use anyhow::Context;
use mimic_stream::{DEFAULT_LISTEN, Server, ServerSettings, check_bind};
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
    #[arg(long, value_name = "ADDR", value_parser = parse_http_addr)]
    pub http: Option<SocketAddr>,
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
    /// An address besides loopback that a tracker's own `"forward"` may name (repeatable);
    /// without it trackers may forward only to loopback addresses.
    #[arg(long, value_name = "IP")]
    pub forward_allow: Vec<std::net::IpAddr>,
    /// Name map from ARKit names to the names VMC receives (e.g.
    /// configs/namemaps/vrm.toml for VRM presets); default: ARKit's names.
    #[arg(long, value_name = "TOML")]
    pub forward_vmc_names: Option<PathBuf>,
    /// Maximum tracker sessions at once.
    #[arg(long, default_value_t = ServerSettings::default().max_sessions)]
    pub max_sessions: usize,
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
    /// With --record: a frame reaches viewers (and the `frames` count) only after it is
    /// written, flushed and synced to disk, so a crash (kill -9, power loss) loses no frame a
    /// viewer saw; costs one fdatasync per frame (docs/reliability.md).
    #[arg(long, requires = "record")]
    pub record_sync: bool,
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
    let token = crate::cmd::setup::token_or_env(args.token.as_deref());
    check_bind("TCP", args.listen, token.as_deref())?;
    if !args.no_udp {
        check_bind("UDP", args.udp.unwrap_or(args.listen), token.as_deref())?;
    }
    // The trackers' own protocols carry no token: beyond loopback they need one all the same
    // (an operator's explicit choice), and are warned about in `bind_udp`.
    if let Some(addr) = args.openseeface {
        check_bind("OpenSeeFace UDP", addr, token.as_deref())?;
    }
    if let Some(addr) = args.livelink {
        check_bind("Live Link Face UDP", addr, token.as_deref())?;
    }
    if let Some(addr) = args.http {
        check_bind("HTTP", addr, token.as_deref())?;
    }
    let dirs = args.rig.config_dirs();
    let (catalog, rig_paths) = crate::cmd::setup::build_catalog(&args.rig, &args.also_rig)?;
    let web = mimic_stream::HttpSettings {
        skin: mimic_render::SKIN_ALBEDO,
        rig_paths,
    };
    let settings = ServerSettings {
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
        record_dir: record_dir(args.record.as_deref())?,
        token,
        record_queue_frames: args.record_queue.max(1),
        record_sync: args.record_sync,
        retarget: args.pipeline.settings(),
        openseeface: bind_udp(args.openseeface, "--openseeface")?,
        livelink: match bind_udp(args.livelink, "--livelink")? {
            Some(socket) => {
                let path = args
                    .namemap
                    .clone()
                    .unwrap_or_else(|| dirs.root.join("namemaps/arkit.toml"));
                let namemap = Arc::new(mimic_trackers::namemap::NameMap::load(&path)?);
                Some(mimic_stream::LiveLinkIntake { socket, namemap })
            }
            None => None,
        },
        forward: forward_settings(&args, &dirs.root)?,
        ..ServerSettings::default()
    };
    if !args.listen.ip().is_loopback() {
        tracing::warn!(addr = %args.listen, "listening beyond loopback with a token: every hello must present it");
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let stats = runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(args.listen)
            .await
            .with_context(|| format!("binding {}", args.listen))?;
        let tcp = listener.local_addr()?;
        let udp = if args.no_udp {
            None
        } else {
            let addr = args.udp.unwrap_or(tcp);
            Some(
                tokio::net::UdpSocket::bind(addr)
                    .await
                    .with_context(|| format!("binding UDP {addr}"))?,
            )
        };
        let udp_addr = match &udp {
            Some(u) => u.local_addr()?.to_string(),
            None => "off".to_string(),
        };
        let http = match args.http {
            Some(addr) => Some(
                tokio::net::TcpListener::bind(addr)
                    .await
                    .with_context(|| format!("--http: binding {addr}"))?,
            ),
            None => None,
        };
        let http_addr = match &http {
            Some(l) => format!(" http {}", l.local_addr()?),
            None => String::new(),
        };
        // The first stdout line says where to connect (tests and scripts read it).
        let livelink = settings.livelink.as_ref().map(|l| l.socket.clone());
        let trackers: String = [
            ("openseeface", &settings.openseeface),
            ("livelink", &livelink),
        ]
        .iter()
        .filter_map(|(name, s)| Some(format!(" {name} {}", s.as_ref()?.local_addr().ok()?)))
        .collect();
        // Connected to NATS (and its buckets) before the ready line.
        let placement = match &args.nats {
            Some(url) => {
                let cluster = mimic_cluster::Cluster::connect(url, Default::default()).await?;
                Some(mimic_cluster::NatsPlacement::new(
                    cluster,
                    &format!("front-{tcp}"),
                ))
            }
            None => None,
        };
        let nats = args
            .nats
            .as_ref()
            .map(|u| format!(" nats {}", mimic_cluster::redact(u)))
            .unwrap_or_default();
        println!(
            "mimic serve: tcp {tcp} udp {udp_addr} rigs {:?}{trackers}{nats}{http_addr}",
            catalog.rig_names()
        );
        std::io::stdout().flush()?;
        let catalog = Arc::new(catalog);
        let server = match placement {
            None => Server::new(catalog, settings),
            Some(p) => Server::with_placement(catalog, settings, Arc::new(p)),
        };
        let shutdown = async {
            let _ = tokio::signal::ctrl_c().await;
        };
        let web_task = http.map(|listener| {
            let server = server.clone();
            let stop = async {
                let _ = tokio::signal::ctrl_c().await;
            };
            tokio::spawn(async move { server.serve_http(listener, web, stop).await })
        });
        let stats = server.run(listener, udp, shutdown).await;
        if let Some(task) = web_task {
            // Browser viewers end with the server's viewer queues; give them a moment.
            let abort = task.abort_handle();
            match tokio::time::timeout(Duration::from_secs(2), task).await {
                Ok(Ok(Err(e))) => tracing::warn!("HTTP server: {e}"),
                Err(_) => abort.abort(),
                _ => {}
            }
        }
        anyhow::Ok(stats)
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&stats)?);
    } else {
        println!(
            "mimic serve: {} connections, {} sessions; latency p50 {} us, p99 {} us; {} frames dropped for slow viewers",
            stats.connections,
            stats.sessions.len(),
            stats.latency.p50_us,
            stats.latency.p99_us,
            stats.viewer_frames_dropped
        );
        if let Some(dir) = &args.record {
            let recorded: u64 = stats.sessions.iter().map(|s| s.recorded).sum();
            let lost: u64 = stats.sessions.iter().map(|s| s.record_lost).sum();
            println!(
                "mimic serve: {recorded} frames recorded in {} ({lost} not recorded)",
                dir.display()
            );
        }
    }
    Ok(())
}

/// `--forward`, `--forward-allow` and the name maps forwarding reads.
fn forward_settings(
    args: &Args,
    root: &std::path::Path,
) -> anyhow::Result<mimic_stream::forward::ForwardSettings> {
    use mimic_trackers::namemap::NameMap;
    for t in &args.forward {
        if !t.addr.ip().is_loopback() {
            tracing::warn!(target = %t, "--forward beyond loopback, as asked");
        }
    }
    let path = args
        .namemap
        .clone()
        .unwrap_or_else(|| root.join("namemaps/arkit.toml"));
    let namemap = Arc::new(NameMap::load(&path)?);
    let vmc_names = match &args.forward_vmc_names {
        Some(p) => Some(Arc::new(NameMap::load(p)?)),
        None => None,
    };
    Ok(mimic_stream::forward::ForwardSettings {
        targets: args.forward.clone(),
        allow: args.forward_allow.clone(),
        namemap,
        vmc_names,
    })
}

/// `--http`: an address, or a port alone for loopback (`8080` is `127.0.0.1:8080`).
fn parse_http_addr(s: &str) -> Result<SocketAddr, String> {
    if let Ok(port) = s.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    s.parse()
        .map_err(|_| format!("`{s}` is neither a port nor an address like 127.0.0.1:8080"))
}

/// A tracker's UDP socket bound at `addr` (warned about beyond loopback), for the server.
fn bind_udp(
    addr: Option<SocketAddr>,
    flag: &str,
) -> anyhow::Result<Option<Arc<std::net::UdpSocket>>> {
    let Some(addr) = addr else { return Ok(None) };
    if !addr.ip().is_loopback() {
        tracing::warn!(%addr, "{flag}: receiving beyond loopback, as asked: this tracker protocol carries no token, so anyone who can reach it can open sessions");
    }
    let socket =
        std::net::UdpSocket::bind(addr).with_context(|| format!("{flag}: binding UDP {addr}"))?;
    Ok(Some(Arc::new(socket)))
}

/// The `--record` folder, created if missing and checked writable before any session starts.
fn record_dir(dir: Option<&std::path::Path>) -> anyhow::Result<Option<PathBuf>> {
    let Some(dir) = dir else { return Ok(None) };
    std::fs::create_dir_all(dir)
        .with_context(|| format!("--record: creating {}", dir.display()))?;
    let probe = probe_writable(dir)?;
    std::fs::remove_file(&probe).with_context(|| format!("--record: {}", probe.display()))?;
    Ok(Some(dir.to_path_buf()))
}

/// Creates an empty, unused file in `dir` (proof that recordings can be written there).
fn probe_writable(dir: &std::path::Path) -> anyhow::Result<PathBuf> {
    let probe = dir.join(format!(".mimic-serve-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(&probe)
        .with_context(|| format!("--record: {} is not writable", dir.display()))?;
    Ok(probe)
}
