//! What `mimic bench` measures, apart from the command's arguments and printing.
//!
//! - [`bench_rig`]: the retarget step on one rig, timed per stage over a looped recording, with
//!   baselines run in the same process ([`baseline`]: the dense product and the face-by-face
//!   normals over every vertex, the previous deform, one read of the deform's bytes), the step
//!   with each kernel variant taking turns with the default ([`kernels`]), and optionally many
//!   sessions at once ([`sessions`]) and numpy's product ([`numpy`]). [`RigReport`] is the
//!   result: JSON by serde, a plain summary for people and the developer detail as text.
//! - [`gpu::bench_rig`]: many sessions morphed in one wgpu compute dispatch ([`BatchMorph`]).
//!
//! The binary loads the rig and the recording; this crate runs and reports. No tokio.

pub mod baseline;
pub mod batch;
pub mod gpu;
pub mod kernels;
pub mod numpy;
pub mod record_cost;
mod report;
mod run;
pub mod sessions;

pub use batch::{BatchError, BatchMorph, BatchTiming, GpuTimes};
pub use report::{LoadAverage, RigReport, StepFigures};
pub use run::bench_rig;

use mimic_retarget::{RetargetError, RetargetSettings, Retargeter};
use mimic_types::{LandmarkFrame, Layout, Rig, SolverSettings};
use std::time::Duration;

/// What can stop a benchmark.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The recording has no frame to step.
    #[error("{0}: no usable frames")]
    NoFrames(String),
    /// Too few of the recording's frames were tracked to collect the steps asked for.
    #[error("too few tracked frames in {0}")]
    TooFewTracked(String),
    /// A retargeter for a variant could not be made.
    #[error("retargeter: {0}")]
    Retarget(#[from] RetargetError),
    /// A sessions run failed.
    #[error(transparent)]
    Sessions(#[from] sessions::SessionsError),
    /// numpy's reference could not be run or read.
    #[error("numpy reference: {0}")]
    Numpy(String),
    /// The GPU batch failed (other than for want of an adapter, which is no error).
    #[error(transparent)]
    Batch(#[from] BatchError),
    /// A report could not be turned into JSON.
    #[error("report: {0}")]
    Json(#[from] serde_json::Error),
}

/// A rig made ready by the caller: what is measured.
pub struct Subject<'a> {
    /// The rig.
    pub rig: &'a Rig,
    /// The layout of the recording's tracker.
    pub layout: &'a Layout,
    /// The retargeter timed (its basis is shared with every variant's).
    pub retargeter: &'a mut Retargeter,
    /// The pipeline settings it was made with, for the variants' retargeters.
    pub settings: RetargetSettings,
    /// The solver that built the basis.
    pub solver: &'a SolverSettings,
    /// Time spent building the basis.
    pub basis_time: Duration,
}

/// A recording's frames, looped by the runs.
pub struct Recorded {
    /// Where it came from (for the report).
    pub name: String,
    /// Its frames.
    pub frames: Vec<LandmarkFrame>,
}

impl Recorded {
    /// The frames' time span plus one frame at 30 fps: the shift of each loop, so that time runs
    /// forward.
    pub fn span_us(&self) -> i64 {
        match (self.frames.first(), self.frames.last()) {
            (Some(a), Some(b)) => b.timestamp_us - a.timestamp_us + 33_333,
            _ => 0,
        }
    }
}

/// What a benchmark run is asked for.
#[derive(Clone, Debug)]
pub struct Options {
    /// Timed steps.
    pub steps: usize,
    /// Also step 1 and then this many sessions at once.
    pub sessions: Option<usize>,
    /// With `sessions`: also step them recording into this folder, in each record mode
    /// ([`record_cost`]).
    pub record_cost: Option<std::path::PathBuf>,
    /// Also time numpy's product over the same rows.
    pub numpy: bool,
}

/// The 1-minute load average (Linux), for the record next to each figure.
pub fn load_average() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    text.split_whitespace().next()?.parse().ok()
}
