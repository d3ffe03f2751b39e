//! Landmark sessions: a tracker whose hello is a recording header and whose lines are recording
//! frame lines (and, after the welcome, UDP frame packets). Every accepted frame is retargeted by
//! the one frame loop (`mimic_retarget::FrameLoop`, no outputs of its own), then broadcast and,
//! when the server records, written to the session's recording (both async, so done here).

use super::admission::{Admission, Refusal, find_rig};
use super::hub::Route;
use super::outputs::{Recording, count_forward, own_forward, start_forwarder};
use super::session::{LineOutcome, Protocol, Session, TrackerLine, future_line, is_blank};
use super::state::Shared;
use crate::catalog::RigEntry;
use crate::forward::{ForwardTarget, Forwarder};
use crate::placement::StepResult;
use crate::record::RecordKind;
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::sync::lock;
use crate::timing::{FrameClock, TimeProblem};
use mimic_capture::{FrameProblem, RecordedFrame, RecordingHeader, parse_frame_line};
use mimic_retarget::{
    BlendshapeFitter, BlendshapeSettings, FrameLoop, FrameStatus, RetargetSettings, Retargeter,
};
use mimic_types::LandmarkFrame;
use mimic_wire::{ErrorCode, SessionRequest};
use serde_json::{Map, Value, json};
use std::hash::{BuildHasher, Hasher};
use std::net::SocketAddr;
use std::time::Instant;
use tokio::sync::mpsc;

/// What a tracker's first line asked for, and who it is.
#[derive(Debug)]
pub(crate) struct LandmarkHello {
    /// The recording header.
    pub(crate) header: Box<RecordingHeader>,
    /// Session and rig asked for.
    pub(crate) request: SessionRequest,
    /// The tracker's address (named in the recording).
    pub(crate) peer: Option<SocketAddr>,
}

/// What admission found: the header, the layout and a retargeter for the rig.
#[derive(Debug)]
pub(crate) struct Admitted {
    header: Box<RecordingHeader>,
    peer: Option<SocketAddr>,
    layout: String,
    point_count: usize,
    retargeter: Retargeter,
    /// The header's `"forward"`, checked.
    own_forward: Option<ForwardTarget>,
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

/// An input of a landmark session besides its TCP lines.
#[derive(Debug)]
pub(crate) enum LandmarkEvent {
    /// A UDP frame packet (arrival, frame).
    Udp(Instant, LandmarkFrame),
    /// A placement's answer.
    Answer(StepResult),
}

mod placed;
use placed::{Remote, Viewers, count_status};

/// A landmark session's frame path.
pub(crate) struct Landmark {
    /// The retargeter, stepped by the frame loop (untimed; the session is its only output).
    frames: FrameLoop,
    viewers: Viewers,
    clock: FrameClock,
    layout: String,
    point_count: usize,
    multi_thread: bool,
    recording: Recording,
    /// With a recording, unless `--record-queued`: a frame is broadcast (or, placed, handed
    /// over) only once written (`Some(true)`: synced to the disk too, `--record-sync`).
    waits: Option<bool>,
    udp: mpsc::Receiver<(Instant, LandmarkFrame)>,
    /// Set when the server's placement steps this session.
    remote: Option<Remote>,
    /// Live out: the forwarding and the blendshape fit of the rig's morph targets it sends.
    forward: Option<Box<(Forwarder, BlendshapeFitter)>>,
}

impl Landmark {
    /// Retargets one frame and broadcasts it (or hands it to its placement); when the frame
    /// waits for its recording, [`Self::keep`] does that once it is written. Late frames and
    /// frames from the future are dropped and counted.
    fn accept(
        &mut self,
        s: &Session,
        frame: &LandmarkFrame,
        arrival: Instant,
        udp: bool,
    ) -> Outcome {
        if let Err(p) = s.check_time(&mut self.clock, frame.timestamp_us, arrival) {
            return Outcome::Refused(p);
        }
        if let Some(r) = &mut self.remote {
            if self.waits.is_none() {
                r.hand_over(frame, arrival, udp);
            }
            return Outcome::Accepted;
        }
        let retargeter =
            |f: &FrameLoop| (f.retargeter()).map(|r| (r.stats(), r.source_to_target().is_some()));
        let (before, fitted) = retargeter(&self.frames).unwrap_or_default();
        // The loop has no outputs (the session broadcasts and records), so its step cannot fail.
        let step =
            |frames: &mut FrameLoop| frames.step(frame, None).unwrap_or(FrameStatus::Rejected);
        let status = if !fitted && self.multi_thread {
            // Finishing the neutral fits the source-to-target map (a consensus search of up to
            // tens of milliseconds): let the runtime move other sessions off this worker meanwhile.
            tokio::task::block_in_place(|| step(&mut self.frames))
        } else {
            step(&mut self.frames)
        };
        let r = &s.record;
        let after = retargeter(&self.frames).unwrap_or_default().0;
        r.gated.add(after.gated.saturating_sub(before.gated));
        r.jumps.add(after.jumps.saturating_sub(before.jumps));
        if !count_status(r, status) {
            return Outcome::Malformed;
        }
        if self.waits.is_none() {
            self.publish(s, arrival, udp);
        }
        Outcome::Accepted
    }

    /// Counts the retargeted frame and broadcasts it to the viewers.
    fn publish(&mut self, s: &Session, arrival: Instant, udp: bool) {
        let out = self.frames.output();
        self.viewers.broadcast(s, s.next_seq(udp), out, arrival);
        if let Some(f) = self.forward.as_mut() {
            let (forwarder, fitter) = &mut **f;
            forwarder.set_gaze(self.frames.retargeter().and_then(|r| r.gaze()));
            let w = fitter.fit(&out.displacements, out.timestamp_us);
            let sent = forwarder.weights(out.timestamp_us, w, out.pose.rotation);
            count_forward(s, sent);
        }
    }

    /// Records a frame [`Self::accept`] judged. Unless `--record-queued`, an accepted frame is
    /// broadcast (placed: handed over) only after it is written, so a kill of the server loses
    /// no frame a viewer saw; under `--record-sync` one that cannot be written is never
    /// broadcast (placed: counted lost).
    async fn keep(
        &mut self,
        s: &Session,
        outcome: Outcome,
        f: RecordedFrame,
        arrival: Instant,
        udp: bool,
    ) {
        if outcome != Outcome::Accepted {
            return;
        }
        let Some(sync) = self.waits else {
            self.recording.frame(f).await;
            return;
        };
        let placed = self.remote.is_some().then(|| f.frame.clone());
        // A failed write is logged and counted `record_lost`; without `--record-sync` the
        // session goes on, with it the frame is never shown.
        let go = self.recording.frame_acked(f, sync).await || !sync;
        match (&mut self.remote, placed) {
            (Some(r), Some(frame)) if go => r.hand_over(&frame, arrival, udp),
            (Some(r), _) => r.skip(),
            (None, _) if go => self.publish(s, arrival, udp),
            (None, _) => {}
        }
    }

    /// A UDP frame: checked against the layout (no reply over UDP), accepted and recorded.
    async fn accept_udp(&mut self, s: &Session, frame: LandmarkFrame, arrival: Instant) {
        let count = frame.points.len();
        let outcome = if (frame.tracked || count > 0) && count != self.point_count {
            s.record.malformed.bump();
            Outcome::Malformed
        } else {
            self.accept(s, &frame, arrival, true)
        };
        let f = RecordedFrame::unlabelled(frame);
        self.keep(s, outcome, f, arrival, true).await;
    }
}

/// The secret a session's UDP packets must carry: from the OS RNG (a hash of the id, the time
/// and the server's random hasher keys only if the OS RNG fails).
fn udp_key(shared: &Shared, id: u32) -> u32 {
    if let Ok(k) = getrandom::u32() {
        return k;
    }
    tracing::warn!("OS RNG unavailable: the UDP key comes from a keyed hash");
    let mut h = shared.keys.build_hasher();
    h.write_u32(id);
    h.write_u128(shared.started.elapsed().as_nanos());
    h.finish() as u32
}

/// A landmark session's forwarding: the blendshape fit of the rig's morph targets to its
/// controls (`mimic_retarget::BlendshapeFitter`, with the rig's `[blendshape_fit]`, as
/// `replay --mode blendshapes` fits) feeds the forwarder; a rig
/// without morph targets forwards nothing (logged).
fn landmark_forward(
    s: &Session,
    own: Option<ForwardTarget>,
) -> Option<Box<(Forwarder, BlendshapeFitter)>> {
    if s.settings().forward.targets.is_empty() && own.is_none() {
        return None;
    }
    let Some(morph) = s.rig.morph.as_ref() else {
        tracing::warn!(session = %s.name, rig = s.rig.name(), "not forwarded: the rig has no [[morph_targets]] to fit weights of");
        return None;
    };
    let settings = BlendshapeSettings::with_fit(&morph.fit);
    let fitter = match BlendshapeFitter::new(&s.rig.rig, morph.targets(), &settings) {
        Ok(f) => f,
        Err(e) => {
            tracing::warn!(session = %s.name, "not forwarded: {e}");
            return None;
        }
    };
    tracing::info!(session = %s.name, fit = ?morph.fit, "forwarding: blend-shape fit");
    let forwarder = start_forwarder(s, own, &morph.names)?;
    Some(Box::new((forwarder, fitter)))
}

impl Protocol for Landmark {
    type Hello = LandmarkHello;
    type Admitted = Admitted;
    type Event = LandmarkEvent;
    const KIND: &'static str = "landmark";

    fn admit(shared: &Shared, hello: LandmarkHello) -> Result<Admission<Admitted>, Refusal> {
        let LandmarkHello {
            header,
            request,
            peer,
        } = hello;
        let Some(layout) = shared.catalog.layout(&header.layout) else {
            return Err(Refusal::UnknownLayout {
                layout: header.layout.clone(),
            });
        };
        let entry = find_rig(shared, request.rig)?;
        if let Some(c) = header.point_count
            && c != layout.point_count
        {
            return Err(Refusal::PointCount {
                header: c,
                layout: layout.name.clone(),
                points: layout.point_count,
            });
        }
        let retarget = RetargetSettings {
            positions: false,
            normals: false,
            ..shared.settings.retarget.clone()
        };
        let retargeter = Retargeter::new(&entry.rig, layout, entry.basis.clone(), retarget)
            .map_err(|e| Refusal::LayoutUnusable(e.to_string()))?;
        let own_forward = own_forward(shared, header.extra.get("forward").and_then(Value::as_str))?;
        Ok(Admission {
            session: request.session,
            rig_message: entry.message.clone(),
            rig: entry,
            layout: layout.name.clone(),
            admitted: Admitted {
                header,
                peer,
                layout: layout.name.clone(),
                point_count: layout.point_count,
                retargeter,
                own_forward,
            },
        })
    }

    fn describe(a: &Admitted, rig: &RigEntry, name: &str, id: u32) -> Value {
        json!({
            "session": name, "session_id": id, "rig": rig.name(), "layout": a.layout,
            "vertices": rig.rig.mesh.vertex_count(), "controls": rig.rig.controls.len(),
            "source": a.header.source, "rate_hz": a.header.rate_hz,
        })
    }

    async fn start(a: Admitted, s: &Session) -> (Self, Value) {
        let settings = s.settings();
        let mut recorded_header = (*a.header).clone();
        recorded_header.point_count = Some(a.point_count);
        let recording = Recording::start(s, RecordKind::Landmarks(&recorded_header), a.peer).await;
        let key = udp_key(&s.shared, s.id);
        let (udp_tx, udp) = mpsc::channel(settings.udp_queue_frames.max(1));
        lock(&s.shared.routes).insert(
            s.id,
            Route {
                key,
                peer_ip: a.peer.map(|p| p.ip()),
                source: None,
                tx: udp_tx,
                record: s.record.clone(),
            },
        );
        let welcome = json!({
            "type": "welcome", "session": s.name, "session_id": s.id, "udp_key": key,
            "rig": s.rig.name(), "layout": a.layout, "points": a.point_count,
            "max_message_bytes": settings.max_message_bytes,
        });
        tracing::info!(session = %s.name, id = s.id, rig = s.rig.name(), layout = %a.layout, "session started");
        let remote = match &s.shared.placement {
            Some(placement) => {
                let description = Self::describe(&a, &s.rig, &s.name, s.id);
                let out = a.retargeter.new_output();
                Some(Remote::place(placement.as_ref(), s, &a.layout, description, out).await)
            }
            None => None,
        };
        let forward = landmark_forward(s, a.own_forward);
        let landmark = Landmark {
            frames: FrameLoop::landmarks(a.retargeter, None).untimed(),
            viewers: Viewers {
                positions: s.rig.rig.mesh.positions.clone(),
                scratch: Vec::new(),
            },
            clock: s.clock(),
            layout: a.layout,
            point_count: a.point_count,
            multi_thread: tokio::runtime::Handle::current().runtime_flavor()
                == tokio::runtime::RuntimeFlavor::MultiThread,
            waits: settings
                .record_mode
                .waits()
                .filter(|_| !matches!(recording, Recording::Off)),
            recording,
            udp,
            remote,
            forward,
        };
        (landmark, welcome)
    }

    async fn next_event(&mut self) -> LandmarkEvent {
        let udp = &mut self.udp;
        match &mut self.remote {
            Some(remote) => tokio::select! {
                Some((arrival, frame)) = udp.recv() => LandmarkEvent::Udp(arrival, frame),
                Some(a) = remote.results.recv() => LandmarkEvent::Answer(a),
                else => std::future::pending().await,
            },
            None => match udp.recv().await {
                Some((arrival, frame)) => LandmarkEvent::Udp(arrival, frame),
                // The route holds the sender until the session ends.
                None => std::future::pending().await,
            },
        }
    }

    async fn on_event(&mut self, s: &Session, event: LandmarkEvent) {
        match event {
            LandmarkEvent::Udp(arrival, frame) => self.accept_udp(s, frame, arrival).await,
            LandmarkEvent::Answer(a) => {
                if let Some(remote) = self.remote.as_mut() {
                    remote.answer(s, a, &mut self.viewers);
                }
            }
        }
    }

    async fn on_line(&mut self, s: &Session, line: TrackerLine<'_>) -> LineOutcome {
        if is_blank(line.text) {
            return LineOutcome::Skipped;
        }
        let (layout, points) = (&self.layout, Some(self.point_count));
        match parse_frame_line(line.text, line.complete, points, layout) {
            Ok(rf) => {
                let outcome = self.accept(s, &rf.frame, line.arrival, false);
                if let Outcome::Refused(TimeProblem::Future {
                    jump_us,
                    allowed_us,
                }) = outcome
                {
                    s.reply(future_line(
                        line.number,
                        rf.frame.timestamp_us,
                        jump_us,
                        allowed_us,
                    ));
                }
                self.keep(s, outcome, rf, line.arrival, false).await;
                LineOutcome::Frame
            }
            Err(problem) => LineOutcome::Malformed(problem_code(&problem), problem.to_string()),
        }
    }

    fn too_long(limit: usize) -> String {
        FrameProblem::TooLong { limit }.to_string()
    }

    async fn finish(mut self, s: &Session) {
        // Flush what was accepted: UDP frames already queued are retargeted and broadcast too.
        lock(&s.shared.routes).remove(&s.id);
        while let Ok((arrival, frame)) = self.udp.try_recv() {
            self.accept_udp(s, frame, arrival).await;
        }
        // A placed session: its last answers are broadcast, frames never answered counted lost.
        if let Some(remote) = self.remote.take() {
            remote.finish(s, &mut self.viewers).await;
        }
        // Every accepted frame is in the recording (written, flushed, synced) before the session
        // is reported ended.
        self.recording.finish().await;
    }

    fn summary(settings: &ServerSettings, end: &SessionSnapshot, bye: bool) -> Map<String, Value> {
        let mut m = Map::new();
        if bye {
            let recorded = settings.record_dir.is_some().then_some(end.recorded);
            m.insert("recorded".into(), json!(recorded));
        }
        m
    }
}

/// The reply code of a rejected frame line.
fn problem_code(p: &FrameProblem) -> ErrorCode {
    match p {
        FrameProblem::Json { .. } => ErrorCode::BadJson,
        FrameProblem::Truncated { .. } => ErrorCode::Truncated,
        FrameProblem::PointCount { .. } => ErrorCode::PointCount,
        FrameProblem::BadCoordinate { .. } => ErrorCode::BadCoordinate,
        FrameProblem::InvalidIndexOutOfRange { .. } => ErrorCode::BadInvalidIndex,
        FrameProblem::TooLong { .. } => ErrorCode::TooLong,
        // Ordering is checked by the session (late frames are dropped, not answered).
        FrameProblem::TimeNotIncreasing { .. } | FrameProblem::Io { .. } => ErrorCode::BadJson,
    }
}
