//! What a session name gathers, below the server's state: a tracker session's counters
//! ([`SessionRecord`], with its [`ViewerLog`]), the viewers ([`Viewer`]), the [`Hub`] viewers join
//! by name and the UDP [`Route`] of a landmark session.

use crate::counter::Counter;
use crate::placement::PlacementStatus;
use crate::queue::{Message, ViewerQueue};
use crate::record::RecordCounters;
use crate::stats::{LatencyHistogram, SessionSnapshot, ViewerSnapshot};
use crate::sync::lock;
use mimic_types::LandmarkFrame;
use std::collections::VecDeque;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio::sync::mpsc;

/// One connected viewer.
#[derive(Debug)]
pub(crate) struct Viewer {
    pub(crate) id: u64,
    pub(crate) session: String,
    pub(crate) positions: bool,
    /// A browser viewer (`/ws/SESSION`): its queue gets the WebSocket frame layout
    /// (`http::ws::encode_web_frame`) instead of the TCP FRAME message.
    pub(crate) web: bool,
    pub(crate) queue: ViewerQueue,
    pub(crate) connected: AtomicBool,
}

impl Viewer {
    /// The viewer's counters as the stats report them.
    pub(crate) fn snapshot(&self) -> ViewerSnapshot {
        ViewerSnapshot {
            id: self.id,
            session: self.session.clone(),
            positions: self.positions,
            frames_sent: self.queue.sent.get(),
            frames_dropped: self.queue.dropped.get(),
            queued: self.queue.queued() as u64,
            connected: self.connected.load(Ordering::Relaxed),
        }
    }
}

/// Counters of one tracker session.
#[derive(Debug)]
pub(crate) struct SessionRecord {
    pub(crate) id: u32,
    pub(crate) name: String,
    pub(crate) rig: String,
    pub(crate) layout: String,
    pub(crate) active: AtomicBool,
    pub(crate) end_reason: Mutex<Option<String>>,
    pub(crate) frames: Counter,
    pub(crate) udp_frames: Counter,
    pub(crate) tracked: Counter,
    pub(crate) calibrating: Counter,
    pub(crate) lost: Counter,
    pub(crate) gated: Counter,
    pub(crate) jumps: Counter,
    pub(crate) late: Counter,
    pub(crate) future: Counter,
    pub(crate) malformed: Counter,
    pub(crate) udp_queue_dropped: Counter,
    pub(crate) replies_dropped: Counter,
    pub(crate) unknown_weights: Counter,
    pub(crate) restarts: Counter,
    pub(crate) forwarded: Counter,
    pub(crate) forward_dropped: Counter,
    pub(crate) record: Arc<RecordCounters>,
    pub(crate) recording: Mutex<Option<String>>,
    pub(crate) latency: Mutex<LatencyHistogram>,
    pub(crate) viewers: Mutex<ViewerLog>,
    /// Where the session is stepped, when a [`Placement`] steps it.
    pub(crate) placement: Mutex<Option<Arc<PlacementStatus>>>,
}

/// Departed viewers whose counters a session keeps one by one; older ones are only summed.
pub(crate) const DEPARTED_VIEWERS_KEPT: usize = 16;

/// The viewers of one session, bounded: those attached now (connected, or departed since the
/// last compaction), the last [`DEPARTED_VIEWERS_KEPT`] departed ones, and totals over all.
#[derive(Debug, Default)]
pub(crate) struct ViewerLog {
    attached: Vec<Arc<Viewer>>,
    departed: VecDeque<ViewerSnapshot>,
    departed_count: u64,
    departed_sent: u64,
    departed_dropped: u64,
}

impl ViewerLog {
    /// Moves viewers that have disconnected from the attached list into the summary.
    fn compact(&mut self) {
        let mut k = 0;
        while k < self.attached.len() {
            if self.attached[k].connected.load(Ordering::Acquire) {
                k += 1;
                continue;
            }
            let v = self.attached.remove(k);
            let snap = v.snapshot();
            self.departed_count += 1;
            self.departed_sent += snap.frames_sent;
            self.departed_dropped += snap.frames_dropped;
            if self.departed.len() >= DEPARTED_VIEWERS_KEPT {
                self.departed.pop_front();
            }
            self.departed.push_back(snap);
        }
    }

    /// Attaches a viewer (compacting first, so churn never grows the list).
    pub(crate) fn attach(&mut self, v: Arc<Viewer>) {
        self.compact();
        self.attached.push(v);
    }

    /// Replaces the attached viewers (a session going live on a hub that has viewers waiting).
    pub(crate) fn attach_all(&mut self, vs: &[Arc<Viewer>]) {
        self.compact();
        self.attached.extend(vs.iter().cloned());
    }

    /// Compacts, then the listed viewers (kept departed ones, then attached, by id) and the
    /// totals over every viewer that ever watched: (list, viewers, frames sent, frames dropped).
    fn summary(&mut self) -> (Vec<ViewerSnapshot>, u64, u64, u64) {
        self.compact();
        let mut list: Vec<ViewerSnapshot> = self.departed.iter().cloned().collect();
        let (mut sent, mut dropped) = (self.departed_sent, self.departed_dropped);
        for v in &self.attached {
            let s = v.snapshot();
            sent += s.frames_sent;
            dropped += s.frames_dropped;
            list.push(s);
        }
        list.sort_by_key(|v| v.id);
        let total = self.departed_count + self.attached.len() as u64;
        (list, total, sent, dropped)
    }
}

impl SessionRecord {
    /// A live session's record with every counter at 0.
    pub(crate) fn new(id: u32, name: &str, rig: &str, layout: &str) -> Self {
        Self {
            id,
            name: name.to_string(),
            rig: rig.to_string(),
            layout: layout.to_string(),
            active: AtomicBool::new(true),
            end_reason: Mutex::new(None),
            frames: Counter::default(),
            udp_frames: Counter::default(),
            tracked: Counter::default(),
            calibrating: Counter::default(),
            lost: Counter::default(),
            gated: Counter::default(),
            jumps: Counter::default(),
            late: Counter::default(),
            future: Counter::default(),
            malformed: Counter::default(),
            udp_queue_dropped: Counter::default(),
            replies_dropped: Counter::default(),
            unknown_weights: Counter::default(),
            restarts: Counter::default(),
            forwarded: Counter::default(),
            forward_dropped: Counter::default(),
            record: Arc::default(),
            recording: Mutex::new(None),
            latency: Mutex::new(LatencyHistogram::default()),
            viewers: Mutex::new(ViewerLog::default()),
            placement: Mutex::new(None),
        }
    }

    /// The counters as the stats report them.
    pub(crate) fn snapshot(&self) -> SessionSnapshot {
        let (viewers, viewers_total, viewer_frames_sent, viewer_frames_dropped) =
            lock(&self.viewers).summary();
        SessionSnapshot {
            id: self.id,
            name: self.name.clone(),
            rig: self.rig.clone(),
            layout: self.layout.clone(),
            active: self.active.load(Ordering::Relaxed),
            end_reason: lock(&self.end_reason).clone(),
            frames: self.frames.get(),
            udp_frames: self.udp_frames.get(),
            tracked: self.tracked.get(),
            calibrating: self.calibrating.get(),
            lost: self.lost.get(),
            gated: self.gated.get(),
            jumps: self.jumps.get(),
            late: self.late.get(),
            future: self.future.get(),
            malformed: self.malformed.get(),
            udp_queue_dropped: self.udp_queue_dropped.get(),
            replies_dropped: self.replies_dropped.get(),
            unknown_weights: self.unknown_weights.get(),
            restarts: self.restarts.get(),
            recording: lock(&self.recording).clone(),
            recorded: self.record.recorded.get(),
            record_lost: self.record.lost.get(),
            record_waits: self.record.waits.get(),
            forwarded: self.forwarded.get(),
            forward_dropped: self.forward_dropped.get(),
            latency: lock(&self.latency).summary(),
            viewers,
            viewers_total,
            viewer_frames_sent,
            viewer_frames_dropped,
            cluster: lock(&self.placement).as_ref().map(|p| p.snapshot()),
        }
    }
}

/// The tracker currently feeding a hub, and what a viewer joining it gets first.
#[derive(Debug)]
pub(crate) struct Live {
    pub(crate) session_message: Message,
    pub(crate) rig_message: Message,
    pub(crate) record: Arc<SessionRecord>,
}

/// Everything attached to one session name: its viewers and, while one is connected, its tracker.
#[derive(Debug, Default)]
pub(crate) struct Hub {
    pub(crate) viewers: Vec<Arc<Viewer>>,
    pub(crate) live: Option<Live>,
    /// A session live on another front door that this hub follows: its SESSION and RIG messages.
    pub(crate) remote: Option<(Message, Message)>,
    /// The follower task of this hub (its number), when the server has a placement.
    pub(crate) following: Option<u64>,
}

/// Where a UDP frame for a session goes.
#[derive(Debug)]
pub(crate) struct Route {
    /// The key the session's welcome line gave its tracker.
    pub(crate) key: u32,
    /// The address the tracker's TCP hello came from: packets must come from it.
    pub(crate) peer_ip: Option<IpAddr>,
    /// The source (address and port) of the session's first accepted packet: later packets
    /// must come from it.
    pub(crate) source: Option<SocketAddr>,
    /// The session's bounded packet queue.
    pub(crate) tx: mpsc::Sender<(Instant, LandmarkFrame)>,
    /// The session's counters (a full queue is counted there).
    pub(crate) record: Arc<SessionRecord>,
}
