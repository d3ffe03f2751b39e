//! The UDP tracker intakes' one loop ([`spawn`], for `openseeface.rs` and `livelink.rs`): a
//! datagram is split into blocks and each decoded ([`UdpTracker`], the per-protocol part). The
//! doors (docs/reliability.md): a datagram from a source the `--udp-allow` list lacks is refused;
//! a key (a face id, a subject name) opens a session only after `udp_open_packets` valid blocks
//! in a row from one source (held in [`pending`], then taken as its first frames), within the
//! intakes' own session budget (`max_udp_sessions`); the session is bound to that source, and
//! blocks for it from any other are refused, unless its source has been silent for
//! [`TAKEOVER_SILENCE`] and the newcomer passes the same test (a restarted tracker: the session
//! is rebound, its clock re-anchored and the restart counted). Refusals are counted
//! (`udp_refused`, `udp_wrong_source`) and logged at most once a second ([`RefusalLog`]).
//! Nothing is ever answered; a session ends after the idle timeout and at shutdown.

mod pending;

use super::session::{Protocol, Session, open, teardown};
use super::state::Shared;
use crate::settings::ServerSettings;
use pending::{Pending, PendingKeys, RefusalLog, Slot, Why};
use std::collections::HashMap;
use std::future::Future;
use std::hash::Hash;
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};

/// A session's source silent this long may be replaced by another that passes the opening
/// test (a restarted tracker sends from a new port).
pub(crate) const TAKEOVER_SILENCE: Duration = Duration::from_millis(500);

/// A UDP tracker protocol: how its datagrams decode and which session each block goes to.
pub(crate) trait UdpTracker: Protocol + 'static {
    /// What a block is routed by (one session per key).
    type Key: Clone + Eq + Hash + Send;
    /// One decoded block (kept, cloned, while its key waits for a session).
    type Unit: Clone + Send + Sync;
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

    /// The block's tracker time in seconds, when it has one (blocks opening a session must go
    /// forward in time).
    fn time(unit: &Self::Unit) -> Option<f64>;

    /// The hello of a key's first block from `peer`, and how the log names it.
    fn hello(unit: &Self::Unit, peer: SocketAddr) -> (Self::Hello, String);

    /// The arrival of the session's last block (for the idle timeout).
    fn last_packet(&self) -> Instant;

    /// A new run of the tracker (another source took the session over): its clock starts
    /// again from the next block.
    fn restart(&mut self, s: &Session);

    /// Takes one block of session `s`, which arrived at `arrival`.
    fn accept(
        &mut self,
        s: &Session,
        unit: &Self::Unit,
        arrival: Instant,
    ) -> impl Future<Output = ()> + Send;
}

/// A live intake session: the session, its frame path, the source it is bound to, and the run
/// of another source that may take it over.
struct Live<P: UdpTracker> {
    /// The session.
    session: Session,
    /// Its frame path.
    proto: P,
    writer: tokio::task::JoinHandle<()>,
    /// The source whose blocks it takes.
    source: SocketAddr,
    /// Blocks of another source, after [`TAKEOVER_SILENCE`] of this one.
    takeover: Option<Pending<P::Unit>>,
}

/// Ends a session (the frame path finished, END to its viewers).
async fn end<P: UdpTracker>(live: Live<P>, reason: &str) {
    let Live {
        session,
        proto,
        writer,
        ..
    } = live;
    proto.finish(&session).await;
    session
        .shared
        .udp_sessions_active
        .fetch_sub(1, Ordering::AcqRel);
    teardown::<P>(session, reason.to_string(), writer).await;
}

/// Opens the session of a key; `Err` with what to log when it cannot be opened. Nothing is
/// ever answered over these trackers' UDP: the replies are drained and dropped.
async fn open_live<P: UdpTracker>(
    shared: &Arc<Shared>,
    hello: P::Hello,
    source: SocketAddr,
) -> Result<Live<P>, String> {
    let (reply_tx, mut reply_rx) = mpsc::channel::<String>(4);
    let writer = tokio::spawn(async move { while reply_rx.recv().await.is_some() {} });
    match open::<P>(shared, hello, reply_tx) {
        Ok((session, admitted)) => {
            shared.udp_sessions_active.fetch_add(1, Ordering::AcqRel);
            let (proto, _welcome) = P::start(admitted, &session).await;
            Ok(Live {
                session,
                proto,
                writer,
                source,
                takeover: None,
            })
        }
        Err(refusal) => {
            shared.refused.bump();
            writer.abort();
            Err(refusal.to_string())
        }
    }
}

/// The intakes' session budget: `max_udp_sessions`, leaving TCP trackers at least one session.
fn udp_budget(settings: &ServerSettings) -> usize {
    settings
        .max_udp_sessions
        .min(settings.max_sessions.saturating_sub(1))
}

/// Whether the `--udp-allow` list (empty: any) lets `ip` in.
fn allowed(allow: &[IpAddr], ip: IpAddr) -> bool {
    allow.is_empty() || allow.iter().any(|a| a.to_canonical() == ip.to_canonical())
}

/// One intake's state: its sessions, the runs of keys without one, its refusal log.
struct Intake<P: UdpTracker> {
    shared: Arc<Shared>,
    sessions: HashMap<P::Key, Live<P>>,
    pending: PendingKeys<P::Key, P::Unit>,
    log: RefusalLog,
}

impl<P: UdpTracker> Intake<P> {
    /// Counts `n` refused blocks for `why`.
    fn refuse(&mut self, why: Why, n: usize, peer: SocketAddr) {
        if n == 0 {
            return;
        }
        match why {
            Why::WrongSource => {
                self.shared.udp_wrong_source.add(n as u64);
                self.shared.udp_bad.add(n as u64);
            }
            _ => self.shared.udp_refused.add(n as u64),
        }
        self.log.note(why, n, || format!("from {peer}"));
    }

    /// Takes one decoded block from `peer`.
    async fn block(&mut self, unit: &P::Unit, peer: SocketAddr, arrival: Instant) {
        let key = P::key(unit);
        let open_n = self.shared.settings.udp_open_packets.max(1);
        if let Some(live) = self.sessions.get_mut(&key) {
            if live.source == peer {
                live.takeover = None;
                live.proto.accept(&live.session, unit, arrival).await;
                return;
            }
            let silent = arrival.saturating_duration_since(live.proto.last_packet());
            if silent < TAKEOVER_SILENCE {
                self.refuse(Why::WrongSource, 1, peer);
                return;
            }
            let run = live
                .takeover
                .get_or_insert_with(|| Pending::new(peer, arrival));
            let mut dropped = 0;
            if run.source != peer {
                dropped += run.len();
                *run = Pending::new(peer, arrival);
            }
            dropped += run.push(unit.clone(), P::time(unit), arrival, open_n);
            let ready = run.len() >= open_n;
            if ready && let Some(run) = live.takeover.take() {
                tracing::info!(session = %live.session.name, from = %live.source, to = %peer,
                    "{}: a new source takes over the silent session (a restarted tracker)", P::INTAKE);
                live.source = peer;
                live.session.record.restarts.bump();
                live.proto.restart(&live.session);
                for (u, at) in &run.units {
                    live.proto.accept(&live.session, u, *at).await;
                }
            }
            self.refuse(Why::Dropped, dropped, peer);
            return;
        }
        let (ready, dropped) = match self.pending.slot(&key, peer, arrival) {
            Slot::OtherSource => {
                self.refuse(Why::WrongSource, 1, peer);
                return;
            }
            Slot::Run(run, dropped) => {
                let d = run.push(unit.clone(), P::time(unit), arrival, open_n);
                (run.len() >= open_n, dropped + d)
            }
        };
        self.refuse(Why::Dropped, dropped, peer);
        if !ready {
            return;
        }
        let Some(run) = self.pending.take(&key) else {
            return;
        };
        let settings = &self.shared.settings;
        if self.shared.udp_sessions_active.load(Ordering::Acquire) >= udp_budget(settings) {
            self.refuse(Why::Budget, run.len(), peer);
            return;
        }
        let (hello, what) = P::hello(unit, peer);
        match open_live::<P>(&self.shared, hello, peer).await {
            Ok(mut live) => {
                for (u, at) in &run.units {
                    live.proto.accept(&live.session, u, *at).await;
                }
                self.sessions.insert(key, live);
            }
            Err(why) => {
                self.refuse(Why::NotOpened, run.len(), peer);
                self.log
                    .note(Why::NotOpened, 0, || format!("{what}: {why}"));
                tracing::debug!("{what} session refused: {why}");
            }
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
    let mut decoder = P::Decoder::default();
    let idle = shared.settings.idle_timeout;
    let mut tick = idle_tick(idle);
    let mut intake = Intake::<P> {
        shared: shared.clone(),
        sessions: HashMap::new(),
        pending: PendingKeys::default(),
        log: RefusalLog::default(),
    };
    loop {
        let got = tokio::select! {
            _ = stop.changed() => break,
            _ = tick.tick() => {
                end_idle(&mut intake.sessions, idle).await;
                intake.log.flush(P::INTAKE, Instant::now());
                continue;
            }
            r = udp.recv_from(&mut buf) => r,
        };
        let Ok((len, peer)) = got else { continue };
        let arrival = Instant::now();
        if !allowed(&shared.settings.udp_allow, peer.ip()) {
            intake.refuse(Why::NotAllowed, 1, peer);
            continue;
        }
        let Some(blocks) = P::blocks(buf.get(..len).unwrap_or_default()) else {
            shared.udp_bad.bump();
            continue;
        };
        for block in blocks {
            let Some(unit) = P::decode(&mut decoder, block) else {
                shared.udp_bad.bump();
                continue;
            };
            intake.block(unit, peer, arrival).await;
        }
    }
    end_all(&mut intake.sessions).await;
    intake
        .log
        .flush(P::INTAKE, Instant::now() + Duration::from_secs(2));
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
async fn end_all<K, P: UdpTracker>(live: &mut HashMap<K, Live<P>>) {
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
