//! The wire protocol (`docs/protocol.md`): hello lines, tracker replies, viewer messages and UDP
//! frame packets. Pure encoding and decoding, no sockets.

use glam::{Quat, Vec3};
use mimic_capture::{FrameProblem, RecordingHeader};
use mimic_retarget::{FrameOutput, FrameStatus};
use mimic_solve::Basis;
use mimic_types::{HeadPose, LandmarkFrame, Rig};
use serde_json::{Value, json};

/// Viewer message kind: session description (JSON).
pub const KIND_SESSION: u8 = 1;
/// Viewer message kind: the rig (rest mesh, triangles, basis `B`).
pub const KIND_RIG: u8 = 2;
/// Viewer message kind: one frame (pose, `d`, optionally positions).
pub const KIND_FRAME: u8 = 3;
/// Viewer message kind: the session ended (JSON).
pub const KIND_END: u8 = 4;
/// Viewer message kind: an error (JSON); the server closes the connection after it.
pub const KIND_ERROR: u8 = 5;
/// First four bytes of a UDP frame packet.
pub const UDP_MAGIC: [u8; 4] = *b"MMF1";
/// Bytes of a UDP frame packet before the points.
pub const UDP_HEADER_BYTES: usize = 28;
/// Bytes of a frame message's fixed part (after length and kind) before `d`.
pub const FRAME_FIXED_BYTES: usize = 8 + 8 + 4 + 4 + 16 + 12 + 4 + 16;

/// Error codes the server sends (tracker reply lines and viewer error messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorCode {
    /// The first line is not a recording header, a viewer hello or a stats request.
    BadHello,
    /// A frame line is not a frame object (bad JSON, missing `t_us`, a point that is not 3 numbers).
    BadJson,
    /// The connection ended in the middle of a line.
    Truncated,
    /// A frame has the wrong number of points for the session's layout.
    PointCount,
    /// A point not listed invalid has a null or non-finite coordinate.
    BadCoordinate,
    /// `invalid` lists a point the frame does not have.
    BadInvalidIndex,
    /// A line longer than the maximum message size (the rest of it is skipped).
    TooLong,
    /// Nothing arrived for the idle timeout; the connection is closed.
    IdleTimeout,
    /// Too many malformed messages in a row; the connection is closed.
    TooManyErrors,
    /// The session limit is reached.
    TooManySessions,
    /// The viewer limit is reached.
    TooManyViewers,
    /// The hello names a rig the server does not have.
    UnknownRig,
    /// The hello names a layout the server does not have, or one the rig cannot use.
    UnknownLayout,
    /// A tracker is already feeding the named session.
    SessionBusy,
    /// The server is shutting down.
    ShuttingDown,
    /// A weight frame whose weights are not an object of numbers (`docs/protocol.md`).
    BadWeight,
    /// A weights session names a rig without morph targets.
    NoMorphTargets,
    /// A weight name that is no target of the rig (a warning, once per name; not an error).
    UnknownWeight,
    /// A frame's timestamp runs ahead of the last accepted one by more than the wall-clock time
    /// between them plus the allowed jump; the frame is dropped, the session goes on.
    FutureTimestamp,
}

impl ErrorCode {
    /// The code as it appears on the wire.
    pub fn name(self) -> &'static str {
        match self {
            ErrorCode::BadHello => "bad_hello",
            ErrorCode::BadJson => "bad_json",
            ErrorCode::Truncated => "truncated",
            ErrorCode::PointCount => "point_count",
            ErrorCode::BadCoordinate => "bad_coordinate",
            ErrorCode::BadInvalidIndex => "bad_invalid_index",
            ErrorCode::TooLong => "too_long",
            ErrorCode::IdleTimeout => "idle_timeout",
            ErrorCode::TooManyErrors => "too_many_errors",
            ErrorCode::TooManySessions => "too_many_sessions",
            ErrorCode::TooManyViewers => "too_many_viewers",
            ErrorCode::UnknownRig => "unknown_rig",
            ErrorCode::UnknownLayout => "unknown_layout",
            ErrorCode::SessionBusy => "session_busy",
            ErrorCode::ShuttingDown => "shutting_down",
            ErrorCode::BadWeight => "bad_weight",
            ErrorCode::NoMorphTargets => "no_morph_targets",
            ErrorCode::UnknownWeight => "unknown_weight",
            ErrorCode::FutureTimestamp => "future_timestamp",
        }
    }

    /// The code of a rejected frame line.
    pub fn of_problem(p: &FrameProblem) -> ErrorCode {
        match p {
            FrameProblem::Json { .. } => ErrorCode::BadJson,
            FrameProblem::Truncated { .. } => ErrorCode::Truncated,
            FrameProblem::PointCount { .. } => ErrorCode::PointCount,
            FrameProblem::BadCoordinate { .. } => ErrorCode::BadCoordinate,
            FrameProblem::InvalidIndexOutOfRange { .. } => ErrorCode::BadInvalidIndex,
            FrameProblem::TooLong { .. } => ErrorCode::TooLong,
            // Ordering is checked by the session (late frames are dropped, not answered).
            FrameProblem::TimeNotIncreasing { .. } | FrameProblem::Io { .. } => ErrorCode::BadJson,
        }
    }
}

/// What the first line of a TCP connection asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Hello {
    /// A tracker: the recording header, with the optional `session` and `rig` fields.
    Tracker {
        /// The header (layout, rate, ...).
        header: Box<RecordingHeader>,
        /// Session name to open (default: one the server makes up).
        session: Option<String>,
        /// Rig to drive (default: the server's default rig).
        rig: Option<String>,
    },
    /// A tracker that sends named blendshape weights (`{"mode":"weights"}`), not landmarks.
    Weights {
        /// Session name to open (default: one the server makes up).
        session: Option<String>,
        /// Rig to drive (default: the server's default rig); it must have morph targets.
        rig: Option<String>,
        /// Frame rate the tracker announces, if any.
        rate_hz: Option<f64>,
        /// Source the tracker announces (e.g. `arkit`), if any.
        source: Option<String>,
    },
    /// A viewer joining a session.
    Viewer {
        /// Session name.
        session: String,
        /// Also send full vertex positions each frame.
        positions: bool,
    },
    /// A request for the counters, answered with one JSON line.
    Stats,
    /// An HTTP `GET` (only `/stats` is served).
    HttpGet {
        /// The request path.
        path: String,
    },
}

/// Why a first line is not a valid hello.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum HelloError {
    /// Not JSON, or not an object.
    #[error(
        "the first line must be a JSON object (a recording header or a viewer/stats hello): {0}"
    )]
    NotJson(String),
    /// A recording header that fails its checks.
    #[error("bad recording header: {0}")]
    BadHeader(String),
    /// A session name that is empty, too long or has odd characters.
    #[error("bad session name `{0}`: 1 to 64 characters of A-Z a-z 0-9 _ . -")]
    BadSessionName(String),
    /// An object that is none of the known hellos.
    #[error("unknown hello: expected `format: mimic-recording`, `type: viewer` or `type: stats`")]
    Unknown,
}

/// True for a session name of 1 to 64 characters from `A-Z a-z 0-9 _ . -`.
pub fn valid_session_name(s: &str) -> bool {
    (1..=64).contains(&s.len())
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'-'))
}

/// Parses the first line of a connection (without its newline).
pub fn parse_hello(line: &[u8]) -> Result<Hello, HelloError> {
    let line = trim_end(line);
    if let Some(rest) = line.strip_prefix(b"GET ") {
        let path = rest.split(|b| *b == b' ').next().unwrap_or_default();
        return Ok(Hello::HttpGet {
            path: String::from_utf8_lossy(path).into_owned(),
        });
    }
    let v: Value = serde_json::from_slice(line).map_err(|e| HelloError::NotJson(e.to_string()))?;
    let Value::Object(obj) = &v else {
        return Err(HelloError::NotJson("not an object".into()));
    };
    if obj.contains_key("format") {
        let header: RecordingHeader =
            serde_json::from_value(v.clone()).map_err(|e| HelloError::BadHeader(e.to_string()))?;
        header.check().map_err(HelloError::BadHeader)?;
        let text = |k: &str| {
            header
                .extra
                .get(k)
                .and_then(Value::as_str)
                .map(str::to_string)
        };
        let session = text("session");
        if let Some(s) = &session
            && !valid_session_name(s)
        {
            return Err(HelloError::BadSessionName(s.clone()));
        }
        let rig = text("rig");
        return Ok(Hello::Tracker {
            header: Box::new(header),
            session,
            rig,
        });
    }
    if obj.get("mode").and_then(Value::as_str) == Some("weights") {
        let text = |k: &str| obj.get(k).and_then(Value::as_str).map(str::to_string);
        let session = text("session");
        if let Some(s) = &session
            && !valid_session_name(s)
        {
            return Err(HelloError::BadSessionName(s.clone()));
        }
        return Ok(Hello::Weights {
            session,
            rig: text("rig"),
            rate_hz: obj.get("rate_hz").and_then(Value::as_f64),
            source: text("source"),
        });
    }
    match obj.get("type").and_then(Value::as_str) {
        Some("viewer") => {
            let session = obj
                .get("session")
                .and_then(Value::as_str)
                .unwrap_or_default()
                .to_string();
            if !valid_session_name(&session) {
                return Err(HelloError::BadSessionName(session));
            }
            let positions = obj
                .get("positions")
                .and_then(Value::as_bool)
                .unwrap_or(false);
            Ok(Hello::Viewer { session, positions })
        }
        Some("stats") => Ok(Hello::Stats),
        _ => Err(HelloError::Unknown),
    }
}

/// One weight frame line: `{"t_us": .., "weights": {"name": value, ..}}`.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightFrame {
    /// Capture time (µs, the tracker's clock).
    pub timestamp_us: i64,
    /// `(name, value)` pairs in line order; values as sent (finite, not yet clamped).
    pub weights: Vec<(String, f64)>,
}

/// Why a weight frame line is rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum WeightFrameError {
    /// Not JSON (JSON has no NaN: a `NaN` literal lands here), not an object, or no integer `t_us`.
    #[error("{0}")]
    Json(String),
    /// `weights` missing or not an object, or a value that is not a number.
    #[error("{0}")]
    Weight(String),
}

impl WeightFrameError {
    /// The error code the session answers with.
    pub fn code(&self) -> ErrorCode {
        match self {
            WeightFrameError::Json(_) => ErrorCode::BadJson,
            WeightFrameError::Weight(_) => ErrorCode::BadWeight,
        }
    }
}

/// Parses a weight frame line (without its newline).
pub fn parse_weight_frame(line: &[u8]) -> Result<WeightFrame, WeightFrameError> {
    let v: Value = serde_json::from_slice(trim_end(line))
        .map_err(|e| WeightFrameError::Json(format!("invalid JSON: {e}")))?;
    let Value::Object(obj) = v else {
        return Err(WeightFrameError::Json(
            "a weight frame is a JSON object".into(),
        ));
    };
    let timestamp_us = obj
        .get("t_us")
        .and_then(Value::as_i64)
        .ok_or_else(|| WeightFrameError::Json("`t_us` must be an integer (µs)".into()))?;
    let Some(Value::Object(map)) = obj.get("weights") else {
        return Err(WeightFrameError::Weight(
            "`weights` must be an object of name: number".into(),
        ));
    };
    let mut weights = Vec::with_capacity(map.len());
    for (name, value) in map {
        match value.as_f64() {
            Some(x) if x.is_finite() => weights.push((name.clone(), x)),
            _ => {
                return Err(WeightFrameError::Weight(format!(
                    "weight `{name}` is {value}, not a number"
                )));
            }
        }
    }
    Ok(WeightFrame {
        timestamp_us,
        weights,
    })
}

/// A tracker warning line: `{"type":"warning","code":..,"line":..,"message":..}` and a newline.
pub fn warning_line(code: ErrorCode, line: u64, message: &str) -> String {
    let mut s = json!({"type": "warning", "code": code.name(), "line": line, "message": message})
        .to_string();
    s.push('\n');
    s
}

/// A tracker reply line: `{"type":"error","code":..,"line":..,"message":..}` and a newline.
pub fn error_line(code: ErrorCode, line: u64, message: &str) -> String {
    let mut s =
        json!({"type": "error", "code": code.name(), "line": line, "message": message}).to_string();
    s.push('\n');
    s
}

/// A viewer message: `u32` length of what follows, the kind byte, the payload.
fn message(kind: u8, payload_len: usize) -> Vec<u8> {
    let mut m = Vec::with_capacity(5 + payload_len);
    m.extend_from_slice(&((payload_len + 1) as u32).to_le_bytes());
    m.push(kind);
    m
}

/// A JSON viewer message (session, end, error).
pub fn encode_json(kind: u8, value: &Value) -> Vec<u8> {
    let text = value.to_string();
    let mut m = message(kind, text.len());
    m.extend_from_slice(text.as_bytes());
    m
}

/// The rig message: a JSON description, then rest positions, triangles and `B` as raw arrays.
pub fn encode_rig(rig: &Rig, basis: &Basis) -> Vec<u8> {
    let meta = json!({
        "name": rig.name,
        "units": rig.units,
        "vertices": rig.mesh.vertex_count(),
        "triangles": rig.mesh.triangles.len(),
        "controls": rig.controls.iter().map(|c| json!({
            "fdp": c.fdp.to_string(), "vertex": c.vertex, "region": c.region.name()
        })).collect::<Vec<_>>(),
        "regions": rig.regions,
    });
    encode_rig_parts(&meta, rig, basis)
}

/// The rig message of a weights session: `B` is the morph basis (three columns per target,
/// `mimic_solve::morph_basis`) and the JSON says `"mode":"weights"` and names the `targets` in
/// weight order (its `controls` list is empty: the columns are not control points).
pub fn encode_morph_rig(rig: &Rig, basis: &Basis, targets: &[String]) -> Vec<u8> {
    let meta = json!({
        "name": rig.name,
        "units": rig.units,
        "vertices": rig.mesh.vertex_count(),
        "triangles": rig.mesh.triangles.len(),
        "mode": "weights",
        "targets": targets,
        "controls": [],
        "regions": rig.regions,
    });
    encode_rig_parts(&meta, rig, basis)
}

fn encode_rig_parts(meta: &Value, rig: &Rig, basis: &Basis) -> Vec<u8> {
    let meta = meta.to_string();
    let n = rig.mesh.vertex_count();
    let t = rig.mesh.triangles.len();
    let m = basis.control_count();
    let len = 4 + meta.len() + 12 + n * 12 + t * 12 + n * m * 4;
    let mut out = message(KIND_RIG, len);
    out.extend_from_slice(&(meta.len() as u32).to_le_bytes());
    out.extend_from_slice(meta.as_bytes());
    for v in [n, t, m] {
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    for p in &rig.mesh.positions {
        put_vec3(&mut out, *p);
    }
    for tri in &rig.mesh.triangles {
        for i in tri {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    for w in basis.as_slice() {
        out.extend_from_slice(&w.to_le_bytes());
    }
    out
}

fn put_vec3(out: &mut Vec<u8>, v: Vec3) {
    for c in v.to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

/// Status byte of a frame message.
pub fn status_byte(s: FrameStatus) -> u8 {
    match s {
        FrameStatus::Calibrating => 0,
        FrameStatus::Tracked => 1,
        FrameStatus::Lost => 2,
        FrameStatus::Rejected => 3,
    }
}

/// A frame message: sequence number, time, status, pose, target rotation, `d`, and the
/// positions when given.
pub fn encode_frame(seq: u64, out: &FrameOutput, positions: Option<&[Vec3]>) -> Vec<u8> {
    let m = out.displacements.len();
    let n = positions.map_or(0, <[Vec3]>::len);
    let len = FRAME_FIXED_BYTES + m * 12 + positions.map_or(0, |_| 4 + n * 12);
    let mut b = message(KIND_FRAME, len);
    b.extend_from_slice(&seq.to_le_bytes());
    b.extend_from_slice(&out.timestamp_us.to_le_bytes());
    b.push(status_byte(out.status));
    b.push(u8::from(positions.is_some()));
    b.extend_from_slice(&[0, 0]);
    b.extend_from_slice(&(m as u32).to_le_bytes());
    for c in out.pose.rotation.to_array() {
        b.extend_from_slice(&c.to_le_bytes());
    }
    put_vec3(&mut b, out.pose.translation);
    b.extend_from_slice(&out.pose.scale.to_le_bytes());
    for c in out.target_rotation.to_array() {
        b.extend_from_slice(&c.to_le_bytes());
    }
    for d in &out.displacements {
        put_vec3(&mut b, *d);
    }
    if let Some(p) = positions {
        b.extend_from_slice(&(n as u32).to_le_bytes());
        for v in p {
            put_vec3(&mut b, *v);
        }
    }
    b
}

/// A decoded viewer message.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewerMessage {
    /// Session description.
    Session(Value),
    /// The rig.
    Rig(RigMessage),
    /// One frame.
    Frame(FrameMessage),
    /// The session ended.
    End(Value),
    /// An error; the connection closes after it.
    Error(Value),
}

/// The rig as a viewer receives it.
#[derive(Clone, Debug, PartialEq)]
pub struct RigMessage {
    /// JSON description (name, units, controls with regions, region bands).
    pub meta: Value,
    /// Rest positions.
    pub rest: Vec<Vec3>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Controls (columns of `B`).
    pub controls: usize,
    /// `B`, n x m row-major.
    pub basis: Vec<f32>,
}

/// One frame as a viewer receives it.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameMessage {
    /// Index of the frame in the session (accepted frames, from 0).
    pub seq: u64,
    /// Frame time (µs, the tracker's clock).
    pub timestamp_us: i64,
    /// 0 calibrating, 1 tracked, 2 lost, 3 rejected.
    pub status: u8,
    /// Head pose (source space).
    pub pose: HeadPose,
    /// Head rotation in target axes.
    pub target_rotation: Quat,
    /// Control displacements `d`, target units.
    pub displacements: Vec<Vec3>,
    /// Deformed positions, when the viewer asked for them.
    pub positions: Option<Vec<Vec3>>,
}

/// Why a viewer message cannot be decoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The payload ends before its fields do.
    #[error("message is {len} bytes, too short for its fields")]
    Short {
        /// Payload bytes.
        len: usize,
    },
    /// Unknown kind byte.
    #[error("unknown message kind {0}")]
    Kind(u8),
    /// A JSON part that does not parse.
    #[error("bad JSON in message: {0}")]
    Json(String),
    /// Wrong magic in a UDP packet.
    #[error("not a mimic frame packet (magic)")]
    Magic,
    /// A UDP packet whose size does not match its point count.
    #[error("packet is {len} bytes; {points} points need {expected}")]
    Size {
        /// Packet bytes.
        len: usize,
        /// Points the packet says it has.
        points: usize,
        /// Bytes that needs.
        expected: usize,
    },
    /// A UDP point with an infinite coordinate.
    #[error("point {0} has an infinite coordinate")]
    Infinite(usize),
}

/// Little-endian cursor over a payload.
struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, k: usize) -> Result<&'a [u8], DecodeError> {
        let s = self
            .b
            .get(self.at..self.at.saturating_add(k))
            .ok_or(DecodeError::Short { len: self.b.len() })?;
        self.at += k;
        Ok(s)
    }
    fn arr<const K: usize>(&mut self) -> Result<[u8; K], DecodeError> {
        let mut a = [0u8; K];
        a.copy_from_slice(self.take(K)?);
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.arr::<1>()?[0])
    }
    fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.arr()?))
    }
    fn count(&mut self) -> Result<usize, DecodeError> {
        let k = self.u32()? as usize;
        // Every counted item takes at least 4 bytes: refuse counts the payload cannot hold.
        if k > self.b.len() {
            return Err(DecodeError::Short { len: self.b.len() });
        }
        Ok(k)
    }
    fn u64(&mut self) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.arr()?))
    }
    fn i64(&mut self) -> Result<i64, DecodeError> {
        Ok(i64::from_le_bytes(self.arr()?))
    }
    fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_le_bytes(self.arr()?))
    }
    fn vec3(&mut self) -> Result<Vec3, DecodeError> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
    fn quat(&mut self) -> Result<Quat, DecodeError> {
        Ok(Quat::from_xyzw(
            self.f32()?,
            self.f32()?,
            self.f32()?,
            self.f32()?,
        ))
    }
    fn f32s(&mut self, k: usize) -> Result<Vec<f32>, DecodeError> {
        let bytes = self.take(k.checked_mul(4).ok_or(DecodeError::Short { len: k })?)?;
        Ok(bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }
    fn vec3s(&mut self, k: usize) -> Result<Vec<Vec3>, DecodeError> {
        let flat = self.f32s(k.checked_mul(3).ok_or(DecodeError::Short { len: k })?)?;
        Ok(flat
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect())
    }
}

fn json_of(b: &[u8]) -> Result<Value, DecodeError> {
    serde_json::from_slice(b).map_err(|e| DecodeError::Json(e.to_string()))
}

/// Decodes a viewer message from its kind byte and payload (what follows the kind).
pub fn decode_viewer_message(kind: u8, payload: &[u8]) -> Result<ViewerMessage, DecodeError> {
    let mut c = Cursor { b: payload, at: 0 };
    match kind {
        KIND_SESSION => Ok(ViewerMessage::Session(json_of(payload)?)),
        KIND_END => Ok(ViewerMessage::End(json_of(payload)?)),
        KIND_ERROR => Ok(ViewerMessage::Error(json_of(payload)?)),
        KIND_RIG => {
            let meta_len = c.count()?;
            let meta = json_of(c.take(meta_len)?)?;
            let (n, t, m) = (c.count()?, c.count()?, c.count()?);
            let rest = c.vec3s(n)?;
            let tri_bytes = c.take(t.checked_mul(12).ok_or(DecodeError::Short { len: t })?)?;
            let triangles = tri_bytes
                .chunks_exact(12)
                .map(|b| {
                    let u = |k: usize| u32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
                    [u(0), u(4), u(8)]
                })
                .collect();
            let basis = c.f32s(n.checked_mul(m).ok_or(DecodeError::Short { len: n })?)?;
            Ok(ViewerMessage::Rig(RigMessage {
                meta,
                rest,
                triangles,
                controls: m,
                basis,
            }))
        }
        KIND_FRAME => {
            let seq = c.u64()?;
            let timestamp_us = c.i64()?;
            let status = c.u8()?;
            let has_positions = c.u8()? != 0;
            c.take(2)?;
            let m = c.count()?;
            let rotation = c.quat()?;
            let translation = c.vec3()?;
            let scale = c.f32()?;
            let target_rotation = c.quat()?;
            let displacements = c.vec3s(m)?;
            let positions = if has_positions {
                let n = c.count()?;
                Some(c.vec3s(n)?)
            } else {
                None
            };
            Ok(ViewerMessage::Frame(FrameMessage {
                seq,
                timestamp_us,
                status,
                pose: HeadPose {
                    rotation,
                    translation,
                    scale,
                },
                target_rotation,
                displacements,
                positions,
            }))
        }
        k => Err(DecodeError::Kind(k)),
    }
}

/// A frame packet as sent over UDP.
#[derive(Clone, Debug, PartialEq)]
pub struct UdpFrame {
    /// Session id from the tracker's welcome line.
    pub session_id: u32,
    /// Session key from the welcome line.
    pub key: u32,
    /// The frame (NaN coordinates mark invalid points).
    pub frame: LandmarkFrame,
}

/// Encodes a UDP frame packet (invalid points are sent as NaN).
pub fn encode_udp_frame(session_id: u32, key: u32, frame: &LandmarkFrame) -> Vec<u8> {
    let mut b = Vec::with_capacity(UDP_HEADER_BYTES + frame.points.len() * 12);
    b.extend_from_slice(&UDP_MAGIC);
    b.extend_from_slice(&session_id.to_le_bytes());
    b.extend_from_slice(&key.to_le_bytes());
    b.extend_from_slice(&frame.timestamp_us.to_le_bytes());
    b.push(u8::from(frame.tracked));
    b.extend_from_slice(&[0, 0, 0]);
    b.extend_from_slice(&(frame.points.len() as u32).to_le_bytes());
    for (i, p) in frame.points.iter().enumerate() {
        put_vec3(&mut b, if frame.is_valid(i) { *p } else { Vec3::NAN });
    }
    b
}

/// Decodes a UDP frame packet; the point count is checked against the layout by the session.
pub fn decode_udp_frame(packet: &[u8]) -> Result<UdpFrame, DecodeError> {
    let mut c = Cursor { b: packet, at: 0 };
    if c.arr::<4>()? != UDP_MAGIC {
        return Err(DecodeError::Magic);
    }
    let session_id = c.u32()?;
    let key = c.u32()?;
    let timestamp_us = c.i64()?;
    let flags = c.u8()?;
    c.take(3)?;
    let points = c.u32()? as usize;
    let expected = points
        .checked_mul(12)
        .and_then(|b| b.checked_add(UDP_HEADER_BYTES));
    if expected != Some(packet.len()) {
        return Err(DecodeError::Size {
            len: packet.len(),
            points,
            expected: expected.unwrap_or(usize::MAX),
        });
    }
    let pts = c.vec3s(points)?;
    let mut valid = Vec::with_capacity(points);
    for (i, p) in pts.iter().enumerate() {
        if p.is_nan() {
            valid.push(false);
        } else if !p.is_finite() {
            return Err(DecodeError::Infinite(i));
        } else {
            valid.push(true);
        }
    }
    Ok(UdpFrame {
        session_id,
        key,
        frame: LandmarkFrame {
            timestamp_us,
            points: pts,
            valid,
            tracked: flags & 1 != 0,
        },
    })
}

fn trim_end(b: &[u8]) -> &[u8] {
    let mut end = b.len();
    while end > 0 && matches!(b[end - 1], b'\n' | b'\r') {
        end -= 1;
    }
    &b[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hello_kinds() {
        let h = br#"{"format":"mimic-recording","version":1,"layout":"ibug68","units":"m","source":"x","rate_hz":30,"session":"a","rig":"candide3"}"#;
        match parse_hello(h).unwrap() {
            Hello::Tracker {
                header,
                session,
                rig,
            } => {
                assert_eq!(header.layout, "ibug68");
                assert_eq!(session.as_deref(), Some("a"));
                assert_eq!(rig.as_deref(), Some("candide3"));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            parse_hello(br#"{"type":"viewer","session":"a","positions":true}"#).unwrap(),
            Hello::Viewer {
                session: "a".into(),
                positions: true
            }
        );
        assert_eq!(
            parse_hello(b"{\"type\":\"stats\"}\r\n").unwrap(),
            Hello::Stats
        );
        assert_eq!(
            parse_hello(b"GET /stats HTTP/1.1\r\n").unwrap(),
            Hello::HttpGet {
                path: "/stats".into()
            }
        );
        assert!(matches!(parse_hello(b"hello"), Err(HelloError::NotJson(_))));
        assert!(matches!(
            parse_hello(br#"{"type":"viewer","session":"a b"}"#),
            Err(HelloError::BadSessionName(_))
        ));
        assert!(matches!(
            parse_hello(br#"{"format":"mimic-recording","version":2,"layout":"x","units":"m","source":"x","rate_hz":30}"#),
            Err(HelloError::BadHeader(_))
        ));
    }

    #[test]
    fn weights_hello_and_frames() {
        assert_eq!(
            parse_hello(br#"{"mode":"weights","session":"w","rig":"ict-face","rate_hz":60}"#)
                .unwrap(),
            Hello::Weights {
                session: Some("w".into()),
                rig: Some("ict-face".into()),
                rate_hz: Some(60.0),
                source: None,
            }
        );
        assert!(matches!(
            parse_hello(br#"{"mode":"weights","session":"a b"}"#),
            Err(HelloError::BadSessionName(_))
        ));
        let f = parse_weight_frame(br#"{"t_us":7,"weights":{"jawOpen":0.5,"x":2}}"#).unwrap();
        assert_eq!(f.timestamp_us, 7);
        assert_eq!(
            f.weights,
            vec![("jawOpen".to_string(), 0.5), ("x".to_string(), 2.0)]
        );
        let code = |l: &[u8]| parse_weight_frame(l).unwrap_err().code();
        // JSON has no NaN: the literal is a JSON error.
        assert_eq!(
            code(br#"{"t_us":7,"weights":{"jawOpen":NaN}}"#),
            ErrorCode::BadJson
        );
        assert_eq!(code(br#"{"weights":{}}"#), ErrorCode::BadJson);
        assert_eq!(code(br#"[1]"#), ErrorCode::BadJson);
        assert_eq!(
            code(br#"{"t_us":7,"weights":{"jawOpen":"a"}}"#),
            ErrorCode::BadWeight
        );
        assert_eq!(
            code(br#"{"t_us":7,"weights":{"jawOpen":null}}"#),
            ErrorCode::BadWeight
        );
        assert_eq!(code(br#"{"t_us":7,"weights":[0.5]}"#), ErrorCode::BadWeight);
        assert_eq!(code(br#"{"t_us":7}"#), ErrorCode::BadWeight);
    }

    #[test]
    fn frame_message_round_trips() {
        let out = FrameOutput {
            timestamp_us: -5,
            status: FrameStatus::Lost,
            positions: vec![],
            normals: vec![],
            displacements: vec![Vec3::new(1.0, -2.0, 3.5), Vec3::splat(0.25)],
            pose: HeadPose {
                rotation: Quat::from_rotation_y(0.3),
                translation: Vec3::new(0.1, 0.2, -0.7),
                scale: 1.5,
            },
            target_rotation: Quat::from_rotation_x(-0.2),
            filled: 0,
            times: Default::default(),
        };
        let pos = [Vec3::X, Vec3::new(7.0, 8.0, 9.0)];
        for positions in [None, Some(&pos[..])] {
            let bytes = encode_frame(42, &out, positions);
            let len = u32::from_le_bytes(bytes[..4].try_into().unwrap()) as usize;
            assert_eq!(len + 4, bytes.len());
            let ViewerMessage::Frame(f) = decode_viewer_message(bytes[4], &bytes[5..]).unwrap()
            else {
                panic!("not a frame")
            };
            // Raw f32 copies: exact.
            assert_eq!(f.seq, 42);
            assert_eq!(f.timestamp_us, -5);
            assert_eq!(f.status, 2);
            assert_eq!(f.pose, out.pose);
            assert_eq!(f.target_rotation, out.target_rotation);
            assert_eq!(f.displacements, out.displacements);
            assert_eq!(f.positions.as_deref(), positions);
            // Any cut-off payload is an error, never a panic.
            for cut in 0..bytes.len() - 5 {
                assert!(decode_viewer_message(bytes[4], &bytes[5..5 + cut]).is_err());
            }
        }
    }

    #[test]
    fn udp_packet_round_trips_and_checks_its_size() {
        let frame = LandmarkFrame {
            timestamp_us: 123_456,
            points: vec![Vec3::new(0.1, 0.2, -0.9), Vec3::NAN, Vec3::ONE],
            valid: vec![true, false, true],
            tracked: true,
        };
        let b = encode_udp_frame(7, 99, &frame);
        assert_eq!(b.len(), UDP_HEADER_BYTES + 3 * 12);
        let u = decode_udp_frame(&b).unwrap();
        assert_eq!((u.session_id, u.key), (7, 99));
        assert_eq!(u.frame.valid, frame.valid);
        assert_eq!(u.frame.points[0], frame.points[0]);
        assert_eq!(u.frame.timestamp_us, 123_456);
        assert!(matches!(
            decode_udp_frame(&b[..b.len() - 1]),
            Err(DecodeError::Size { .. })
        ));
        let mut bad = b.clone();
        bad[0] = b'X';
        assert_eq!(decode_udp_frame(&bad), Err(DecodeError::Magic));
        let mut inf = b;
        inf[UDP_HEADER_BYTES..UDP_HEADER_BYTES + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        assert_eq!(decode_udp_frame(&inf), Err(DecodeError::Infinite(0)));
    }
}
