//! The accept loop (`Server::run`), shutdown, and what the first line of a connection makes it:
//! a tracker session (of one of the protocols), a viewer, or a stats request.

use super::admission::{Refusal, refuse, token_ok, write_and_close};
use super::audio::{Audio, AudioSession};
use super::intake;
use super::landmark::{Landmark, LandmarkHello};
use super::livelink::LiveLink;
use super::openseeface::OpenSeeFace;
use super::session;
use super::slots::{Slot, Slots, general_slots, keepalive};
use super::state::Shared;
use super::udp::udp_loop;
use super::viewer::viewer;
use super::weights::{Weights, WeightsSession};
use crate::lines::{Line, LineReader};
use crate::settings::HELLO_MAX_BYTES;
use crate::stats::ServerStats;
use crate::sync::lock;
use mimic_wire::{Hello, KIND_ERROR};
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use tokio::io::BufReader;
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::time::sleep;

/// Serves until `shutdown` completes, then shuts down (`Server::run`).
pub(crate) async fn run(
    shared: &Arc<Shared>,
    listener: TcpListener,
    udp: Option<UdpSocket>,
    shutdown: impl Future<Output = ()>,
) -> ServerStats {
    let settings = &shared.settings;
    let (stop_tx, stop_rx) = watch::channel(false);
    let (done_tx, mut done_rx) = mpsc::channel::<()>(1);
    let slots = Slots::new(general_slots(settings), settings.stats_slots);
    if let Some(udp) = udp {
        tokio::spawn(udp_loop(
            shared.clone(),
            udp,
            stop_rx.clone(),
            done_tx.clone(),
        ));
    }
    intake::spawn::<OpenSeeFace>(shared, &stop_rx, &done_tx);
    intake::spawn::<LiveLink>(shared, &stop_rx, &done_tx);
    tokio::pin!(shutdown);
    loop {
        let accepted = tokio::select! {
            _ = &mut shutdown => break,
            a = listener.accept() => a,
        };
        match accepted {
            Ok((socket, peer)) => {
                shared.connections.bump();
                tracing::debug!(%peer, "connection");
                keepalive(&socket, settings.tcp_keepalive);
                let (guard, slot) = match slots.admit(shared, peer.ip()) {
                    Ok(s) => s,
                    Err(refusal) => {
                        tracing::debug!(%peer, "refused: {refusal}");
                        slots.refuse(shared, socket, &refusal);
                        continue;
                    }
                };
                let stats_only = matches!(slot, Slot::Stats(_));
                let (shared, stop, done) = (shared.clone(), stop_rx.clone(), done_tx.clone());
                tokio::spawn(async move {
                    connection(shared, socket, stop, stats_only).await;
                    drop(slot);
                    drop(guard);
                    drop(done);
                });
            }
            Err(e) => {
                // E.g. out of file descriptors: back off instead of spinning.
                tracing::warn!("accept failed: {e}");
                sleep(std::time::Duration::from_millis(50)).await;
            }
        }
    }
    drop(listener);
    tracing::info!("shutting down");
    let _ = stop_tx.send(true);
    let deadline =
        crate::timing::instant_after(tokio::time::Instant::now(), settings.shutdown_grace);
    // Sessions end first (their END message reaches the viewers), then the viewer queues close.
    while shared.sessions_active.load(Ordering::Acquire) > 0
        && tokio::time::Instant::now() < deadline
    {
        sleep(std::time::Duration::from_millis(5)).await;
    }
    for hub in lock(&shared.hubs).values() {
        hub.viewers.iter().for_each(|v| v.queue.close());
    }
    drop(done_tx);
    let _ = tokio::time::timeout_at(deadline, done_rx.recv()).await;
    // Accepted frames are never given up: wait (past the grace) until every session's
    // recording has written, flushed and synced what it was given.
    let mut waited = 0u32;
    while shared.recordings_open.load(Ordering::Acquire) > 0 {
        if waited % 1000 == 999 {
            tracing::warn!(
                open = shared.recordings_open.load(Ordering::Acquire),
                "waiting for session recordings to reach the disk"
            );
        }
        waited = waited.wrapping_add(1);
        sleep(std::time::Duration::from_millis(5)).await;
    }
    let stats = shared.stats();
    for s in &stats.sessions {
        tracing::info!(session = %s.name, frames = s.frames, late = s.late, malformed = s.malformed,
            p50_us = s.latency.p50_us, p99_us = s.latency.p99_us, "final session counters");
    }
    stats
}

/// How long a connection in a stats slot has for its hello.
const STATS_SLOT_HELLO: std::time::Duration = std::time::Duration::from_secs(2);

/// One TCP connection: read the hello, then serve it as a tracker, viewer or stats request
/// (only a stats request when it holds one of the slots kept for them).
async fn connection(
    shared: Arc<Shared>,
    socket: TcpStream,
    mut stop: watch::Receiver<bool>,
    stats_only: bool,
) {
    let _ = socket.set_nodelay(true);
    let peer = socket.peer_addr().ok();
    let (r, mut w) = socket.into_split();
    let hello_limit = shared.settings.max_message_bytes.min(HELLO_MAX_BYTES);
    let mut lines = LineReader::new(BufReader::new(r), hello_limit);
    let mut idle = shared.settings.idle_timeout;
    if stats_only {
        idle = idle.min(STATS_SLOT_HELLO);
    }
    let read = tokio::select! {
        _ = stop.changed() => return,
        _ = sleep(idle) => {
            refuse(&shared, &mut w, Refusal::NoHello).await;
            return;
        }
        l = lines.next_line() => l,
    };
    let hello = match read {
        Ok(Line::Complete | Line::Partial) => mimic_wire::parse_hello_with_token(lines.line()),
        Ok(Line::TooLong) => {
            let limit = hello_limit;
            refuse(&shared, &mut w, Refusal::HelloTooLong { limit }).await;
            return;
        }
        Ok(Line::Eof) | Err(_) => return,
    };
    // Trackers' frame lines may be as long as the message limit.
    lines.set_limit(shared.settings.max_message_bytes);
    let hello = match hello {
        Ok((hello, token)) => {
            if !token_ok(shared.settings.token.as_deref(), token.as_deref()) {
                tracing::info!(?peer, "hello without the server's token refused");
                if matches!(hello, Hello::Viewer { .. }) {
                    shared.refused.bump();
                    let m = mimic_wire::encode_json(KIND_ERROR, &Refusal::BadToken.json());
                    write_and_close(&mut w, &m).await;
                } else {
                    refuse(&shared, &mut w, Refusal::BadToken).await;
                }
                return;
            }
            Ok(hello)
        }
        Err(e) => Err(e),
    };
    if stats_only && !matches!(hello, Ok(Hello::Stats | Hello::HttpGet { .. })) {
        let why = "no connection slot left but those kept for stats requests";
        refuse(&shared, &mut w, Refusal::TooManyConnections(why.into())).await;
        return;
    }
    match hello {
        Err(e) => refuse(&shared, &mut w, Refusal::BadHello(e)).await,
        Ok(Hello::Stats) => {
            let mut s = shared.stats_json();
            s.push('\n');
            write_and_close(&mut w, s.as_bytes()).await;
        }
        Ok(Hello::HttpGet { path }) => {
            let (status, body) = if path == "/stats" {
                ("200 OK", shared.stats_json())
            } else {
                ("404 Not Found", "{\"error\":\"only /stats\"}".to_string())
            };
            let reply = format!(
                "HTTP/1.0 {status}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
                body.len()
            );
            write_and_close(&mut w, reply.as_bytes()).await;
        }
        Ok(Hello::Viewer { session, positions }) => {
            viewer(shared, lines, w, session, positions).await;
        }
        Ok(Hello::Tracker { header, request }) => {
            let hello = LandmarkHello {
                header,
                request,
                peer,
            };
            session::run::<Landmark>(shared, lines, w, hello, stop).await;
        }
        Ok(Hello::Weights(hello)) => {
            let hello = WeightsSession::new(hello, peer);
            session::run::<Weights>(shared, lines, w, hello, stop).await;
        }
        Ok(Hello::Audio(hello)) => {
            let hello = AudioSession::new(hello, peer);
            session::run::<Audio>(shared, lines, w, hello, stop).await;
        }
    }
}
