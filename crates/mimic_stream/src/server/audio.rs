//! Audio sessions (`{"mode":"audio"}`, docs/protocol.md and docs/audio.md): a tracker sends
//! speech as PCM chunks; a worker on the blocking pool (one per session, bounded queues both
//! ways, so speech processing never holds the runtime nor another session) turns it into ARKit
//! mouth weights as it arrives (`mimic_audio::live`, causal, 60 frames a second), which go out
//! exactly like a weights session's frames ([`MorphFrame`]: viewers, `--record`, `--forward`).
//!
//! Stream time: the first chunk's `t_us` anchors the stream; frame `k` is at `anchor + k / 60 s`
//! and holds the mouth after the audio up to that time. A chunk starting before the previous
//! one ended is dropped (`late`); a gap up to [`MAX_GAP_US`] is silence, a longer one starts the
//! stream again from that chunk (the mouth closed). When the worker's queue is full (a sender
//! faster than real time, `mimic send --fast`), the session stops reading its tracker until
//! there is room, publishing the worker's frames meanwhile: TCP slows that sender down, no audio
//! is dropped and no other session waits.

use super::admission::{Admission, Refusal, find_rig};
use super::outputs::own_forward;
use super::session::{LineOutcome, Protocol, Session, TrackerLine, future_line, is_blank};
use super::state::Shared;
use super::weights::{MorphFrame, describe_weights, morph_targets, weights_summary};
use crate::catalog::RigEntry;
use crate::forward::ForwardTarget;
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::timing::{FrameClock, TimeProblem};
use glam::Quat;
use mimic_audio::live::LiveLipSync;
use mimic_audio::visemes::VisemeTable;
use mimic_types::arkit::ARKIT_NAMES;
use mimic_wire::{AudioFormat, AudioHello, ErrorCode, parse_audio_chunk};
use serde_json::{Map, Value, json};
use std::net::SocketAddr;
use std::sync::mpsc as std_mpsc;
use std::time::Instant;
use tokio::sync::mpsc;

/// Chunks queued for a session's worker before its tracker waits (1 s of 20 ms chunks).
pub(crate) const CHUNK_QUEUE: usize = 50;
/// Frames queued from the worker to the session (2 s at 60 fps).
const FRAME_QUEUE: usize = 120;
/// Longest gap between chunks taken as silence (µs); a longer one starts the stream again.
pub(crate) const MAX_GAP_US: i64 = 1_000_000;
/// A chunk this close to where the last one ended (µs; the sender's times are rounded) is
/// taken as following it.
const TOLERANCE_US: i64 = 1_000;

/// What the session hands its worker.
enum ToWorker {
    /// Start the stream again at `anchor_us` (the mouth closed).
    Restart { anchor_us: i64 },
    /// Mono samples starting `at` samples after the anchor.
    Samples {
        at: u64,
        buf: Vec<f32>,
        arrival: Instant,
    },
}

/// One mouth frame from the worker: its time, its weights (the live names' order) and the
/// arrival of the chunk that completed it.
pub(crate) struct MouthFrame {
    t_us: i64,
    weights: [f32; ARKIT_NAMES.len()],
    arrival: Instant,
}

/// An audio tracker's hello and where it came from.
#[derive(Debug)]
pub(crate) struct AudioSession {
    hello: AudioHello,
    peer: Option<SocketAddr>,
    own_forward: Option<ForwardTarget>,
}

impl AudioSession {
    /// A hello from `peer`.
    pub(crate) fn new(hello: AudioHello, peer: Option<SocketAddr>) -> Self {
        Self {
            hello,
            peer,
            own_forward: None,
        }
    }
}

/// An audio session's state on the runtime: the frame path, the stream clock, the queues to
/// and from its worker and the chunk buffers they recycle.
pub(crate) struct Audio {
    frame: MorphFrame,
    format: AudioFormat,
    clock: FrameClock,
    names: Vec<&'static str>,
    to_worker: Option<mpsc::Sender<ToWorker>>,
    spare: std_mpsc::Receiver<Vec<f32>>,
    frames: mpsc::Receiver<MouthFrame>,
    scratch: Vec<u8>,
    mono: Vec<f32>,
    /// Samples since the anchor (`None` before the first chunk).
    at: Option<u64>,
    anchor_us: i64,
}

impl std::fmt::Debug for Audio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Audio")
            .field("format", &self.format)
            .field("at", &self.at)
            .finish_non_exhaustive()
    }
}

/// The worker: chunks in, mouth frames out, until the session drops its sender (or its frame
/// queue is gone). Runs on the blocking pool.
fn work(
    fresh: LiveLipSync,
    mut rx: mpsc::Receiver<ToWorker>,
    spare: std_mpsc::SyncSender<Vec<f32>>,
    out: mpsc::Sender<MouthFrame>,
) {
    let zeros = [0.0f32; 480];
    let mut live = fresh.clone();
    let mut anchor_us = 0i64;
    let mut open = true;
    while open && let Some(m) = rx.blocking_recv() {
        let (at, buf, arrival) = match m {
            ToWorker::Restart { anchor_us: a } => {
                anchor_us = a;
                live = fresh.clone();
                continue;
            }
            ToWorker::Samples { at, buf, arrival } => (at, buf, arrival),
        };
        let mut emit = |k: u64, w: &[f32]| {
            let mut weights = [0.0; ARKIT_NAMES.len()];
            weights[..w.len()].copy_from_slice(w);
            let t_us = anchor_us.saturating_add(LiveLipSync::frame_t_us(k));
            let f = MouthFrame {
                t_us,
                weights,
                arrival,
            };
            open = open && out.blocking_send(f).is_ok();
        };
        // A gap in the stream: silence, so the frame times stay true.
        while live.samples() < at {
            let n = (at - live.samples()).min(zeros.len() as u64) as usize;
            live.push(&zeros[..n], &mut emit);
        }
        live.push(&buf, &mut emit);
        let _ = spare.try_send(buf);
    }
}

impl Audio {
    /// Takes one chunk at `t_us` (its samples in `self.mono`): checks its time, then queues it
    /// for the worker.
    async fn accept(&mut self, s: &Session, t_us: i64, arrival: Instant, line_no: u64) {
        let rate = i64::from(self.format.sample_rate);
        let ahead = self.at.map(|at| {
            let end_us = self.anchor_us.saturating_add(
                i64::try_from(at)
                    .unwrap_or(i64::MAX)
                    .saturating_mul(1_000_000)
                    / rate,
            );
            t_us.saturating_sub(end_us)
        });
        if ahead.is_some_and(|d| d < -TOLERANCE_US) {
            // It overlaps the audio already taken.
            s.record.late.bump();
            return;
        }
        match s.check_time(&mut self.clock, t_us, arrival) {
            Ok(()) => {}
            Err(TimeProblem::Late) => return,
            Err(TimeProblem::Future {
                jump_us,
                allowed_us,
            }) => return s.reply(future_line(line_no, t_us, jump_us, allowed_us)),
        }
        let at = match (self.at, ahead) {
            (Some(at), Some(d)) if d <= MAX_GAP_US => {
                // A gap is silence: the worker fills it.
                at + u64::try_from(d.max(0).saturating_mul(rate) / 1_000_000).unwrap_or(0)
            }
            _ => {
                self.anchor_us = t_us;
                self.send(s, ToWorker::Restart { anchor_us: t_us }).await;
                0
            }
        };
        let n = self.mono.len() as u64;
        let mut buf = self.spare.try_recv().unwrap_or_default();
        std::mem::swap(&mut buf, &mut self.mono);
        self.send(s, ToWorker::Samples { at, buf, arrival }).await;
        self.at = Some(at + n);
    }

    /// Queues a message for the worker, publishing its frames while its queue is full.
    async fn send(&mut self, s: &Session, m: ToWorker) {
        let Some(tx) = &self.to_worker else { return };
        loop {
            tokio::select! {
                biased;
                permit = tx.reserve() => {
                    if let Ok(p) = permit {
                        p.send(m);
                    }
                    return;
                }
                Some(f) = self.frames.recv() => publish(&mut self.frame, &self.names, s, f).await,
            }
        }
    }
}

/// Sends one mouth frame (weights in `names`' order) out as the session's weights.
async fn publish(frame: &mut MorphFrame, names: &[&'static str], s: &Session, f: MouthFrame) {
    let Some(morph) = s.rig.morph.as_ref() else {
        return;
    };
    let pairs = names.iter().copied().zip(f.weights.iter().copied());
    morph.map.apply(pairs, &mut frame.weights);
    frame
        .keep(s, morph, f.t_us, Quat::IDENTITY, false, f.arrival)
        .await;
}

impl Protocol for Audio {
    type Hello = AudioSession;
    type Admitted = AudioSession;
    type Event = MouthFrame;
    const KIND: &'static str = "audio";

    fn admit(shared: &Shared, mut hello: AudioSession) -> Result<Admission<AudioSession>, Refusal> {
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

    fn describe(hello: &AudioSession, rig: &RigEntry, name: &str, id: u32) -> Value {
        let f = hello.hello.format;
        let mut v = describe_weights(
            rig,
            name,
            id,
            json!("audio"),
            json!(mimic_audio::coart::FPS),
        );
        v["audio"] = json!({"sample_rate": f.sample_rate, "channels": f.channels});
        v
    }

    async fn start(hello: AudioSession, s: &Session) -> (Self, Value) {
        let format = hello.hello.format;
        // The shipped table parses (a unit test of mimic_audio says so); the rate is checked.
        let fresh = VisemeTable::shipped()
            .and_then(|t| LiveLipSync::new(format.sample_rate, &t))
            .ok();
        let names: Vec<&'static str> = fresh.as_ref().map_or(Vec::new(), |l| l.names().to_vec());
        let targets = s.rig.morph.as_ref().map_or(&[][..], |m| &m.names[..]);
        let mut scratch = vec![0.0; targets.len()];
        let mouth: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| {
                s.rig
                    .morph
                    .as_ref()
                    .is_some_and(|m| m.map.apply([(*n, 1.0)], &mut scratch) == 0)
            })
            .collect();
        let welcome = json!({
            "type": "welcome", "session": s.name, "session_id": s.id, "rig": s.rig.name(),
            "mode": "audio", "targets": targets, "mouth": mouth, "fps": mimic_audio::coart::FPS,
            "sample_rate": format.sample_rate, "channels": format.channels,
            "max_message_bytes": s.settings().max_message_bytes,
        });
        tracing::info!(session = %s.name, id = s.id, rig = s.rig.name(), rate = format.sample_rate,
            channels = format.channels, "audio session started");
        let (tx, rx) = mpsc::channel(CHUNK_QUEUE);
        let (spare_tx, spare) = std_mpsc::sync_channel(CHUNK_QUEUE + 2);
        let (out_tx, frames) = mpsc::channel(FRAME_QUEUE);
        let to_worker = fresh.map(|fresh| {
            tokio::task::spawn_blocking(move || work(fresh, rx, spare_tx, out_tx));
            tx
        });
        let audio = Audio {
            frame: MorphFrame::start(s, hello.peer, hello.own_forward).await,
            format,
            clock: s.clock(),
            names,
            to_worker,
            spare,
            frames,
            scratch: Vec::new(),
            mono: Vec::new(),
            at: None,
            anchor_us: 0,
        };
        (audio, welcome)
    }

    async fn next_event(&mut self) -> MouthFrame {
        match self.frames.recv().await {
            Some(f) => f,
            None => std::future::pending().await,
        }
    }

    async fn on_event(&mut self, s: &Session, f: MouthFrame) {
        publish(&mut self.frame, &self.names, s, f).await;
    }

    async fn on_line(&mut self, s: &Session, line: TrackerLine<'_>) -> LineOutcome {
        if !line.complete {
            let message = "the connection ended in the middle of a line".to_string();
            return LineOutcome::Malformed(ErrorCode::Truncated, message);
        }
        if is_blank(line.text) {
            return LineOutcome::Skipped;
        }
        match parse_audio_chunk(line.text, self.format, &mut self.scratch, &mut self.mono) {
            Ok(t_us) => {
                self.accept(s, t_us, line.arrival, line.number).await;
                LineOutcome::Frame
            }
            Err(e) => LineOutcome::Malformed(e.code(), e.to_string()),
        }
    }

    fn too_long(limit: usize) -> String {
        format!("line longer than {limit} bytes")
    }

    async fn finish(mut self, s: &Session) {
        // The worker ends once it has the last chunk's frames out; they are published.
        self.to_worker = None;
        while let Some(f) = self.frames.recv().await {
            publish(&mut self.frame, &self.names, s, f).await;
        }
        self.frame.finish().await;
    }

    fn summary(settings: &ServerSettings, end: &SessionSnapshot, bye: bool) -> Map<String, Value> {
        weights_summary(settings, end, bye)
    }
}
