//! Limits and knobs of a server.

use mimic_retarget::RetargetSettings;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// The address `mimic serve` listens on unless told otherwise: loopback only.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:7878";

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
    /// Record every landmark session's accepted frames as a v1 recording in this folder.
    pub record_dir: Option<PathBuf>,
    /// Accepted frames queued per session for its recording before the session waits for the disk.
    pub record_queue_frames: usize,
    /// A bound UDP socket for OpenSeeFace's datagrams (`mimic serve --openseeface`): one
    /// session per face id (`server/openseeface.rs`); `None`, the default, for none.
    pub openseeface: Option<Arc<std::net::UdpSocket>>,
    /// Live Link Face's intake (`mimic serve --livelink`): one weights session per subject
    /// (`server/livelink.rs`); `None`, the default, for none.
    pub livelink: Option<LiveLinkIntake>,
    /// Pipeline settings of every session (`positions` and `normals` are forced off: the
    /// server computes positions itself, only for viewers that ask for them).
    pub retarget: RetargetSettings,
}

impl Default for ServerSettings {
    fn default() -> Self {
        Self {
            max_sessions: 128,
            max_viewers: 256,
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
            record_dir: None,
            record_queue_frames: 128,
            openseeface: None,
            livelink: None,
            retarget: RetargetSettings::default(),
        }
    }
}
