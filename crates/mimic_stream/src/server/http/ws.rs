//! A browser viewer over a WebSocket (`/ws/SESSION`): it joins the session's hub like a TCP viewer
//! (its own drop-oldest queue, counted in the stats) and gets text messages (JSON: `hello`,
//! `session`, `end`, `error`, `clock`) and one binary message per frame ([`encode_web_frame`],
//! layout in docs/protocol.md, "Browser viewer").

use super::EXPRESSION_KEYS;
use crate::server::state::Shared;
use crate::server::viewer::{attach, detach, is_live};
use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket};
use mimic_retarget::FrameOutput;
use mimic_wire::{ErrorCode, KIND_END, KIND_ERROR, KIND_FRAME, KIND_SESSION};
use serde_json::{Value, json};
use std::sync::Arc;
use std::time::{Instant, SystemTime, UNIX_EPOCH};
use tokio::time::{sleep_until, timeout};

/// Longest message a browser may send (its clock requests are about 50 bytes).
pub(super) const CLIENT_MESSAGE_MAX: usize = 4096;

/// Bytes of a web frame before `d`.
pub(crate) const WEB_FRAME_FIXED_BYTES: usize = 80;

/// Offset of the send time in a web frame (filled when the frame leaves for the browser).
const SENT_AT: usize = 24;

/// The server's wall clock, in microseconds since the Unix epoch.
fn unix_now_us() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_micros()).unwrap_or(i64::MAX))
}

/// The browser's frame message (docs/protocol.md, "Browser viewer"), after the queue's 5-byte
/// header (length, kind FRAME): seq, tracker time, arrival time (server wall clock of the
/// frame's read), send time (0 here; [`run`] fills it), status, `m` and `k`, the session's gated
/// count, head rotation in target axes, pose translation and scale, `d`, and for a weights
/// session (`weights`) the `k = m / 3` weights (`d[3j].x`).
pub(crate) fn encode_web_frame(
    seq: u64,
    out: &FrameOutput,
    arrival: Instant,
    gated: u64,
    weights: bool,
) -> Vec<u8> {
    let m = out.displacements.len();
    let k = if weights { m / 3 } else { 0 };
    let len = WEB_FRAME_FIXED_BYTES + 12 * m + 4 * k;
    let mut b = Vec::with_capacity(5 + len);
    b.extend_from_slice(&u32::try_from(len + 1).unwrap_or(u32::MAX).to_le_bytes());
    b.push(KIND_FRAME);
    let since = i64::try_from(arrival.elapsed().as_micros()).unwrap_or(0);
    b.extend_from_slice(&seq.to_le_bytes());
    b.extend_from_slice(&out.timestamp_us.to_le_bytes());
    b.extend_from_slice(&(unix_now_us() - since).to_le_bytes());
    b.extend_from_slice(&0i64.to_le_bytes());
    b.push(mimic_wire::status_byte(out.status));
    b.push(u8::from(weights));
    b.extend_from_slice(&[0, 0]);
    for x in [m, k] {
        b.extend_from_slice(&u32::try_from(x).unwrap_or(u32::MAX).to_le_bytes());
    }
    b.extend_from_slice(&u32::try_from(gated).unwrap_or(u32::MAX).to_le_bytes());
    let r = out.target_rotation.to_array();
    let t = out.pose.translation.to_array();
    for c in r.iter().chain(&t).chain(&[out.pose.scale]) {
        b.extend_from_slice(&c.to_le_bytes());
    }
    for d in &out.displacements {
        for c in d.to_array() {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for j in 0..k {
        let w = out.displacements.get(3 * j).map_or(0.0, |d| d.x);
        b.extend_from_slice(&w.to_le_bytes());
    }
    b
}

/// What one queued message becomes for the browser.
enum Out {
    /// A JSON text message; `true` when the viewer closes after it (an error).
    Text(String, bool),
    /// A frame.
    Binary(Bytes),
    /// Nothing (the TCP rig message: the page loads the GLB instead).
    Skip,
}

/// The queued viewer message `m` (length, kind, payload) as the browser gets it.
fn transcode(shared: &Shared, m: &[u8]) -> Out {
    let (Some(&kind), Some(payload)) = (m.get(4), m.get(5..)) else {
        return Out::Skip;
    };
    let json_of = |kind: &str| {
        let mut v: Value = serde_json::from_slice(payload).unwrap_or_else(|_| json!({}));
        if let Value::Object(o) = &mut v {
            o.insert("type".into(), kind.into());
        }
        v
    };
    match kind {
        KIND_FRAME => Out::Binary(stamped(payload)),
        KIND_SESSION => {
            let mut v = json_of("session");
            let name = v["session"].as_str().unwrap_or_default().to_string();
            let entry = v["rig"].as_str().and_then(|r| shared.catalog.rig(Some(r)));
            if let (Value::Object(o), Some(entry)) = (&mut v, entry) {
                let scale = mimic_gltf::metres_per_unit(&entry.rig.units);
                o.insert("metres_per_unit".into(), json!(scale));
                o.insert("rig_units".into(), json!(entry.rig.units));
                o.insert("glb".into(), json!(format!("/rig/{name}.glb")));
                let weights = o.get("mode").and_then(Value::as_str) == Some("weights");
                if weights {
                    let names = entry.morph.as_ref().map(|s| s.names.clone());
                    o.insert("target_names".into(), json!(names.unwrap_or_default()));
                }
                // The number keys' morph targets: the rig's first nine, in the GLB after the
                // basis columns (landmarks) or as its own targets (weights).
                let names: Vec<&String> = entry
                    .morph
                    .as_ref()
                    .map(|s| s.names.iter().take(EXPRESSION_KEYS).collect())
                    .unwrap_or_default();
                let first = if weights {
                    0
                } else {
                    3 * entry.basis.control_count()
                };
                o.insert(
                    "expressions".into(),
                    json!({"first_target": first, "names": names}),
                );
            }
            Out::Text(v.to_string(), false)
        }
        KIND_END => Out::Text(json_of("end").to_string(), false),
        KIND_ERROR => Out::Text(json_of("error").to_string(), true),
        _ => Out::Skip,
    }
}

/// A web frame's payload with its send time set to now.
fn stamped(payload: &[u8]) -> Bytes {
    let mut b = payload.to_vec();
    if let Some(at) = b.get_mut(SENT_AT..SENT_AT + 8) {
        at.copy_from_slice(&unix_now_us().to_le_bytes());
    }
    Bytes::from(b)
}

/// The answer to a browser's clock request `{"type":"clock","client_ms":T}`: the same `T` and
/// the server's wall clock; `None` for anything else.
fn clock_reply(text: &str) -> Option<String> {
    let v: Value = serde_json::from_str(text).ok()?;
    if v["type"] != "clock" {
        return None;
    }
    let client = v["client_ms"].as_f64()?;
    Some(json!({"type": "clock", "client_ms": client, "server_us": unix_now_us()}).to_string())
}

/// What woke the viewer's loop.
enum Next {
    Queue(Option<crate::queue::Message>),
    Client(Option<Result<Message, axum::Error>>),
    Idle,
}

/// Serves one browser viewer of `session` until it leaves, is idle too long without a tracker,
/// cannot keep up with its writes, or the server stops.
pub(super) async fn run(shared: Arc<Shared>, mut socket: WebSocket, session: String) {
    let settings = &shared.settings;
    let write_timeout = settings.viewer_write_timeout;
    let v = match attach(&shared, &session, false, true) {
        Ok(v) => v,
        Err(refusal) => {
            let mut e = refusal.json();
            e["type"] = "error".into();
            let _ = timeout(
                write_timeout,
                socket.send(Message::Text(e.to_string().into())),
            )
            .await;
            let _ = timeout(write_timeout, socket.send(Message::Close(None))).await;
            return;
        }
    };
    tracing::info!(viewer = v.id, session = %session, "browser viewer joined");
    let hello = json!({"type": "hello", "session": session, "viewer": v.id,
        "live": is_live(&shared, &session), "server_us": unix_now_us()});
    let mut ok = timeout(
        write_timeout,
        socket.send(Message::Text(hello.to_string().into())),
    )
    .await
    .is_ok_and(|r| r.is_ok());
    // At least 10 ms, so that a 0 never spins this loop while a silent tracker is live.
    let idle = settings
        .viewer_idle_timeout
        .max(std::time::Duration::from_millis(10));
    let mut deadline = tokio::time::Instant::now() + idle;
    while ok {
        let next = tokio::select! {
            m = v.queue.pop() => Next::Queue(m),
            r = socket.recv() => Next::Client(r),
            _ = sleep_until(deadline) => Next::Idle,
        };
        let (out, close) = match next {
            Next::Queue(None) => break,
            Next::Queue(Some(m)) => {
                deadline = tokio::time::Instant::now() + idle;
                match transcode(&shared, &m) {
                    Out::Skip => continue,
                    Out::Binary(b) => (Message::Binary(b), false),
                    Out::Text(t, close) => (Message::Text(t.into()), close),
                }
            }
            Next::Client(None | Some(Err(_)) | Some(Ok(Message::Close(_)))) => break,
            Next::Client(Some(Ok(Message::Text(t)))) => match clock_reply(t.as_str()) {
                Some(reply) => (Message::Text(reply.into()), false),
                None => continue,
            },
            Next::Client(Some(Ok(_))) => continue,
            Next::Idle => {
                if is_live(&shared, &session) {
                    deadline = tokio::time::Instant::now() + idle;
                    continue;
                }
                let secs = settings.viewer_idle_timeout.as_secs_f64();
                let why = format!("session `{session}` has had no tracker for {secs} s");
                let e =
                    json!({"type": "error", "code": ErrorCode::IdleTimeout.name(), "message": why});
                (Message::Text(e.to_string().into()), true)
            }
        };
        ok = timeout(write_timeout, socket.send(out))
            .await
            .is_ok_and(|r| r.is_ok())
            && !close;
    }
    v.queue.abandon();
    let _ = timeout(
        std::time::Duration::from_secs(1),
        socket.send(Message::Close(None)),
    )
    .await;
    detach(&shared, &v);
    tracing::info!(
        viewer = v.id,
        session = %session,
        sent = v.queue.sent.get(),
        dropped = v.queue.dropped.get(),
        "browser viewer left"
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use mimic_retarget::FrameStatus;

    #[test]
    fn a_web_frame_has_the_documented_layout() {
        let mut out = FrameOutput {
            timestamp_us: -7,
            status: FrameStatus::Lost,
            positions: Vec::new(),
            normals: Vec::new(),
            displacements: vec![Vec3::new(0.25, 0.0, 0.0), Vec3::Y, Vec3::Z],
            pose: mimic_types::HeadPose::default(),
            target_rotation: Quat::from_rotation_y(0.5),
            filled: 0,
            times: Default::default(),
        };
        out.pose.translation = Vec3::new(1.0, 2.0, 3.0);
        let before = unix_now_us();
        let b = encode_web_frame(42, &out, Instant::now(), 5, true);
        let after = unix_now_us();
        let (m, k) = (3usize, 1usize);
        assert_eq!(b.len(), 5 + WEB_FRAME_FIXED_BYTES + 12 * m + 4 * k);
        assert_eq!(
            u32::from_le_bytes(b[0..4].try_into().unwrap()) as usize,
            b.len() - 4
        );
        assert_eq!(b[4], KIND_FRAME);
        let p = &b[5..];
        let i64_at = |o: usize| i64::from_le_bytes(p[o..o + 8].try_into().unwrap());
        let u32_at = |o: usize| u32::from_le_bytes(p[o..o + 4].try_into().unwrap());
        let f32_at = |o: usize| f32::from_le_bytes(p[o..o + 4].try_into().unwrap());
        assert_eq!(u64::from_le_bytes(p[0..8].try_into().unwrap()), 42);
        assert_eq!(i64_at(8), -7);
        assert!(
            (before..=after).contains(&i64_at(16)),
            "arrival {}",
            i64_at(16)
        );
        assert_eq!(i64_at(24), 0);
        assert_eq!((p[32], p[33]), (2, 1));
        assert_eq!((u32_at(36), u32_at(40), u32_at(44)), (3, 1, 5));
        let r = out.target_rotation.to_array();
        for (a, want) in r.iter().enumerate() {
            assert_eq!(f32_at(48 + 4 * a), *want);
        }
        assert_eq!(
            (f32_at(64), f32_at(68), f32_at(72), f32_at(76)),
            (1.0, 2.0, 3.0, 1.0)
        );
        assert_eq!(f32_at(80 + 12 + 4), 1.0, "d[1].y");
        assert_eq!(f32_at(80 + 36), 0.25, "the weight is d[0].x");
        // The send time is filled when the frame leaves.
        let sent = stamped(&b[5..]);
        assert_eq!(sent[..SENT_AT], p[..SENT_AT]);
        let at = i64::from_le_bytes(sent[24..32].try_into().unwrap());
        assert!(at >= after, "sent {at}");
    }

    #[test]
    fn clock_requests_are_answered_and_anything_else_ignored() {
        let r: Value =
            serde_json::from_str(&clock_reply(r#"{"type":"clock","client_ms":12.5}"#).unwrap())
                .unwrap();
        assert_eq!(r["client_ms"], 12.5);
        assert!(r["server_us"].as_i64().unwrap() > 0);
        assert!(clock_reply(r#"{"type":"other"}"#).is_none());
        assert!(clock_reply("not json").is_none());
    }
}
