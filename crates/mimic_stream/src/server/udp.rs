//! UDP intake: frame packets of landmark sessions, routed by session id and key.

use super::state::{SessionRecord, Shared, lock};
use mimic_types::LandmarkFrame;
use std::sync::Arc;
use std::time::Instant;
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};

/// Where a UDP frame for a session goes.
#[derive(Debug)]
pub(crate) struct Route {
    /// The key the session's welcome line gave its tracker.
    pub(crate) key: u32,
    /// The session's bounded packet queue.
    pub(crate) tx: mpsc::Sender<(Instant, LandmarkFrame)>,
    /// The session's counters (a full queue is counted there).
    pub(crate) record: Arc<SessionRecord>,
}

/// Receives UDP frame packets and hands each to its session's queue (dropped when full).
pub(crate) async fn udp_loop(
    shared: Arc<Shared>,
    udp: UdpSocket,
    mut stop: watch::Receiver<bool>,
    done: mpsc::Sender<()>,
) {
    let mut buf = vec![0u8; 65_536];
    loop {
        let got = tokio::select! {
            _ = stop.changed() => break,
            r = udp.recv_from(&mut buf) => r,
        };
        let Ok((len, _peer)) = got else { continue };
        let arrival = Instant::now();
        let Some(packet) = buf.get(..len) else {
            continue;
        };
        let Ok(u) = mimic_wire::decode_udp_frame(packet) else {
            shared.udp_bad.bump();
            continue;
        };
        let routes = lock(&shared.routes);
        match routes.get(&u.session_id) {
            Some(route) if route.key == u.key => {
                if route.tx.try_send((arrival, u.frame)).is_err() {
                    route.record.udp_queue_dropped.bump();
                }
            }
            _ => shared.udp_bad.bump(),
        }
    }
    drop(done);
}
