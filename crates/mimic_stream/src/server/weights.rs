//! Weights sessions: a tracker that sends named blendshape weights (ARKit-style) instead of
//! landmarks. The weights go through the rig's [`WeightMap`](mimic_retarget::WeightMap) onto its
//! morph targets and reach viewers as the morph basis's control values (`d[3k + a] = w_k e_a`),
//! or as positions `P0 + sum_k w_k dP_k`.

use super::admission::{Admission, Refusal, find_rig};
use super::session::{LineOutcome, Protocol, Session, TrackerLine, future_line, is_blank};
use super::state::Shared;
use crate::catalog::{MorphSet, RigEntry};
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::timing::{FrameClock, TimeProblem};
use glam::{Quat, Vec3};
use mimic_retarget::{FrameOutput, FrameStatus};
use mimic_types::HeadPose;
use mimic_wire::{ErrorCode, WeightsHello, parse_weight_frame, warning_line};
use serde_json::{Map, Value, json};
use std::collections::HashSet;
use std::convert::Infallible;
use std::time::Instant;

/// Distinct unknown weight names a session remembers (and warns about once each).
const UNKNOWN_NAMES_KEPT: usize = 256;

/// The frame path every weights session shares (named weights over TCP here, Live Link Face
/// packets in `livelink.rs`): one weight per rig morph target, the frame viewers get (`d` as the
/// morph basis's controls, the head rotation as its pose) and the blended positions.
#[derive(Debug)]
pub(crate) struct MorphFrame {
    /// One weight per morph target of the session's rig, set by the protocol before [`Self::send`].
    pub(crate) weights: Vec<f32>,
    out: FrameOutput,
    positions: Vec<Vec3>,
}

impl MorphFrame {
    /// All weights zero, the rig's rest positions, no head rotation.
    pub(crate) fn new(s: &Session) -> Self {
        let k = s.rig.morph.as_ref().map_or(0, MorphSet::len);
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
        }
    }

    /// Counts the current weights as an accepted frame at `t_us` (`udp` when it came as a
    /// packet) and broadcasts it with head rotation `rotation`; allocates nothing.
    pub(crate) fn send(
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

/// What a weights session's end summary adds: the unknown weight names it was sent.
pub(crate) fn weights_summary(end: &SessionSnapshot) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("unknown_weights".into(), json!(end.unknown_weights));
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
    fn accept(
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
            .send(s, morph, t_us, Quat::IDENTITY, false, arrival);
    }
}

impl Protocol for Weights {
    type Hello = WeightsHello;
    type Admitted = WeightsHello;
    type Event = Infallible;
    const KIND: &'static str = "weights";

    fn admit(shared: &Shared, hello: WeightsHello) -> Result<Admission<WeightsHello>, Refusal> {
        let rig = find_rig(shared, hello.request.rig.clone())?;
        let morph = morph_targets(&rig)?;
        Ok(Admission {
            session: hello.request.session.clone(),
            rig_message: morph.message.clone(),
            rig,
            layout: "weights".into(),
            admitted: hello,
        })
    }

    fn describe(hello: &WeightsHello, rig: &RigEntry, name: &str, id: u32) -> Value {
        describe_weights(rig, name, id, json!(hello.source), json!(hello.rate_hz))
    }

    async fn start(_: WeightsHello, s: &Session) -> (Self, Value) {
        let settings = s.settings();
        let names = s.rig.morph.as_ref().map_or(&[][..], |m| &m.names[..]);
        let k = names.len();
        let welcome = json!({
            "type": "welcome", "session": s.name, "session_id": s.id, "rig": s.rig.name(),
            "mode": "weights", "targets": names,
            "max_message_bytes": settings.max_message_bytes,
        });
        tracing::info!(session = %s.name, id = s.id, rig = s.rig.name(), targets = k, "weights session started");
        if settings.record_dir.is_some() {
            tracing::info!(session = %s.name, "weights sessions are not recorded (recordings hold landmark frames)");
        }
        let weights = Weights {
            frame: MorphFrame::new(s),
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
                self.accept(s, f.timestamp_us, &f.weights, line.arrival, line.number);
                LineOutcome::Frame
            }
            Err(e) => LineOutcome::Malformed(e.code(), e.to_string()),
        }
    }

    fn too_long(limit: usize) -> String {
        format!("line longer than {limit} bytes")
    }

    async fn finish(self, _: &Session) {}

    fn summary(_: &ServerSettings, end: &SessionSnapshot, _bye: bool) -> Map<String, Value> {
        weights_summary(end)
    }
}
