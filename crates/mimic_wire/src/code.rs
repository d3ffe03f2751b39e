//! Error codes and the reply lines a tracker gets.

use serde_json::json;

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
    /// Past the connection limit (all slots, or this peer's share of them); the connection is
    /// answered and closed at once.
    TooManyConnections,
    /// The server has a token and the hello did not present it (or presented another).
    BadToken,
    /// An audio chunk whose `pcm` is not base64 whole samples of the session's channels, or
    /// longer than the chunk limit.
    BadAudio,
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
            ErrorCode::TooManyConnections => "too_many_connections",
            ErrorCode::BadToken => "bad_token",
            ErrorCode::BadAudio => "bad_audio",
        }
    }
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
