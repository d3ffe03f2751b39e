//! What the UDP tracker intakes share (`openseeface.rs`, `livelink.rs`): sessions opened on a
//! key's first packet (a face id, a subject name), never answered, ended after the idle timeout
//! and at shutdown.

use super::admission::open;
use super::session::{Protocol, Session, teardown};
use super::state::Shared;
use std::collections::HashMap;
use std::hash::Hash;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;
use tokio::sync::mpsc;

/// A frame path that knows when its last packet came (for the idle timeout).
pub(crate) trait Idle {
    /// The arrival of the session's last packet.
    fn last_packet(&self) -> Instant;
}

/// A live intake session: the session and its frame path.
pub(crate) struct Live<P> {
    /// The session.
    pub(crate) session: Session,
    /// Its frame path.
    pub(crate) proto: P,
    writer: tokio::task::JoinHandle<()>,
}

/// Ends a session (the frame path finished, END to its viewers).
async fn end<P: Protocol>(live: Live<P>, reason: &str) {
    let Live {
        session,
        proto,
        writer,
    } = live;
    proto.finish(&session).await;
    teardown::<P>(session, reason.to_string(), writer).await;
}

/// Opens the session of a key seen for the first time; `None` (counted as refused, logged with
/// `what`) when it cannot be opened. Nothing is ever answered over these trackers' UDP: the
/// replies are drained and dropped.
pub(crate) async fn open_live<P: Protocol>(
    shared: &Arc<Shared>,
    hello: P::Hello,
    what: &str,
) -> Option<Live<P>> {
    let (reply_tx, mut reply_rx) = mpsc::channel::<String>(4);
    let writer = tokio::spawn(async move { while reply_rx.recv().await.is_some() {} });
    match open::<P>(shared, hello, reply_tx) {
        Ok((session, admitted)) => {
            let (proto, _welcome) = P::start(admitted, &session).await;
            Some(Live {
                session,
                proto,
                writer,
            })
        }
        Err(refusal) => {
            shared.refused.bump();
            tracing::warn!("{what} session refused: {refusal}");
            writer.abort();
            None
        }
    }
}

/// Ends every session whose last packet is `idle` or more ago (`idle_timeout`).
pub(crate) async fn end_idle<K: Clone + Eq + Hash, P: Protocol + Idle>(
    live: &mut HashMap<K, Live<P>>,
    idle: Duration,
) {
    let now = Instant::now();
    let idle_keys: Vec<K> = live
        .iter()
        .filter(|(_, l)| now.duration_since(l.proto.last_packet()) >= idle)
        .map(|(k, _)| k.clone())
        .collect();
    for k in idle_keys {
        if let Some(l) = live.remove(&k) {
            end(l, "idle_timeout").await;
        }
    }
}

/// Ends every session (`shutdown`).
pub(crate) async fn end_all<K, P: Protocol>(live: &mut HashMap<K, Live<P>>) {
    for (_, l) in live.drain() {
        end(l, "shutdown").await;
    }
}

/// The idle sweep's tick: every 100 ms, or every idle timeout when that is shorter.
pub(crate) fn idle_tick(idle: Duration) -> tokio::time::Interval {
    tokio::time::interval(Duration::from_millis(100).min(idle.max(Duration::from_millis(1))))
}

/// The intake's socket for tokio; `None`, logged with `what`, for a socket tokio cannot take.
pub(crate) fn tokio_socket(socket: &std::net::UdpSocket, what: &str) -> Option<UdpSocket> {
    let udp = socket.try_clone().and_then(|s| {
        s.set_nonblocking(true)?;
        UdpSocket::from_std(s)
    });
    match udp {
        Ok(udp) => Some(udp),
        Err(e) => {
            tracing::error!("{what} socket unusable: {e}");
            None
        }
    }
}
