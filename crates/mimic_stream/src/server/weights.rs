//! Weights sessions: a tracker that sends named blendshape weights (ARKit-style) instead of
//! landmarks. The weights go through the rig's [`WeightMap`](mimic_retarget::WeightMap) onto its
//! morph targets and reach viewers as the morph basis's control values (`d[3k + a] = w_k e_a`),
//! or as positions `P0 + sum_k w_k dP_k`.

use super::admission::{Admission, Refusal, find_rig};
use super::outputs::{Recording, count_forward, own_forward, start_forwarder};
use super::session::{LineOutcome, Protocol, Session, TrackerLine, future_line, is_blank};
use super::state::Shared;
use crate::catalog::{MorphSet, RigEntry};
use crate::forward::{ForwardTarget, Forwarder};
use crate::record::{Entry, RecordKind};
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::timing::{FrameClock, TimeProblem};
use glam::{Quat, Vec3};
use mimic_retarget::{FrameOutput, FrameStatus};
use mimic_trackers::livelink::CURVES;
use mimic_types::HeadPose;
use mimic_wire::{ErrorCode, WeightsHello, parse_weight_frame, warning_line};
use serde_json::{Map, Value, json};
use std::collections::HashSet;
use std::convert::Infallible;
use std::net::SocketAddr;
use std::time::Instant;

/// Distinct unknown weight names a session remembers (and warns about once each).
const UNKNOWN_NAMES_KEPT: usize = 256;

/// The frame path every weights session shares (named weights over TCP here, Live Link Face
/// packets in `livelink.rs`): one weight per rig morph target, the frame viewers get (`d` as the
/// morph basis's controls, the head rotation as its pose), the blended positions and the
/// session's recording (`--record`: the weights as a weights CSV, `crate::record`).
#[derive(Debug)]
pub(crate) struct MorphFrame {
    /// One weight per morph target of the session's rig, set by the protocol before [`Self::keep`].
    pub(crate) weights: Vec<f32>,
    out: FrameOutput,
    positions: Vec<Vec3>,
    recording: Recording,
    /// With a recording, unless `--record-queued`: a frame is broadcast (and counted) only once
    /// written (`Some(true)`: synced to the disk too, `--record-sync`).
    waits: Option<bool>,
    /// Live out (`--forward`, a hello's `"forward"`).
    forward: Option<Forwarder>,
    /// The Live Link curves of this frame as they came (forwarded as they are), if any.
    pub(crate) curves: Option<Box<[f32; CURVES]>>,
}

impl MorphFrame {
    /// All weights zero, the rig's rest positions, no head rotation; the recording started when
    /// the server records (one column per rig morph target).
    pub(crate) async fn start(
        s: &Session,
        peer: Option<SocketAddr>,
        own_forward: Option<ForwardTarget>,
    ) -> Self {
        let k = s.rig.morph.as_ref().map_or(0, MorphSet::len);
        let names = s.rig.morph.as_ref().map_or(&[][..], |m| &m.names[..]);
        let recording = Recording::start(s, RecordKind::Weights(names), peer).await;
        let forward = start_forwarder(s, own_forward, names);
        Self {
            weights: vec![0.0; k],
            out: FrameOutput {
                timestamp_us: 0,
                status: FrameStatus::Tracked,
                positions: Vec::new(),
                normals: Vec::new(),
                displacements: vec![Vec3::ZERO; 3 * k],
                pose: HeadPose::default(),
                target_rotation: Quat::IDENTITY,
                filled: 0,
                times: Default::default(),
            },
            positions: s.rig.rig.mesh.positions.clone(),
            waits: s
                .settings()
                .record_mode
                .waits()
                .filter(|_| recording.is_on()),
            recording,
            forward,
            curves: None,
        }
    }

    /// Broadcasts ([`Self::send`]) and forwards the current frame.
    fn publish(
        &mut self,
        s: &Session,
        morph: &MorphSet,
        t_us: i64,
        rotation: Quat,
        udp: bool,
        arrival: Instant,
    ) {
        self.send(s, morph, t_us, rotation, udp, arrival);
        if let Some(f) = self.forward.as_mut() {
            let sent = match &self.curves {
                Some(c) => f.curves(t_us, c, rotation),
                None => f.weights(t_us, &self.weights, rotation),
            };
            count_forward(s, sent);
        }
    }

    /// Keeps the current weights as an accepted frame at `t_us`: broadcast ([`Self::send`]) and
    /// recorded; broadcast only once written (`--record-sync`: on disk, and never if it cannot
    /// be), unless `--record-queued`.
    pub(crate) async fn keep(
        &mut self,
        s: &Session,
        morph: &MorphSet,
        t_us: i64,
        rotation: Quat,
        udp: bool,
        arrival: Instant,
    ) {
        if !self.recording.is_on() {
            self.publish(s, morph, t_us, rotation, udp, arrival);
            return;
        }
        let entry = Entry::Weights {
            t_us,
            weights: self.weights.clone(),
        };
        if let Some(sync) = self.waits {
            // Without `--record-sync` a failed write (counted `record_lost`) does not stop it.
            if self.recording.frame_acked(entry, sync).await || !sync {
                self.publish(s, morph, t_us, rotation, udp, arrival);
            }
        } else {
            self.publish(s, morph, t_us, rotation, udp, arrival);
            self.recording.frame(entry).await;
        }
    }

    /// Waits until every recorded frame is on disk.
    pub(crate) async fn finish(self) {
        self.recording.finish().await;
    }

    /// Counts the current weights as an accepted frame at `t_us` (`udp` when it came as a
    /// packet) and broadcasts it with head rotation `rotation`; allocates nothing.
    fn send(
        &mut self,
        s: &Session,
        morph: &MorphSet,
        t_us: i64,
        rotation: Quat,
        udp: bool,
        arrival: Instant,
    ) {
        mimic_solve::morph_basis::morph_controls(&self.weights, &mut self.out.displacements);
        self.out.pose.rotation = rotation;
        self.out.target_rotation = rotation;
        self.out.timestamp_us = t_us;
        s.record.tracked.bump();
        let seq = s.next_seq(udp);
        let rest = &s.rig.rig.mesh.positions;
        let weights = &self.weights;
        s.broadcast(
            seq,
            &self.out,
            &mut self.positions,
            |_, positions| morph.blend(rest, weights, positions),
            arrival,
        );
    }
}

/// The rig's morph targets, or the refusal of a weights session on a rig without them.
pub(crate) fn morph_targets(rig: &RigEntry) -> Result<&MorphSet, Refusal> {
    rig.morph.as_ref().ok_or_else(|| Refusal::NoMorphTargets {
        rig: rig.name().to_string(),
    })
}

/// A weights session as `/stats` lists it: its rig's morph targets are its controls (three each).
pub(crate) fn describe_weights(
    rig: &RigEntry,
    name: &str,
    id: u32,
    source: Value,
    rate_hz: Value,
) -> Value {
    let k = rig.morph.as_ref().map_or(0, MorphSet::len);
    json!({
        "session": name, "session_id": id, "rig": rig.name(), "layout": null,
        "mode": "weights", "targets": k,
        "vertices": rig.rig.mesh.vertex_count(), "controls": 3 * k,
        "source": source, "rate_hz": rate_hz,
    })
}

/// What a weights session's end summary adds: the unknown weight names it was sent, and (in
/// the tracker's `bye`) the frames recorded, `null` when the server does not record.
pub(crate) fn weights_summary(
    settings: &ServerSettings,
    end: &SessionSnapshot,
    bye: bool,
) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("unknown_weights".into(), json!(end.unknown_weights));
    if bye {
        let recorded = settings.record_dir.is_some().then_some(end.recorded);
        m.insert("recorded".into(), json!(recorded));
    }
    m
}

/// A weights session's frame path.
#[derive(Debug)]
pub(crate) struct Weights {
    frame: MorphFrame,
    scratch: Vec<f32>,
    clock: FrameClock,
    reported: HashSet<String>,
}

impl Weights {
    /// Maps, orders and broadcasts one weight frame; replies with a warning for each name never
    /// seen (or the error line of a frame from the future).
    async fn accept(
        &mut self,
        s: &Session,
        t_us: i64,
        pairs: &[(String, f64)],
        arrival: Instant,
        line_no: u64,
    ) {
        match s.check_time(&mut self.clock, t_us, arrival) {
            Ok(()) => {}
            Err(TimeProblem::Late) => return,
            Err(TimeProblem::Future {
                jump_us,
                allowed_us,
            }) => return s.reply(future_line(line_no, t_us, jump_us, allowed_us)),
        }
        let Some(morph) = s.rig.morph.as_ref() else {
            return;
        };
        // Clamped here, in f64: a huge value must give 1, not an infinite f32.
        let as_f32 = |x: f64| x.clamp(0.0, 1.0) as f32;
        let unknown = morph.map.apply(
            pairs.iter().map(|(n, v)| (n.as_str(), as_f32(*v))),
            &mut self.frame.weights,
        );
        if unknown > 0 {
            s.record.unknown_weights.add(unknown as u64);
            for (name, _) in pairs {
                if self.reported.len() < UNKNOWN_NAMES_KEPT
                    && !self.reported.contains(name)
                    && morph.map.apply([(name.as_str(), 0.0)], &mut self.scratch) == 1
                {
                    self.reported.insert(name.clone());
                    s.reply(warning_line(
                        ErrorCode::UnknownWeight,
                        line_no,
                        &format!(
                            "`{name}` names no morph target of rig `{}` (ignored; reported once)",
                            s.rig.name()
                        ),
                    ));
                }
            }
        }
        self.frame
            .keep(s, morph, t_us, Quat::IDENTITY, false, arrival)
            .await;
    }
}

/// A weights tracker's hello and where it came from (named in its recording).
#[derive(Debug)]
pub(crate) struct WeightsSession {
    /// The hello.
    pub(crate) hello: WeightsHello,
    /// The tracker's address.
    pub(crate) peer: Option<SocketAddr>,
    /// The hello's `"forward"`, once admission checked it.
    own_forward: Option<ForwardTarget>,
}

impl WeightsSession {
    /// A hello from `peer`.
    pub(crate) fn new(hello: WeightsHello, peer: Option<SocketAddr>) -> Self {
        Self {
            hello,
            peer,
            own_forward: None,
        }
    }
}

impl Protocol for Weights {
    type Hello = WeightsSession;
    type Admitted = WeightsSession;
    type Event = Infallible;
    const KIND: &'static str = "weights";

    fn admit(
        shared: &Shared,
        mut hello: WeightsSession,
    ) -> Result<Admission<WeightsSession>, Refusal> {
        let rig = find_rig(shared, hello.hello.request.rig.clone())?;
        let morph = morph_targets(&rig)?;
        hello.own_forward = own_forward(shared, hello.hello.forward.as_deref())?;
        Ok(Admission {
            session: hello.hello.request.session.clone(),
            rig_message: morph.message.clone(),
            rig,
            layout: "weights".into(),
            admitted: hello,
        })
    }

    fn describe(hello: &WeightsSession, rig: &RigEntry, name: &str, id: u32) -> Value {
        let h = &hello.hello;
        describe_weights(rig, name, id, json!(h.source), json!(h.rate_hz))
    }

    async fn start(hello: WeightsSession, s: &Session) -> (Self, Value) {
        let settings = s.settings();
        let names = s.rig.morph.as_ref().map_or(&[][..], |m| &m.names[..]);
        let k = names.len();
        let welcome = json!({
            "type": "welcome", "session": s.name, "session_id": s.id, "rig": s.rig.name(),
            "mode": "weights", "targets": names,
            "max_message_bytes": settings.max_message_bytes,
        });
        tracing::info!(session = %s.name, id = s.id, rig = s.rig.name(), targets = k, "weights session started");
        let weights = Weights {
            frame: MorphFrame::start(s, hello.peer, hello.own_forward).await,
            scratch: vec![0.0; k],
            clock: s.clock(),
            reported: HashSet::new(),
        };
        (weights, welcome)
    }

    async fn on_event(&mut self, _: &Session, event: Infallible) {
        match event {}
    }

    async fn on_line(&mut self, s: &Session, line: TrackerLine<'_>) -> LineOutcome {
        if !line.complete {
            let message = "the connection ended in the middle of a line".to_string();
            return LineOutcome::Malformed(ErrorCode::Truncated, message);
        }
        if is_blank(line.text) {
            return LineOutcome::Skipped;
        }
        match parse_weight_frame(line.text) {
            Ok(f) => {
                self.accept(s, f.timestamp_us, &f.weights, line.arrival, line.number)
                    .await;
                LineOutcome::Frame
            }
            Err(e) => LineOutcome::Malformed(e.code(), e.to_string()),
        }
    }

    fn too_long(limit: usize) -> String {
        format!("line longer than {limit} bytes")
    }

    async fn finish(self, _: &Session) {
        self.frame.finish().await;
    }

    fn summary(settings: &ServerSettings, end: &SessionSnapshot, bye: bool) -> Map<String, Value> {
        weights_summary(settings, end, bye)
    }
}
