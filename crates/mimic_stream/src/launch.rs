//! Starting a server as `mimic serve` does: the tracker UDP sockets ([`bind_tracker_udp`],
//! warned about beyond loopback), the record folder checked writable ([`record_dir`]), the
//! forwarding's name maps ([`forward_settings`]), the listeners and the ready line
//! ([`Listeners`]), and serving TCP and the browser viewer until shutdown ([`serve`]).

use crate::forward::{ForwardSettings, ForwardTarget};
use crate::server::Server;
use crate::settings::{HttpSettings, LiveLinkIntake, ServerSettings};
use crate::stats::ServerStats;
use mimic_trackers::namemap::NameMap;
use std::future::Future;
use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;
use tokio::net::{TcpListener, UdpSocket};

/// Why a server cannot start.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// A socket or file operation failed (`what` says which).
    #[error("{what}")]
    Io {
        /// What was being done.
        what: String,
        /// Why it failed.
        #[source]
        source: std::io::Error,
    },
    /// A bound socket without an address.
    #[error(transparent)]
    Socket(#[from] std::io::Error),
    /// A name map that cannot be read.
    #[error(transparent)]
    NameMap(#[from] mimic_trackers::TrackerError),
    /// A tracker intake beyond loopback without a list of the sources it takes.
    #[error(
        "{flag}: refusing to receive on {addr} beyond loopback without --udp-allow: this tracker protocol carries no token, so name the addresses its trackers send from (--udp-allow ADDR[,ADDR])"
    )]
    NeedsUdpAllow {
        /// The option.
        flag: String,
        /// The address asked for.
        addr: SocketAddr,
    },
}

/// `io`'s error with what was being done.
fn doing<T>(what: impl FnOnce() -> String, io: std::io::Result<T>) -> Result<T, LaunchError> {
    io.map_err(|source| LaunchError::Io {
        what: what(),
        source,
    })
}

/// A tracker protocol's UDP socket bound at `addr`; beyond loopback only with an `allow` list
/// of source addresses (`--udp-allow`: these protocols carry no token); `flag` names the option
/// in messages.
pub fn bind_tracker_udp(
    addr: Option<SocketAddr>,
    flag: &str,
    allow: &[IpAddr],
) -> Result<Option<Arc<std::net::UdpSocket>>, LaunchError> {
    let Some(addr) = addr else { return Ok(None) };
    if !addr.ip().is_loopback() {
        if allow.is_empty() {
            return Err(LaunchError::NeedsUdpAllow {
                flag: flag.to_string(),
                addr,
            });
        }
        tracing::warn!(%addr, "{flag}: receiving beyond loopback, as asked, from the --udp-allow addresses only");
    }
    let socket = doing(
        || format!("{flag}: binding UDP {addr}"),
        std::net::UdpSocket::bind(addr),
    )?;
    Ok(Some(Arc::new(socket)))
}

/// The Live Link intake on `socket` (if bound), its curves through the name map at `namemap`.
pub fn livelink_intake(
    socket: Option<Arc<std::net::UdpSocket>>,
    namemap: &Path,
) -> Result<Option<LiveLinkIntake>, LaunchError> {
    let Some(socket) = socket else {
        return Ok(None);
    };
    let namemap = Arc::new(NameMap::load(namemap)?);
    Ok(Some(LiveLinkIntake { socket, namemap }))
}

/// The `--record` folder, created if missing and checked writable before any session starts.
pub fn record_dir(dir: Option<&Path>) -> Result<Option<PathBuf>, LaunchError> {
    let Some(dir) = dir else { return Ok(None) };
    doing(
        || format!("--record: creating {}", dir.display()),
        std::fs::create_dir_all(dir),
    )?;
    // An empty, unused file: proof that recordings can be written there.
    let probe = dir.join(format!(".mimic-serve-probe-{}", std::process::id()));
    let created = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(&probe);
    doing(
        || format!("--record: {} is not writable", dir.display()),
        created,
    )?;
    doing(
        || format!("--record: {}", probe.display()),
        std::fs::remove_file(&probe),
    )?;
    Ok(Some(dir.to_path_buf()))
}

/// Forwarding to `targets` (warned about beyond loopback), trackers' own targets allowed at
/// `allow` (address and port) besides those, the weights read back as ARKit curves through the name map at
/// `namemap`, and VMC's names from `vmc_names` (ARKit's without one).
pub fn forward_settings(
    targets: Vec<ForwardTarget>,
    allow: Vec<SocketAddr>,
    namemap: &Path,
    vmc_names: Option<&Path>,
) -> Result<ForwardSettings, LaunchError> {
    for t in &targets {
        if !t.addr.ip().is_loopback() {
            tracing::warn!(target = %t, "--forward beyond loopback, as asked");
        }
    }
    let namemap = Arc::new(NameMap::load(namemap)?);
    let vmc_names = match vmc_names {
        Some(p) => Some(Arc::new(NameMap::load(p)?)),
        None => None,
    };
    Ok(ForwardSettings {
        targets,
        allow,
        namemap,
        vmc_names,
    })
}

/// A server's bound listeners: TCP, UDP frames (unless off) and the browser viewer's (if asked).
#[derive(Debug)]
pub struct Listeners {
    /// Trackers, viewers and stats.
    pub tcp: TcpListener,
    /// Binary tracker frames.
    pub udp: Option<UdpSocket>,
    /// The browser viewer.
    pub http: Option<TcpListener>,
}

impl Listeners {
    /// Binds TCP at `listen`, UDP at `udp` (`None`: off; `Some(None)`: the TCP address and
    /// port) and the browser viewer at `http`.
    pub async fn bind(
        listen: SocketAddr,
        udp: Option<Option<SocketAddr>>,
        http: Option<SocketAddr>,
    ) -> Result<Self, LaunchError> {
        let tcp = doing(
            || format!("binding {listen}"),
            TcpListener::bind(listen).await,
        )?;
        let udp = match udp {
            None => None,
            Some(at) => {
                let addr = at.unwrap_or(tcp.local_addr()?);
                let bound = UdpSocket::bind(addr).await;
                Some(doing(|| format!("binding UDP {addr}"), bound)?)
            }
        };
        let http = match http {
            Some(addr) => {
                let bound = TcpListener::bind(addr).await;
                Some(doing(|| format!("--http: binding {addr}"), bound)?)
            }
            None => None,
        };
        Ok(Self { tcp, udp, http })
    }

    /// The line that says where to connect (tests and scripts read it): `mimic serve: tcp ADDR
    /// udp ADDR rigs [..]`, then the tracker intakes of `settings`, `extra` (e.g. a cluster's)
    /// and the browser viewer's address.
    pub fn ready_line(
        &self,
        settings: &ServerSettings,
        rigs: &[String],
        extra: &str,
    ) -> Result<String, LaunchError> {
        let tcp = self.tcp.local_addr()?;
        let udp = match &self.udp {
            Some(u) => u.local_addr()?.to_string(),
            None => "off".to_string(),
        };
        let http = match &self.http {
            Some(l) => format!(" http {}", l.local_addr()?),
            None => String::new(),
        };
        let livelink = settings.livelink.as_ref().map(|l| l.socket.clone());
        let trackers: String = [
            ("openseeface", &settings.openseeface),
            ("livelink", &livelink),
        ]
        .iter()
        .filter_map(|(name, s)| Some(format!(" {name} {}", s.as_ref()?.local_addr().ok()?)))
        .collect();
        Ok(format!(
            "mimic serve: tcp {tcp} udp {udp} rigs {rigs:?}{trackers}{extra}{http}"
        ))
    }
}

/// Serves `listeners` (the browser viewer too, with `web`) until the future `shutdown` makes
/// completes, then gives browser viewers up to 2 s to end; returns the final counters.
pub async fn serve<F>(
    server: Server,
    listeners: Listeners,
    web: HttpSettings,
    shutdown: impl Fn() -> F,
) -> ServerStats
where
    F: Future<Output = ()> + Send + 'static,
{
    // Room for every slot, recording and the browser endpoint's budget (`HttpSettings`).
    if let Some(n) = crate::fdlimit::raise() {
        tracing::debug!("open-file limit {n}");
    }
    let Listeners { tcp, udp, http } = listeners;
    let web_task = http.map(|listener| {
        let server = server.clone();
        let stop = shutdown();
        tokio::spawn(async move { server.serve_http(listener, web, stop).await })
    });
    let stats = server.run(tcp, udp, shutdown()).await;
    if let Some(task) = web_task {
        // Browser viewers end with the server's viewer queues; give them a moment.
        let abort = task.abort_handle();
        match tokio::time::timeout(Duration::from_secs(2), task).await {
            Ok(Ok(Err(e))) => tracing::warn!("HTTP server: {e}"),
            Err(_) => abort.abort(),
            _ => {}
        }
    }
    stats
}
