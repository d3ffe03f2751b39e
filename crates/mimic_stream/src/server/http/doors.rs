//! The browser endpoint's doors (docs/reliability.md, "Doors"): its own accept loop in place of
//! `axum::serve`, so that every connection is admitted against a per-address cap and a budget
//! kept below the open-file limit (refused ones get a one-line 503 and are closed at once), reads
//! its request heads under a timeout (hyper's, also between requests of a kept-alive
//! connection), and is closed when its peer stops taking writes; and the `Host` and `Origin`
//! checks of every request ([`check_request`]).

use crate::server::state::Shared;
use crate::settings::{HttpSettings, ServerSettings};
use crate::sync::lock;
use axum::Router;
use axum::http::{HeaderMap, StatusCode, header};
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::collections::HashMap;
use std::future::Future;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::task::{Context, Poll, ready};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore, watch};

/// Descriptors kept for everything but the browser endpoint besides the TCP slots and the
/// recordings: listeners, UDP sockets, forwarding sockets, rig and config files, the runtime.
const FD_SPARE: usize = 64;

/// Largest request head (and read buffer) of a connection.
const MAX_HEAD_BYTES: usize = 64 * 1024;

/// The browser endpoint's connection budget: its `max_connections`, but never more than the
/// soft open-file limit `nofile` leaves once the TCP slots (sessions, viewers, the 16 before a
/// hello, stats slots, refusals being answered), a recording per session and [`FD_SPARE`] are
/// kept.
pub(super) fn connection_budget(
    web: &HttpSettings,
    s: &ServerSettings,
    nofile: Option<u64>,
) -> usize {
    let want = web.max_connections.max(1);
    let Some(nofile) = nofile else { return want };
    let reserve = crate::server::slots::general_slots(s)
        .saturating_add(s.stats_slots)
        .saturating_add(crate::server::slots::REFUSALS_IN_FLIGHT)
        .saturating_add(s.max_sessions)
        .saturating_add(FD_SPARE);
    let room = usize::try_from(nofile)
        .unwrap_or(usize::MAX)
        .saturating_sub(reserve);
    want.min(room.max(1))
}

/// What admits a connection: the budget and each address's count.
#[derive(Debug)]
struct Doors {
    shared: Arc<Shared>,
    budget: Arc<Semaphore>,
    per_peer: usize,
    peers: std::sync::Mutex<HashMap<IpAddr, usize>>,
}

/// An admitted connection's place, given back when its socket closes (also after an upgrade
/// to a WebSocket: it travels with the socket).
#[derive(Debug)]
struct Ticket {
    doors: Arc<Doors>,
    ip: IpAddr,
    _permit: OwnedSemaphorePermit,
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut peers = lock(&self.doors.peers);
        if let Some(n) = peers.get_mut(&self.ip) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                peers.remove(&self.ip);
            }
        }
        self.doors
            .shared
            .http_connections
            .fetch_sub(1, Ordering::AcqRel);
    }
}

impl Doors {
    /// A place for a connection from `ip`, or why not.
    fn admit(self: &Arc<Self>, ip: IpAddr) -> Result<Ticket, String> {
        let ip = ip.to_canonical();
        let mut peers = lock(&self.peers);
        let n = peers.entry(ip).or_insert(0);
        if *n >= self.per_peer {
            return Err(format!("at most {} connections from {ip}", self.per_peer));
        }
        let Ok(permit) = self.budget.clone().try_acquire_owned() else {
            if *n == 0 {
                peers.remove(&ip);
            }
            return Err("every connection of the browser endpoint is taken".into());
        };
        *n += 1;
        drop(peers);
        self.shared.http_connections.fetch_add(1, Ordering::AcqRel);
        Ok(Ticket {
            doors: self.clone(),
            ip,
            _permit: permit,
        })
    }
}

/// Serves `router` on `listener` through the doors until `shutdown` completes.
pub(super) async fn serve(
    shared: Arc<Shared>,
    listener: TcpListener,
    router: Router,
    web: &HttpSettings,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let budget = connection_budget(web, &shared.settings, crate::fdlimit::soft());
    tracing::info!(
        budget,
        per_peer = web.max_connections_per_peer,
        "browser endpoint connection limits"
    );
    let doors = Arc::new(Doors {
        shared: shared.clone(),
        budget: Arc::new(Semaphore::new(budget)),
        per_peer: web.max_connections_per_peer.max(1),
        peers: std::sync::Mutex::new(HashMap::new()),
    });
    let (stop_tx, stop_rx) = watch::channel(false);
    let mut refusals_logged: Option<std::time::Instant> = None;
    tokio::pin!(shutdown);
    loop {
        let accepted = tokio::select! {
            _ = &mut shutdown => break,
            a = listener.accept() => a,
        };
        let (socket, peer) = match accepted {
            Ok(a) => a,
            Err(e) => {
                // E.g. out of file descriptors: back off instead of spinning.
                tracing::warn!("browser endpoint: accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let ticket = match doors.admit(peer.ip()) {
            Ok(t) => t,
            Err(why) => {
                shared.http_refused.bump();
                let now = std::time::Instant::now();
                if refusals_logged.is_none_or(|t| now.duration_since(t) >= Duration::from_secs(1)) {
                    tracing::warn!(%peer, "browser endpoint: connection refused: {why} (logged at most once a second; counted in http_refused)");
                    refusals_logged = Some(now);
                }
                refuse(&socket, &why);
                continue;
            }
        };
        let _ = socket.set_nodelay(true);
        let io = Guarded {
            inner: socket,
            _ticket: ticket,
            write_timeout: web.write_timeout,
            stalled: None,
        };
        tokio::spawn(connection(
            io,
            peer,
            router.clone(),
            web.header_timeout,
            stop_rx.clone(),
        ));
    }
    let _ = stop_tx.send(true);
    Ok(())
}

/// A refused connection's answer, written without waiting (what the socket takes), then closed.
fn refuse(socket: &TcpStream, why: &str) {
    let body = format!("{why}\n");
    let reply = format!(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = socket.try_write(reply.as_bytes());
}

/// One HTTP/1 connection (and its upgrade to a WebSocket), under a header-read timeout.
async fn connection(
    io: Guarded,
    peer: SocketAddr,
    router: Router,
    header_timeout: Duration,
    mut stop: watch::Receiver<bool>,
) {
    let service = TowerToHyperService::new(router);
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(header_timeout.max(Duration::from_millis(10)))
        .max_buf_size(MAX_HEAD_BYTES);
    let conn = builder
        .serve_connection(TokioIo::new(io), service)
        .with_upgrades();
    tokio::pin!(conn);
    tokio::select! {
        r = conn.as_mut() => {
            if let Err(e) = r {
                tracing::debug!(%peer, "browser endpoint connection: {e}");
            }
        }
        _ = stop.changed() => {
            conn.as_mut().graceful_shutdown();
            let _ = tokio::time::timeout(Duration::from_secs(2), conn).await;
        }
    }
}

/// A connection's socket with its ticket, closed with an error when a write waits longer than
/// `write_timeout` (a peer that stopped reading).
struct Guarded {
    inner: TcpStream,
    _ticket: Ticket,
    write_timeout: Duration,
    stalled: Option<Pin<Box<tokio::time::Sleep>>>,
}

impl Guarded {
    /// Polls a write-side operation under the stall timeout.
    fn guard<T>(
        &mut self,
        cx: &mut Context<'_>,
        op: impl FnOnce(Pin<&mut TcpStream>, &mut Context<'_>) -> Poll<std::io::Result<T>>,
    ) -> Poll<std::io::Result<T>> {
        match op(Pin::new(&mut self.inner), cx) {
            Poll::Ready(r) => {
                self.stalled = None;
                Poll::Ready(r)
            }
            Poll::Pending => {
                let timeout = self.write_timeout;
                let sleep = self
                    .stalled
                    .get_or_insert_with(|| Box::pin(tokio::time::sleep(timeout)));
                ready!(sleep.as_mut().poll(cx));
                Poll::Ready(Err(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    "the peer took no data for the write timeout",
                )))
            }
        }
    }
}

impl AsyncRead for Guarded {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl AsyncWrite for Guarded {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        self.get_mut().guard(cx, |s, cx| s.poll_write(cx, buf))
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        self.get_mut().guard(cx, |s, cx| s.poll_flush(cx))
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        self.get_mut().guard(cx, |s, cx| s.poll_shutdown(cx))
    }
}

/// Why a request is refused for its `Host` or `Origin` (status and reason), if it is.
pub(super) fn check_request(
    headers: &HeaderMap,
    local: SocketAddr,
    web: &HttpSettings,
) -> Option<(StatusCode, String)> {
    let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
        let why = "a request must name this server in its Host header".to_string();
        return Some((StatusCode::MISDIRECTED_REQUEST, why));
    };
    if !host_ok(host, local, &web.hosts) {
        let why = format!(
            "Host `{}` does not name this server: it answers its own address, loopback names and the names given with `mimic serve --http-host` (docs/browser.md)",
            escape(host)
        );
        return Some((StatusCode::MISDIRECTED_REQUEST, why));
    }
    let origin = headers.get(header::ORIGIN)?;
    let origin = origin.to_str().unwrap_or("?");
    let own = format!("http://{}", host.to_ascii_lowercase());
    let origin_lc = origin.to_ascii_lowercase();
    let listed = web
        .origins
        .iter()
        .any(|o| o.trim_end_matches('/').eq_ignore_ascii_case(&origin_lc));
    if origin_lc == own || listed {
        return None;
    }
    let why = format!(
        "Origin `{}` is not this server's page ({own}) nor one given with `mimic serve --http-origin` (docs/browser.md)",
        escape(origin)
    );
    Some((StatusCode::FORBIDDEN, why))
}

/// A header value, safe to echo in a plain-text answer (at most 64 characters).
fn escape(s: &str) -> String {
    let s: String = s.chars().take(64).collect();
    mimic_wire::escape_untrusted(&s).into_owned()
}

/// Whether a `Host` header names the listener at `local`: an IP address the listener answers
/// (its own, any loopback one, any when it listens on all addresses), `localhost`, or a name of
/// `hosts`; the port is not compared (proxies may change it).
fn host_ok(host: &str, local: SocketAddr, hosts: &[String]) -> bool {
    let name = match host.strip_prefix('[') {
        Some(rest) => rest.split(']').next().unwrap_or_default(),
        None => host.rsplit_once(':').map_or(host, |(n, port)| {
            if port.bytes().all(|b| b.is_ascii_digit()) {
                n
            } else {
                host
            }
        }),
    };
    let name = name.trim_end_matches('.').to_ascii_lowercase();
    if let Ok(ip) = name.parse::<IpAddr>() {
        let ip = ip.to_canonical();
        return ip.is_loopback() || ip == local.ip().to_canonical() || local.ip().is_unspecified();
    }
    name == "localhost"
        || name.ends_with(".localhost")
        || hosts
            .iter()
            .any(|h| h.trim_end_matches('.').eq_ignore_ascii_case(&name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(host: Option<&str>, origin: Option<&str>) -> HeaderMap {
        let mut h = HeaderMap::new();
        if let Some(v) = host {
            h.insert(header::HOST, HeaderValue::from_str(v).unwrap());
        }
        if let Some(v) = origin {
            h.insert(header::ORIGIN, HeaderValue::from_str(v).unwrap());
        }
        h
    }

    #[test]
    fn host_and_origin_must_name_this_server() {
        let local: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        let mut web = HttpSettings::default();
        let ok = |h: Option<&str>, o: Option<&str>, web: &HttpSettings| {
            check_request(&headers(h, o), local, web).map(|(s, _)| s.as_u16())
        };
        for host in [
            "127.0.0.1:8080",
            "localhost:8080",
            "[::1]:8080",
            "127.0.0.1",
            "LOCALHOST",
        ] {
            assert_eq!(ok(Some(host), None, &web), None, "{host}");
        }
        assert_eq!(ok(Some("attacker.example:8080"), None, &web), Some(421));
        assert_eq!(ok(Some("10.0.0.5:8080"), None, &web), Some(421));
        assert_eq!(ok(None, None, &web), Some(421));
        let own = Some("http://127.0.0.1:8080");
        assert_eq!(ok(Some("127.0.0.1:8080"), own, &web), None);
        assert_eq!(
            ok(Some("127.0.0.1:8080"), Some("http://evil.example"), &web),
            Some(403)
        );
        assert_eq!(ok(Some("127.0.0.1:8080"), Some("null"), &web), Some(403));
        web.hosts.push("face.lan".into());
        web.origins.push("https://studio.example".into());
        assert_eq!(
            ok(Some("face.lan:8080"), Some("http://face.lan:8080"), &web),
            None
        );
        assert_eq!(
            ok(Some("127.0.0.1:8080"), Some("https://studio.example"), &web),
            None
        );
        // Listening on every address: any IP literal names it (no DNS rebinding through one).
        let any: SocketAddr = "0.0.0.0:8080".parse().unwrap();
        assert!(check_request(&headers(Some("10.0.0.5:8080"), None), any, &web).is_none());
        assert!(check_request(&headers(Some("evil.example"), None), any, &web).is_some());
    }

    #[test]
    fn the_budget_stays_below_the_file_limit() {
        let web = HttpSettings::default();
        let s = ServerSettings::default();
        assert_eq!(connection_budget(&web, &s, None), 256);
        assert_eq!(connection_budget(&web, &s, Some(1 << 20)), 256);
        // Under 1024 descriptors: 400 + 4 + 256 + 128 + 64 kept, 172 for the browser.
        assert_eq!(connection_budget(&web, &s, Some(1024)), 172);
        assert_eq!(connection_budget(&web, &s, Some(100)), 1);
    }
}
