//! Limits and knobs of a server.

use mimic_retarget::RetargetSettings;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// The address `mimic serve` listens on unless told otherwise: loopback only.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:7878";

/// Longest first line of a connection (hello or recording header), unless the message limit is
/// smaller: a connection that has not said what it is holds at most this much.
pub const HELLO_MAX_BYTES: usize = 64 * 1024;

/// What the browser viewer needs beyond the server's state: where each rig's file is (for its
/// look and morph targets in the GLB), the skin colour of the rig's look, and the endpoint's
/// doors (docs/reliability.md, "Doors"): which `Host` and `Origin` it answers, and its
/// connection limits and timeouts.
#[derive(Clone, Debug)]
pub struct HttpSettings {
    /// Rig name -> its `.toml` file, for every rig of the catalog.
    pub rig_paths: BTreeMap<String, PathBuf>,
    /// Linear RGB of the look's skin materials (`mimic_render::SKIN_ALBEDO` in `mimic serve`).
    pub skin: [f32; 3],
    /// Host names (besides loopback names and IP addresses of the listener) a request's `Host`
    /// may give (`--http-host`): a name a DNS-rebinding page would use is refused.
    pub hosts: Vec<String>,
    /// Origins (`http://name:port`) besides the served page's own that a request's `Origin`
    /// (a WebSocket's included) may give (`--http-origin`).
    pub origins: Vec<String>,
    /// Connections at once (also kept below the open-file limit, with room for the rest).
    pub max_connections: usize,
    /// Connections at once from one IP address.
    pub max_connections_per_peer: usize,
    /// A connection must send a whole request head within this long (also between requests
    /// of a kept-alive connection), else it is closed.
    pub header_timeout: Duration,
    /// A connection whose peer takes longer than this to take one write is closed.
    pub write_timeout: Duration,
}

impl Default for HttpSettings {
    fn default() -> Self {
        Self {
            rig_paths: BTreeMap::new(),
            skin: [0.0; 3],
            hosts: Vec::new(),
            origins: Vec::new(),
            max_connections: 256,
            max_connections_per_peer: 32,
            header_timeout: Duration::from_secs(10),
            write_timeout: Duration::from_secs(30),
        }
    }
}

/// Live Link Face's intake: its bound UDP socket and the name map its curves go through.
#[derive(Clone, Debug)]
pub struct LiveLinkIntake {
    /// The bound UDP socket.
    pub socket: Arc<std::net::UdpSocket>,
    /// Curve names to the rig's morph-target names (`configs/namemaps/arkit.toml`).
    pub namemap: Arc<mimic_trackers::namemap::NameMap>,
}

/// Limits and pipeline settings of a [`Server`](crate::Server).
#[derive(Clone, Debug)]
pub struct ServerSettings {
    /// Tracker sessions at once; more are refused with `too_many_sessions`.
    pub max_sessions: usize,
    /// Viewers at once; more are refused with `too_many_viewers`.
    pub max_viewers: usize,
    /// Connections at once from one IP address (trackers, viewers, stats and connections that
    /// have not said hello yet); more are answered `too_many_connections` and closed.
    pub max_connections_per_peer: usize,
    /// Connection slots kept for stats requests when every other slot is taken; a connection in
    /// one of them must send its stats hello within 2 s.
    pub stats_slots: usize,
    /// A viewer whose session has had no tracker (and which has had no message) this long is
    /// closed with `idle_timeout`.
    pub viewer_idle_timeout: Duration,
    /// TCP keepalive on every connection: probes start after this much silence (a vanished peer
    /// is dropped about 30 s later).
    pub tcp_keepalive: Duration,
    /// Longest message (tracker line, hello) in bytes; longer lines are answered `too_long`.
    pub max_message_bytes: usize,
    /// A tracker (or a connection that has not said hello) silent this long is closed.
    pub idle_timeout: Duration,
    /// Frames a viewer's queue holds before the oldest is dropped.
    pub viewer_queue_frames: usize,
    /// A viewer whose socket takes longer than this to accept one message is disconnected.
    pub viewer_write_timeout: Duration,
    /// Malformed messages in a row after which a tracker connection is closed.
    pub max_errors_in_a_row: u32,
    /// UDP frames queued per session before new ones are dropped.
    pub udp_queue_frames: usize,
    /// After shutdown is asked for, how long to wait for viewers to receive what was accepted.
    pub shutdown_grace: Duration,
    /// Ended sessions kept in the stats.
    pub ended_sessions_kept: usize,
    /// How often each live session logs its counters (tracing, info level).
    pub log_every: Duration,
    /// A frame may run ahead of the last accepted one by the wall-clock time between their
    /// arrivals plus this much; further ahead it is refused as `future_timestamp`.
    pub max_time_jump: Duration,
    /// When set, every hello (tracker, viewer, stats) must present this token; without one,
    /// only loopback addresses may be listened on ([`check_bind`]).
    pub token: Option<String>,
    /// Record every landmark session's accepted frames as a v1 recording in this folder.
    pub record_dir: Option<PathBuf>,
    /// With a record folder: when a frame is written relative to its broadcast to viewers.
    pub record_mode: RecordMode,
    /// Accepted frames queued per session for its recording before the session waits for the disk.
    pub record_queue_frames: usize,
    /// A bound UDP socket for OpenSeeFace's datagrams (`mimic serve --openseeface`): one
    /// session per face id (`server/openseeface.rs`); `None`, the default, for none.
    pub openseeface: Option<Arc<std::net::UdpSocket>>,
    /// Live Link Face's intake (`mimic serve --livelink`): one weights session per subject
    /// (`server/livelink.rs`); `None`, the default, for none.
    pub livelink: Option<LiveLinkIntake>,
    /// UDP tracker intake sessions (OpenSeeFace faces, Live Link subjects) at once, a budget
    /// of their own inside `max_sessions`: TCP trackers always have the rest.
    pub max_udp_sessions: usize,
    /// Valid packets in a row (decoded, from one source, time going forward) a face or subject
    /// must send before its session opens; they are then taken as its first frames.
    pub udp_open_packets: usize,
    /// Source addresses the UDP tracker intakes take datagrams from (`--udp-allow`); empty:
    /// any (only allowed on loopback).
    pub udp_allow: Vec<std::net::IpAddr>,
    /// Live out: where sessions' frames are forwarded (VMC, Live Link Face), and what trackers
    /// may ask for (`crate::forward`); none by default.
    pub forward: crate::forward::ForwardSettings,
    /// Pipeline settings of every session (`positions` and `normals` are forced off: the
    /// server computes positions itself, only for viewers that ask for them).
    pub retarget: RetargetSettings,
}

impl Default for ServerSettings {
    fn default() -> Self {
        Self {
            max_sessions: 128,
            max_viewers: 256,
            max_connections_per_peer: 64,
            stats_slots: 4,
            viewer_idle_timeout: Duration::from_secs(60),
            tcp_keepalive: Duration::from_secs(30),
            max_message_bytes: 1 << 20,
            idle_timeout: Duration::from_secs(30),
            viewer_queue_frames: 8,
            viewer_write_timeout: Duration::from_secs(10),
            max_errors_in_a_row: 16,
            udp_queue_frames: 8,
            shutdown_grace: Duration::from_secs(3),
            ended_sessions_kept: 256,
            log_every: Duration::from_secs(10),
            max_time_jump: Duration::from_secs(10),
            token: None,
            record_dir: None,
            record_mode: RecordMode::Written,
            record_queue_frames: 128,
            openseeface: None,
            livelink: None,
            max_udp_sessions: 16,
            udp_open_packets: 3,
            udp_allow: Vec::new(),
            forward: crate::forward::ForwardSettings::default(),
            retarget: RetargetSettings::default(),
        }
    }
}

/// When a recorded frame is written, relative to its broadcast to viewers (docs/reliability.md,
/// "Crash loss").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RecordMode {
    /// Broadcast (and counted in `frames`) only once written and flushed to the OS: a kill of
    /// the server loses no frame a viewer saw (the default).
    #[default]
    Written,
    /// As `Written`, and synced to the disk (`fdatasync`) first: a power loss loses none either.
    Synced,
    /// Broadcast at once, written behind through the queue (`--record-queued`): the fastest; a
    /// kill loses the queued frames, up to the queue's length plus one.
    Queued,
}

impl RecordMode {
    /// The mode `--record-sync` (`sync`) or `--record-queued` (`queued`) asks for; neither:
    /// [`RecordMode::Written`].
    pub fn from_flags(sync: bool, queued: bool) -> Self {
        match (sync, queued) {
            (true, _) => RecordMode::Synced,
            (false, true) => RecordMode::Queued,
            (false, false) => RecordMode::Written,
        }
    }

    /// Whether a frame waits for its write before its broadcast, and whether to sync it too.
    pub fn waits(self) -> Option<bool> {
        match self {
            RecordMode::Written => Some(false),
            RecordMode::Synced => Some(true),
            RecordMode::Queued => None,
        }
    }
}

/// Why a listener may not bind its address (protected mode).
#[derive(Debug, thiserror::Error)]
pub enum BindError {
    /// A non-loopback address without a token.
    #[error(
        "refusing to listen for {what} on {addr} without a token: anyone who can reach it could open sessions and watch them. Pass --token (or set MIMIC_TOKEN), or listen on a loopback address (127.0.0.1, ::1)"
    )]
    NeedsToken {
        /// The listener (`TCP`, `UDP`, ...).
        what: String,
        /// The address asked for.
        addr: SocketAddr,
    },
    /// An empty token.
    #[error("--token / MIMIC_TOKEN is empty")]
    EmptyToken,
}

/// Protected mode: a listener (`what`: `TCP`, `UDP`, any other) may bind `addr` only if it is
/// a loopback address or the server has a (non-empty) `token`. Every listener's address goes
/// through here before it is bound.
pub fn check_bind(what: &str, addr: SocketAddr, token: Option<&str>) -> Result<(), BindError> {
    match token {
        Some("") => Err(BindError::EmptyToken),
        Some(_) => Ok(()),
        None if addr.ip().is_loopback() => Ok(()),
        None => Err(BindError::NeedsToken {
            what: what.to_string(),
            addr,
        }),
    }
}

/// [`check_bind`] for every door a server opens: TCP at `listen`, UDP frames at `udp` (`None`:
/// off) and the `more` named ones that are asked for.
pub fn check_binds(
    listen: SocketAddr,
    udp: Option<SocketAddr>,
    more: &[(&str, Option<SocketAddr>)],
    token: Option<&str>,
) -> Result<(), BindError> {
    check_bind("TCP", listen, token)?;
    if let Some(addr) = udp {
        check_bind("UDP", addr, token)?;
    }
    for (what, addr) in more {
        if let Some(addr) = addr {
            check_bind(what, *addr, token)?;
        }
    }
    Ok(())
}

/// `--token`, else the MIMIC_TOKEN environment variable (shared by serve, send and view).
pub fn token_or_env(flag: Option<&str>) -> Option<String> {
    flag.map(str::to_string)
        .or_else(|| std::env::var("MIMIC_TOKEN").ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_loopback_binds_without_a_token() {
        let a = |s: &str| s.parse::<SocketAddr>().unwrap();
        assert!(check_bind("TCP", a("127.0.0.1:7878"), None).is_ok());
        assert!(check_bind("TCP", a("[::1]:0"), None).is_ok());
        assert!(check_bind("UDP", a("127.3.4.5:9"), None).is_ok());
        for addr in ["0.0.0.0:0", "[::]:0", "192.168.1.2:7878"] {
            let e = check_bind("UDP", a(addr), None).unwrap_err().to_string();
            assert!(e.contains("--token") && e.contains(addr), "{e}");
            assert!(check_bind("UDP", a(addr), Some("t")).is_ok());
        }
        assert!(matches!(
            check_bind("TCP", a("127.0.0.1:1"), Some("")),
            Err(BindError::EmptyToken)
        ));
    }
}
