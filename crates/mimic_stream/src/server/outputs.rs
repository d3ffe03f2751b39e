//! What a session's accepted frames go to besides its viewers, shared by the landmark, weights
//! and Live Link sessions: its recording ([`Recording`], `--record`) and its forwarding
//! ([`start_forwarder`], `--forward` and a hello's own `"forward"`, checked by [`own_forward`]).

use super::admission::Refusal;
use super::session::Session;
use super::state::Shared;
use crate::forward::{ForwardTarget, Forwarder, Sent};
use crate::record::{Entry, RecordCounters, RecordKind, Recorder, SessionLabel};
use crate::sync::lock;
use std::net::SocketAddr;
use std::sync::Arc;

/// A session's recording (landmark, weights and Live Link sessions): off, on, or asked for but
/// not started (its frames count as lost).
#[derive(Debug)]
pub(crate) enum Recording {
    /// The server does not record.
    Off,
    /// Recording.
    On(Recorder),
    /// Asked for, but the file could not be started.
    Failed(Arc<RecordCounters>),
}

impl Recording {
    /// Starts a session's recording when the server records; a failure is logged, and the
    /// session's accepted frames are then counted as `record_lost`.
    pub(crate) async fn start(s: &Session, kind: RecordKind<'_>, peer: Option<SocketAddr>) -> Self {
        let settings = s.settings();
        let Some(dir) = settings.record_dir.as_ref() else {
            return Recording::Off;
        };
        let who = SessionLabel {
            name: &s.name,
            id: s.id,
            rig: s.rig.name(),
            peer,
        };
        let started = Recorder::start(
            dir,
            kind,
            &who,
            settings.record_queue_frames,
            s.record.record.clone(),
            s.shared.recordings_open.clone(),
        )
        .await;
        match started {
            Ok(r) => {
                *lock(&s.record.recording) = Some(r.path().display().to_string());
                tracing::info!(session = %s.name, path = %r.path().display(), "recording");
                Recording::On(r)
            }
            Err(e) => {
                tracing::error!(session = %s.name, "not recorded; its accepted frames count as record_lost: {e}");
                Recording::Failed(s.record.record.clone())
            }
        }
    }

    /// True when frames go (or were meant to go) to a file.
    pub(crate) fn is_on(&self) -> bool {
        !matches!(self, Recording::Off)
    }

    /// Writes an accepted frame (with `sync`, to the disk too) before returning; false when it
    /// could not be (then it is counted `record_lost` and must not be broadcast).
    pub(crate) async fn frame_acked(&self, f: impl Into<Entry>, sync: bool) -> bool {
        match self {
            Recording::Off => true,
            Recording::On(r) => r.record_acked(f, sync).await,
            Recording::Failed(c) => {
                c.lost.bump();
                false
            }
        }
    }

    /// Hands an accepted frame to the recording, if the server records.
    pub(crate) async fn frame(&self, f: impl Into<Entry>) {
        match self {
            Recording::Off => {}
            Recording::On(r) => r.record(f).await,
            Recording::Failed(c) => c.lost.bump(),
        }
    }

    /// Waits until every queued frame is written, flushed and synced.
    pub(crate) async fn finish(self) {
        if let Recording::On(r) = self {
            r.finish().await;
        }
    }
}

/// The forwarding of session `s` (the server's `--forward` targets and `own`, the tracker's),
/// or `None` without targets; a socket that cannot be opened is logged and forwards nothing.
pub(crate) fn start_forwarder(
    s: &Session,
    own: Option<ForwardTarget>,
    rig_names: &[String],
) -> Option<Forwarder> {
    let settings = &s.settings().forward;
    let targets: Vec<ForwardTarget> = settings.targets.iter().copied().chain(own).collect();
    match Forwarder::new(settings, &targets, rig_names, &s.name) {
        Ok(Some(f)) => {
            let list: Vec<String> = f.targets().map(ToString::to_string).collect();
            tracing::info!(session = %s.name, "forwarding to {}", list.join(", "));
            Some(f)
        }
        Ok(None) => None,
        Err(e) => {
            tracing::error!(session = %s.name, "not forwarded: {e}");
            None
        }
    }
}

/// Counts what a forward did in the session's `forwarded` and `forward_dropped`.
pub(crate) fn count_forward(s: &Session, sent: Sent) {
    s.record.forwarded.add(sent.sent);
    s.record.forward_dropped.add(sent.dropped);
}

/// A hello's `"forward"` checked against the server's rules: loopback or `--forward-allow`.
pub(crate) fn own_forward(
    shared: &Shared,
    text: Option<&str>,
) -> Result<Option<ForwardTarget>, Refusal> {
    text.map(|t| shared.settings.forward.check_session_target(t))
        .transpose()
        .map_err(|e| Refusal::Forward(e.to_string()))
}
