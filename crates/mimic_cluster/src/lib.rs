//! mimic's live sessions spread over worker processes through NATS (docs/cluster.md).
//!
//! A front door (`mimic serve --nats URL`) keeps its sockets and hands each landmark session to
//! a worker through [`NatsPlacement`], which implements mimic_stream's
//! [`Placement`](mimic_stream::placement::Placement) seam; a worker (`mimic worker --nats URL`,
//! [`Worker`]) owns no socket but a NATS connection and steps the sessions it claimed.
//!
//! Subjects (`<s>`: the session's [`token`]):
//! - `mimic.ctl.open`, queue group `mimic-workers`: a front door asks for a worker (JSON request
//!   and reply); exactly one worker of the group gets each request.
//! - `mimic.in.<s>`: the session's frames in order, from its front door to its worker.
//! - `mimic.out.<s>`: the worker's answers (and the front door's live / end notices) to every
//!   front door that hosts the session or has viewers of it.
//! - `mimic.info.<s>`: a front door with viewers of a session it does not host asks its host
//!   for the session description.
//!
//! A worker holds each session by a lease in the JetStream key-value bucket `mimic_leases`
//! (entries expire after [`ClusterSettings::lease_ttl`] unless renewed) and checkpoints the
//! session's [`Checkpoint`](mimic_retarget::Checkpoint) to `mimic_state`; when its answers stop
//! and the lease has expired, the front door asks again and another worker restores the
//! checkpoint and goes on.

mod codec;
mod front;
mod servers;
mod worker;

pub use codec::token;
pub use front::NatsPlacement;
pub use servers::redact;
pub use worker::{Worker, WorkerStats};

use async_nats::jetstream::{self, kv};
use std::time::Duration;

/// Timing of leases, checkpoints and failover.
#[derive(Clone, Debug)]
pub struct ClusterSettings {
    /// A lease not renewed for this long expires (the bucket's entry age).
    pub lease_ttl: Duration,
    /// How often a worker renews its leases.
    pub renew_every: Duration,
    /// How often a worker checkpoints a session that stepped frames since the last one.
    pub checkpoint_every: Duration,
    /// A front door whose frames go unanswered this long checks the session's lease.
    pub stall_after: Duration,
    /// How often a front door retries a placement (and checks a stalled lease).
    pub retry_every: Duration,
    /// How long an ending session waits for its worker's last answers.
    pub finish_wait: Duration,
}

impl Default for ClusterSettings {
    fn default() -> Self {
        Self {
            lease_ttl: Duration::from_millis(1000),
            renew_every: Duration::from_millis(300),
            checkpoint_every: Duration::from_millis(250),
            stall_after: Duration::from_millis(300),
            retry_every: Duration::from_millis(100),
            finish_wait: Duration::from_secs(3),
        }
    }
}

/// What can go wrong talking to NATS.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// The server could not be reached.
    #[error("NATS {url}: {message}")]
    Connect {
        /// The URL given.
        url: String,
        /// The client's error.
        message: String,
    },
    /// A JetStream bucket could not be opened or made (is the server started with `-js`?).
    #[error(
        "NATS JetStream bucket `{bucket}`: {message} (the server needs JetStream: nats-server -js)"
    )]
    Bucket {
        /// The bucket.
        bucket: String,
        /// The client's error.
        message: String,
    },
    /// A subscription failed.
    #[error("NATS subscribe {subject}: {message}")]
    Subscribe {
        /// The subject.
        subject: String,
        /// The client's error.
        message: String,
    },
}

/// The lease bucket.
pub const LEASES: &str = "mimic_leases";
/// The checkpoint bucket.
pub const STATE: &str = "mimic_state";

/// One connection to NATS with the two buckets, shared by a process's tasks.
#[derive(Clone, Debug)]
pub struct Cluster {
    client: async_nats::Client,
    leases: kv::Store,
    state: kv::Store,
    settings: ClusterSettings,
}

impl Cluster {
    /// Connects to `url` and opens (or makes) the buckets. `url` may list several servers of a
    /// NATS cluster, comma-separated (`nats://a:4222,nats://b:4222`; `tls://` for TLS), and carry
    /// a token (`nats://TOKEN@host:4222`) or a user and password (`nats://USER:PASS@host:4222`).
    pub async fn connect(url: &str, settings: ClusterSettings) -> Result<Self, ClusterError> {
        let (addrs, credentials) = servers::parse(url)?;
        let options = async_nats::ConnectOptions::new().name("mimic");
        let options = match credentials {
            servers::Credentials::None => options,
            servers::Credentials::Token(t) => options.token(t),
            servers::Credentials::UserPassword(u, p) => options.user_and_password(u, p),
        };
        let client = options
            .connect(addrs)
            .await
            .map_err(|e| ClusterError::Connect {
                url: servers::redact(url),
                message: e.to_string(),
            })?;
        let js = jetstream::new(client.clone());
        let leases = bucket(
            &js,
            kv::Config {
                bucket: LEASES.into(),
                description: "mimic: which worker holds each live session".into(),
                history: 1,
                max_age: settings.lease_ttl,
                storage: jetstream::stream::StorageType::Memory,
                ..Default::default()
            },
        )
        .await?;
        let state = bucket(
            &js,
            kv::Config {
                bucket: STATE.into(),
                description: "mimic: checkpoints of live sessions".into(),
                history: 1,
                max_age: Duration::from_secs(3600),
                storage: jetstream::stream::StorageType::File,
                ..Default::default()
            },
        )
        .await?;
        Ok(Self {
            client,
            leases,
            state,
            settings,
        })
    }

    /// The client, e.g. to flush before exiting.
    pub fn client(&self) -> &async_nats::Client {
        &self.client
    }
}

/// Opens bucket `config.bucket`, making it when it does not exist yet (another process may
/// make it at the same time: then it is opened).
async fn bucket(js: &jetstream::Context, config: kv::Config) -> Result<kv::Store, ClusterError> {
    let name = config.bucket.clone();
    let err = |e: &dyn std::fmt::Display| ClusterError::Bucket {
        bucket: name.clone(),
        message: e.to_string(),
    };
    if let Ok(store) = js.get_key_value(&name).await {
        return Ok(store);
    }
    match js.create_key_value(config).await {
        Ok(store) => Ok(store),
        Err(created) => js.get_key_value(&name).await.map_err(|_| err(&created)),
    }
}
