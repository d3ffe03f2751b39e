//! The browser viewer (`mimic serve --http ADDR`, docs/browser.md): an axum HTTP/1 server on its
//! own listener, sharing the server's state. Routes: `/` (the sessions, refreshed from
//! `/sessions`), `/view/SESSION` (the three.js page), `/rig/SESSION.glb` (the session's rig as a
//! GLB, `glb.rs`, built once per rig and cached), `/ws/SESSION` (a WebSocket viewer of the
//! session's hub, `ws.rs`), `/stats`, and `/static/...` (the page's scripts and the vendored
//! three.js, embedded in the binary: `assets.rs`). With a server token every route but
//! `/static/` wants `?token=T`, compared as the TCP hello's is. Every request must name this
//! server in its `Host` and, with an `Origin`, come from its own page or an allowed origin;
//! connections are admitted, timed and bounded by `doors.rs`.

mod assets;
mod doors;
mod glb;
mod ws;

use super::admission::token_ok;
use super::state::Shared;
use crate::settings::HttpSettings;
use crate::sync::lock;
use axum::Router;
use axum::body::Bytes;
use axum::extract::ws::WebSocketUpgrade;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::{Path, RawQuery, Request, State};
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::json;
use std::future::Future;
use std::sync::Arc;
use tokio::net::TcpListener;

/// State of the HTTP routes.
#[derive(Debug)]
struct App {
    shared: Arc<Shared>,
    glbs: glb::GlbCache,
    /// The listener's address (a `Host` naming it is this server).
    local: std::net::SocketAddr,
    /// The allowed hosts and origins, the limits.
    web: HttpSettings,
}

type AppState = State<Arc<App>>;

/// Serves the browser viewer on `listener` until `shutdown` completes (`Server::serve_http`).
pub(crate) async fn serve(
    shared: Arc<Shared>,
    listener: TcpListener,
    web: HttpSettings,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let local = listener.local_addr()?;
    let app = Arc::new(App {
        shared: shared.clone(),
        glbs: glb::GlbCache::new(web.clone()),
        local,
        web: web.clone(),
    });
    let router = Router::new()
        .route("/", get(index))
        .route("/sessions", get(sessions))
        .route("/stats", get(stats))
        .route("/view/{session}", get(view))
        .route("/rig/{file}", get(rig_glb))
        .route("/ws/{session}", get(ws_upgrade))
        .route("/static/{*path}", get(static_file))
        .layer(axum::middleware::from_fn_with_state(
            app.clone(),
            host_and_origin,
        ))
        .with_state(app);
    doors::serve(shared, listener, router, &web, shutdown).await
}

/// Refuses a request whose `Host` does not name this server (421) or whose `Origin` is not
/// its own page's nor an allowed one (403), with the reason, before any route sees it.
async fn host_and_origin(State(app): AppState, request: Request, next: Next) -> Response {
    if let Some((status, why)) = doors::check_request(request.headers(), app.local, &app.web) {
        app.shared.http_refused.bump();
        return text(status, format!("{why}\n"));
    }
    next.run(request).await
}

/// The `token` parameter of a query string, percent-decoded (`+` as a space).
fn query_token(query: Option<&str>) -> Option<String> {
    let q = query?;
    let raw = q.split('&').find_map(|kv| kv.strip_prefix("token="))?;
    let b = raw.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut k = 0;
    while k < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match b[k] {
            b'%' if k + 2 < b.len() => match (hex(b[k + 1]), hex(b[k + 2])) {
                (Some(h), Some(l)) => {
                    out.push((h * 16 + l) as u8);
                    k += 3;
                    continue;
                }
                _ => out.push(b'%'),
            },
            b'+' => out.push(b' '),
            c => out.push(c),
        }
        k += 1;
    }
    String::from_utf8(out).ok()
}

/// Whether a request's query presents the server's token (always, without one).
fn authorized(app: &App, query: Option<&str>) -> bool {
    let presented = query_token(query);
    token_ok(app.shared.settings.token.as_deref(), presented.as_deref())
}

/// The answer to a request without the server's token.
fn unauthorized() -> Response {
    let msg = "this server wants its token: add ?token=T to the address (docs/browser.md)\n";
    (StatusCode::UNAUTHORIZED, msg).into_response()
}

/// A plain-text error answer.
fn text(status: StatusCode, msg: String) -> Response {
    (
        status,
        [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
        msg,
    )
        .into_response()
}

/// An embedded file as a response.
fn embedded(path: &str) -> Response {
    match assets::asset(path) {
        Some((mime, body)) => (
            [
                (header::CONTENT_TYPE, mime),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            body,
        )
            .into_response(),
        None => text(StatusCode::NOT_FOUND, format!("no file `{path}`\n")),
    }
}

async fn index(State(app): AppState, RawQuery(q): RawQuery) -> Response {
    if !authorized(&app, q.as_deref()) {
        return unauthorized();
    }
    embedded("index.html")
}

async fn view(
    State(app): AppState,
    Path(session): Path<String>,
    RawQuery(q): RawQuery,
) -> Response {
    if !authorized(&app, q.as_deref()) {
        return unauthorized();
    }
    if !mimic_wire::valid_session_name(&session) {
        return text(StatusCode::NOT_FOUND, "no such session name\n".into());
    }
    embedded("view.html")
}

async fn static_file(Path(path): Path<String>) -> Response {
    embedded(&path)
}

/// A JSON response.
fn json_response(body: String) -> Response {
    (
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body,
    )
        .into_response()
}

/// `/sessions`: the sessions the server knows (live ones first, then the most recent ended),
/// with what the list page shows.
async fn sessions(State(app): AppState, RawQuery(q): RawQuery) -> Response {
    if !authorized(&app, q.as_deref()) {
        return unauthorized();
    }
    let stats = app.shared.stats();
    let mut list: Vec<_> = stats
        .sessions
        .iter()
        .rev()
        .map(|s| {
            json!({
                "name": s.name, "id": s.id, "rig": s.rig, "layout": s.layout,
                "active": s.active, "end_reason": s.end_reason, "frames": s.frames,
                "viewers": s.viewers.iter().filter(|v| v.connected).count(),
            })
        })
        .collect();
    list.sort_by_key(|s| !s["active"].as_bool().unwrap_or(false));
    json_response(json!({ "sessions": list }).to_string())
}

/// `/stats`: the counters, as `GET /stats` on the TCP port gives them.
async fn stats(State(app): AppState, RawQuery(q): RawQuery) -> Response {
    if !authorized(&app, q.as_deref()) {
        return unauthorized();
    }
    json_response(app.shared.stats_json())
}

/// The rig and kind of the session named `name`: its live tracker's, else the most recent
/// ended session of that name's; `(rig, weights session)`.
fn session_rig(shared: &Shared, name: &str) -> Option<(String, bool)> {
    let of = |r: &super::hub::SessionRecord| (r.rig.clone(), r.layout == "weights");
    if let Some(live) = lock(&shared.hubs).get(name).and_then(|h| h.live.as_ref()) {
        return Some(of(&live.record));
    }
    lock(&shared.sessions)
        .iter()
        .rev()
        .find(|s| s.name == name)
        .map(|s| of(s))
}

/// `/rig/SESSION.glb`: the session's rig as a GLB (morph targets: the basis columns and the
/// number keys' targets, or the rig's own targets for a weights session).
async fn rig_glb(
    State(app): AppState,
    Path(file): Path<String>,
    RawQuery(q): RawQuery,
) -> Response {
    if !authorized(&app, q.as_deref()) {
        return unauthorized();
    }
    let Some(session) = file.strip_suffix(".glb") else {
        return text(
            StatusCode::NOT_FOUND,
            "rigs are at /rig/SESSION.glb\n".into(),
        );
    };
    let Some((rig, weights)) = session_rig(&app.shared, session) else {
        let msg = format!("no session `{}` (live or recent)\n", escape(session));
        return text(StatusCode::NOT_FOUND, msg);
    };
    match app.glbs.get(&app.shared, &rig, weights).await {
        Ok(bytes) => glb_response(bytes),
        Err(e) => {
            tracing::error!(rig = %rig, "GLB for the browser viewer: {e}");
            text(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("rig `{rig}`: {e}\n"),
            )
        }
    }
}

/// A GLB body.
fn glb_response(bytes: Bytes) -> Response {
    (
        [
            (header::CONTENT_TYPE, "model/gltf-binary"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        bytes,
    )
        .into_response()
}

/// A name from a request, safe to echo in a plain-text answer.
fn escape(s: &str) -> String {
    let s: String = s.chars().take(64).collect();
    mimic_wire::escape_untrusted(&s).into_owned()
}

/// `/ws/SESSION`: upgrades to a WebSocket viewer of the session.
async fn ws_upgrade(
    State(app): AppState,
    Path(session): Path<String>,
    RawQuery(q): RawQuery,
    upgrade: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Response {
    // The token first: a request without it learns nothing else.
    if !authorized(&app, q.as_deref()) {
        app.shared.refused.bump();
        return unauthorized();
    }
    let upgrade = match upgrade {
        Ok(u) => u,
        Err(rejection) => return rejection.into_response(),
    };
    if !mimic_wire::valid_session_name(&session) {
        return text(
            StatusCode::NOT_FOUND,
            "a session name is 1-64 of A-Z a-z 0-9 _ . -\n".into(),
        );
    }
    let shared = app.shared.clone();
    upgrade
        .max_message_size(ws::CLIENT_MESSAGE_MAX)
        .max_frame_size(ws::CLIENT_MESSAGE_MAX)
        .on_upgrade(move |socket| ws::run(shared, socket, session))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_is_taken_from_the_query_and_decoded() {
        assert_eq!(query_token(Some("token=abc")).as_deref(), Some("abc"));
        assert_eq!(
            query_token(Some("x=1&token=a%20b%2Bc+d")).as_deref(),
            Some("a b+c d")
        );
        assert_eq!(query_token(Some("tok=abc")), None);
        assert_eq!(query_token(None), None);
        // A stray or short escape stays as it is.
        assert_eq!(query_token(Some("token=50%")).as_deref(), Some("50%"));
        assert_eq!(query_token(Some("token=%4")).as_deref(), Some("%4"));
        assert_eq!(query_token(Some("token=%zz")).as_deref(), Some("%zz"));
    }
}
