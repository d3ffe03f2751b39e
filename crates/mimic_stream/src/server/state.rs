//! State shared by every task of a server: the session records, the hubs viewers join by session
//! name and the UDP routes (their types in `hub`), the server's counters, and the stats built
//! from them.

use super::hub::{Hub, Live, Route, SessionRecord};
use crate::catalog::Catalog;
use crate::counter::Counter;
use crate::placement::Placement;
use crate::queue::Message;
use crate::settings::ServerSettings;
use crate::stats::{LatencyHistogram, ServerStats, SessionSnapshot};
use crate::sync::lock;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

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
    pub(crate) udp_refused: Counter,
    pub(crate) http_refused: Counter,
    pub(crate) http_connections: AtomicUsize,
    /// UDP intake sessions live now (OpenSeeFace and Live Link together; `max_udp_sessions`).
    pub(crate) udp_sessions_active: AtomicUsize,
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
            udp_refused: Counter::default(),
            http_refused: Counter::default(),
            http_connections: AtomicUsize::new(0),
            udp_sessions_active: AtomicUsize::new(0),
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
            udp_refused: self.udp_refused.get(),
            http_refused: self.http_refused.get(),
            http_connections: self.http_connections.load(Ordering::Relaxed) as u64,
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
