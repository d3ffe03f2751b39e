//! mimic's live service: tracker sessions in, viewers out.
//!
//! [`Server::run`] takes a bound `TcpListener` (and optionally a `UdpSocket`) and a shutdown
//! future, in the shape of tokio's mini-redis. The first line of each TCP connection says what
//! it is (`docs/protocol.md`): a recording header opens a tracker session whose following lines
//! are recording frame lines (so `cat rec.jsonl | nc` feeds one), a viewer hello joins a session
//! by name and then receives the rig once and every frame's pose and control displacements `d`
//! (or full positions) as length-prefixed binary messages, and a stats hello (or `GET /stats`)
//! gets the counters as JSON. Trackers may also send compact binary frames over UDP.
//!
//! Every session has its own [`Retargeter`](mimic_retarget::Retargeter); each rig's basis is
//! built once ([`RigEntry`]) and shared. Everything is bounded: sessions, viewers, message size,
//! idle time, reply and UDP queues, and viewer queues, which drop their oldest frame (counted per
//! viewer) so a slow viewer never slows a session. With a record folder, every accepted frame of
//! a session is also written, flushed per frame, to that session's file (a v1 recording, or a
//! weights CSV for weights and Live Link sessions); with forward targets ([`forward`]) it is
//! also sent on to VMC and Live Link receivers. Wire
//! encoding lives in the `mimic_wire` crate (re-exported as [`wire`]).
//! With `Server::serve_http` it also serves the browser viewer (axum, docs/browser.md).
//! [`launch`] starts a server as `mimic serve` does; [`send`] is the tracker simulator behind
//! `mimic send`.
//! Depends on mimic_types, mimic_solve, mimic_retarget, mimic_capture, mimic_wire and tokio; no
//! renderer.

mod catalog;
mod catalog_load;
mod counter;
mod fdlimit;
pub mod forward;
pub mod launch;
mod lines;
pub mod placement;
mod queue;
mod record;
pub mod send;
mod server;
mod settings;
mod stats;
mod sync;
mod timing;

/// The wire protocol (`docs/protocol.md`), from the `mimic_wire` crate.
pub use mimic_wire as wire;

pub use catalog::{Catalog, CatalogError, MorphSet, RigEntry};
pub use catalog_load::{CatalogLoadError, load_catalog};
pub use server::Server;
pub use settings::{
    BindError, DEFAULT_LISTEN, HELLO_MAX_BYTES, HttpSettings, LiveLinkIntake, RecordMode,
    ServerSettings, check_bind, check_binds, token_or_env,
};
pub use stats::{LatencyHistogram, LatencySummary, ServerStats, SessionSnapshot, ViewerSnapshot};
