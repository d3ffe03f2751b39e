//! The server, split by what each part holds: the accept loop and hello dispatch (`accept`), the
//! session skeleton every tracker protocol plugs into (`session`, with `admission` for refusals),
//! the protocols (`landmark`, `weights`), UDP intake (`udp`), viewers (`viewer`), the browser
//! viewer's HTTP and WebSocket server (`http`) and the state they share (`state`).

use crate::catalog::Catalog;
use crate::settings::ServerSettings;
use crate::stats::{LatencyHistogram, ServerStats};
use state::{Shared, lock};
use std::sync::Arc;

mod accept;
mod admission;
mod follow;
mod http;
mod intake;
mod landmark;
mod livelink;
mod openseeface;
mod session;
mod slots;
mod state;
mod udp;
mod viewer;
mod weights;

pub use http::HttpSettings;

/// Longest first line of a connection (hello or recording header), unless the message limit is
/// smaller: a connection that has not said what it is holds at most this much.
pub const HELLO_MAX_BYTES: usize = 64 * 1024;

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
        placement: Arc<dyn crate::placement::Placement>,
    ) -> Self {
        let mut shared = Shared::new(catalog, settings);
        shared.placement = Some(placement);
        Self {
            shared: Arc::new(shared),
        }
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
