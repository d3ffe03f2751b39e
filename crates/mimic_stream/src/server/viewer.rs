//! Viewers: join a hub by session name, get its messages through a drop-oldest queue, leave.

use super::admission::{Refusal, write_and_close};
use super::hub::Viewer;
use super::state::Shared;
use crate::lines::LineReader;
use crate::queue::ViewerQueue;
use crate::sync::lock;
use mimic_wire::{ErrorCode, KIND_ERROR, encode_json};
use serde_json::json;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use tokio::io::{AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::time::timeout;

/// Takes a viewer slot and attaches a new viewer of `session` to its hub (it gets the session
/// and rig messages at once when the session is live); `TooManyViewers` when every slot is
/// taken. TCP and browser viewers alike; [`detach`] undoes it.
pub(crate) fn attach(
    shared: &Arc<Shared>,
    session: &str,
    positions: bool,
    web: bool,
) -> Result<Arc<Viewer>, Refusal> {
    let settings = &shared.settings;
    if shared.viewers_active.fetch_add(1, Ordering::AcqRel) >= settings.max_viewers {
        shared.viewers_active.fetch_sub(1, Ordering::AcqRel);
        shared.refused.bump();
        return Err(Refusal::TooManyViewers {
            max: settings.max_viewers,
        });
    }
    let v = Arc::new(Viewer {
        id: shared.next_viewer.fetch_add(1, Ordering::Relaxed),
        session: session.to_string(),
        positions,
        web,
        queue: ViewerQueue::new(settings.viewer_queue_frames),
        connected: AtomicBool::new(true),
    });
    let mut hubs = lock(&shared.hubs);
    let hub = hubs.entry(session.to_string()).or_default();
    if let Some(live) = &hub.live {
        v.queue.push_control(live.session_message.clone(), true);
        v.queue.push_control(live.rig_message.clone(), false);
        lock(&live.record.viewers).attach(v.clone());
    } else if let Some((session_message, rig_message)) = &hub.remote {
        v.queue.push_control(session_message.clone(), true);
        v.queue.push_control(rig_message.clone(), false);
    }
    hub.viewers.push(v.clone());
    // A session hosted by another front door of the cluster reaches this hub's viewers too.
    super::follow::start_following(shared, hub, session);
    Ok(v)
}

/// Marks viewer `v` gone, takes it off its hub (a hub left with neither viewers nor tracker
/// goes) and frees its slot.
pub(crate) fn detach(shared: &Shared, v: &Arc<Viewer>) {
    v.connected.store(false, Ordering::Release);
    {
        let mut hubs = lock(&shared.hubs);
        if let Some(hub) = hubs.get_mut(&v.session) {
            hub.viewers.retain(|x| !Arc::ptr_eq(x, v));
            if hub.viewers.is_empty() && hub.live.is_none() {
                hubs.remove(&v.session);
            }
        }
    }
    shared.viewers_active.fetch_sub(1, Ordering::AcqRel);
}

/// True when `session` has a live tracker now (here, or at another front door it is followed from).
pub(crate) fn is_live(shared: &Shared, session: &str) -> bool {
    lock(&shared.hubs)
        .get(session)
        .is_some_and(|h| h.live.is_some() || h.remote.is_some())
}

/// A viewer: attach to the hub, forward its queue, detach.
pub(crate) async fn viewer(
    shared: Arc<Shared>,
    lines: LineReader<BufReader<OwnedReadHalf>>,
    mut w: OwnedWriteHalf,
    session: String,
    positions: bool,
) {
    let settings = &shared.settings;
    let v = match attach(&shared, &session, positions, false) {
        Ok(v) => v,
        Err(refusal) => {
            write_and_close(&mut w, &encode_json(KIND_ERROR, &refusal.json())).await;
            return;
        }
    };
    tracing::info!(viewer = v.id, session = %session, positions, "viewer joined");
    // The viewer sends nothing after its hello; reading (and discarding, through the reader's
    // fixed buffer) tells us when it goes away.
    let watcher = {
        let v = v.clone();
        let mut r = lines.into_inner();
        tokio::spawn(async move {
            let _ = tokio::io::copy(&mut r, &mut tokio::io::sink()).await;
            v.queue.abandon();
        })
    };
    // At least 10 ms, so that a 0 never spins this loop while a silent tracker is live.
    let idle = settings
        .viewer_idle_timeout
        .max(std::time::Duration::from_millis(10));
    loop {
        let m = match timeout(idle, v.queue.pop()).await {
            Ok(Some(m)) => m,
            Ok(None) => break,
            Err(_) => {
                if is_live(&shared, &session) {
                    continue;
                }
                let secs = settings.viewer_idle_timeout.as_secs_f64();
                let why = format!("session `{session}` has had no tracker for {secs} s");
                let error = json!({"code": ErrorCode::IdleTimeout.name(), "message": why});
                let _ = timeout(
                    settings.viewer_write_timeout,
                    w.write_all(&encode_json(KIND_ERROR, &error)),
                )
                .await;
                v.queue.abandon();
                break;
            }
        };
        match timeout(settings.viewer_write_timeout, w.write_all(&m)).await {
            Ok(Ok(())) => {}
            _ => {
                v.queue.abandon();
                break;
            }
        }
    }
    let _ = timeout(std::time::Duration::from_secs(1), w.shutdown()).await;
    watcher.abort();
    detach(&shared, &v);
    tracing::info!(
        viewer = v.id,
        session = %session,
        sent = v.queue.sent.get(),
        dropped = v.queue.dropped.get(),
        "viewer left"
    );
}
