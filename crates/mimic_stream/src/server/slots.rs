//! Connection slots: the shared pool, the few kept for stats requests, each peer's share of
//! them, and the answer a connection gets past them (a reply line, then close: never a backlog).

use super::admission::{Refusal, write_and_close};
use super::state::Shared;
use crate::sync::lock;
use mimic_wire::{Hello, KIND_ERROR, encode_json, error_line, parse_hello};
use std::net::IpAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::AsyncReadExt;
use tokio::net::TcpStream;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Refused connections being answered at once; past this many, a refused connection is closed
/// without an answer (so a flood of refusals holds a bounded number of tasks).
pub(crate) const REFUSALS_IN_FLIGHT: usize = 256;

/// One peer's connection, counted until it is dropped.
#[derive(Debug)]
pub(crate) struct PeerGuard {
    shared: Arc<Shared>,
    ip: IpAddr,
}

impl Drop for PeerGuard {
    fn drop(&mut self) {
        let mut peers = lock(&self.shared.peers);
        if let Some(n) = peers.get_mut(&self.ip) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                peers.remove(&self.ip);
            }
        }
    }
}

/// Which pool a connection's slot came from.
#[derive(Debug)]
pub(crate) enum Slot {
    /// The shared pool: any hello.
    General(#[allow(dead_code, reason = "held for its Drop")] OwnedSemaphorePermit),
    /// A slot kept for stats requests: only a stats hello, within 2 s.
    Stats(#[allow(dead_code, reason = "held for its Drop")] OwnedSemaphorePermit),
}

/// The pools of one accept loop.
#[derive(Debug)]
pub(crate) struct Slots {
    general: Arc<Semaphore>,
    stats: Arc<Semaphore>,
    refusing: Arc<Semaphore>,
}

impl Slots {
    /// Pools for `general` connections and `stats` kept ones.
    pub(crate) fn new(general: usize, stats: usize) -> Self {
        Self {
            general: Arc::new(Semaphore::new(general)),
            stats: Arc::new(Semaphore::new(stats)),
            refusing: Arc::new(Semaphore::new(REFUSALS_IN_FLIGHT)),
        }
    }

    /// A slot for a connection from `ip`, or the refusal: within the peer's share, one of the
    /// shared pool (counted against the peer); otherwise, or when that pool is full, one of the
    /// stats slots (not counted against the peer).
    pub(crate) fn admit(
        &self,
        shared: &Arc<Shared>,
        ip: IpAddr,
    ) -> Result<(Option<PeerGuard>, Slot), Refusal> {
        let max = shared.settings.max_connections_per_peer;
        let within_share = {
            let mut peers = lock(&shared.peers);
            let n = peers.entry(ip).or_insert(0);
            let ok = *n < max;
            if ok {
                *n += 1;
            } else if *n == 0 {
                peers.remove(&ip);
            }
            ok
        };
        if within_share {
            let guard = PeerGuard {
                shared: shared.clone(),
                ip,
            };
            if let Ok(p) = self.general.clone().try_acquire_owned() {
                return Ok((Some(guard), Slot::General(p)));
            }
        }
        // Past the peer's share or the shared pool: a stats request may still get in.
        if let Ok(p) = self.stats.clone().try_acquire_owned() {
            return Ok((None, Slot::Stats(p)));
        }
        Err(Refusal::TooManyConnections(if within_share {
            format!(
                "all {} connection slots are taken",
                self.general_capacity(shared)
            )
        } else {
            format!("at most {max} connections from {ip}")
        }))
    }

    fn general_capacity(&self, shared: &Shared) -> usize {
        general_slots(&shared.settings)
    }

    /// Answers a refused connection and closes it, without waiting: the answer is written by
    /// a task (at most [`REFUSALS_IN_FLIGHT`] at once, each at most about 2.5 s); past that the
    /// socket is just closed. A viewer hello arriving within 0.5 s gets the refusal as a viewer
    /// ERROR message, anything else a tracker error line.
    pub(crate) fn refuse(&self, shared: &Shared, socket: TcpStream, refusal: &Refusal) {
        shared.refused.bump();
        let Ok(permit) = self.refusing.clone().try_acquire_owned() else {
            return;
        };
        let line = error_line(refusal.code(), 1, &refusal.to_string());
        let message = encode_json(KIND_ERROR, &refusal.json());
        tokio::spawn(async move {
            let (mut r, mut w) = socket.into_split();
            let mut first = [0u8; 1024];
            let mut n = 0;
            // Long enough for a hello written right after connecting to arrive on a loaded
            // machine (a viewer must get its refusal as a viewer message, not a JSON line).
            let _ = tokio::time::timeout(REFUSAL_HELLO_WAIT, async {
                while n < first.len() && !first[..n].contains(&b'\n') {
                    match r.read(&mut first[n..]).await {
                        Ok(0) | Err(_) => break,
                        Ok(k) => n += k,
                    }
                }
            })
            .await;
            let hello = first[..n].split(|b| *b == b'\n').next().unwrap_or_default();
            let viewer = matches!(parse_hello(hello), Ok(Hello::Viewer { .. }));
            let answer = if viewer {
                &message[..]
            } else {
                line.as_bytes()
            };
            // The hello was read, so closing sends FIN (not RST) and the peer reads the answer.
            write_and_close(&mut w, answer).await;
            drop(r);
            drop(permit);
        });
    }
}

/// How long a refused connection has to send its hello (to answer it in its own protocol).
const REFUSAL_HELLO_WAIT: Duration = Duration::from_secs(2);

/// Connection slots of the shared pool: every session and viewer, plus 16 for connections
/// that have not said hello yet and stats requests.
pub(crate) fn general_slots(s: &crate::settings::ServerSettings) -> usize {
    s.max_sessions
        .saturating_add(s.max_viewers)
        .saturating_add(16)
}

/// Turns TCP keepalive on (probes after `idle`, then every 10 s, 3 of them), so a viewer whose
/// peer vanished frees its slot even when no frame is flowing.
pub(crate) fn keepalive(socket: &TcpStream, idle: Duration) {
    let ka = socket2::TcpKeepalive::new()
        .with_time(idle.max(Duration::from_secs(1)))
        .with_interval(Duration::from_secs(10))
        .with_retries(3);
    if let Err(e) = socket2::SockRef::from(socket).set_tcp_keepalive(&ka) {
        tracing::debug!("TCP keepalive not set: {e}");
    }
}
