//! `mimic worker`: claims sessions from the queue group, holds each by a renewed lease, steps
//! its frames in order, publishes the answers and checkpoints the retargeter.

use crate::codec::{
    In, Lease, OPEN, OpenReply, OpenRequest, Saved, WORKERS, decode_in, encode_answer, encode_done,
    in_subject, out_subject, token,
};
use crate::{Cluster, ClusterError};
use bytes::Bytes;
use futures_util::StreamExt;
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_stream::Catalog;
use mimic_wire::encode_frame;
use serde::Serialize;
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use tokio::sync::watch;

/// Counters of a worker.
#[derive(Debug, Default)]
struct Counters {
    sessions_active: AtomicUsize,
    sessions_taken: AtomicU64,
    sessions_resumed: AtomicU64,
    frames: AtomicU64,
    refused: AtomicU64,
    leases_lost: AtomicU64,
}

/// A worker's counters, as it prints them on exit.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WorkerStats {
    /// Sessions held now.
    pub sessions_active: u64,
    /// Sessions taken (new and resumed).
    pub sessions_taken: u64,
    /// Of those, sessions resumed from another worker's checkpoint.
    pub sessions_resumed: u64,
    /// Frames stepped.
    pub frames: u64,
    /// Placement requests declined (full, unknown rig or layout, lease held).
    pub refused: u64,
    /// Sessions stopped because their lease could not be renewed.
    pub leases_lost: u64,
}

impl WorkerStats {
    /// The line `mimic worker` ends with.
    pub fn summary(&self) -> String {
        format!(
            "mimic worker: {} sessions taken ({} resumed), {} frames",
            self.sessions_taken, self.sessions_resumed, self.frames
        )
    }
}

/// A worker process's sessions.
#[derive(Debug)]
pub struct Worker {
    cluster: Cluster,
    catalog: Arc<Catalog>,
    retarget: RetargetSettings,
    name: String,
    max_sessions: usize,
    counters: Arc<Counters>,
}

impl Worker {
    /// A worker named `name` stepping sessions of the catalog's rigs and layouts, at most
    /// `max_sessions` at once.
    pub fn new(
        cluster: Cluster,
        catalog: Arc<Catalog>,
        retarget: RetargetSettings,
        name: &str,
        max_sessions: usize,
    ) -> Self {
        Self {
            cluster,
            catalog,
            retarget: RetargetSettings {
                positions: false,
                normals: false,
                ..retarget
            },
            name: name.to_string(),
            max_sessions,
            counters: Arc::default(),
        }
    }

    /// The counters now.
    pub fn stats(&self) -> WorkerStats {
        let c = &self.counters;
        WorkerStats {
            sessions_active: c.sessions_active.load(Ordering::Relaxed) as u64,
            sessions_taken: c.sessions_taken.load(Ordering::Relaxed),
            sessions_resumed: c.sessions_resumed.load(Ordering::Relaxed),
            frames: c.frames.load(Ordering::Relaxed),
            refused: c.refused.load(Ordering::Relaxed),
            leases_lost: c.leases_lost.load(Ordering::Relaxed),
        }
    }

    /// Takes sessions until `shutdown` completes; then checkpoints every session and gives its
    /// lease up, so that another worker takes it over at once.
    pub async fn run(&self, shutdown: impl Future<Output = ()>) -> Result<(), ClusterError> {
        let client = &self.cluster.client;
        let mut requests = client
            .queue_subscribe(OPEN, WORKERS.into())
            .await
            .map_err(|e| ClusterError::Subscribe {
                subject: OPEN.into(),
                message: e.to_string(),
            })?;
        let (stop_tx, stop_rx) = watch::channel(false);
        let mut tasks = tokio::task::JoinSet::new();
        tokio::pin!(shutdown);
        tracing::info!(worker = %self.name, "worker ready");
        loop {
            let m = tokio::select! {
                _ = &mut shutdown => break,
                m = requests.next() => m,
            };
            let Some(m) = m else { break };
            let Some(reply_to) = m.reply.clone() else {
                continue;
            };
            let reply = match serde_json::from_slice::<OpenRequest>(&m.payload) {
                Ok(req) => self.open(req, &mut tasks, stop_rx.clone()).await,
                Err(e) => self.refuse(format!("bad request: {e}")),
            };
            let body = serde_json::to_vec(&reply).unwrap_or_default();
            if let Err(e) = client.publish(reply_to, body.into()).await {
                tracing::warn!("placement reply not sent: {e}");
            }
            while tasks.try_join_next().is_some() {}
        }
        let _ = stop_tx.send(true);
        while tasks.join_next().await.is_some() {}
        let _ = client.flush().await;
        Ok(())
    }

    /// A declined placement.
    fn refuse(&self, why: String) -> OpenReply {
        self.counters.refused.fetch_add(1, Ordering::Relaxed);
        OpenReply {
            ok: false,
            worker: self.name.clone(),
            why,
            restored: false,
        }
    }

    /// Takes session `req` when this worker can: lease first, then the checkpoint (on a resume)
    /// and the input subscription, all before the reply, so that no frame sent after it is missed.
    async fn open(
        &self,
        req: OpenRequest,
        tasks: &mut tokio::task::JoinSet<()>,
        stop: watch::Receiver<bool>,
    ) -> OpenReply {
        let c = &self.counters;
        if c.sessions_active.load(Ordering::Acquire) >= self.max_sessions {
            return self.refuse(format!("full: {} sessions", self.max_sessions));
        }
        let Some(entry) = self.catalog.rig(Some(&req.rig)).cloned() else {
            return self.refuse(format!("no rig `{}`", req.rig));
        };
        let Some(layout) = self.catalog.layout(&req.layout) else {
            return self.refuse(format!("no layout `{}`", req.layout));
        };
        let mut retargeter = match Retargeter::new(
            &entry.rig,
            layout,
            entry.basis.clone(),
            self.retarget.clone(),
        ) {
            Ok(r) => r,
            Err(e) => return self.refuse(e.to_string()),
        };
        let tok = token(&req.session);
        let lease = Lease {
            worker: self.name.clone(),
            host: req.host.clone(),
            id: req.id,
        };
        let lease = Bytes::from(serde_json::to_vec(&lease).unwrap_or_default());
        let revision = match self.cluster.leases.create(&tok, lease.clone()).await {
            Ok(r) => r,
            Err(e) => return self.refuse(format!("lease of `{}`: {e}", req.session)),
        };
        let mut restored = false;
        if req.resume {
            match self.cluster.state.get(tok.clone()).await {
                Ok(Some(b)) => match serde_json::from_slice::<Saved>(&b) {
                    Ok(saved) => match retargeter.restore(&saved.checkpoint) {
                        Ok(()) => {
                            restored = true;
                            tracing::info!(session = %req.session, after = saved.n, "checkpoint restored");
                        }
                        Err(e) => {
                            tracing::warn!(session = %req.session, "checkpoint not restored: {e}")
                        }
                    },
                    Err(e) => tracing::warn!(session = %req.session, "checkpoint unreadable: {e}"),
                },
                Ok(None) => {
                    tracing::info!(session = %req.session, "no checkpoint: starting afresh")
                }
                Err(e) => tracing::warn!(session = %req.session, "checkpoint not read: {e}"),
            }
        } else {
            let _ = self.cluster.state.purge(&tok).await;
        }
        let frames = match self.cluster.client.subscribe(in_subject(&tok)).await {
            Ok(s) => s,
            Err(e) => {
                let _ = self.cluster.leases.delete(&tok).await;
                return self.refuse(format!("subscribe: {e}"));
            }
        };
        c.sessions_active.fetch_add(1, Ordering::AcqRel);
        c.sessions_taken.fetch_add(1, Ordering::Relaxed);
        if req.resume {
            c.sessions_resumed.fetch_add(1, Ordering::Relaxed);
        }
        tracing::info!(session = %req.session, worker = %self.name, resume = req.resume, "session taken");
        let held = Held {
            cluster: self.cluster.clone(),
            counters: self.counters.clone(),
            session: req.session,
            tok,
            lease,
            revision,
            retargeter,
        };
        tasks.spawn(held.run(frames, stop));
        OpenReply {
            ok: true,
            worker: self.name.clone(),
            why: String::new(),
            restored,
        }
    }
}

/// One session this worker holds.
struct Held {
    cluster: Cluster,
    counters: Arc<Counters>,
    session: String,
    tok: String,
    lease: Bytes,
    revision: u64,
    retargeter: Retargeter,
}

/// How a held session ended.
enum Ending {
    /// Its front door ended it: lease and checkpoint go.
    Done,
    /// The lease could not be renewed: someone else may hold it; touch nothing.
    LeaseLost,
    /// This worker stops: checkpoint, then give the lease up.
    Shutdown,
}

impl Held {
    /// Steps the session's frames until it ends, renewing the lease and checkpointing.
    async fn run(mut self, mut frames: async_nats::Subscriber, mut stop: watch::Receiver<bool>) {
        let settings = self.cluster.settings.clone();
        let out = out_subject(&self.tok);
        let mut output = self.retargeter.new_output();
        let mut renew = tokio::time::interval(settings.renew_every);
        let mut save = tokio::time::interval(settings.checkpoint_every);
        let mut last_n = None;
        let mut saved_n = None;
        let ending = loop {
            tokio::select! {
                _ = stop.changed() => break Ending::Shutdown,
                _ = renew.tick() => {
                    match self.cluster.leases.update(&self.tok, self.lease.clone(), self.revision).await {
                        Ok(r) => self.revision = r,
                        Err(e) => {
                            tracing::warn!(session = %self.session, "lease lost: {e}");
                            break Ending::LeaseLost;
                        }
                    }
                }
                _ = save.tick() => {
                    if last_n != saved_n && let Some(n) = last_n {
                        self.checkpoint(n).await;
                        saved_n = last_n;
                    }
                }
                m = frames.next() => {
                    let Some(m) = m else { break Ending::LeaseLost };
                    match decode_in(&m.payload) {
                        Some(In::Frame(n, frame)) => {
                            let before = self.retargeter.stats();
                            let status = self.retargeter.step(&frame, &mut output);
                            let after = self.retargeter.stats();
                            self.counters.frames.fetch_add(1, Ordering::Relaxed);
                            let gated = after.gated > before.gated;
                            let jump = after.jumps > before.jumps && status == FrameStatus::Tracked;
                            let message = encode_frame(n, &output.view(), None);
                            let body = encode_answer(gated, jump, &message);
                            if let Err(e) = self.cluster.client.publish(out.clone(), body.into()).await {
                                tracing::warn!(session = %self.session, "answer not sent: {e}");
                            }
                            last_n = Some(n);
                        }
                        Some(In::End) => break Ending::Done,
                        None => tracing::warn!(session = %self.session, "unreadable frame message"),
                    }
                }
            }
        };
        drop(frames);
        match ending {
            Ending::Done => {
                let _ = self.cluster.client.publish(out, encode_done().into()).await;
                let _ = self.cluster.state.purge(&self.tok).await;
                let _ = self.cluster.leases.purge(&self.tok).await;
                tracing::info!(session = %self.session, "session done");
            }
            Ending::LeaseLost => {
                self.counters.leases_lost.fetch_add(1, Ordering::Relaxed);
            }
            Ending::Shutdown => {
                if let Some(n) = last_n {
                    self.checkpoint(n).await;
                }
                let _ = self.cluster.leases.purge(&self.tok).await;
                tracing::info!(session = %self.session, "session given up (worker stopping)");
            }
        }
        self.counters.sessions_active.fetch_sub(1, Ordering::AcqRel);
    }

    /// Stores the retargeter's state after frame `n`.
    async fn checkpoint(&self, n: u64) {
        let saved = Saved {
            n,
            checkpoint: self.retargeter.checkpoint(),
        };
        match serde_json::to_vec(&saved) {
            Ok(b) => {
                if let Err(e) = self.cluster.state.put(&self.tok, b.into()).await {
                    tracing::warn!(session = %self.session, "checkpoint not stored: {e}");
                }
            }
            Err(e) => tracing::warn!(session = %self.session, "checkpoint not encoded: {e}"),
        }
    }
}
