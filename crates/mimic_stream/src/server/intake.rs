//! The UDP tracker intakes' one loop ([`spawn`], for `openseeface.rs` and `livelink.rs`): a
//! datagram is split into blocks and each decoded ([`UdpTracker`], the per-protocol part); a
//! session opens on a key's first block (a face id, a subject name), is never answered, and
//! ends after the idle timeout and at shutdown.

use super::session::{Protocol, Session, open, teardown};
use super::state::Shared;
use crate::settings::ServerSettings;
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::future::Future;
use std::hash::Hash;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};

/// A UDP tracker protocol: how its datagrams decode and which session each block goes to.
pub(crate) trait UdpTracker: Protocol + 'static {
    /// What a block is routed by (one session per key).
    type Key: Clone + Eq + Hash + Send;
    /// One decoded block.
    type Unit: Send + Sync;
    /// Decoding state reused from block to block.
    type Decoder: Default + Send;
    /// The intake's name in logs.
    const INTAKE: &'static str;

    /// The intake's bound socket, when the settings have one.
    fn socket(settings: &ServerSettings) -> Option<&std::net::UdpSocket>;

    /// The blocks of a datagram; `None` (counted in `udp_bad_packets`) for a datagram that
    /// cannot hold any.
    fn blocks(datagram: &[u8]) -> Option<impl Iterator<Item = &[u8]> + Send>;

    /// Decodes one block; `None` (counted in `udp_bad_packets`) when it is not one.
    fn decode<'d>(decoder: &'d mut Self::Decoder, block: &[u8]) -> Option<&'d Self::Unit>;

    /// The session a block goes to.
    fn key(unit: &Self::Unit) -> Self::Key;

    /// The hello of a key's first block from `peer`, and how the log names it.
    fn hello(unit: &Self::Unit, peer: SocketAddr) -> (Self::Hello, String);

    /// The arrival of the session's last block (for the idle timeout).
    fn last_packet(&self) -> Instant;

    /// Takes one block of session `s`, which arrived at `arrival`.
    fn accept(
        &mut self,
        s: &Session,
        unit: &Self::Unit,
        arrival: Instant,
    ) -> impl Future<Output = ()> + Send;
}

/// A live intake session: the session and its frame path.
struct Live<P> {
    /// The session.
    session: Session,
    /// Its frame path.
    proto: P,
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
async fn open_live<P: Protocol>(
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

/// Receives datagrams of protocol `P` until shutdown, one session per key.
async fn intake_loop<P: UdpTracker>(
    shared: Arc<Shared>,
    udp: UdpSocket,
    mut stop: watch::Receiver<bool>,
    done: mpsc::Sender<()>,
) {
    let mut buf = vec![0u8; 65_536];
    let mut sessions: HashMap<P::Key, Live<P>> = HashMap::new();
    let mut decoder = P::Decoder::default();
    let idle = shared.settings.idle_timeout;
    let mut tick = idle_tick(idle);
    loop {
        let got = tokio::select! {
            _ = stop.changed() => break,
            _ = tick.tick() => {
                end_idle(&mut sessions, idle).await;
                continue;
            }
            r = udp.recv_from(&mut buf) => r,
        };
        let Ok((len, peer)) = got else { continue };
        let arrival = Instant::now();
        let Some(blocks) = P::blocks(buf.get(..len).unwrap_or_default()) else {
            shared.udp_bad.bump();
            continue;
        };
        for block in blocks {
            let Some(unit) = P::decode(&mut decoder, block) else {
                shared.udp_bad.bump();
                continue;
            };
            let live = match sessions.entry(P::key(unit)) {
                Entry::Occupied(e) => e.into_mut(),
                Entry::Vacant(e) => {
                    let (hello, what) = P::hello(unit, peer);
                    match open_live::<P>(&shared, hello, &what).await {
                        Some(live) => e.insert(live),
                        None => continue,
                    }
                }
            };
            live.proto.accept(&live.session, unit, arrival).await;
        }
    }
    end_all(&mut sessions).await;
    drop(done);
}

/// Starts the intake of protocol `P` when the settings hold its socket (a socket tokio cannot
/// take is logged and left unused).
pub(crate) fn spawn<P: UdpTracker>(
    shared: &Arc<Shared>,
    stop: &watch::Receiver<bool>,
    done: &mpsc::Sender<()>,
) {
    let Some(socket) = P::socket(&shared.settings) else {
        return;
    };
    if let Some(udp) = tokio_socket(socket, P::INTAKE) {
        tokio::spawn(intake_loop::<P>(
            shared.clone(),
            udp,
            stop.clone(),
            done.clone(),
        ));
    }
}

/// Ends every session whose last packet is `idle` or more ago (`idle_timeout`).
async fn end_idle<K: Clone + Eq + Hash, P: UdpTracker>(
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
async fn end_all<K, P: Protocol>(live: &mut HashMap<K, Live<P>>) {
    for (_, l) in live.drain() {
        end(l, "shutdown").await;
    }
}

/// The idle sweep's tick: every 100 ms, or every idle timeout when that is shorter.
fn idle_tick(idle: Duration) -> tokio::time::Interval {
    tokio::time::interval(Duration::from_millis(100).min(idle.max(Duration::from_millis(1))))
}

/// The intake's socket for tokio; `None`, logged with `what`, for a socket tokio cannot take.
fn tokio_socket(socket: &std::net::UdpSocket, what: &str) -> Option<UdpSocket> {
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
