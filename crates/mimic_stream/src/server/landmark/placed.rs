//! A landmark session stepped by the server's placement (`mimic serve --nats`): accepted frames
//! go out numbered ([`Remote::hand_over`]), answers come back in order ([`Remote::answer`]) and
//! are counted ([`count_status`]) and broadcast ([`Viewers`]) as a local step's are.

use crate::placement::{PlaceRequest, PlacedFrame, Placement, PlacementStatus, StepResult};
use crate::server::follow::read_result;
use crate::server::hub::SessionRecord;
use crate::server::session::Session;
use crate::sync::lock;
use glam::Vec3;
use mimic_retarget::{FrameOutput, FrameStatus};
use mimic_types::LandmarkFrame;
use serde_json::Value;
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// Frames handed to a placement whose arrival times are kept for the latency (older ones are
/// forgotten; they are counted all the same).
const PENDING_KEPT: usize = 4096;

/// How long an ending placed session waits for each of its last answers (the placement closes
/// the answers sooner; this only guards a hang).
const FINISH_WAIT: Duration = Duration::from_secs(10);

/// How long a new session waits for its first worker before it starts anyway (its frames are
/// lost until a worker takes it).
const PLACE_WAIT: Duration = Duration::from_secs(5);

/// A placed landmark session's side of the placement (module docs).
#[derive(Debug)]
pub(super) struct Remote {
    frames: mpsc::Sender<PlacedFrame>,
    /// The placement's answers.
    pub(super) results: mpsc::Receiver<StepResult>,
    status: Arc<PlacementStatus>,
    /// Frames handed over so far (the next frame's number).
    next_n: u64,
    /// The lowest frame number an answer may still have.
    expected: u64,
    /// Number, arrival time and transport (UDP) of frames not answered yet, oldest first.
    pending: VecDeque<(u64, Instant, bool)>,
    /// The last answer's frame.
    out: FrameOutput,
}

impl Remote {
    /// Places session `s` (of `layout`, described by `description`) and waits (a while) for a
    /// worker to take it; `out` is the frame its answers are read into.
    pub(super) async fn place(
        placement: &dyn Placement,
        s: &Session,
        layout: &str,
        description: Value,
        out: FrameOutput,
    ) -> Self {
        let placed = placement.place(PlaceRequest {
            session: s.name.clone(),
            id: s.id,
            rig: s.rig.name().to_string(),
            layout: layout.to_string(),
            description,
        });
        *lock(&s.record.placement) = Some(placed.status.clone());
        if !matches!(
            tokio::time::timeout(PLACE_WAIT, placed.ready).await,
            Ok(Ok(()))
        ) {
            tracing::warn!(session = %s.name, "no worker took the session yet: its frames are lost until one does");
        }
        Self {
            frames: placed.frames,
            results: placed.results,
            status: placed.status,
            next_n: 0,
            expected: 0,
            pending: VecDeque::new(),
            out,
        }
    }

    /// Hands an accepted frame over (a full queue loses it: counted when answers pass it).
    pub(super) fn hand_over(&mut self, frame: &LandmarkFrame, arrival: Instant, udp: bool) {
        let n = self.next_n;
        self.next_n += 1;
        self.status.sent.bump();
        if self.pending.len() >= PENDING_KEPT {
            self.pending.pop_front();
        }
        self.pending.push_back((n, arrival, udp));
        let placed = PlacedFrame {
            n,
            frame: frame.clone(),
        };
        if self.frames.try_send(placed).is_err() {
            tracing::debug!(n, "placement queue full: frame lost");
        }
    }

    /// A frame accepted but not handed over (under a waiting record mode its write failed):
    /// counted sent, and so lost once answers pass it or the session ends.
    pub(super) fn skip(&mut self) {
        self.next_n += 1;
        self.status.sent.bump();
    }

    /// Takes answer `n` in order: frames it passed are counted lost; returns the frame's arrival
    /// and transport, or `None` for a duplicate or an answer to no frame.
    fn take(&mut self, n: u64) -> Option<(Instant, bool)> {
        if n < self.expected || n >= self.next_n {
            return None;
        }
        self.status.lost.add(n - self.expected);
        self.status.retargeted.bump();
        self.expected = n + 1;
        let mut found = None;
        while let Some(&(k, t, udp)) = self.pending.front() {
            if k > n {
                break;
            }
            self.pending.pop_front();
            if k == n {
                found = Some((t, udp));
            }
        }
        Some(found.unwrap_or_else(|| (Instant::now(), false)))
    }

    /// A placement's answer: counted as the local step counts it and broadcast with the frame's
    /// number as its sequence number.
    pub(super) fn answer(&mut self, s: &Session, a: StepResult, viewers: &mut Viewers) {
        let Some((arrival, udp)) = self.take(a.n) else {
            return;
        };
        let r = &s.record;
        if !read_result(&a, &mut self.out) {
            r.malformed.bump();
            return;
        }
        r.gated.add(u64::from(a.gated));
        r.jumps.add(u64::from(a.jump));
        if !count_status(r, self.out.status) {
            return;
        }
        r.frames.bump();
        if udp {
            r.udp_frames.bump();
        }
        viewers.broadcast(s, a.n, &self.out, arrival);
    }

    /// Ends the placed session: closing its frames ends it on the worker, whose last answers are
    /// broadcast; frames never answered are counted lost.
    pub(super) async fn finish(mut self, s: &Session, viewers: &mut Viewers) {
        let (closed, _) = mpsc::channel(1);
        drop(std::mem::replace(&mut self.frames, closed));
        while let Ok(Some(a)) = tokio::time::timeout(FINISH_WAIT, self.results.recv()).await {
            self.answer(s, a, viewers);
        }
        self.status.lost.add(self.next_n - self.expected);
        self.status.end();
    }
}

/// Counts a retargeted frame by its status; false for a rejected one (counted malformed).
pub(super) fn count_status(r: &SessionRecord, status: FrameStatus) -> bool {
    match status {
        FrameStatus::Tracked => r.tracked.bump(),
        FrameStatus::Calibrating => r.calibrating.bump(),
        FrameStatus::Lost => r.lost.bump(),
        FrameStatus::Rejected => {
            r.malformed.bump();
            return false;
        }
    }
    true
}

/// What a broadcast fills the full positions in (for viewers that want them) from `d`.
#[derive(Debug)]
pub(super) struct Viewers {
    pub(super) positions: Vec<Vec3>,
    pub(super) scratch: Vec<Vec3>,
}

impl Viewers {
    /// Broadcasts `out` as frame `seq` to the session's viewers.
    pub(super) fn broadcast(&mut self, s: &Session, seq: u64, out: &FrameOutput, arrival: Instant) {
        let (rig, scratch) = (&s.rig, &mut self.scratch);
        let fill = |d: &[Vec3], positions: &mut [Vec3]| rig.deform(d, scratch, positions);
        s.broadcast(seq, out, &mut self.positions, fill, arrival);
    }
}
