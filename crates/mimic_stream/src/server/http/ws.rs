//! A browser viewer over a WebSocket (`/ws/SESSION`): it joins the session's hub like a TCP viewer
//! (its own drop-oldest queue, counted in the stats) and gets text messages (JSON: `hello`,
//! `session`, `end`, `error`, `clock`) and one binary message per frame (`server::web_frame`,
//! layout in docs/protocol.md, "Browser viewer").

use super::glb::EXPRESSION_KEYS;
use crate::server::state::Shared;
use crate::server::viewer::{attach, detach, is_live};
use crate::server::web_frame::{stamped, unix_now_us};
use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket};
use mimic_wire::{ErrorCode, KIND_END, KIND_ERROR, KIND_FRAME, KIND_SESSION};
use serde_json::{Value, json};
use std::sync::Arc;
use tokio::time::{sleep_until, timeout};

/// Longest message a browser may send (its clock requests are about 50 bytes).
pub(super) const CLIENT_MESSAGE_MAX: usize = 4096;

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
