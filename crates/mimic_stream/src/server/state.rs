//! State shared by every task of a server: session records and their counters, the hubs viewers
//! join by session name, UDP routes, and the stats built from them.

use super::udp::Route;
use super::viewer::Viewer;
use crate::catalog::Catalog;
use crate::placement::{Placement, PlacementStatus};
use crate::queue::Message;
use crate::record::RecordCounters;
use crate::settings::ServerSettings;
use crate::stats::{Counter, LatencyHistogram, ServerStats, SessionSnapshot, ViewerSnapshot};
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

/// Locks `m`, taking the data of a poisoned lock as it is (counters stay readable).
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
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

/// State shared by every task of a server.
#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) catalog: Arc<Catalog>,
    pub(crate) settings: ServerSettings,
    pub(crate) started: Instant,
    pub(crate) hubs: Mutex<HashMap<String, Hub>>,
    pub(crate) routes: Mutex<HashMap<u32, Route>>,
    pub(crate) sessions: Mutex<Vec<Arc<SessionRecord>>>,
    pub(crate) next_session: AtomicU32,
    pub(crate) next_viewer: AtomicU64,
    pub(crate) sessions_active: AtomicUsize,
    pub(crate) peers: Mutex<HashMap<std::net::IpAddr, usize>>,
    pub(crate) viewers_active: AtomicUsize,
    pub(crate) connections: Counter,
    pub(crate) refused: Counter,
    pub(crate) udp_bad: Counter,
    pub(crate) udp_wrong_key: Counter,
    pub(crate) udp_wrong_source: Counter,
    pub(crate) recordings_open: Arc<AtomicUsize>,
    pub(crate) keys: std::collections::hash_map::RandomState,
    /// Where landmark sessions are stepped when not here (`None`: here, the default).
    pub(crate) placement: Option<Arc<dyn Placement>>,
    /// Numbers of follower tasks.
    pub(crate) next_follower: AtomicU64,
}

impl Shared {
    /// A server's state before its first connection.
    pub(crate) fn new(catalog: Arc<Catalog>, settings: ServerSettings) -> Self {
        Self {
            catalog,
            settings,
            started: Instant::now(),
            hubs: Mutex::new(HashMap::new()),
            routes: Mutex::new(HashMap::new()),
            sessions: Mutex::new(Vec::new()),
            next_session: AtomicU32::new(1),
            next_viewer: AtomicU64::new(1),
            sessions_active: AtomicUsize::new(0),
            peers: Mutex::new(HashMap::new()),
            viewers_active: AtomicUsize::new(0),
            connections: Counter::default(),
            refused: Counter::default(),
            udp_bad: Counter::default(),
            udp_wrong_key: Counter::default(),
            udp_wrong_source: Counter::default(),
            recordings_open: Arc::new(AtomicUsize::new(0)),
            keys: std::collections::hash_map::RandomState::new(),
            placement: None,
            next_follower: AtomicU64::new(1),
        }
    }

    /// Counters of the server, its live sessions and the most recent ended ones.
    pub(crate) fn stats(&self) -> ServerStats {
        let sessions: Vec<SessionSnapshot> =
            lock(&self.sessions).iter().map(|s| s.snapshot()).collect();
        let mut all = LatencyHistogram::default();
        for s in lock(&self.sessions).iter() {
            all.merge(&lock(&s.latency));
        }
        ServerStats {
            uptime_s: self.started.elapsed().as_secs_f64(),
            connections: self.connections.get(),
            refused: self.refused.get(),
            sessions_active: self.sessions_active.load(Ordering::Relaxed) as u64,
            viewers_active: self.viewers_active.load(Ordering::Relaxed) as u64,
            udp_bad_packets: self.udp_bad.get(),
            udp_wrong_key: self.udp_wrong_key.get(),
            udp_wrong_source: self.udp_wrong_source.get(),
            latency: all.summary(),
            viewer_frames_dropped: sessions.iter().map(|s| s.viewer_frames_dropped).sum(),
            sessions,
        }
    }

    /// The stats as one JSON object.
    pub(crate) fn stats_json(&self) -> String {
        serde_json::to_string(&self.stats()).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }

    /// Makes `record` the live tracker of session `name`: viewers already waiting get the session
    /// and rig messages, and the session joins the stats list, which keeps every live session and
    /// at most `ended_sessions_kept` ended ones. Returns false, changing nothing, when the session
    /// already has a live tracker.
    pub(crate) fn go_live(
        &self,
        name: &str,
        record: &Arc<SessionRecord>,
        session_message: Message,
        rig_message: &Message,
    ) -> bool {
        {
            let mut hubs = lock(&self.hubs);
            let hub = hubs.entry(name.to_string()).or_default();
            if hub.live.is_some() {
                return false;
            }
            for v in &hub.viewers {
                v.queue.push_control(session_message.clone(), true);
                v.queue.push_control(rig_message.clone(), false);
            }
            lock(&record.viewers).attach_all(&hub.viewers);
            hub.live = Some(Live {
                session_message,
                rig_message: rig_message.clone(),
                record: record.clone(),
            });
        }
        let mut sessions = lock(&self.sessions);
        sessions.push(record.clone());
        let ended = sessions
            .iter()
            .filter(|s| !s.active.load(Ordering::Relaxed))
            .count();
        if ended > self.settings.ended_sessions_kept
            && let Some(i) = sessions
                .iter()
                .position(|s| !s.active.load(Ordering::Relaxed))
        {
            sessions.remove(i);
        }
        true
    }

    /// Ends the live tracker of session `name`: its viewers get `end_message`, and a hub left
    /// without viewers goes.
    pub(crate) fn go_offline(&self, name: &str, end_message: Message) {
        let mut hubs = lock(&self.hubs);
        if let Some(hub) = hubs.get_mut(name) {
            hub.viewers
                .iter()
                .for_each(|v| v.queue.push_control(end_message.clone(), false));
            hub.live = None;
            if hub.viewers.is_empty() {
                hubs.remove(name);
            }
        }
    }
}
