//! Where a landmark session is stepped when this server does not step it itself: the seam a
//! cluster implements (`mimic_cluster`, over NATS; docs/cluster.md), so that this crate knows
//! nothing of the transport. With a [`Placement`] ([`crate::Server::with_placement`]) a front door
//! keeps its sockets, admission, timing checks, recording, viewers and stats, but hands each
//! accepted landmark frame to [`Placed::frames`] and broadcasts what comes back on
//! [`Placed::results`]; viewers of a session this front door does not host get it through
//! [`Placement::follow`]. Frames handed over and never answered are counted lost
//! ([`ClusterSnapshot`]: `sent = retargeted + lost` once the session has ended).

use crate::counter::Counter;
use mimic_types::LandmarkFrame;
use serde::Serialize;
use serde_json::Value;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use tokio::sync::{mpsc, oneshot};

/// Steps sessions elsewhere (e.g. on worker processes).
pub trait Placement: Send + Sync + std::fmt::Debug {
    /// Places a new landmark session and returns at once; placing, and placing again after a
    /// failure, is the implementation's work. Frames sent to [`Placed::frames`] are stepped in
    /// order; closing it ends the session, and the implementation then closes
    /// [`Placed::results`] within a bounded time (answers still coming are given first).
    fn place(&self, request: PlaceRequest) -> Placed;

    /// Follows session `session` hosted by another front door: its description, frames and end,
    /// until the receiver is dropped.
    fn follow(&self, session: &str) -> mpsc::Receiver<Followed>;
}

/// A session to place.
#[derive(Clone, Debug)]
pub struct PlaceRequest {
    /// Session name (unique over the cluster).
    pub session: String,
    /// The front door's session id.
    pub id: u32,
    /// Rig name (every worker and front door loads the same configs).
    pub rig: String,
    /// Layout name.
    pub layout: String,
    /// The SESSION message's JSON, for viewers on other front doors.
    pub description: Value,
}

/// A placed session, as its front door drives it.
#[derive(Debug)]
pub struct Placed {
    /// Accepted frames, numbered from 0 in the order they were accepted.
    pub frames: mpsc::Sender<PlacedFrame>,
    /// Answers, in frame order (some may be missing: those frames are lost).
    pub results: mpsc::Receiver<StepResult>,
    /// Fires once the session has a worker (or never, when none could be found).
    pub ready: oneshot::Receiver<()>,
    /// Who holds it and how often it was placed, for the stats.
    pub status: std::sync::Arc<PlacementStatus>,
}

/// One accepted frame handed over.
#[derive(Clone, Debug)]
pub struct PlacedFrame {
    /// Its number in the session (from 0).
    pub n: u64,
    /// The frame.
    pub frame: LandmarkFrame,
}

/// One stepped frame.
#[derive(Clone, Debug)]
pub struct StepResult {
    /// The frame's number.
    pub n: u64,
    /// The plausibility gate held it.
    pub gated: bool,
    /// Some control jumped past the jump bound.
    pub jump: bool,
    /// Its FRAME viewer message (`docs/protocol.md`, sequence number `n`, no positions).
    pub message: Vec<u8>,
}

/// What a follower of a session hosted elsewhere gets.
#[derive(Clone, Debug)]
pub enum Followed {
    /// The session is live: its SESSION message JSON and rig name.
    Live {
        /// SESSION message JSON.
        description: Value,
        /// Rig name.
        rig: String,
    },
    /// One stepped frame.
    Frame(StepResult),
    /// The session ended on its front door.
    End,
}

/// Who holds a placed session, shared between the front door and the placement.
#[derive(Debug, Default)]
pub struct PlacementStatus {
    worker: Mutex<Option<String>>,
    /// Times the session was placed on a worker (1, plus one per failover).
    pub placements: Counter,
    /// Frames handed over.
    pub sent: Counter,
    /// Frames answered by a worker.
    pub retargeted: Counter,
    /// Frames handed over that no worker answered (a worker died, a queue was full, the
    /// session ended before the answer).
    pub lost: Counter,
    ended: AtomicBool,
}

impl PlacementStatus {
    /// Sets (or clears) the worker holding the session.
    pub fn set_worker(&self, worker: Option<String>) {
        *self
            .worker
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = worker;
    }

    /// The worker holding the session now.
    pub fn worker(&self) -> Option<String> {
        self.worker
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// Marks the session ended (its counts are final).
    pub(crate) fn end(&self) {
        self.ended.store(true, Ordering::Release);
    }

    /// The counters as the stats report them.
    pub fn snapshot(&self) -> ClusterSnapshot {
        ClusterSnapshot {
            worker: self.worker(),
            placements: self.placements.get(),
            sent: self.sent.get(),
            retargeted: self.retargeted.get(),
            lost: self.lost.get(),
            ended: self.ended.load(Ordering::Acquire),
        }
    }
}

/// A placed session's counters in the stats.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ClusterSnapshot {
    /// The worker holding it now (none between a worker's death and the next placement).
    pub worker: Option<String>,
    /// Times it was placed (1, plus one per failover).
    pub placements: u64,
    /// Frames handed to workers.
    pub sent: u64,
    /// Frames a worker answered.
    pub retargeted: u64,
    /// Frames handed over that no worker answered; once `ended`, `sent = retargeted + lost`.
    pub lost: u64,
    /// The session has ended and the counts are final.
    pub ended: bool,
}
