//! Errors of reading and writing recordings.

use std::path::PathBuf;

/// Why one frame line was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameProblem {
    /// The line is not a valid frame object.
    #[error("invalid JSON at column {column} ({detail})")]
    Json {
        /// 1-based column where parsing failed.
        column: usize,
        /// What the JSON parser said.
        detail: String,
    },
    /// The last line ends without a newline and does not parse: the file was cut off.
    #[error("truncated JSON ({detail})")]
    Truncated {
        /// What the JSON parser said.
        detail: String,
    },
    /// A tracked frame whose point count differs from the layout's.
    #[error("frame has {found} points; layout {layout} has {expected}")]
    PointCount {
        /// Points in the frame.
        found: usize,
        /// Points the layout has.
        expected: usize,
        /// Layout name from the header.
        layout: String,
    },
    /// A point not listed in `invalid` is `null`, has a `null` coordinate or does not fit in f32.
    #[error("point {point} has a NaN coordinate (null or out of range) but is not listed invalid")]
    BadCoordinate {
        /// 0-based point index.
        point: usize,
    },
    /// `invalid` names a point the frame does not have.
    #[error("`invalid` lists point {index}, but the frame has {count} points")]
    InvalidIndexOutOfRange {
        /// The listed index.
        index: usize,
        /// Points in the frame.
        count: usize,
    },
    /// The timestamp is not after the previous accepted frame's.
    #[error("timestamp {t_us} us is not after the previous frame's {previous_us} us")]
    TimeNotIncreasing {
        /// This frame's timestamp (µs).
        t_us: i64,
        /// The previous accepted frame's timestamp (µs).
        previous_us: i64,
    },
    /// The line is longer than the reader's limit; the rest of it was skipped.
    #[error("line longer than {limit} bytes")]
    TooLong {
        /// The limit, in bytes.
        limit: usize,
    },
    /// Reading the line failed.
    #[error("read error: {detail}")]
    Io {
        /// The I/O error, in words.
        detail: String,
    },
}

/// A rejected frame: which file, which line, what was wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}:{line}: {problem}", path.display())]
pub struct FrameError {
    /// The recording.
    pub path: PathBuf,
    /// 1-based line number.
    pub line: u64,
    /// What was wrong.
    pub problem: FrameProblem,
}

/// A recording that cannot be read at all (or, in strict mode, has a bad frame).
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file cannot be opened.
    #[error("{}: cannot open: {source}", path.display())]
    Open {
        /// The recording.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The header line is missing or wrong.
    #[error("{}:1: {reason}", path.display())]
    Header {
        /// The recording.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A frame was rejected (strict reading only).
    #[error(transparent)]
    Frame(#[from] FrameError),
}

/// Why a frame or header could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The underlying writer failed.
    #[error("write failed: {0}")]
    Io(#[from] std::io::Error),
    /// The header does not pass [`crate::recording::RecordingHeader::check`].
    #[error("bad header: {0}")]
    Header(String),
    /// A tracked frame's point count differs from the recording's.
    #[error("frame at {t_us} us has {found} points; the recording has {expected}")]
    PointCount {
        /// Frame timestamp (µs).
        t_us: i64,
        /// Points in the frame.
        found: usize,
        /// Points in the recording.
        expected: usize,
    },
    /// `valid` and `points` differ in length.
    #[error("frame at {t_us} us has {points} points but {valid} validity flags")]
    ValidityLength {
        /// Frame timestamp (µs).
        t_us: i64,
        /// Points in the frame.
        points: usize,
        /// Validity flags in the frame.
        valid: usize,
    },
    /// Timestamps must increase strictly.
    #[error("timestamp {t_us} us is not after the previous frame's {previous_us} us")]
    TimeNotIncreasing {
        /// This frame's timestamp (µs).
        t_us: i64,
        /// The previous frame's timestamp (µs).
        previous_us: i64,
    },
}
