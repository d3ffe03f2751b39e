//! Admission: why a connection is refused ([`Refusal`]), how it is told, the token check, and
//! what a protocol's checks of a hello admitted ([`Admission`]); `session::open` makes an
//! admitted tracker a live session.

use super::state::Shared;
use crate::catalog::RigEntry;
use crate::queue::Message;
use mimic_wire::{ErrorCode, HelloError, error_line};
use serde_json::{Value, json};
use std::sync::Arc;
use tokio::io::{AsyncWrite, AsyncWriteExt};
use tokio::time::timeout;

/// Why a connection is refused before its session (or viewer) starts; the text is the reply's
/// `message`.
#[derive(Debug, thiserror::Error)]
pub(crate) enum Refusal {
    /// Nothing arrived for the idle timeout before the hello.
    #[error("no hello")]
    NoHello,
    /// The hello is longer than the hello limit.
    #[error("hello longer than {limit} bytes")]
    HelloTooLong {
        /// The hello limit (bytes).
        limit: usize,
    },
    /// The first line is no hello.
    #[error("{0}")]
    BadHello(HelloError),
    /// The header names a layout the server does not have.
    #[error("no layout `{layout}`")]
    UnknownLayout {
        /// The layout asked for.
        layout: String,
    },
    /// The hello names a rig the server does not have.
    #[error("no rig `{rig}`; this server has {have:?}")]
    UnknownRig {
        /// The rig asked for (empty for the default).
        rig: String,
        /// The rigs the server has.
        have: Vec<String>,
    },
    /// The header's point count is not the layout's.
    #[error("header says {header} points, layout `{layout}` has {points}")]
    PointCount {
        /// Points the header says.
        header: usize,
        /// The layout.
        layout: String,
        /// Points the layout has.
        points: usize,
    },
    /// The rig cannot be driven by the layout (the retargeter refused).
    #[error("{0}")]
    LayoutUnusable(String),
    /// A weights session names a rig without morph targets.
    #[error("rig `{rig}` has no [[morph_targets]]: a weights session needs a blendshape rig")]
    NoMorphTargets {
        /// The rig.
        rig: String,
    },
    /// The session limit is reached.
    #[error("at most {max} sessions")]
    TooManySessions {
        /// The limit.
        max: usize,
    },
    /// The viewer limit is reached.
    #[error("at most {max} viewers")]
    TooManyViewers {
        /// The limit.
        max: usize,
    },
    /// Past the connection limit (the text says which).
    #[error("{0}")]
    TooManyConnections(String),
    /// The server has a token and the hello did not present it.
    #[error("this server needs a token: start the client with --token (or MIMIC_TOKEN)")]
    BadToken,
    /// The hello's `"forward"` is not a target this server forwards to (`crate::forward`).
    #[error("{0}")]
    Forward(String),
    /// The session already has a tracker.
    #[error("session `{session}` already has a tracker")]
    SessionBusy {
        /// The session name.
        session: String,
    },
}

impl Refusal {
    /// The error code on the wire.
    pub(crate) fn code(&self) -> ErrorCode {
        match self {
            Refusal::NoHello => ErrorCode::IdleTimeout,
            Refusal::HelloTooLong { .. } => ErrorCode::TooLong,
            Refusal::BadHello(_) | Refusal::Forward(_) => ErrorCode::BadHello,
            Refusal::UnknownLayout { .. }
            | Refusal::PointCount { .. }
            | Refusal::LayoutUnusable(_) => ErrorCode::UnknownLayout,
            Refusal::UnknownRig { .. } => ErrorCode::UnknownRig,
            Refusal::NoMorphTargets { .. } => ErrorCode::NoMorphTargets,
            Refusal::TooManySessions { .. } => ErrorCode::TooManySessions,
            Refusal::TooManyViewers { .. } => ErrorCode::TooManyViewers,
            Refusal::SessionBusy { .. } => ErrorCode::SessionBusy,
            Refusal::TooManyConnections(_) => ErrorCode::TooManyConnections,
            Refusal::BadToken => ErrorCode::BadToken,
        }
    }

    /// The refusal as a viewer's ERROR message JSON: `{"code","message"}`.
    pub(crate) fn json(&self) -> Value {
        json!({"code": self.code().name(), "message": self.to_string()})
    }
}

/// Writes `bytes` and shuts the write side; errors writing are the peer's problem.
pub(crate) async fn write_and_close<W: AsyncWrite + Unpin>(w: &mut W, bytes: &[u8]) {
    let _ = timeout(std::time::Duration::from_secs(2), async {
        let _ = w.write_all(bytes).await;
        let _ = w.shutdown().await;
    })
    .await;
}

/// Counts a refused line connection and answers it with the refusal's error line (line 1).
pub(crate) async fn refuse<W: AsyncWrite + Unpin>(shared: &Shared, w: &mut W, refusal: Refusal) {
    shared.refused.bump();
    let line = error_line(refusal.code(), 1, &refusal.to_string());
    write_and_close(w, line.as_bytes()).await;
}

/// The rig a hello names (`None`: the server's default one).
pub(crate) fn find_rig(shared: &Shared, rig: Option<String>) -> Result<Arc<RigEntry>, Refusal> {
    shared
        .catalog
        .rig(rig.as_deref())
        .cloned()
        .ok_or_else(|| Refusal::UnknownRig {
            rig: rig.unwrap_or_default(),
            have: shared.catalog.rig_names(),
        })
}

/// What a protocol's own checks of a hello admitted.
#[derive(Debug)]
pub(crate) struct Admission<A> {
    /// The session name the hello asked for (default: `s<id>`).
    pub(crate) session: Option<String>,
    /// The rig the session drives.
    pub(crate) rig: Arc<RigEntry>,
    /// What the stats call the session's layout.
    pub(crate) layout: String,
    /// The RIG message its viewers get.
    pub(crate) rig_message: Message,
    /// What the protocol keeps for its `Protocol::start`.
    pub(crate) admitted: A,
}

/// Whether a hello's token is the server's (always, when the server has none); compared
/// without an early exit.
pub(crate) fn token_ok(server: Option<&str>, presented: Option<&str>) -> bool {
    let Some(want) = server else { return true };
    let got = presented.unwrap_or_default().as_bytes();
    let want = want.as_bytes();
    let mut diff = u8::from(got.len() != want.len());
    for (k, w) in want.iter().enumerate() {
        diff |= w ^ got.get(k).copied().unwrap_or(!w);
    }
    std::hint::black_box(diff) == 0
}
