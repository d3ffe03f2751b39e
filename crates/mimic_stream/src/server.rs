//! The server, split by what each part holds, each module importing only those below it (no
//! circle; `tests/module_graph.rs` checks): this facade ([`Server`]) on top; the accept loop and
//! hello dispatch (`accept`); the protocols (`landmark`, `weights`, `audio` (speech to weights
//! on a worker each), and the UDP tracker intakes
//! `openseeface` and `livelink` on the one loop of `intake`), with what their frames go to
//! besides viewers (`outputs`); viewers (`viewer`, `follow` for sessions of other front doors)
//! and the browser viewer's HTTP and WebSocket server (`http`); the session skeleton every
//! tracker protocol plugs into (`session`, with `admission` for refusals), which pushes frames
//! to viewers (`web_frame` for browsers); UDP frames of landmark sessions (`udp`); and at the
//! bottom the state they share (`state`) over the hubs, routes and session records (`hub`).

use crate::catalog::Catalog;
use crate::placement::Placement;
use crate::settings::{HttpSettings, ServerSettings};
use crate::stats::{LatencyHistogram, ServerStats};
use crate::sync::lock;
use state::Shared;
use std::future::Future;
use std::sync::Arc;
use tokio::net::{TcpListener, UdpSocket};

mod accept;
mod admission;
mod audio;
mod follow;
mod http;
mod hub;
mod intake;
mod landmark;
mod livelink;
mod openseeface;
mod outputs;
mod session;
mod slots;
mod state;
mod udp;
mod viewer;
mod web_frame;
mod weights;

/// A live-session server: trackers in (TCP lines, UDP packets), viewers out (TCP messages).
#[derive(Debug, Clone)]
pub struct Server {
    shared: Arc<Shared>,
}

impl Server {
    /// A server offering the catalog's rigs and layouts under these limits.
    pub fn new(catalog: Arc<Catalog>, settings: ServerSettings) -> Self {
        Self {
            shared: Arc::new(Shared::new(catalog, settings)),
        }
    }

    /// A server that hands its landmark sessions to `placement` to be stepped (a front door of
    /// a cluster, docs/cluster.md) instead of stepping them itself.
    pub fn with_placement(
        catalog: Arc<Catalog>,
        settings: ServerSettings,
        placement: Arc<dyn Placement>,
    ) -> Self {
        let mut shared = Shared::new(catalog, settings);
        shared.placement = Some(placement);
        Self {
            shared: Arc::new(shared),
        }
    }

    /// Serves until `shutdown` completes; then stops accepting, ends every session (frames
    /// already read are retargeted and broadcast), lets viewers drain their queues for up to
    /// `shutdown_grace`, and returns the final counters.
    pub async fn run(
        &self,
        listener: TcpListener,
        udp: Option<UdpSocket>,
        shutdown: impl Future<Output = ()>,
    ) -> ServerStats {
        accept::run(&self.shared, listener, udp, shutdown).await
    }

    /// Serves the browser viewer on `listener` until `shutdown` completes (then open WebSockets
    /// end when the server's viewer queues close, as TCP viewers do).
    pub async fn serve_http(
        &self,
        listener: TcpListener,
        web: HttpSettings,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> std::io::Result<()> {
        http::serve(self.shared.clone(), listener, web, shutdown).await
    }

    /// Counters of the server, its live sessions and the most recent ended ones.
    pub fn stats(&self) -> ServerStats {
        self.shared.stats()
    }

    /// Clears every session's latency histogram (e.g. after a warm-up), keeping the counters.
    pub fn reset_latency(&self) {
        for s in lock(&self.shared.sessions).iter() {
            *lock(&s.latency) = LatencyHistogram::default();
        }
    }
}
