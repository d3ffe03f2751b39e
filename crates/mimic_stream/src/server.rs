//! The server: accept loop, hello dispatch, session hubs, UDP intake, stats and shutdown.

use crate::catalog::{Catalog, RigEntry};
use crate::lines::{Line, LineReader};
use crate::queue::{Message, ViewerQueue};
use crate::record::{RecordCounters, Recorder, SessionLabel};
use crate::settings::ServerSettings;
use crate::stats::{Counter, LatencyHistogram, ServerStats, SessionSnapshot, ViewerSnapshot};
use crate::timing::{FrameClock, TimeProblem};
use crate::wire::{
    self, ErrorCode, Hello, KIND_END, KIND_ERROR, KIND_SESSION, encode_frame, encode_json,
    error_line,
};
use glam::Vec3;
use mimic_capture::{FrameProblem, RecordedFrame, RecordingHeader, parse_frame_line};
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_types::LandmarkFrame;
use serde_json::json;
use std::collections::HashMap;
use std::future::Future;
use std::hash::{BuildHasher, Hasher};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;
use tokio::io::{AsyncWrite, AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{Semaphore, mpsc, watch};
use tokio::time::{sleep, sleep_until, timeout};

mod weights;

/// Longest first line of a connection (hello or recording header), unless the message limit is
/// smaller: a connection that has not said what it is holds at most this much.
pub const HELLO_MAX_BYTES: usize = 64 * 1024;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// One connected viewer.
#[derive(Debug)]
struct Viewer {
    id: u64,
    session: String,
    positions: bool,
    queue: ViewerQueue,
    connected: AtomicBool,
}

impl Viewer {
    fn snapshot(&self) -> ViewerSnapshot {
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
struct SessionRecord {
    id: u32,
    name: String,
    rig: String,
    layout: String,
    active: AtomicBool,
    end_reason: Mutex<Option<String>>,
    frames: Counter,
    udp_frames: Counter,
    tracked: Counter,
    calibrating: Counter,
    lost: Counter,
    late: Counter,
    future: Counter,
    malformed: Counter,
    udp_queue_dropped: Counter,
    replies_dropped: Counter,
    unknown_weights: Counter,
    record: Arc<RecordCounters>,
    recording: Mutex<Option<String>>,
    latency: Mutex<LatencyHistogram>,
    viewers: Mutex<Vec<Arc<Viewer>>>,
}

impl SessionRecord {
    /// A live session's record with every counter at 0.
    fn new(id: u32, name: &str, rig: &str, layout: &str) -> Self {
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
            late: Counter::default(),
            future: Counter::default(),
            malformed: Counter::default(),
            udp_queue_dropped: Counter::default(),
            replies_dropped: Counter::default(),
            unknown_weights: Counter::default(),
            record: Arc::default(),
            recording: Mutex::new(None),
            latency: Mutex::new(LatencyHistogram::default()),
            viewers: Mutex::new(Vec::new()),
        }
    }

    fn snapshot(&self) -> SessionSnapshot {
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
            latency: lock(&self.latency).summary(),
            viewers: lock(&self.viewers).iter().map(|v| v.snapshot()).collect(),
        }
    }
}

/// The tracker currently feeding a hub, and what a viewer joining it gets first.
#[derive(Debug)]
struct Live {
    session_message: Message,
    rig_message: Message,
    record: Arc<SessionRecord>,
}

/// Everything attached to one session name: its viewers and, while one is connected, its tracker.
#[derive(Debug, Default)]
struct Hub {
    viewers: Vec<Arc<Viewer>>,
    live: Option<Live>,
}

/// Where a UDP frame for a session goes.
#[derive(Debug)]
struct Route {
    key: u32,
    tx: mpsc::Sender<(Instant, LandmarkFrame)>,
    record: Arc<SessionRecord>,
}

/// State shared by every task of a server.
#[derive(Debug)]
struct Shared {
    catalog: Arc<Catalog>,
    settings: ServerSettings,
    started: Instant,
    hubs: Mutex<HashMap<String, Hub>>,
    routes: Mutex<HashMap<u32, Route>>,
    sessions: Mutex<Vec<Arc<SessionRecord>>>,
    next_session: AtomicU32,
    next_viewer: AtomicU64,
    sessions_active: AtomicUsize,
    viewers_active: AtomicUsize,
    connections: Counter,
    refused: Counter,
    udp_bad: Counter,
    recordings_open: Arc<AtomicUsize>,
    keys: std::collections::hash_map::RandomState,
}

/// A live-session server: trackers in (TCP lines, UDP packets), viewers out (TCP messages).
#[derive(Debug, Clone)]
pub struct Server {
    shared: Arc<Shared>,
}

impl Server {
    /// A server offering the catalog's rigs and layouts under these limits.
    pub fn new(catalog: Arc<Catalog>, settings: ServerSettings) -> Self {
        Self {
            shared: Arc::new(Shared {
                catalog,
                settings,
                started: Instant::now(),
                hubs: Mutex::new(HashMap::new()),
                routes: Mutex::new(HashMap::new()),
                sessions: Mutex::new(Vec::new()),
                next_session: AtomicU32::new(1),
                next_viewer: AtomicU64::new(1),
                sessions_active: AtomicUsize::new(0),
                viewers_active: AtomicUsize::new(0),
                connections: Counter::default(),
                refused: Counter::default(),
                udp_bad: Counter::default(),
                recordings_open: Arc::new(AtomicUsize::new(0)),
                keys: std::collections::hash_map::RandomState::new(),
            }),
        }
    }

    /// Counters of the server, its live sessions and the most recent ended ones.
    pub fn stats(&self) -> ServerStats {
        self.shared.stats()
    }

    /// Clears every session's latency histogram (e.g. after a warm-up), keeping the counters.
    pub fn reset_latency(&self) {
        for s in lock(&self.shared.sessions).iter() {
            *lock(&s.latency) = LatencyHistogram::default();
        }
    }

    /// Serves until `shutdown` completes; then stops accepting, ends every session (frames
    /// already read are retargeted and broadcast), lets viewers drain their queues for up to
    /// `shutdown_grace`, and returns the final counters.
    pub async fn run(
        &self,
        listener: TcpListener,
        udp: Option<UdpSocket>,
        shutdown: impl Future<Output = ()>,
    ) -> ServerStats {
        let shared = &self.shared;
        let settings = &shared.settings;
        let (stop_tx, stop_rx) = watch::channel(false);
        let (done_tx, mut done_rx) = mpsc::channel::<()>(1);
        let permits = Arc::new(Semaphore::new(
            settings.max_sessions + settings.max_viewers + 16,
        ));
        if let Some(udp) = udp {
            tokio::spawn(udp_loop(
                shared.clone(),
                udp,
                stop_rx.clone(),
                done_tx.clone(),
            ));
        }
        tokio::pin!(shutdown);
        loop {
            let permit = tokio::select! {
                _ = &mut shutdown => break,
                p = permits.clone().acquire_owned() => p,
            };
            let Ok(permit) = permit else { break };
            let accepted = tokio::select! {
                _ = &mut shutdown => break,
                a = listener.accept() => a,
            };
            match accepted {
                Ok((socket, peer)) => {
                    shared.connections.bump();
                    tracing::debug!(%peer, "connection");
                    let (shared, stop, done) = (shared.clone(), stop_rx.clone(), done_tx.clone());
                    tokio::spawn(async move {
                        connection(shared, socket, stop).await;
                        drop(permit);
                        drop(done);
                    });
                }
                Err(e) => {
                    // E.g. out of file descriptors: back off instead of spinning.
                    tracing::warn!("accept failed: {e}");
                    sleep(std::time::Duration::from_millis(50)).await;
                }
            }
        }
        drop(listener);
        tracing::info!("shutting down");
        let _ = stop_tx.send(true);
        let deadline = tokio::time::Instant::now() + settings.shutdown_grace;
        // Sessions end first (their END message reaches the viewers), then the viewer queues close.
        while shared.sessions_active.load(Ordering::Acquire) > 0
            && tokio::time::Instant::now() < deadline
        {
            sleep(std::time::Duration::from_millis(5)).await;
        }
        for hub in lock(&shared.hubs).values() {
            hub.viewers.iter().for_each(|v| v.queue.close());
        }
        drop(done_tx);
        let _ = tokio::time::timeout_at(deadline, done_rx.recv()).await;
        // Accepted frames are never given up: wait (past the grace) until every session's
        // recording has written, flushed and synced what it was given.
        let mut waited = 0u32;
        while shared.recordings_open.load(Ordering::Acquire) > 0 {
            if waited % 1000 == 999 {
                tracing::warn!(
                    open = shared.recordings_open.load(Ordering::Acquire),
                    "waiting for session recordings to reach the disk"
                );
            }
            waited = waited.wrapping_add(1);
            sleep(std::time::Duration::from_millis(5)).await;
        }
        let stats = shared.stats();
        for s in &stats.sessions {
            tracing::info!(session = %s.name, frames = s.frames, late = s.late, malformed = s.malformed,
                p50_us = s.latency.p50_us, p99_us = s.latency.p99_us, "final session counters");
        }
        stats
    }
}

impl Shared {
    fn stats(&self) -> ServerStats {
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
            latency: all.summary(),
            viewer_frames_dropped: sessions
                .iter()
                .flat_map(|s| &s.viewers)
                .map(|v| v.frames_dropped)
                .sum(),
            sessions,
        }
    }

    fn stats_json(&self) -> String {
        serde_json::to_string(&self.stats()).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }
}

/// Writes one error reply and shuts the write side; errors writing are the peer's problem.
async fn refuse<W: AsyncWrite + Unpin>(w: &mut W, bytes: &[u8]) {
    let _ = timeout(std::time::Duration::from_secs(2), async {
        let _ = w.write_all(bytes).await;
        let _ = w.shutdown().await;
    })
    .await;
}

/// One TCP connection: read the hello, then serve it as a tracker, viewer or stats request.
async fn connection(shared: Arc<Shared>, socket: TcpStream, mut stop: watch::Receiver<bool>) {
    let _ = socket.set_nodelay(true);
    let peer = socket.peer_addr().ok();
    let (r, mut w) = socket.into_split();
    let hello_limit = shared.settings.max_message_bytes.min(HELLO_MAX_BYTES);
    let mut lines = LineReader::new(BufReader::new(r), hello_limit);
    let idle = shared.settings.idle_timeout;
    let read = tokio::select! {
        _ = stop.changed() => return,
        _ = sleep(idle) => {
            shared.refused.bump();
            refuse(&mut w, error_line(ErrorCode::IdleTimeout, 1, "no hello").as_bytes()).await;
            return;
        }
        l = lines.next_line() => l,
    };
    let hello = match read {
        Ok(Line::Complete | Line::Partial) => wire::parse_hello(lines.line()),
        Ok(Line::TooLong) => {
            shared.refused.bump();
            let msg = format!("hello longer than {hello_limit} bytes");
            refuse(&mut w, error_line(ErrorCode::TooLong, 1, &msg).as_bytes()).await;
            return;
        }
        Ok(Line::Eof) | Err(_) => return,
    };
    // Trackers' frame lines may be as long as the message limit.
    lines.set_limit(shared.settings.max_message_bytes);
    match hello {
        Err(e) => {
            shared.refused.bump();
            refuse(
                &mut w,
                error_line(ErrorCode::BadHello, 1, &e.to_string()).as_bytes(),
            )
            .await;
        }
        Ok(Hello::Stats) => {
            let mut s = shared.stats_json();
            s.push('\n');
            refuse(&mut w, s.as_bytes()).await;
        }
        Ok(Hello::HttpGet { path }) => {
            let (status, body) = if path == "/stats" {
                ("200 OK", shared.stats_json())
            } else {
                ("404 Not Found", "{\"error\":\"only /stats\"}".to_string())
            };
            let reply = format!(
                "HTTP/1.0 {status}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
                body.len()
            );
            refuse(&mut w, reply.as_bytes()).await;
        }
        Ok(Hello::Viewer { session, positions }) => {
            viewer(shared, lines, w, session, positions).await;
        }
        Ok(Hello::Tracker {
            header,
            session,
            rig,
        }) => {
            let hello = TrackerHello {
                header,
                session,
                rig,
                peer,
            };
            tracker(shared, lines, w, hello, stop).await;
        }
        Ok(Hello::Weights {
            session,
            rig,
            rate_hz,
            source,
        }) => {
            let hello = weights::WeightsHello {
                session,
                rig,
                rate_hz,
                source,
            };
            weights::session(shared, lines, w, hello, stop).await;
        }
    }
}

/// A viewer: attach to the hub, forward its queue, detach.
async fn viewer(
    shared: Arc<Shared>,
    lines: LineReader<BufReader<OwnedReadHalf>>,
    mut w: OwnedWriteHalf,
    session: String,
    positions: bool,
) {
    let settings = &shared.settings;
    if shared.viewers_active.fetch_add(1, Ordering::AcqRel) >= settings.max_viewers {
        shared.viewers_active.fetch_sub(1, Ordering::AcqRel);
        shared.refused.bump();
        let m = encode_json(
            KIND_ERROR,
            &json!({"code": ErrorCode::TooManyViewers.name(), "message": format!("at most {} viewers", settings.max_viewers)}),
        );
        refuse(&mut w, &m).await;
        return;
    }
    let v = Arc::new(Viewer {
        id: shared.next_viewer.fetch_add(1, Ordering::Relaxed),
        session: session.clone(),
        positions,
        queue: ViewerQueue::new(settings.viewer_queue_frames),
        connected: AtomicBool::new(true),
    });
    {
        let mut hubs = lock(&shared.hubs);
        let hub = hubs.entry(session.clone()).or_default();
        if let Some(live) = &hub.live {
            v.queue.push_control(live.session_message.clone(), true);
            v.queue.push_control(live.rig_message.clone(), false);
            lock(&live.record.viewers).push(v.clone());
        }
        hub.viewers.push(v.clone());
    }
    tracing::info!(viewer = v.id, session = %session, positions, "viewer joined");
    // The viewer sends nothing after its hello; reading (and discarding, through the reader's
    // fixed buffer) tells us when it goes away.
    let watcher = {
        let v = v.clone();
        let mut r = lines.into_inner();
        tokio::spawn(async move {
            let _ = tokio::io::copy(&mut r, &mut tokio::io::sink()).await;
            v.queue.abandon();
        })
    };
    while let Some(m) = v.queue.pop().await {
        match timeout(settings.viewer_write_timeout, w.write_all(&m)).await {
            Ok(Ok(())) => {}
            _ => {
                v.queue.abandon();
                break;
            }
        }
    }
    let _ = timeout(std::time::Duration::from_secs(1), w.shutdown()).await;
    watcher.abort();
    v.connected.store(false, Ordering::Relaxed);
    {
        let mut hubs = lock(&shared.hubs);
        if let Some(hub) = hubs.get_mut(&session) {
            hub.viewers.retain(|x| !Arc::ptr_eq(x, &v));
            if hub.viewers.is_empty() && hub.live.is_none() {
                hubs.remove(&session);
            }
        }
    }
    shared.viewers_active.fetch_sub(1, Ordering::AcqRel);
    tracing::info!(
        viewer = v.id,
        session = %session,
        sent = v.queue.sent.get(),
        dropped = v.queue.dropped.get(),
        "viewer left"
    );
}

/// Per-session state of the frame path.
struct Pipeline {
    shared: Arc<Shared>,
    rig: Arc<RigEntry>,
    record: Arc<SessionRecord>,
    retargeter: Retargeter,
    out: mimic_retarget::FrameOutput,
    positions: Vec<Vec3>,
    scratch: Vec<Vec3>,
    clock: FrameClock,
    point_count: usize,
    multi_thread: bool,
}

/// What became of a frame handed to a session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    /// Retargeted and broadcast (counted in `frames`).
    Accepted,
    /// Dropped for its timestamp (counted in `late` or `future`).
    Refused(TimeProblem),
    /// Wrong point count or refused by the pipeline (counted in `malformed`).
    Malformed,
}

/// Checks a frame's timestamp against the session clock, counting a refusal.
fn check_time(
    clock: &mut FrameClock,
    record: &SessionRecord,
    t_us: i64,
    arrival: Instant,
) -> Result<(), TimeProblem> {
    clock.advance(t_us, arrival).inspect_err(|p| match p {
        TimeProblem::Late => record.late.bump(),
        TimeProblem::Future { .. } => record.future.bump(),
    })
}

/// The error line answering a frame from the future.
fn future_line(line_no: u64, t_us: i64, jump_us: u64, allowed_us: u64) -> String {
    error_line(
        ErrorCode::FutureTimestamp,
        line_no,
        &format!(
            "t_us {t_us} is {jump_us} us after the last accepted frame; at most {allowed_us} us \
             (the time between their arrivals plus the allowed jump) is taken"
        ),
    )
}

/// Sends frame `seq` to the viewers of session `r`: pose and `d` to those that asked for `d`, the
/// full positions (filled by `fill` from `d`, only when some viewer wants them) to the others;
/// then records the frame's arrival-to-broadcast latency.
fn broadcast(
    shared: &Shared,
    r: &SessionRecord,
    seq: u64,
    out: &mimic_retarget::FrameOutput,
    positions: &mut [Vec3],
    fill: impl FnOnce(&[Vec3], &mut [Vec3]),
    arrival: Instant,
) {
    let (want_d, want_positions) = {
        let hubs = lock(&shared.hubs);
        hubs.get(&r.name).map_or((false, false), |h| {
            (
                h.viewers.iter().any(|v| !v.positions),
                h.viewers.iter().any(|v| v.positions),
            )
        })
    };
    let d_message = want_d.then(|| Arc::new(encode_frame(seq, out, None)));
    let p_message = want_positions.then(|| {
        fill(&out.displacements, positions);
        Arc::new(encode_frame(seq, out, Some(positions)))
    });
    {
        let hubs = lock(&shared.hubs);
        if let Some(h) = hubs.get(&r.name) {
            for v in &h.viewers {
                let m = if v.positions { &p_message } else { &d_message };
                if let Some(m) = m {
                    v.queue.push_frame(m.clone());
                }
            }
        }
    }
    let us = u64::try_from(arrival.elapsed().as_micros()).unwrap_or(u64::MAX);
    tracing::trace!(session = %r.name, seq, us, "broadcast");
    lock(&r.latency).record(us);
}

impl Pipeline {
    /// Retargets one frame and broadcasts it; late frames and frames from the future are
    /// dropped and counted.
    fn accept(&mut self, frame: &LandmarkFrame, arrival: Instant, udp: bool) -> Outcome {
        let r = &self.record;
        if let Err(p) = check_time(&mut self.clock, r, frame.timestamp_us, arrival) {
            return Outcome::Refused(p);
        }
        let status = if self.retargeter.source_to_target().is_none() && self.multi_thread {
            // Finishing the neutral fits the source-to-target map (a consensus search of up to
            // tens of milliseconds): let the runtime move other sessions off this worker meanwhile.
            tokio::task::block_in_place(|| self.retargeter.step(frame, &mut self.out))
        } else {
            self.retargeter.step(frame, &mut self.out)
        };
        match status {
            FrameStatus::Tracked => r.tracked.bump(),
            FrameStatus::Calibrating => r.calibrating.bump(),
            FrameStatus::Lost => r.lost.bump(),
            FrameStatus::Rejected => {
                r.malformed.bump();
                return Outcome::Malformed;
            }
        }
        let seq = r.frames.get();
        r.frames.bump();
        if udp {
            r.udp_frames.bump();
        }
        let (rig, scratch) = (&self.rig, &mut self.scratch);
        broadcast(
            &self.shared,
            r,
            seq,
            &self.out,
            &mut self.positions,
            |d, positions| rig.deform(d, scratch, positions),
            arrival,
        );
        Outcome::Accepted
    }

    /// A UDP frame: checked against the layout (no reply over UDP), then accepted.
    fn accept_udp(&mut self, frame: &LandmarkFrame, arrival: Instant) -> Outcome {
        let count = frame.points.len();
        if (frame.tracked || count > 0) && count != self.point_count {
            self.record.malformed.bump();
            return Outcome::Malformed;
        }
        self.accept(frame, arrival, true)
    }
}

/// A session's recording: off, on, or asked for but not started (its frames count as lost).
#[derive(Debug)]
enum Recording {
    Off,
    On(Recorder),
    Failed(Arc<RecordCounters>),
}

/// Hands an accepted frame to the session's recording, if the server records.
async fn record_frame(recording: &Recording, outcome: Outcome, f: RecordedFrame) {
    if outcome != Outcome::Accepted {
        return;
    }
    match recording {
        Recording::Off => {}
        Recording::On(r) => r.record(f).await,
        Recording::Failed(c) => c.lost.bump(),
    }
}

/// Starts a session's recording when the server records; a failure is logged, and the
/// session's accepted frames are then counted as `record_lost`.
async fn start_recording(
    shared: &Shared,
    header: &RecordingHeader,
    who: &SessionLabel<'_>,
    record: &SessionRecord,
) -> Recording {
    let Some(dir) = shared.settings.record_dir.as_ref() else {
        return Recording::Off;
    };
    let started = Recorder::start(
        dir,
        header,
        who,
        shared.settings.record_queue_frames,
        record.record.clone(),
        shared.recordings_open.clone(),
    )
    .await;
    match started {
        Ok(r) => {
            *lock(&record.recording) = Some(r.path().display().to_string());
            tracing::info!(session = %who.name, path = %r.path().display(), "recording");
            Recording::On(r)
        }
        Err(e) => {
            tracing::error!(session = %who.name, "not recorded; its accepted frames count as record_lost: {e}");
            Recording::Failed(record.record.clone())
        }
    }
}

/// Queues a reply line to the tracker; dropped (and counted) if the tracker does not read.
fn reply(tx: &mpsc::Sender<String>, record: &SessionRecord, line: String) {
    if tx.try_send(line).is_err() {
        record.replies_dropped.bump();
    }
}

/// Counts and answers a tracker that sent nothing for `settings.idle_timeout`.
fn reply_idle_timeout(
    tx: &mpsc::Sender<String>,
    record: &SessionRecord,
    settings: &ServerSettings,
    line_no: u64,
) {
    record.malformed.bump();
    let message = format!(
        "nothing received for {} s",
        settings.idle_timeout.as_secs_f64()
    );
    reply(
        tx,
        record,
        error_line(ErrorCode::IdleTimeout, line_no, &message),
    );
}

/// Counts and answers malformed line `line_no`; true when it makes `max_errors_in_a_row` in a
/// row (the closing error is sent too) and the session must end.
fn reply_malformed(
    tx: &mpsc::Sender<String>,
    record: &SessionRecord,
    settings: &ServerSettings,
    errors_in_a_row: &mut u32,
    line_no: u64,
    code: ErrorCode,
    message: &str,
) -> bool {
    record.malformed.bump();
    *errors_in_a_row += 1;
    reply(tx, record, error_line(code, line_no, message));
    if *errors_in_a_row < settings.max_errors_in_a_row {
        return false;
    }
    let closing = format!("{errors_in_a_row} malformed messages in a row; closing");
    reply(
        tx,
        record,
        error_line(ErrorCode::TooManyErrors, line_no, &closing),
    );
    true
}

/// Makes `record` the live tracker of session `name`: viewers already waiting get the session and
/// rig messages, and the session joins the stats list, which keeps every live session and at most
/// `ended_sessions_kept` ended ones. Returns false, changing nothing, when the session already has
/// a live tracker.
fn go_live(
    shared: &Shared,
    name: &str,
    record: &Arc<SessionRecord>,
    session_message: Message,
    rig_message: &Message,
) -> bool {
    {
        let mut hubs = lock(&shared.hubs);
        let hub = hubs.entry(name.to_string()).or_default();
        if hub.live.is_some() {
            return false;
        }
        for v in &hub.viewers {
            v.queue.push_control(session_message.clone(), true);
            v.queue.push_control(rig_message.clone(), false);
        }
        *lock(&record.viewers) = hub.viewers.clone();
        hub.live = Some(Live {
            session_message,
            rig_message: rig_message.clone(),
            record: record.clone(),
        });
    }
    let mut sessions = lock(&shared.sessions);
    sessions.push(record.clone());
    let ended = sessions
        .iter()
        .filter(|s| !s.active.load(Ordering::Relaxed))
        .count();
    if ended > shared.settings.ended_sessions_kept
        && let Some(i) = sessions
            .iter()
            .position(|s| !s.active.load(Ordering::Relaxed))
    {
        sessions.remove(i);
    }
    true
}

/// What a tracker's first line asked for, and who it is.
#[derive(Debug)]
struct TrackerHello {
    header: Box<RecordingHeader>,
    session: Option<String>,
    rig: Option<String>,
    peer: Option<SocketAddr>,
}

/// A tracker session: set up the pipeline, then retarget its lines (and UDP packets) until it ends.
async fn tracker(
    shared: Arc<Shared>,
    mut lines: LineReader<BufReader<OwnedReadHalf>>,
    mut w: OwnedWriteHalf,
    hello: TrackerHello,
    mut stop: watch::Receiver<bool>,
) {
    let TrackerHello {
        header,
        session,
        rig: rig_name,
        peer,
    } = hello;
    let settings = &shared.settings;
    let refuse_with = |code: ErrorCode, msg: String| error_line(code, 1, &msg);
    let Some(layout) = shared.catalog.layout(&header.layout) else {
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::UnknownLayout,
            format!("no layout `{}`", header.layout),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    };
    let Some(rig) = shared.catalog.rig(rig_name.as_deref()).cloned() else {
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::UnknownRig,
            format!(
                "no rig `{}`; this server has {:?}",
                rig_name.unwrap_or_default(),
                shared.catalog.rig_names()
            ),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    };
    if let Some(c) = header.point_count
        && c != layout.point_count
    {
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::UnknownLayout,
            format!(
                "header says {c} points, layout `{}` has {}",
                layout.name, layout.point_count
            ),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    }
    let retarget = RetargetSettings {
        positions: false,
        normals: false,
        ..settings.retarget.clone()
    };
    let retargeter = match Retargeter::new(&rig.rig, layout, rig.basis.clone(), retarget) {
        Ok(r) => r,
        Err(e) => {
            shared.refused.bump();
            let m = refuse_with(ErrorCode::UnknownLayout, e.to_string());
            refuse(&mut w, m.as_bytes()).await;
            return;
        }
    };
    if shared.sessions_active.fetch_add(1, Ordering::AcqRel) >= settings.max_sessions {
        shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::TooManySessions,
            format!("at most {} sessions", settings.max_sessions),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    }
    let id = shared.next_session.fetch_add(1, Ordering::Relaxed);
    let name = session.unwrap_or_else(|| format!("s{id}"));
    let record = Arc::new(SessionRecord::new(id, &name, rig.name(), &layout.name));
    let session_message = Arc::new(encode_json(
        KIND_SESSION,
        &json!({
            "session": name, "session_id": id, "rig": rig.name(), "layout": layout.name,
            "vertices": rig.rig.mesh.vertex_count(), "controls": rig.rig.controls.len(),
            "source": header.source, "rate_hz": header.rate_hz,
        }),
    ));
    if !go_live(&shared, &name, &record, session_message, &rig.message) {
        shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::SessionBusy,
            format!("session `{name}` already has a tracker"),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    }
    let who = SessionLabel {
        name: &name,
        id,
        rig: rig.name(),
        peer,
    };
    let mut recorded_header = (*header).clone();
    recorded_header.point_count = Some(layout.point_count);
    let recorder = start_recording(&shared, &recorded_header, &who, &record).await;
    let key = {
        let mut h = shared.keys.build_hasher();
        h.write_u32(id);
        h.write_u128(shared.started.elapsed().as_nanos());
        h.finish() as u32
    };
    let (udp_tx, mut udp_rx) = mpsc::channel(settings.udp_queue_frames.max(1));
    lock(&shared.routes).insert(
        id,
        Route {
            key,
            tx: udp_tx,
            record: record.clone(),
        },
    );
    // Replies go through a bounded queue to their own writer, so a tracker that never reads
    // cannot stall its session.
    let (reply_tx, mut reply_rx) = mpsc::channel::<String>(32);
    let writer = tokio::spawn(async move {
        while let Some(line) = reply_rx.recv().await {
            if w.write_all(line.as_bytes()).await.is_err() {
                break;
            }
        }
        let _ = w.shutdown().await;
    });
    let mut welcome = json!({
        "type": "welcome", "session": name, "session_id": id, "udp_key": key,
        "rig": rig.name(), "layout": layout.name, "points": layout.point_count,
        "max_message_bytes": settings.max_message_bytes,
    })
    .to_string();
    welcome.push('\n');
    reply(&reply_tx, &record, welcome);
    tracing::info!(session = %name, id, rig = rig.name(), layout = %layout.name, "session started");

    let mut p = Pipeline {
        shared: shared.clone(),
        positions: rig.rig.mesh.positions.clone(),
        scratch: Vec::new(),
        out: retargeter.new_output(),
        retargeter,
        rig: rig.clone(),
        record: record.clone(),
        clock: FrameClock::new(settings.max_time_jump),
        point_count: layout.point_count,
        multi_thread: tokio::runtime::Handle::current().runtime_flavor()
            == tokio::runtime::RuntimeFlavor::MultiThread,
    };
    let layout_name = layout.name.clone();
    let mut errors_in_a_row = 0u32;
    let mut line_no = 1u64;
    let mut last_activity = tokio::time::Instant::now();
    let mut log_tick = tokio::time::interval_at(
        tokio::time::Instant::now() + settings.log_every,
        settings
            .log_every
            .max(std::time::Duration::from_millis(100)),
    );
    let reason: String = loop {
        if *stop.borrow() {
            break "shutdown".into();
        }
        tokio::select! {
            biased;
            _ = stop.changed() => break "shutdown".into(),
            Some((arrival, frame)) = udp_rx.recv() => {
                last_activity = tokio::time::Instant::now();
                let outcome = p.accept_udp(&frame, arrival);
                record_frame(&recorder, outcome, RecordedFrame::unlabelled(frame)).await;
            }
            _ = log_tick.tick() => {
                let s = record.snapshot();
                tracing::info!(session = %s.name, frames = s.frames, tracked = s.tracked,
                    lost = s.lost, late = s.late, malformed = s.malformed,
                    udp_queue_dropped = s.udp_queue_dropped, viewers = s.viewers.len(),
                    viewer_drops = s.viewers.iter().map(|v| v.frames_dropped).sum::<u64>(),
                    p50_us = s.latency.p50_us, p99_us = s.latency.p99_us, "session counters");
            }
            _ = sleep_until(last_activity + settings.idle_timeout) => {
                reply_idle_timeout(&reply_tx, &record, settings, line_no);
                break "idle_timeout".into();
            }
            read = lines.next_line() => {
                last_activity = tokio::time::Instant::now();
                let arrival = Instant::now();
                let problem = match read {
                    Err(e) => break format!("read error: {e}"),
                    Ok(Line::Eof) => break "closed".into(),
                    Ok(Line::TooLong) => {
                        line_no += 1;
                        Some(FrameProblem::TooLong { limit: settings.max_message_bytes })
                    }
                    Ok(kind @ (Line::Complete | Line::Partial)) => {
                        line_no += 1;
                        let text = lines.line();
                        if text.iter().all(u8::is_ascii_whitespace) {
                            None
                        } else {
                            match parse_frame_line(text, kind == Line::Complete, Some(p.point_count), &layout_name) {
                                Ok(rf) => {
                                    errors_in_a_row = 0;
                                    let outcome = p.accept(&rf.frame, arrival, false);
                                    if let Outcome::Refused(TimeProblem::Future { jump_us, allowed_us }) = outcome {
                                        reply(&reply_tx, &record, future_line(line_no, rf.frame.timestamp_us, jump_us, allowed_us));
                                    }
                                    record_frame(&recorder, outcome, rf).await;
                                    None
                                }
                                Err(problem) => Some(problem),
                            }
                        }
                    }
                };
                if let Some(problem) = problem {
                    let code = ErrorCode::of_problem(&problem);
                    if reply_malformed(&reply_tx, &record, settings, &mut errors_in_a_row, line_no, code, &problem.to_string()) {
                        break "too_many_errors".into();
                    }
                }
            }
        }
    };
    // Flush what was accepted: UDP frames already queued are retargeted and broadcast too.
    lock(&shared.routes).remove(&id);
    while let Ok((arrival, frame)) = udp_rx.try_recv() {
        let outcome = p.accept_udp(&frame, arrival);
        record_frame(&recorder, outcome, RecordedFrame::unlabelled(frame)).await;
    }
    // Every accepted frame is in the recording (written, flushed, synced) before the session
    // is reported ended.
    if let Recording::On(r) = recorder {
        r.finish().await;
    }
    *lock(&record.end_reason) = Some(reason.clone());
    record.active.store(false, Ordering::Relaxed);
    let end = record.snapshot();
    let end_json = json!({
        "session": name, "reason": reason, "frames": end.frames, "late": end.late,
        "future": end.future, "malformed": end.malformed,
    });
    {
        let mut hubs = lock(&shared.hubs);
        if let Some(hub) = hubs.get_mut(&name) {
            let m = Arc::new(encode_json(KIND_END, &end_json));
            hub.viewers
                .iter()
                .for_each(|v| v.queue.push_control(m.clone(), false));
            hub.live = None;
            if hub.viewers.is_empty() {
                hubs.remove(&name);
            }
        }
    }
    shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
    let mut bye = json!({"type": "bye", "reason": reason, "frames": end.frames, "late": end.late,
        "future": end.future, "malformed": end.malformed,
        "recorded": settings.record_dir.is_some().then_some(end.recorded)})
    .to_string();
    bye.push('\n');
    reply(&reply_tx, &record, bye);
    drop(reply_tx);
    let _ = timeout(std::time::Duration::from_secs(2), writer).await;
    tracing::info!(
        session = %name, reason = %reason, frames = end.frames, tracked = end.tracked,
        lost = end.lost, late = end.late, malformed = end.malformed,
        p50_us = end.latency.p50_us, p99_us = end.latency.p99_us, "session ended"
    );
}

/// Receives UDP frame packets and hands each to its session's queue (dropped when full).
async fn udp_loop(
    shared: Arc<Shared>,
    udp: UdpSocket,
    mut stop: watch::Receiver<bool>,
    done: mpsc::Sender<()>,
) {
    let mut buf = vec![0u8; 65_536];
    loop {
        let got = tokio::select! {
            _ = stop.changed() => break,
            r = udp.recv_from(&mut buf) => r,
        };
        let Ok((len, _peer)) = got else { continue };
        let arrival = Instant::now();
        let Some(packet) = buf.get(..len) else {
            continue;
        };
        let Ok(u) = wire::decode_udp_frame(packet) else {
            shared.udp_bad.bump();
            continue;
        };
        let routes = lock(&shared.routes);
        match routes.get(&u.session_id) {
            Some(route) if route.key == u.key => {
                if route.tx.try_send((arrival, u.frame)).is_err() {
                    route.record.udp_queue_dropped.bump();
                }
            }
            _ => shared.udp_bad.bump(),
        }
    }
    drop(done);
}
