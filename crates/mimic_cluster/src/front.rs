//! The front door's side: [`NatsPlacement`] places each landmark session on a worker, forwards
//! its frames, hands the answers back, places it again when its worker's answers stop and its
//! lease has expired, and follows sessions of other front doors for this one's viewers.

use crate::Cluster;
use crate::codec::Lease;
use crate::codec::{
    LiveNotice, OPEN, OpenReply, OpenRequest, Out, decode_out, encode_in_end, encode_in_frame,
    encode_live, encode_out_end, in_subject, info_subject, out_subject, token,
};
use futures_util::StreamExt;
use mimic_stream::placement::{
    Followed, PlaceRequest, Placed, PlacedFrame, Placement, PlacementStatus, StepResult,
};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

/// Frames of one session queued for NATS before more are dropped (and counted lost).
const FRAMES_QUEUE: usize = 256;
/// Answers of one session queued for its front door's session task.
const ANSWERS_QUEUE: usize = 256;
/// Messages queued for one follower hub before more are dropped.
const FOLLOW_QUEUE: usize = 1024;
/// How long a placement request waits for a worker's reply.
const OPEN_TIMEOUT: Duration = Duration::from_millis(500);

/// Places a front door's landmark sessions on workers through NATS.
#[derive(Debug)]
pub struct NatsPlacement {
    cluster: Cluster,
    host: String,
}

impl NatsPlacement {
    /// Placement for the front door named `host` (shown in leases and logs).
    pub fn new(cluster: Cluster, host: &str) -> Self {
        Self {
            cluster,
            host: host.to_string(),
        }
    }
}

impl Placement for NatsPlacement {
    fn place(&self, request: PlaceRequest) -> Placed {
        let (frames_tx, frames_rx) = mpsc::channel(FRAMES_QUEUE);
        let (answers_tx, answers_rx) = mpsc::channel(ANSWERS_QUEUE);
        let (ready_tx, ready_rx) = oneshot::channel();
        let status = Arc::new(PlacementStatus::default());
        let host = Host {
            cluster: self.cluster.clone(),
            host: self.host.clone(),
            tok: token(&request.session),
            request,
            status: status.clone(),
            worker: None,
        };
        tokio::spawn(host.run(frames_rx, answers_tx, ready_tx));
        Placed {
            frames: frames_tx,
            results: answers_rx,
            ready: ready_rx,
            status,
        }
    }

    fn follow(&self, session: &str) -> mpsc::Receiver<Followed> {
        let (tx, rx) = mpsc::channel(FOLLOW_QUEUE);
        tokio::spawn(follow(self.cluster.clone(), token(session), tx));
        rx
    }
}

/// One hosted session's link to its worker.
struct Host {
    cluster: Cluster,
    host: String,
    tok: String,
    request: PlaceRequest,
    status: Arc<PlacementStatus>,
    /// The worker holding it, as far as this front door knows.
    worker: Option<String>,
}

impl Host {
    /// Asks the queue group once; true when a worker took the session.
    async fn place_once(&mut self, resume: bool) -> bool {
        let req = OpenRequest {
            session: self.request.session.clone(),
            rig: self.request.rig.clone(),
            layout: self.request.layout.clone(),
            host: self.host.clone(),
            id: Some(self.request.id),
            resume,
        };
        let body = serde_json::to_vec(&req).unwrap_or_default();
        let asked = self.cluster.client.request(OPEN, body.into());
        let reply = match tokio::time::timeout(OPEN_TIMEOUT, asked).await {
            Ok(Ok(m)) => m,
            Ok(Err(e)) => {
                tracing::debug!(session = %self.request.session, "no worker: {e}");
                return self.adopt().await;
            }
            // A worker may have taken the session and answered too late: its lease says so.
            Err(_) => return self.adopt().await,
        };
        let Ok(reply) = serde_json::from_slice::<OpenReply>(&reply.payload) else {
            return false;
        };
        if !reply.ok {
            tracing::debug!(session = %self.request.session, worker = %reply.worker, why = %reply.why, "placement declined");
            // Declined because the lease is taken: perhaps for this very request, earlier.
            return self.adopt().await;
        }
        tracing::info!(session = %self.request.session, worker = %reply.worker, resume, restored = reply.restored, "session placed");
        self.placed_on(reply.worker);
        true
    }

    /// Records that `worker` holds the session.
    fn placed_on(&mut self, worker: String) {
        self.status.set_worker(Some(worker.clone()));
        self.status.placements.bump();
        self.worker = Some(worker);
    }

    /// After a placement request got no usable reply: when the session's lease was taken for
    /// this session by some worker (whose reply was lost or late), that worker holds it; true
    /// then. Without this a slow reply left the session stepped by a worker the front door did
    /// not know, every later request declined (the lease is held), and no failover.
    async fn adopt(&mut self) -> bool {
        let Ok(Some(b)) = self.cluster.leases.get(self.tok.clone()).await else {
            return false;
        };
        match serde_json::from_slice::<Lease>(&b) {
            Ok(l) if l.taken_for(&self.host, self.request.id) => {
                tracing::info!(session = %self.request.session, worker = %l.worker, "placement reply lost; the lease names the worker");
                self.placed_on(l.worker);
                true
            }
            _ => false,
        }
    }

    /// Whether the session's lease is still held by the worker this front door placed it on.
    async fn lease_held(&self) -> bool {
        match self.cluster.leases.get(self.tok.clone()).await {
            Ok(Some(b)) => serde_json::from_slice::<Lease>(&b)
                .is_ok_and(|l| Some(&l.worker) == self.worker.as_ref()),
            Ok(None) => false,
            // NATS itself unreachable: no evidence the worker is gone.
            Err(_) => true,
        }
    }

    /// Places the session, forwards frames and answers, fails over, and ends it.
    async fn run(
        mut self,
        mut frames: mpsc::Receiver<PlacedFrame>,
        answers: mpsc::Sender<StepResult>,
        ready: oneshot::Sender<()>,
    ) {
        let settings = self.cluster.settings.clone();
        let client = self.cluster.client.clone();
        let (in_subj, out_subj) = (in_subject(&self.tok), out_subject(&self.tok));
        let (Ok(mut out), Ok(mut info)) = (
            client.subscribe(out_subj.clone()).await,
            client.subscribe(info_subject(&self.tok)).await,
        ) else {
            tracing::error!(session = %self.request.session, "NATS subscriptions failed: the session's frames are lost");
            return;
        };
        let live = LiveNotice {
            description: self.request.description.clone(),
            rig: self.request.rig.clone(),
        };
        let live_bytes = encode_live(&live);
        let mut ready = Some(ready);
        let mut retry = tokio::time::interval(settings.retry_every);
        let mut sent = 0u64;
        let mut answered = 0u64;
        let mut progress = Instant::now();
        let mut placed = false;
        // Forward frames and answers; place (again) whenever the session has no worker.
        loop {
            tokio::select! {
                f = frames.recv() => {
                    let Some(f) = f else { break };
                    if sent == answered {
                        progress = Instant::now();
                    }
                    sent = f.n + 1;
                    let _ = client.publish(in_subj.clone(), encode_in_frame(f.n, &f.frame).into()).await;
                }
                m = out.next() => {
                    let Some(m) = m else { break };
                    if let Some(Out::Answer(a)) = decode_out(&m.payload) {
                        answered = answered.max(a.n + 1);
                        progress = Instant::now();
                        if answers.send(a).await.is_err() {
                            break;
                        }
                    }
                }
                r = info.next() => {
                    if let Some(reply) = r.and_then(|m| m.reply) {
                        let _ = client.publish(reply, live_bytes[1..].to_vec().into()).await;
                    }
                }
                _ = retry.tick() => {
                    if !placed {
                        placed = self.place_once(self.status.placements.get() > 0).await;
                        if placed {
                            progress = Instant::now();
                            // Followers learn of the session once; a failover changes nothing
                            // they see but a gap.
                            if self.status.placements.get() == 1 {
                                let _ = client.publish(out_subj.clone(), live_bytes.clone().into()).await;
                            }
                            if let Some(r) = ready.take() {
                                let _ = r.send(());
                            }
                        }
                    } else if sent > answered
                        && progress.elapsed() >= settings.stall_after
                        && !self.lease_held().await
                    {
                        tracing::warn!(session = %self.request.session, worker = ?self.worker, "worker gone (lease expired): placing the session again");
                        self.status.set_worker(None);
                        self.worker = None;
                        placed = false;
                    }
                }
            }
        }
        // The tracker is gone: tell the worker, then wait for its last answers.
        let _ = client.publish(in_subj, encode_in_end(sent).into()).await;
        if placed {
            let deadline = Instant::now() + settings.finish_wait;
            loop {
                let m = tokio::select! {
                    _ = tokio::time::sleep_until(deadline) => break,
                    m = out.next() => m,
                };
                let gone = match m.and_then(|m| decode_out(&m.payload)) {
                    Some(Out::Answer(a)) => answers.send(a).await.is_err(),
                    Some(Out::Done) => true,
                    _ => false,
                };
                if gone {
                    break;
                }
            }
        } else {
            let _ = self.cluster.state.purge(&self.tok).await;
        }
        let _ = client.publish(out_subj, encode_out_end().into()).await;
        let _ = client.flush().await;
    }
}

/// Follows a session hosted by another front door for this one's viewers, until `tx` closes.
async fn follow(cluster: Cluster, tok: String, tx: mpsc::Sender<Followed>) {
    let client = cluster.client.clone();
    let Ok(mut out) = client.subscribe(out_subject(&tok)).await else {
        return;
    };
    let mut ask = tokio::time::interval(Duration::from_millis(500));
    let mut live = false;
    loop {
        tokio::select! {
            _ = tx.closed() => break,
            _ = ask.tick(), if !live => {
                let asked = client.request(info_subject(&tok), Vec::new().into());
                if let Ok(Ok(m)) = tokio::time::timeout(OPEN_TIMEOUT, asked).await
                    && let Ok(n) = serde_json::from_slice::<LiveNotice>(&m.payload)
                {
                    live = true;
                    let _ = tx.send(Followed::Live { description: n.description, rig: n.rig }).await;
                }
            }
            m = out.next() => {
                let Some(m) = m else { break };
                match decode_out(&m.payload) {
                    Some(Out::Live(n)) if !live => {
                        live = true;
                        let _ = tx.send(Followed::Live { description: n.description, rig: n.rig }).await;
                    }
                    Some(Out::Answer(a)) if live => {
                        // A follower that cannot keep up drops frames (its viewers' queues would).
                        let _ = tx.try_send(Followed::Frame(a));
                    }
                    Some(Out::End) => {
                        live = false;
                        let _ = tx.send(Followed::End).await;
                    }
                    _ => {}
                }
            }
        }
    }
}
