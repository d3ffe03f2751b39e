//! The session skeleton every tracker protocol plugs into ([`Protocol`], driven by [`run`]):
//! admission (the protocol's checks, then the session limit and the hub), a reply writer, a read
//! loop (idle timeout, error streak, periodic counters) that hands the protocol each line and
//! each of its own events (e.g. UDP packets), and teardown (END to the viewers, `bye` to the
//! tracker).
//!
//! A new protocol implements the hooks: `admit` (its refusals), `describe` (the SESSION message),
//! `start` (its frame path and welcome), `on_line` / `next_event` + `on_event` (per line and per
//! packet), `finish` and `summary` (teardown).

use super::admission::{Admission, Refusal, refuse};
use super::hub::SessionRecord;
use super::state::Shared;
use crate::catalog::RigEntry;
use crate::lines::{Line, LineReader};
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::sync::lock;
use crate::timing::{FrameClock, TimeProblem};
use glam::Vec3;
use mimic_retarget::FrameOutput;
use mimic_wire::{ErrorCode, KIND_END, KIND_SESSION, encode_frame, encode_json, error_line};
use serde_json::{Map, Value, json};
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;
use tokio::io::{AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::sync::{mpsc, watch};
use tokio::time::{sleep_until, timeout};

/// A tracker connection's line reader.
pub(crate) type Lines = LineReader<BufReader<OwnedReadHalf>>;

/// Reply lines a session queues for its tracker before dropping (and counting) more.
const REPLY_QUEUE: usize = 32;

/// A live session as its protocol sees it: the server, the session's record and rig, and its
/// reply queue.
#[derive(Debug)]
pub(crate) struct Session {
    /// The server's shared state.
    pub(crate) shared: Arc<Shared>,
    /// The session's counters.
    pub(crate) record: Arc<SessionRecord>,
    /// Session id (also the UDP session id).
    pub(crate) id: u32,
    /// Session name.
    pub(crate) name: String,
    /// The rig it drives.
    pub(crate) rig: Arc<RigEntry>,
    /// Reply lines to the tracker's writer task.
    pub(crate) replies: mpsc::Sender<String>,
}

/// One line of a tracker, as the read loop hands it to the protocol.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TrackerLine<'a> {
    /// The line (with its newline, if it had one).
    pub(crate) text: &'a [u8],
    /// False when the connection ended in the middle of the line.
    pub(crate) complete: bool,
    /// Its line number (the hello is line 1).
    pub(crate) number: u64,
    /// When it was read.
    pub(crate) arrival: Instant,
}

/// What a protocol made of one line.
#[derive(Debug)]
pub(crate) enum LineOutcome {
    /// Nothing to do (a blank line).
    Skipped,
    /// A frame that parsed (whatever became of it): the error streak starts over.
    Frame,
    /// A malformed line, answered with this code and message and counted.
    Malformed(ErrorCode, String),
}

/// A tracker protocol: the hooks [`run`] calls.
pub(crate) trait Protocol: Sized + Send {
    /// What the hello asked for.
    type Hello: Send;
    /// What admission found and [`Protocol::start`] needs (e.g. the layout and a retargeter).
    type Admitted: Send;
    /// An input besides the tracker's lines (e.g. a UDP frame); counts as tracker activity.
    type Event: Send;
    /// The protocol's name in logs.
    const KIND: &'static str;

    /// The protocol's own checks of a hello (before the session limit), or why it is refused.
    fn admit(shared: &Shared, hello: Self::Hello) -> Result<Admission<Self::Admitted>, Refusal>;

    /// The SESSION message's JSON of admitted session `name`, number `id`.
    fn describe(admitted: &Self::Admitted, rig: &RigEntry, name: &str, id: u32) -> Value;

    /// Starts the frame path of an admitted session; returns its state and the welcome JSON.
    fn start(admitted: Self::Admitted, s: &Session) -> impl Future<Output = (Self, Value)> + Send;

    /// Waits for the next event; cancel-safe (it races the tracker's lines). Never, by default.
    fn next_event(&mut self) -> impl Future<Output = Self::Event> + Send {
        std::future::pending()
    }

    /// Handles one event.
    fn on_event(&mut self, s: &Session, event: Self::Event) -> impl Future<Output = ()> + Send;

    /// Handles one line of the tracker (not the hello, not one too long).
    fn on_line(
        &mut self,
        s: &Session,
        line: TrackerLine<'_>,
    ) -> impl Future<Output = LineOutcome> + Send;

    /// The message answering a line longer than `limit` bytes.
    fn too_long(limit: usize) -> String;

    /// Flushes what was accepted (queued packets, the recording) before the session is reported
    /// ended.
    fn finish(self, s: &Session) -> impl Future<Output = ()> + Send;

    /// Fields after the common ones of END (`bye` false) or of the tracker's `bye` line.
    fn summary(settings: &ServerSettings, end: &SessionSnapshot, bye: bool) -> Map<String, Value>;
}

impl Session {
    /// Queues a reply line to the tracker; dropped (and counted) if the tracker does not read.
    pub(crate) fn reply(&self, line: String) {
        if self.replies.try_send(line).is_err() {
            self.record.replies_dropped.bump();
        }
    }

    /// The server's limits.
    pub(crate) fn settings(&self) -> &ServerSettings {
        &self.shared.settings
    }

    /// A frame clock under the server's allowed time jump.
    pub(crate) fn clock(&self) -> FrameClock {
        FrameClock::new(self.settings().max_time_jump)
    }

    /// Checks a frame's timestamp against the session clock, counting a refusal.
    pub(crate) fn check_time(
        &self,
        clock: &mut FrameClock,
        t_us: i64,
        arrival: Instant,
    ) -> Result<(), TimeProblem> {
        let restarts = clock.restarts();
        let got = clock.advance(t_us, arrival).inspect_err(|p| match p {
            TimeProblem::Late => self.record.late.bump(),
            TimeProblem::Future { .. } => self.record.future.bump(),
        });
        if clock.restarts() > restarts {
            self.record.restarts.bump();
            tracing::info!(session = %self.name, t_us, "the tracker's clock started again (a new run): re-anchored");
        }
        got
    }

    /// Counts an accepted frame (`udp` when it came as a packet) and returns its sequence number.
    pub(crate) fn next_seq(&self, udp: bool) -> u64 {
        let seq = self.record.frames.get();
        self.record.frames.bump();
        if udp {
            self.record.udp_frames.bump();
        }
        seq
    }

    /// Sends frame `seq` to the session's viewers: pose and `d` to those that asked for `d`, the
    /// full positions (filled by `fill` from `d`, only when some viewer wants them) to the
    /// others; then records the frame's arrival-to-broadcast latency.
    pub(crate) fn broadcast(
        &self,
        seq: u64,
        out: &FrameOutput,
        positions: &mut [Vec3],
        fill: impl FnOnce(&[Vec3], &mut [Vec3]),
        arrival: Instant,
    ) {
        // Weights sessions (TCP and Live Link) carry the layout `weights`.
        let web = WebFrame {
            arrival,
            gated: self.record.gated.get(),
            weights: self.record.layout == "weights",
        };
        push_frame(&self.shared, &self.name, seq, out, positions, fill, &web);
        let us = u64::try_from(arrival.elapsed().as_micros()).unwrap_or(u64::MAX);
        tracing::trace!(session = %self.name, seq, us, "broadcast");
        lock(&self.record.latency).record(us);
    }

    /// Counts and answers a tracker that sent nothing for `settings.idle_timeout`.
    fn reply_idle_timeout(&self, line_no: u64) {
        self.record.malformed.bump();
        let message = format!(
            "nothing received for {} s",
            self.settings().idle_timeout.as_secs_f64()
        );
        self.reply(error_line(ErrorCode::IdleTimeout, line_no, &message));
    }

    /// Counts and answers malformed line `line_no`; true when it makes `max_errors_in_a_row` in
    /// a row (the closing error is sent too) and the session must end.
    fn reply_malformed(
        &self,
        errors_in_a_row: &mut u32,
        line_no: u64,
        code: ErrorCode,
        message: &str,
    ) -> bool {
        self.record.malformed.bump();
        *errors_in_a_row += 1;
        self.reply(error_line(code, line_no, message));
        if *errors_in_a_row < self.settings().max_errors_in_a_row {
            return false;
        }
        let closing = format!("{errors_in_a_row} malformed messages in a row; closing");
        self.reply(error_line(ErrorCode::TooManyErrors, line_no, &closing));
        true
    }
}

/// Pushes frame `seq` to the viewers of hub `name`: pose and `d` to those that asked for `d`, the
/// full positions (filled by `fill` from `d`, only when some viewer wants them) to the others.
pub(crate) fn push_frame(
    shared: &Shared,
    name: &str,
    seq: u64,
    out: &FrameOutput,
    positions: &mut [Vec3],
    fill: impl FnOnce(&[Vec3], &mut [Vec3]),
    web: &WebFrame,
) {
    let (want_d, want_positions, want_web) = {
        let hubs = lock(&shared.hubs);
        hubs.get(name).map_or((false, false, false), |h| {
            (
                h.viewers.iter().any(|v| !v.positions && !v.web),
                h.viewers.iter().any(|v| v.positions),
                h.viewers.iter().any(|v| v.web),
            )
        })
    };
    let d_message = want_d.then(|| Arc::new(encode_frame(seq, &out.view(), None)));
    // Browser viewers (`server/http`): their own layout, with the arrival time.
    let web_message = want_web.then(|| {
        Arc::new(super::web_frame::encode_web_frame(
            seq,
            out,
            web.arrival,
            web.gated,
            web.weights,
        ))
    });
    let p_message = want_positions.then(|| {
        fill(&out.displacements, positions);
        Arc::new(encode_frame(seq, &out.view(), Some(positions)))
    });
    let hubs = lock(&shared.hubs);
    if let Some(h) = hubs.get(name) {
        for v in &h.viewers {
            let m = if v.web {
                &web_message
            } else if v.positions {
                &p_message
            } else {
                &d_message
            };
            if let Some(m) = m {
                v.queue.push_frame(m.clone());
            }
        }
    }
}

/// What a browser viewer's frame carries beyond the TCP viewers' one.
pub(crate) struct WebFrame {
    /// When the frame arrived from the tracker (at this front door).
    pub(crate) arrival: Instant,
    /// The session's gated-frame count so far.
    pub(crate) gated: u64,
    /// True for weights sessions (the frame carries the weights).
    pub(crate) weights: bool,
}

/// The error line answering a frame from the future.
pub(crate) fn future_line(line_no: u64, t_us: i64, jump_us: u64, allowed_us: u64) -> String {
    error_line(
        ErrorCode::FutureTimestamp,
        line_no,
        &format!(
            "t_us {t_us} is {jump_us} us after the last accepted frame; at most {allowed_us} us \
             (the time between their arrivals plus the allowed jump) is taken"
        ),
    )
}

/// True for a line of only whitespace (skipped, never answered).
pub(crate) fn is_blank(line: &[u8]) -> bool {
    line.iter().all(u8::is_ascii_whitespace)
}

/// A JSON object as one reply line.
fn json_line(v: &Value) -> String {
    let mut s = v.to_string();
    s.push('\n');
    s
}

/// `base` (an object) with `extra`'s fields after its own.
fn with_fields(mut base: Value, extra: Map<String, Value>) -> Value {
    if let Value::Object(m) = &mut base {
        m.extend(extra);
    }
    base
}

/// Spawns the writer of a tracker's reply lines: a bounded queue of its own, so a tracker that
/// never reads cannot stall its session.
fn spawn_writer(
    mut w: OwnedWriteHalf,
    mut rx: mpsc::Receiver<String>,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        while let Some(line) = rx.recv().await {
            if w.write_all(line.as_bytes()).await.is_err() {
                break;
            }
        }
        let _ = w.shutdown().await;
    })
}

/// Logs a session's counters (every `log_every`).
fn log_counters(record: &SessionRecord) {
    let s = record.snapshot();
    tracing::info!(session = %s.name, frames = s.frames, tracked = s.tracked,
        lost = s.lost, late = s.late, malformed = s.malformed,
        udp_queue_dropped = s.udp_queue_dropped,
        viewers = s.viewers.iter().filter(|v| v.connected).count(),
        viewers_total = s.viewers_total, viewer_drops = s.viewer_frames_dropped,
        p50_us = s.latency.p50_us, p99_us = s.latency.p99_us, "session counters");
}

/// Admits a tracker: the protocol's checks, then the session limit, an id and a name, and the
/// session's hub (refused when the name already has a tracker). The session's replies go to
/// `replies`.
pub(crate) fn open<P: Protocol>(
    shared: &Arc<Shared>,
    hello: P::Hello,
    replies: tokio::sync::mpsc::Sender<String>,
) -> Result<(Session, P::Admitted), Refusal> {
    let a = P::admit(shared, hello)?;
    let settings = &shared.settings;
    if shared.sessions_active.fetch_add(1, Ordering::AcqRel) >= settings.max_sessions {
        shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
        return Err(Refusal::TooManySessions {
            max: settings.max_sessions,
        });
    }
    let id = shared.next_session.fetch_add(1, Ordering::Relaxed);
    let name = a.session.unwrap_or_else(|| format!("s{id}"));
    let record = Arc::new(SessionRecord::new(id, &name, a.rig.name(), &a.layout));
    let description = P::describe(&a.admitted, &a.rig, &name, id);
    let session_message = Arc::new(encode_json(KIND_SESSION, &description));
    if !shared.go_live(&name, &record, session_message, &a.rig_message) {
        shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
        return Err(Refusal::SessionBusy { session: name });
    }
    let session = Session {
        shared: shared.clone(),
        record,
        id,
        name,
        rig: a.rig,
        replies,
    };
    Ok((session, a.admitted))
}

/// A tracker session of protocol `P`: admit it, then hand its lines and events to `P` until it
/// ends (closed, idle, too many errors, a read error or shutdown), then tear it down.
pub(crate) async fn run<P: Protocol>(
    shared: Arc<Shared>,
    mut lines: Lines,
    mut w: OwnedWriteHalf,
    hello: P::Hello,
    mut stop: watch::Receiver<bool>,
) {
    let (reply_tx, reply_rx) = mpsc::channel::<String>(REPLY_QUEUE);
    let (s, admitted) = match open::<P>(&shared, hello, reply_tx) {
        Ok(opened) => opened,
        Err(refusal) => {
            refuse(&shared, &mut w, refusal).await;
            return;
        }
    };
    let writer = spawn_writer(w, reply_rx);
    let (mut proto, welcome) = P::start(admitted, &s).await;
    s.reply(json_line(&welcome));
    let settings = &shared.settings;
    let mut errors_in_a_row = 0u32;
    let mut line_no = 1u64;
    let mut last_activity = tokio::time::Instant::now();
    let mut log_tick = tokio::time::interval_at(
        crate::timing::instant_after(tokio::time::Instant::now(), settings.log_every),
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
            event = proto.next_event() => {
                last_activity = tokio::time::Instant::now();
                proto.on_event(&s, event).await;
            }
            _ = log_tick.tick() => log_counters(&s.record),
            _ = sleep_until(crate::timing::instant_after(last_activity, settings.idle_timeout)) => {
                s.reply_idle_timeout(line_no);
                break "idle_timeout".into();
            }
            read = lines.next_line() => {
                last_activity = tokio::time::Instant::now();
                let arrival = Instant::now();
                let outcome = match read {
                    Err(e) => break format!("read error: {e}"),
                    Ok(Line::Eof) => break "closed".into(),
                    Ok(Line::TooLong) => {
                        line_no += 1;
                        LineOutcome::Malformed(ErrorCode::TooLong, P::too_long(settings.max_message_bytes))
                    }
                    Ok(kind @ (Line::Complete | Line::Partial)) => {
                        line_no += 1;
                        let line = TrackerLine {
                            text: lines.line(),
                            complete: kind == Line::Complete,
                            number: line_no,
                            arrival,
                        };
                        proto.on_line(&s, line).await
                    }
                };
                match outcome {
                    LineOutcome::Skipped => {}
                    LineOutcome::Frame => errors_in_a_row = 0,
                    LineOutcome::Malformed(code, message) => {
                        if s.reply_malformed(&mut errors_in_a_row, line_no, code, &message) {
                            break "too_many_errors".into();
                        }
                    }
                }
            }
        }
    };
    proto.finish(&s).await;
    teardown::<P>(s, reason, writer).await;
}

/// Ends a session: marks its record ended, sends END to its viewers and `bye` to its tracker,
/// and waits (briefly) for the reply writer to drain.
pub(crate) async fn teardown<P: Protocol>(
    s: Session,
    reason: String,
    writer: tokio::task::JoinHandle<()>,
) {
    let settings = s.settings();
    *lock(&s.record.end_reason) = Some(reason.clone());
    s.record.active.store(false, Ordering::Relaxed);
    let end = s.record.snapshot();
    let end_json = json!({
        "session": s.name, "reason": reason, "frames": end.frames, "late": end.late,
        "future": end.future, "malformed": end.malformed,
    });
    let end_json = with_fields(end_json, P::summary(settings, &end, false));
    s.shared
        .go_offline(&s.name, Arc::new(encode_json(KIND_END, &end_json)));
    s.shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
    let bye = json!({"type": "bye", "reason": reason, "frames": end.frames, "late": end.late,
        "future": end.future, "malformed": end.malformed, "restarts": end.restarts});
    s.reply(json_line(&with_fields(
        bye,
        P::summary(settings, &end, true),
    )));
    let Session { replies, name, .. } = s;
    drop(replies);
    let _ = timeout(std::time::Duration::from_secs(2), writer).await;
    tracing::info!(
        session = %name, kind = P::KIND, reason = %reason, frames = end.frames,
        tracked = end.tracked, lost = end.lost, late = end.late, malformed = end.malformed,
        unknown_weights = end.unknown_weights, p50_us = end.latency.p50_us,
        p99_us = end.latency.p99_us, "session ended"
    );
}
