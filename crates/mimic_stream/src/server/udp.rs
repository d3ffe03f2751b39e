//! UDP intake: frame packets of landmark sessions, routed by session id and key.

use super::state::Shared;
use crate::sync::lock;
use std::net::IpAddr;
use std::sync::Arc;
use std::time::Instant;
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};

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
        let Ok((len, from)) = got else { continue };
        let arrival = Instant::now();
        let Some(packet) = buf.get(..len) else {
            continue;
        };
        let Ok(u) = mimic_wire::decode_udp_frame(packet) else {
            shared.udp_bad.bump();
            continue;
        };
        let mut routes = lock(&shared.routes);
        let Some(route) = routes.get_mut(&u.session_id) else {
            shared.udp_bad.bump();
            continue;
        };
        if !key_matches(route.key, u.key) {
            shared.udp_bad.bump();
            shared.udp_wrong_key.bump();
            continue;
        }
        let source_ok = route.peer_ip.is_none_or(|ip| same_ip(ip, from.ip()))
            && route.source.is_none_or(|s| s == from);
        if !source_ok {
            shared.udp_bad.bump();
            shared.udp_wrong_source.bump();
            continue;
        }
        route.source = Some(from);
        if route.tx.try_send((arrival, u.frame)).is_err() {
            route.record.udp_queue_dropped.bump();
        }
    }
    drop(done);
}

/// Compares two keys without an early exit.
fn key_matches(a: u32, b: u32) -> bool {
    std::hint::black_box(a ^ b) == 0
}

/// The same address, an IPv4 one also when seen as IPv4-mapped IPv6.
fn same_ip(a: IpAddr, b: IpAddr) -> bool {
    a.to_canonical() == b.to_canonical()
}
