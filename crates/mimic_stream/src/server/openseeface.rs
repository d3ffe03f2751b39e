//! OpenSeeFace UDP intake (`mimic serve --openseeface ADDR`): OpenSeeFace's own datagrams
//! (`mimic_trackers::openseeface`), one session per face id, named `openseeface-<id>`, opened on
//! that face's first packet with the `openseeface68` layout and the server's default rig, ended
//! after the idle timeout (or at shutdown). Each face's pose-free 3D points, placed with its head
//! pose (`mimic_trackers::osf_pose`: the quaternion corrected and refined on the 2D landmarks),
//! become a landmark frame (`mimic_trackers::osf_frames`) timed by the datagram's timestamp from
//! the session's first, retargeted, broadcast to the session's viewers and, with a record folder,
//! recorded, as a landmark session's UDP frames are. Every packet is counted: a frame accepted (`frames`), late
//! or from the future (`late`, `future`) or refused by the pipeline (`malformed`) in its session,
//! an undecodable datagram in the server's `udp_bad_packets`. OpenSeeFace sends no hello and reads
//! no reply, so nothing is sent back.

use super::admission::{Admission, Refusal, find_rig};
use super::intake::UdpTracker;
use super::session::{LineOutcome, Protocol, Session, TrackerLine};
use super::state::Shared;
use crate::catalog::RigEntry;
use crate::record::{RecordKind, Recorder, SessionLabel};
use crate::settings::ServerSettings;
use crate::stats::SessionSnapshot;
use crate::sync::lock;
use crate::timing::FrameClock;
use glam::Vec3;
use mimic_capture::{RecordedFrame, RecordingHeader};
use mimic_retarget::{FrameOutput, FrameStatus, RetargetSettings, Retargeter};
use mimic_trackers::openseeface::{FACE_BYTES, OsfFace, decode_face};
use mimic_trackers::osf_frames::{LAYOUT, POINT_COUNT, fill_frame};
use mimic_types::LandmarkFrame;
use serde_json::{Map, Value, json};
use std::convert::Infallible;
use std::net::SocketAddr;
use std::time::Instant;

/// A face's first packet, as admission sees it.
#[derive(Debug)]
pub(crate) struct OsfHello {
    face_id: i32,
    peer: SocketAddr,
}

/// What admission found: the face and a retargeter for the default rig.
#[derive(Debug)]
pub(crate) struct OsfAdmitted {
    face_id: i32,
    peer: SocketAddr,
    retargeter: Retargeter,
}

/// One face's session: its frame path and recording.
#[derive(Debug)]
pub(crate) struct OpenSeeFace {
    retargeter: Retargeter,
    out: FrameOutput,
    frame: LandmarkFrame,
    positions: Vec<Vec3>,
    scratch: Vec<Vec3>,
    clock: FrameClock,
    first_timestamp: Option<f64>,
    recorder: Option<Recorder>,
    last_packet: Instant,
}

impl OpenSeeFace {
    /// Retargets, broadcasts and records one face of a datagram.
    async fn take(&mut self, s: &Session, face: &OsfFace, arrival: Instant) {
        self.last_packet = arrival;
        let t0 = *self.first_timestamp.get_or_insert(face.timestamp);
        let t_us = (face.timestamp - t0) * 1e6;
        if !t_us.is_finite() || t_us.abs() > 9e15 {
            s.record.malformed.bump();
            return;
        }
        fill_frame(face, t_us.round() as i64, &mut self.frame);
        if s.check_time(&mut self.clock, self.frame.timestamp_us, arrival)
            .is_err()
        {
            return;
        }
        let status = self.retargeter.step(&self.frame, &mut self.out);
        let r = &s.record;
        match status {
            FrameStatus::Tracked => r.tracked.bump(),
            FrameStatus::Calibrating => r.calibrating.bump(),
            FrameStatus::Lost => r.lost.bump(),
            FrameStatus::Rejected => {
                r.malformed.bump();
                return;
            }
        }
        let seq = s.next_seq(true);
        let (rig, scratch) = (&s.rig, &mut self.scratch);
        s.broadcast(
            seq,
            &self.out,
            &mut self.positions,
            |d, positions| rig.deform(d, scratch, positions),
            arrival,
        );
        if let Some(rec) = &self.recorder {
            rec.record(RecordedFrame::unlabelled(self.frame.clone()))
                .await;
        }
    }
}

impl Protocol for OpenSeeFace {
    type Hello = OsfHello;
    type Admitted = OsfAdmitted;
    type Event = Infallible;
    const KIND: &'static str = "openseeface";

    fn admit(shared: &Shared, hello: OsfHello) -> Result<Admission<OsfAdmitted>, Refusal> {
        let Some(layout) = shared.catalog.layout(LAYOUT) else {
            return Err(Refusal::UnknownLayout {
                layout: LAYOUT.into(),
            });
        };
        let entry = find_rig(shared, None)?;
        let retarget = RetargetSettings {
            positions: false,
            normals: false,
            ..shared.settings.retarget.clone()
        };
        let retargeter = Retargeter::new(&entry.rig, layout, entry.basis.clone(), retarget)
            .map_err(|e| Refusal::LayoutUnusable(e.to_string()))?;
        Ok(Admission {
            session: Some(format!("openseeface-{}", hello.face_id)),
            rig_message: entry.message.clone(),
            rig: entry,
            layout: LAYOUT.into(),
            admitted: OsfAdmitted {
                face_id: hello.face_id,
                peer: hello.peer,
                retargeter,
            },
        })
    }

    fn describe(a: &OsfAdmitted, rig: &RigEntry, name: &str, id: u32) -> Value {
        json!({
            "session": name, "session_id": id, "rig": rig.name(), "layout": LAYOUT,
            "vertices": rig.rig.mesh.vertex_count(), "controls": rig.rig.controls.len(),
            "source": format!("OpenSeeFace UDP from {}, face {}", a.peer, a.face_id),
            "rate_hz": Value::Null,
        })
    }

    async fn start(a: OsfAdmitted, s: &Session) -> (Self, Value) {
        let settings = s.settings();
        let mut recorder = None;
        if let Some(dir) = settings.record_dir.as_ref() {
            let source = format!("OpenSeeFace UDP from {}, face {}", a.peer, a.face_id);
            let header = RecordingHeader::new(LAYOUT, &source, 30.0, Some(POINT_COUNT));
            let who = SessionLabel {
                name: &s.name,
                id: s.id,
                rig: s.rig.name(),
                peer: Some(a.peer),
            };
            match Recorder::start(
                dir,
                RecordKind::Landmarks(&header),
                &who,
                settings.record_queue_frames,
                s.record.record.clone(),
                s.shared.recordings_open.clone(),
            )
            .await
            {
                Ok(r) => {
                    *lock(&s.record.recording) = Some(r.path().display().to_string());
                    recorder = Some(r);
                }
                Err(e) => tracing::error!(session = %s.name, "not recorded: {e}"),
            }
        }
        tracing::info!(session = %s.name, id = s.id, face = a.face_id, peer = %a.peer, "openseeface session started");
        let proto = OpenSeeFace {
            positions: s.rig.rig.mesh.positions.clone(),
            scratch: Vec::new(),
            out: a.retargeter.new_output(),
            retargeter: a.retargeter,
            frame: LandmarkFrame {
                timestamp_us: 0,
                points: Vec::with_capacity(POINT_COUNT),
                valid: Vec::with_capacity(POINT_COUNT),
                tracked: false,
            },
            clock: s.clock(),
            first_timestamp: None,
            recorder,
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
        format!("datagram longer than {limit} bytes")
    }

    async fn finish(self, _: &Session) {
        if let Some(r) = self.recorder {
            r.finish().await;
        }
    }

    fn summary(settings: &ServerSettings, end: &SessionSnapshot, _bye: bool) -> Map<String, Value> {
        let mut m = Map::new();
        let recorded = settings.record_dir.is_some().then_some(end.recorded);
        m.insert("recorded".into(), json!(recorded));
        m
    }
}

impl UdpTracker for OpenSeeFace {
    type Key = i32;
    type Unit = OsfFace;
    type Decoder = OsfFace;
    const INTAKE: &'static str = "OpenSeeFace";

    fn socket(settings: &ServerSettings) -> Option<&std::net::UdpSocket> {
        settings.openseeface.as_deref()
    }

    fn blocks(datagram: &[u8]) -> Option<impl Iterator<Item = &[u8]> + Send> {
        let whole = !datagram.is_empty() && datagram.len().is_multiple_of(FACE_BYTES);
        whole.then(|| datagram.chunks_exact(FACE_BYTES))
    }

    fn decode<'d>(face: &'d mut OsfFace, block: &[u8]) -> Option<&'d OsfFace> {
        decode_face(block, face).ok().map(|()| &*face)
    }

    fn key(face: &OsfFace) -> i32 {
        face.face_id
    }

    fn time(face: &OsfFace) -> Option<f64> {
        Some(face.timestamp)
    }

    fn restart(&mut self, s: &Session) {
        self.first_timestamp = None;
        self.clock = s.clock();
    }

    fn hello(face: &OsfFace, peer: SocketAddr) -> (OsfHello, String) {
        let what = format!("openseeface face {} from {peer}", face.face_id);
        let hello = OsfHello {
            face_id: face.face_id,
            peer,
        };
        (hello, what)
    }

    fn last_packet(&self) -> Instant {
        self.last_packet
    }

    async fn accept(&mut self, s: &Session, face: &OsfFace, arrival: Instant) {
        self.take(s, face, arrival).await;
    }
}
