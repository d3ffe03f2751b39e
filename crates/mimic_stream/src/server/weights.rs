//! Weights sessions: a tracker that sends named blendshape weights (ARKit-style) instead of
//! landmarks. The weights go through the rig's [`WeightMap`](mimic_retarget::WeightMap) onto its
//! morph targets and reach viewers as the morph basis's control values (`d[3k + a] = w_k e_a`),
//! or as positions `P0 + sum_k w_k dP_k`.

use super::{
    SessionRecord, Shared, broadcast, check_time, future_line, go_live, lock, refuse, reply,
    reply_idle_timeout, reply_malformed,
};
use crate::catalog::RigEntry;
use crate::lines::{Line, LineReader};
use crate::timing::{FrameClock, TimeProblem};
use crate::wire::{
    ErrorCode, KIND_END, KIND_SESSION, encode_json, error_line, parse_weight_frame, warning_line,
};
use glam::{Quat, Vec3};
use mimic_retarget::{FrameOutput, FrameStatus};
use mimic_types::HeadPose;
use serde_json::json;
use std::collections::HashSet;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;
use tokio::io::{AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::sync::{mpsc, watch};
use tokio::time::{sleep_until, timeout};

/// Distinct unknown weight names a session remembers (and warns about once each).
const UNKNOWN_NAMES_KEPT: usize = 256;

/// What a weights hello asked for.
#[derive(Debug)]
pub(super) struct WeightsHello {
    pub session: Option<String>,
    pub rig: Option<String>,
    pub rate_hz: Option<f64>,
    pub source: Option<String>,
}

/// Per-session state of the weights frame path.
struct WeightsPipeline {
    shared: Arc<Shared>,
    rig: Arc<RigEntry>,
    record: Arc<SessionRecord>,
    weights: Vec<f32>,
    scratch: Vec<f32>,
    out: FrameOutput,
    positions: Vec<Vec3>,
    clock: FrameClock,
    reported: HashSet<String>,
}

impl WeightsPipeline {
    /// Maps, orders and broadcasts one weight frame; returns warning lines for names never seen
    /// (or the error line of a frame from the future).
    fn accept(
        &mut self,
        t_us: i64,
        pairs: &[(String, f64)],
        arrival: Instant,
        line_no: u64,
    ) -> Vec<String> {
        let r = self.record.clone();
        match check_time(&mut self.clock, &r, t_us, arrival) {
            Ok(()) => {}
            Err(TimeProblem::Late) => return Vec::new(),
            Err(TimeProblem::Future {
                jump_us,
                allowed_us,
            }) => return vec![future_line(line_no, t_us, jump_us, allowed_us)],
        }
        let mut warnings = Vec::new();
        let Some(morph) = self.rig.morph.as_ref() else {
            return warnings;
        };
        // Clamped here, in f64: a huge value must give 1, not an infinite f32.
        let as_f32 = |x: f64| x.clamp(0.0, 1.0) as f32;
        let unknown = morph.map.apply(
            pairs.iter().map(|(n, v)| (n.as_str(), as_f32(*v))),
            &mut self.weights,
        );
        if unknown > 0 {
            r.unknown_weights.add(unknown as u64);
            for (name, _) in pairs {
                if self.reported.len() < UNKNOWN_NAMES_KEPT
                    && !self.reported.contains(name)
                    && morph.map.apply([(name.as_str(), 0.0)], &mut self.scratch) == 1
                {
                    self.reported.insert(name.clone());
                    warnings.push(warning_line(
                        ErrorCode::UnknownWeight,
                        line_no,
                        &format!(
                            "`{name}` names no morph target of rig `{}` (ignored; reported once)",
                            self.rig.name()
                        ),
                    ));
                }
            }
        }
        mimic_solve::morph_basis::morph_controls(&self.weights, &mut self.out.displacements);
        self.out.timestamp_us = t_us;
        r.tracked.bump();
        let seq = r.frames.get();
        r.frames.bump();
        let rest = &self.rig.rig.mesh.positions;
        let weights = &self.weights;
        broadcast(
            &self.shared,
            &r,
            seq,
            &self.out,
            &mut self.positions,
            |_, positions| morph.blend(rest, weights, positions),
            arrival,
        );
        warnings
    }
}

/// A weights session: check the rig, register the session, then map its lines until it ends.
pub(super) async fn session(
    shared: Arc<Shared>,
    mut lines: LineReader<BufReader<OwnedReadHalf>>,
    mut w: OwnedWriteHalf,
    hello: WeightsHello,
    mut stop: watch::Receiver<bool>,
) {
    let settings = &shared.settings;
    let refuse_with = |code: ErrorCode, msg: String| error_line(code, 1, &msg);
    let Some(rig) = shared.catalog.rig(hello.rig.as_deref()).cloned() else {
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::UnknownRig,
            format!(
                "no rig `{}`; this server has {:?}",
                hello.rig.unwrap_or_default(),
                shared.catalog.rig_names()
            ),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    };
    let Some(morph) = rig.morph.as_ref() else {
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::NoMorphTargets,
            format!(
                "rig `{}` has no [[morph_targets]]: a weights session needs a blendshape rig",
                rig.name()
            ),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
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
    let k = morph.len();
    let id = shared.next_session.fetch_add(1, Ordering::Relaxed);
    let name = hello.session.unwrap_or_else(|| format!("s{id}"));
    let record = Arc::new(SessionRecord::new(id, &name, rig.name(), "weights"));
    let session_message = Arc::new(encode_json(
        KIND_SESSION,
        &json!({
            "session": name, "session_id": id, "rig": rig.name(), "layout": null,
            "mode": "weights", "targets": k,
            "vertices": rig.rig.mesh.vertex_count(), "controls": 3 * k,
            "source": hello.source, "rate_hz": hello.rate_hz,
        }),
    ));
    if !go_live(&shared, &name, &record, session_message, &morph.message) {
        shared.sessions_active.fetch_sub(1, Ordering::AcqRel);
        shared.refused.bump();
        let m = refuse_with(
            ErrorCode::SessionBusy,
            format!("session `{name}` already has a tracker"),
        );
        refuse(&mut w, m.as_bytes()).await;
        return;
    }
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
        "type": "welcome", "session": name, "session_id": id, "rig": rig.name(),
        "mode": "weights", "targets": morph.names,
        "max_message_bytes": settings.max_message_bytes,
    })
    .to_string();
    welcome.push('\n');
    reply(&reply_tx, &record, welcome);
    tracing::info!(session = %name, id, rig = rig.name(), targets = k, "weights session started");
    if settings.record_dir.is_some() {
        tracing::info!(session = %name, "weights sessions are not recorded (recordings hold landmark frames)");
    }

    let mut p = WeightsPipeline {
        shared: shared.clone(),
        rig: rig.clone(),
        record: record.clone(),
        weights: vec![0.0; k],
        scratch: vec![0.0; k],
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
        positions: rig.rig.mesh.positions.clone(),
        clock: FrameClock::new(settings.max_time_jump),
        reported: HashSet::new(),
    };
    let mut errors_in_a_row = 0u32;
    let mut line_no = 1u64;
    let mut last_activity = tokio::time::Instant::now();
    let reason: String = loop {
        if *stop.borrow() {
            break "shutdown".into();
        }
        tokio::select! {
            biased;
            _ = stop.changed() => break "shutdown".into(),
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
                        Some((ErrorCode::TooLong, format!("line longer than {} bytes", settings.max_message_bytes)))
                    }
                    Ok(Line::Partial) => {
                        line_no += 1;
                        Some((ErrorCode::Truncated, "the connection ended in the middle of a line".to_string()))
                    }
                    Ok(Line::Complete) => {
                        line_no += 1;
                        let text = lines.line();
                        if text.iter().all(u8::is_ascii_whitespace) {
                            None
                        } else {
                            match parse_weight_frame(text) {
                                Ok(f) => {
                                    errors_in_a_row = 0;
                                    for warning in p.accept(f.timestamp_us, &f.weights, arrival, line_no) {
                                        reply(&reply_tx, &record, warning);
                                    }
                                    None
                                }
                                Err(e) => Some((e.code(), e.to_string())),
                            }
                        }
                    }
                };
                if let Some((code, message)) = problem
                    && reply_malformed(&reply_tx, &record, settings, &mut errors_in_a_row, line_no, code, &message)
                {
                    break "too_many_errors".into();
                }
            }
        }
    };
    *lock(&record.end_reason) = Some(reason.clone());
    record.active.store(false, Ordering::Relaxed);
    let end = record.snapshot();
    let end_json = json!({
        "session": name, "reason": reason, "frames": end.frames, "late": end.late,
        "future": end.future, "malformed": end.malformed, "unknown_weights": end.unknown_weights,
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
        "future": end.future, "malformed": end.malformed, "unknown_weights": end.unknown_weights})
    .to_string();
    bye.push('\n');
    reply(&reply_tx, &record, bye);
    drop(reply_tx);
    let _ = timeout(std::time::Duration::from_secs(2), writer).await;
    tracing::info!(session = %name, reason = %reason, frames = end.frames, late = end.late,
        malformed = end.malformed, unknown_weights = end.unknown_weights, "weights session ended");
}
