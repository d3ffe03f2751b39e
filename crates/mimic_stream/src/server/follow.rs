//! Viewers of a session that another front door hosts (a cluster, docs/cluster.md): a hub with
//! viewers but no tracker here follows the session through the server's placement, and its
//! viewers get the same SESSION, RIG, FRAME and END messages as viewers on the hosting front door.

use super::hub::Hub;
use super::session::push_frame;
use super::state::Shared;
use crate::catalog::RigEntry;
use crate::placement::{Followed, StepResult};
use crate::sync::lock;
use glam::{Quat, Vec3};
use mimic_retarget::{FrameOutput, FrameStatus, StageTimes};
use mimic_types::HeadPose;
use mimic_wire::{KIND_END, KIND_FRAME, KIND_SESSION, ViewerMessage, encode_json};
use serde_json::json;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::sync::mpsc;

/// Starts following session `name` for `hub` (under the hubs lock) when the server has a
/// placement and the hub has neither a tracker here nor a follower.
pub(crate) fn start_following(shared: &Arc<Shared>, hub: &mut Hub, name: &str) {
    let Some(placement) = &shared.placement else {
        return;
    };
    if hub.following.is_some() || hub.live.is_some() {
        return;
    }
    let id = shared.next_follower.fetch_add(1, Ordering::Relaxed);
    hub.following = Some(id);
    let rx = placement.follow(name);
    tokio::spawn(follow(shared.clone(), name.to_string(), id, rx));
}

/// An output buffer for frames of `entry`'s rig read back from FRAME messages.
pub(crate) fn output_for(entry: &RigEntry) -> FrameOutput {
    FrameOutput {
        timestamp_us: 0,
        status: FrameStatus::Calibrating,
        positions: Vec::new(),
        normals: Vec::new(),
        displacements: vec![Vec3::ZERO; entry.rig.controls.len()],
        pose: HeadPose::IDENTITY,
        target_rotation: Quat::IDENTITY,
        filled: 0,
        times: StageTimes::default(),
    }
}

/// Reads a stepped frame's FRAME message into `out`; false (out unchanged) when it is not a
/// frame message of `out`'s control count.
pub(crate) fn read_result(r: &StepResult, out: &mut FrameOutput) -> bool {
    let (Some(&kind), Some(payload)) = (r.message.get(4), r.message.get(5..)) else {
        return false;
    };
    if kind != KIND_FRAME {
        return false;
    }
    let Ok(ViewerMessage::Frame(f)) = mimic_wire::decode_viewer_message(kind, payload) else {
        return false;
    };
    if f.displacements.len() != out.displacements.len() {
        return false;
    }
    out.timestamp_us = f.timestamp_us;
    out.status = FrameStatus::from_code(f.status);
    out.pose = f.pose;
    out.target_rotation = f.target_rotation;
    out.displacements.copy_from_slice(&f.displacements);
    true
}

/// What a follower needs per frame of a live session: the rig and its buffers.
struct Following {
    rig: Arc<RigEntry>,
    out: FrameOutput,
    positions: Vec<Vec3>,
    scratch: Vec<Vec3>,
}

/// Whether follower `id` still serves hub `name` (it has viewers and no tracker here took it).
fn still_mine(shared: &Shared, name: &str, id: u64) -> bool {
    lock(&shared.hubs)
        .get(name)
        .is_some_and(|h| h.following == Some(id) && !h.viewers.is_empty())
}

/// The follower task of hub `name`: forwards the session's messages until the hub has no
/// viewers left.
async fn follow(shared: Arc<Shared>, name: String, id: u64, mut rx: mpsc::Receiver<Followed>) {
    let mut tick = tokio::time::interval(Duration::from_millis(500));
    let mut live: Option<Following> = None;
    loop {
        let event = tokio::select! {
            _ = tick.tick() => {
                if still_mine(&shared, &name, id) {
                    continue;
                }
                break;
            }
            e = rx.recv() => e,
        };
        match event {
            None => break,
            Some(Followed::Live { description, rig }) => {
                let Some(entry) = shared.catalog.rig(Some(&rig)).cloned() else {
                    tracing::warn!(session = %name, rig, "followed session drives a rig this front door does not have");
                    continue;
                };
                let session_message = Arc::new(encode_json(KIND_SESSION, &description));
                let mut hubs = lock(&shared.hubs);
                let Some(h) = hubs.get_mut(&name) else { break };
                if h.following != Some(id) {
                    break;
                }
                if h.live.is_none() {
                    for v in &h.viewers {
                        v.queue.push_control(session_message.clone(), true);
                        v.queue.push_control(entry.message.clone(), false);
                    }
                }
                h.remote = Some((session_message, entry.message.clone()));
                live = Some(Following {
                    out: output_for(&entry),
                    positions: entry.rig.mesh.positions.clone(),
                    scratch: Vec::new(),
                    rig: entry,
                });
                tracing::info!(session = %name, "following a session hosted by another front door");
            }
            Some(Followed::Frame(r)) => {
                let Some(f) = live.as_mut() else { continue };
                let here = lock(&shared.hubs)
                    .get(&name)
                    .is_some_and(|h| h.live.is_some());
                if here || !read_result(&r, &mut f.out) {
                    continue;
                }
                let (rig, scratch) = (&f.rig, &mut f.scratch);
                push_frame(
                    &shared,
                    &name,
                    r.n,
                    &f.out,
                    &mut f.positions,
                    |d, positions| rig.deform(d, scratch, positions),
                    &super::session::WebFrame {
                        arrival: std::time::Instant::now(),
                        gated: 0,
                        weights: false,
                    },
                );
            }
            Some(Followed::End) => {
                live = None;
                let end = Arc::new(encode_json(
                    KIND_END,
                    &json!({"session": name, "reason": "ended on its front door"}),
                ));
                let mut hubs = lock(&shared.hubs);
                if let Some(h) = hubs.get_mut(&name)
                    && h.remote.take().is_some()
                    && h.live.is_none()
                {
                    h.viewers
                        .iter()
                        .for_each(|v| v.queue.push_control(end.clone(), false));
                }
            }
        }
    }
    let mut hubs = lock(&shared.hubs);
    if let Some(h) = hubs.get_mut(&name)
        && h.following == Some(id)
    {
        h.following = None;
        h.remote = None;
        if h.viewers.is_empty() && h.live.is_none() {
            hubs.remove(&name);
        }
    }
}
