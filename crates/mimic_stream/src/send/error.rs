//! Why a send could not start or go on ([`SendError`]).

use std::path::PathBuf;

/// Why a send could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// The server cannot be reached.
    #[error("connecting to {to}")]
    Connect {
        /// The address.
        to: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A frame of a recording could not be written to the server.
    #[error("sending a frame")]
    Frame(#[source] mimic_capture::WriteError),
    /// A weight frame could not be written to the server.
    #[error("sending a weight frame")]
    WeightFrame(#[source] std::io::Error),
    /// No UDP socket to send from.
    #[error("binding a UDP socket")]
    Bind(#[source] std::io::Error),
    /// A datagram could not be sent.
    #[error("sending {what} {n} to {to}")]
    Datagram {
        /// `datagram` or `packet`.
        what: &'static str,
        /// Its number (from 0).
        n: usize,
        /// The address.
        to: std::net::SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A recording for `--openseeface` of another layout.
    #[error(
        "{}: layout `{layout}`; --openseeface sends `{want}` recordings (mimic import openseeface)",
        path.display()
    )]
    Layout {
        /// The recording.
        path: PathBuf,
        /// Its layout.
        layout: String,
        /// The layout OpenSeeFace datagrams carry.
        want: &'static str,
    },
    /// A weights CSV without weight columns.
    #[error("{}: no weight columns", .0.display())]
    NoWeights(PathBuf),
    /// A rate that is not positive.
    #[error("--rate must be positive")]
    Rate,
    /// A `t_us` field that is not an integer.
    #[error("{}:{line}: `t_us` `{text}` is not an integer", path.display())]
    Time {
        /// The CSV.
        path: PathBuf,
        /// Its line.
        line: usize,
        /// The field.
        text: String,
        /// Why.
        #[source]
        source: std::num::ParseIntError,
    },
    /// A weight that is not a finite number.
    #[error("{}:{line}: column `{column}`: `{text}` is not a number", path.display())]
    Weight {
        /// The CSV.
        path: PathBuf,
        /// Its line.
        line: usize,
        /// The column.
        column: String,
        /// The field.
        text: String,
    },
    /// The server sent no welcome in time.
    #[error("no welcome from the server")]
    NoWelcome(#[source] std::sync::mpsc::RecvTimeoutError),
    /// A socket error.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A recording that cannot be read.
    #[error(transparent)]
    Recording(#[from] mimic_capture::RecordingError),
    /// A recording that cannot be written (its header).
    #[error(transparent)]
    Write(#[from] mimic_capture::WriteError),
    /// A replay that failed.
    #[error(transparent)]
    Replay(#[from] mimic_capture::ReplayError),
    /// A CSV that cannot be read.
    #[error(transparent)]
    Csv(#[from] mimic_capture::named_csv::CsvError),
    /// A WAV that cannot be read.
    #[error(transparent)]
    Audio(#[from] mimic_audio::AudioError),
    /// An audio chunk could not be written to the server.
    #[error("sending an audio chunk")]
    AudioChunk(#[source] std::io::Error),
    /// A take or name map that cannot be read.
    #[error(transparent)]
    Tracker(#[from] mimic_trackers::TrackerError),
}
