//! Live Link Face UDP intake (`mimic serve --livelink ADDR`): the iPhone app's packets
//! (`mimic_trackers::livelink`), one weights session per subject name, named `livelink-<subject>`,
//! opened on its first packet on the server's default rig (which needs morph targets), ended after
//! the idle timeout (or at shutdown). The 52 blendshape curves go through the server's name map
//! (`configs/namemaps/arkit.toml`: gain, offset, clamp) onto the rig's morph targets, as a weights
//! session's named weights do; the names the rig lacks are logged once per session, in one line.
//! Head yaw, pitch and roll (radians) become the frame's head pose, `Quat::from_euler(YXZ, yaw,
//! pitch, roll)`, sent to viewers as the landmark path's pose is. Every packet is counted: an
//! accepted frame (`frames`), a late one (`late`, `future`) in its session, an undecodable packet
//! in the server's `udp_bad_packets`. Nothing is sent back.

use super::admission::{Admission, Refusal, find_rig, open};
use super::session::{LineOutcome, Protocol, Session, TrackerLine, teardown};
use super::state::Shared;
use crate::catalog::RigEntry;
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::timing::FrameClock;
use glam::{EulerRot, Quat, Vec3};
use mimic_retarget::{FrameOutput, FrameStatus};
use mimic_trackers::livelink::{BLENDSHAPES, CURVE_NAMES, LiveLinkPacket, decode_packet};
use mimic_trackers::namemap::{Mapping, NameMap};
use mimic_types::HeadPose;
use serde_json::{Map, Value, json};
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};

/// A subject's first packet, as admission sees it.
#[derive(Debug)]
pub(crate) struct LiveLinkHello {
    subject: String,
    peer: SocketAddr,
}

/// One subject's weights session.
#[derive(Debug)]
pub(crate) struct LiveLink {
    namemap: Arc<NameMap>,
    mapping: Mapping,
    /// Rig morph-target indices of each mapping target.
    routes: Vec<Vec<usize>>,
    values: [f32; BLENDSHAPES],
    mapped: Vec<f32>,
    weights: Vec<f32>,
    out: FrameOutput,
    positions: Vec<Vec3>,
    clock: FrameClock,
    first_us: Option<i64>,
    started: Instant,
    last_packet: Instant,
}

impl LiveLink {
    /// Maps, poses and broadcasts one packet.
    fn accept(&mut self, s: &Session, p: &LiveLinkPacket, arrival: Instant) {
        self.last_packet = arrival;
        let Some(morph) = s.rig.morph.as_ref() else {
            return;
        };
        // The frame time, or the arrival time for a packet without a usable rate.
        let now_us = i64::try_from(arrival.duration_since(self.started).as_micros()).unwrap_or(0);
        let t = p.time_us().unwrap_or(now_us);
        let t0 = *self.first_us.get_or_insert(t);
        let t_us = t.saturating_sub(t0);
        if s.check_time(&mut self.clock, t_us, arrival).is_err() {
            return;
        }
        self.values.copy_from_slice(&p.curves[..BLENDSHAPES]);
        self.mapping
            .apply(&self.namemap, &self.values, &mut self.mapped);
        self.weights.iter_mut().for_each(|w| *w = 0.0);
        for (t, rig) in self.routes.iter().enumerate() {
            for &k in rig {
                if let (Some(w), Some(v)) = (self.weights.get_mut(k), self.mapped.get(t)) {
                    *w = *v;
                }
            }
        }
        mimic_solve::morph_basis::morph_controls(&self.weights, &mut self.out.displacements);
        let [yaw, pitch, roll] = p.head_rotation();
        let rotation = if yaw.is_finite() && pitch.is_finite() && roll.is_finite() {
            Quat::from_euler(EulerRot::YXZ, yaw, pitch, roll)
        } else {
            Quat::IDENTITY
        };
        self.out.pose.rotation = rotation;
        self.out.target_rotation = rotation;
        self.out.timestamp_us = t_us;
        s.record.tracked.bump();
        let seq = s.next_seq(true);
        let rest = &s.rig.rig.mesh.positions;
        let weights = &self.weights;
        s.broadcast(
            seq,
            &self.out,
            &mut self.positions,
            |_, positions| morph.blend(rest, weights, positions),
            arrival,
        );
    }
}

impl Protocol for LiveLink {
    type Hello = LiveLinkHello;
    type Admitted = LiveLinkHello;
    type Event = Infallible;
    const KIND: &'static str = "livelink";

    fn admit(shared: &Shared, hello: LiveLinkHello) -> Result<Admission<LiveLinkHello>, Refusal> {
        let rig = find_rig(shared, None)?;
        let Some(morph) = rig.morph.as_ref() else {
            return Err(Refusal::NoMorphTargets {
                rig: rig.name().to_string(),
            });
        };
        let safe: String = hello
            .subject
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .take(64)
            .collect();
        Ok(Admission {
            session: Some(format!("livelink-{safe}")),
            rig_message: morph.message.clone(),
            rig,
            layout: "weights".into(),
            admitted: hello,
        })
    }

    fn describe(hello: &LiveLinkHello, rig: &RigEntry, name: &str, id: u32) -> Value {
        let k = rig.morph.as_ref().map_or(0, |m| m.len());
        json!({
            "session": name, "session_id": id, "rig": rig.name(), "layout": null,
            "mode": "weights", "targets": k,
            "vertices": rig.rig.mesh.vertex_count(), "controls": 3 * k,
            "source": format!("Live Link Face `{}` from {}", hello.subject, hello.peer),
            "rate_hz": Value::Null,
        })
    }

    async fn start(hello: LiveLinkHello, s: &Session) -> (Self, Value) {
        let namemap = s
            .settings()
            .livelink
            .as_ref()
            .map(|l| l.namemap.clone())
            .unwrap_or_default();
        let mapping = namemap.resolve(&CURVE_NAMES[..BLENDSHAPES]);
        let morph = s.rig.morph.as_ref();
        let k = morph.map_or(0, |m| m.len());
        let mut probe = vec![0.0f32; k];
        let mut lacking = Vec::new();
        let routes: Vec<Vec<usize>> = mapping
            .targets
            .iter()
            .map(|t| {
                let Some(m) = morph else { return Vec::new() };
                m.map.apply([(t.as_str(), 1.0)], &mut probe);
                let hit: Vec<usize> = (0..k).filter(|&i| probe[i] > 0.0).collect();
                if hit.is_empty() {
                    lacking.push(t.as_str());
                }
                hit
            })
            .collect();
        if !lacking.is_empty() {
            tracing::info!(session = %s.name, "rig `{}` has no morph target for {} of the {} mapped names (ignored): {}",
                s.rig.name(), lacking.len(), mapping.targets.len(), lacking.join(", "));
        }
        tracing::info!(session = %s.name, id = s.id, subject = %hello.subject, peer = %hello.peer, "livelink session started");
        let proto = LiveLink {
            mapped: vec![0.0; mapping.targets.len()],
            mapping,
            namemap,
            routes,
            values: [0.0; BLENDSHAPES],
            weights: vec![0.0; k],
            out: FrameOutput {
                timestamp_us: 0,
                status: FrameStatus::Tracked,
                positions: Vec::new(),
                normals: Vec::new(),
                displacements: vec![Vec3::ZERO; 3 * k],
                pose: HeadPose::default(),
                target_rotation: Quat::IDENTITY,
                filled: 0,
                times: Default::default(),
            },
            positions: s.rig.rig.mesh.positions.clone(),
            clock: s.clock(),
            first_us: None,
            started: Instant::now(),
            last_packet: Instant::now(),
        };
        (proto, json!({"type": "welcome", "session": s.name}))
    }

    async fn on_event(&mut self, _: &Session, event: Infallible) {
        match event {}
    }

    async fn on_line(&mut self, _: &Session, _: TrackerLine<'_>) -> LineOutcome {
        LineOutcome::Skipped
    }

    fn too_long(limit: usize) -> String {
        format!("packet longer than {limit} bytes")
    }

    async fn finish(self, _: &Session) {}

    fn summary(_: &ServerSettings, end: &SessionSnapshot, _bye: bool) -> Map<String, Value> {
        let mut m = Map::new();
        m.insert("unknown_weights".into(), json!(end.unknown_weights));
        m
    }
}

/// A live subject: its session and frame path.
struct Live {
    session: Session,
    proto: LiveLink,
    writer: tokio::task::JoinHandle<()>,
}

/// Ends a subject's session (END to its viewers).
async fn end(live: Live, reason: &str) {
    let Live {
        session,
        proto,
        writer,
    } = live;
    proto.finish(&session).await;
    teardown::<LiveLink>(session, reason.to_string(), writer).await;
}

/// Opens the session of a subject seen for the first time; `None` (counted as refused) when it
/// cannot be opened.
async fn open_subject(shared: &Arc<Shared>, subject: &str, peer: SocketAddr) -> Option<Live> {
    let (reply_tx, mut reply_rx) = mpsc::channel::<String>(4);
    let writer = tokio::spawn(async move { while reply_rx.recv().await.is_some() {} });
    let hello = LiveLinkHello {
        subject: subject.to_string(),
        peer,
    };
    match open::<LiveLink>(shared, hello, reply_tx) {
        Ok((session, admitted)) => {
            let (proto, _welcome) = LiveLink::start(admitted, &session).await;
            Some(Live {
                session,
                proto,
                writer,
            })
        }
        Err(refusal) => {
            shared.refused.bump();
            tracing::warn!(subject, %peer, "livelink session refused: {refusal}");
            writer.abort();
            None
        }
    }
}

/// Receives Live Link Face packets until shutdown, one session per subject name.
async fn livelink_loop(
    shared: Arc<Shared>,
    udp: UdpSocket,
    mut stop: watch::Receiver<bool>,
    done: mpsc::Sender<()>,
) {
    let mut buf = vec![0u8; 65_536];
    let mut subjects: HashMap<String, Live> = HashMap::new();
    let idle = shared.settings.idle_timeout;
    let mut tick =
        tokio::time::interval(Duration::from_millis(100).min(idle.max(Duration::from_millis(1))));
    loop {
        let got = tokio::select! {
            _ = stop.changed() => break,
            _ = tick.tick() => {
                let now = Instant::now();
                let idle_names: Vec<String> = subjects
                    .iter()
                    .filter(|(_, l)| now.duration_since(l.proto.last_packet) >= idle)
                    .map(|(n, _)| n.clone())
                    .collect();
                for n in idle_names {
                    if let Some(live) = subjects.remove(&n) {
                        end(live, "idle_timeout").await;
                    }
                }
                continue;
            }
            r = udp.recv_from(&mut buf) => r,
        };
        let Ok((len, peer)) = got else { continue };
        let arrival = Instant::now();
        let Ok(p) = decode_packet(buf.get(..len).unwrap_or_default()) else {
            shared.udp_bad.bump();
            continue;
        };
        let live = match subjects.entry(p.subject.clone()) {
            Entry::Occupied(e) => e.into_mut(),
            Entry::Vacant(e) => match open_subject(&shared, &p.subject, peer).await {
                Some(live) => e.insert(live),
                None => continue,
            },
        };
        live.proto.accept(&live.session, &p, arrival);
    }
    for (_, live) in subjects.drain() {
        end(live, "shutdown").await;
    }
    drop(done);
}

/// Starts the Live Link intake when the settings hold its socket.
pub(crate) fn spawn(shared: &Arc<Shared>, stop: &watch::Receiver<bool>, done: &mpsc::Sender<()>) {
    let Some(intake) = shared.settings.livelink.as_ref() else {
        return;
    };
    let udp = intake.socket.try_clone().and_then(|s| {
        s.set_nonblocking(true)?;
        UdpSocket::from_std(s)
    });
    match udp {
        Ok(udp) => {
            tokio::spawn(livelink_loop(
                shared.clone(),
                udp,
                stop.clone(),
                done.clone(),
            ));
        }
        Err(e) => tracing::error!("Live Link socket unusable: {e}"),
    }
}
