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

use super::admission::{Admission, Refusal, find_rig};
use super::intake::UdpTracker;
use super::session::{LineOutcome, Protocol, Session, TrackerLine};
use super::state::Shared;
use super::weights::{MorphFrame, describe_weights, morph_targets, weights_summary};
use crate::catalog::RigEntry;
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::timing::FrameClock;
use glam::{EulerRot, Quat};
use mimic_trackers::livelink::{BLENDSHAPES, CURVE_NAMES, LiveLinkPacket, decode_packet};
use mimic_trackers::namemap::{Mapping, NameMap};
use serde_json::{Map, Value, json};
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Instant;

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
    frame: MorphFrame,
    clock: FrameClock,
    first_us: Option<i64>,
    started: Instant,
    last_packet: Instant,
}

impl LiveLink {
    /// Maps, poses, broadcasts and records one packet.
    async fn take(&mut self, s: &Session, p: &LiveLinkPacket, arrival: Instant) {
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
        let weights = &mut self.frame.weights;
        weights.iter_mut().for_each(|w| *w = 0.0);
        for (t, rig) in self.routes.iter().enumerate() {
            for &k in rig {
                if let (Some(w), Some(v)) = (weights.get_mut(k), self.mapped.get(t)) {
                    *w = *v;
                }
            }
        }
        let [yaw, pitch, roll] = p.head_rotation();
        let rotation = if yaw.is_finite() && pitch.is_finite() && roll.is_finite() {
            Quat::from_euler(EulerRot::YXZ, yaw, pitch, roll)
        } else {
            Quat::IDENTITY
        };
        if let Some(c) = self.frame.curves.as_mut() {
            **c = p.curves;
        }
        self.frame
            .keep(s, morph, t_us, rotation, true, arrival)
            .await;
    }
}

impl Protocol for LiveLink {
    type Hello = LiveLinkHello;
    type Admitted = LiveLinkHello;
    type Event = Infallible;
    const KIND: &'static str = "livelink";

    fn admit(shared: &Shared, hello: LiveLinkHello) -> Result<Admission<LiveLinkHello>, Refusal> {
        let rig = find_rig(shared, None)?;
        let morph = morph_targets(&rig)?;
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
        let source = format!("Live Link Face `{}` from {}", hello.subject, hello.peer);
        describe_weights(rig, name, id, json!(source), Value::Null)
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
        let mut frame = MorphFrame::start(s, Some(hello.peer), None).await;
        // Forwarded as they came: every curve, also those the rig lacks.
        frame.curves = Some(Box::new([0.0; mimic_trackers::livelink::CURVES]));
        let proto = LiveLink {
            mapped: vec![0.0; mapping.targets.len()],
            mapping,
            namemap,
            routes,
            values: [0.0; BLENDSHAPES],
            frame,
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

    async fn finish(self, _: &Session) {
        self.frame.finish().await;
    }

    fn summary(settings: &ServerSettings, end: &SessionSnapshot, bye: bool) -> Map<String, Value> {
        weights_summary(settings, end, bye)
    }
}

impl UdpTracker for LiveLink {
    type Key = String;
    type Unit = LiveLinkPacket;
    type Decoder = Option<LiveLinkPacket>;
    const INTAKE: &'static str = "Live Link";

    fn socket(settings: &ServerSettings) -> Option<&std::net::UdpSocket> {
        settings.livelink.as_ref().map(|l| &*l.socket)
    }

    fn blocks(datagram: &[u8]) -> Option<impl Iterator<Item = &[u8]> + Send> {
        Some(std::iter::once(datagram))
    }

    fn decode<'d>(decoder: &'d mut Self::Decoder, block: &[u8]) -> Option<&'d LiveLinkPacket> {
        *decoder = decode_packet(block).ok();
        decoder.as_ref()
    }

    fn key(p: &LiveLinkPacket) -> String {
        p.subject.clone()
    }

    fn time(p: &LiveLinkPacket) -> Option<f64> {
        p.time_us().map(|t| t as f64 / 1e6)
    }

    fn restart(&mut self, s: &Session) {
        self.first_us = None;
        self.clock = s.clock();
        self.started = Instant::now();
    }

    fn hello(p: &LiveLinkPacket, peer: SocketAddr) -> (LiveLinkHello, String) {
        let what = format!("livelink subject `{}` from {peer}", p.subject);
        let hello = LiveLinkHello {
            subject: p.subject.clone(),
            peer,
        };
        (hello, what)
    }

    fn last_packet(&self) -> Instant {
        self.last_packet
    }

    async fn accept(&mut self, s: &Session, p: &LiveLinkPacket, arrival: Instant) {
        self.take(s, p, arrival).await;
    }
}
