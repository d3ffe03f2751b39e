//! mimic's per-frame pipeline, with no I/O.
//!
//! [`Retargeter::new`] ties a landmark [`Layout`](mimic_types::Layout) to a target
//! [`Rig`](mimic_types::Rig) and a precomputed [`Basis`](mimic_solve::Basis), and allocates every
//! buffer the pipeline needs. [`Retargeter::step`] then takes one [`LandmarkFrame`](mimic_types::LandmarkFrame)
//! at a time: select the controls -> remove rigid head motion (Kabsch on the layout's stable points)
//! -> displacement against the neutral -> scale to the target -> One Euro filter -> `u = B d`
//! -> normals, writing into a caller-owned [`FrameOutput`] and allocating nothing. A plausibility
//! gate ([`GateSettings`], `docs/gate.md`) holds tracked frames no face can make (a fit failure's
//! head turn) like lost ones and clamps control speeds.
//! [`BlendshapeFitter`] turns the same control displacements into morph-target weights and the
//! blended mesh (blendshape mode). [`StageSamples`] turns many steps' [`StageTimes`] into
//! median / p99 per stage. [`Checkpoint`] is a retargeter's learned state (neutral, scale,
//! filters), serialisable, so another process can continue a session. [`FrameLoop`] is the one
//! frame loop every command and session runs: frames in, then every output
//! ([`FrameSink`](mimic_types::FrameSink)) in turn. [`gaze`] estimates each eye's gaze from a
//! layout's pupils, eye corners and lids, and ARKit's `eyeLook*` weights from it.
//! No tokio, no wgpu, no file formats: sources and sinks live in other crates.

mod blendshape;
mod checkpoint;
mod filter;
#[cfg(any(test, feature = "test-fixtures"))]
pub mod fixtures;
mod frame_loop;
pub use mimic_types::frame_metrics;
mod gate;
pub mod gaze;
pub mod mouth;
mod patch;
mod pipeline;
pub mod quality;
pub mod repair;
mod scale;
mod settings;
mod stage_stats;
pub mod summary;
mod weight_stats;

pub use blendshape::{
    BlendshapeError, BlendshapeFit, BlendshapeFitter, BlendshapeSettings, WeightMap,
};
pub use checkpoint::{Checkpoint, CheckpointError};
pub use filter::{OneEuro, OneEuroSettings, OneEuroStep};
pub use frame_loop::{FrameLoop, LoopReport};
pub use gate::{GateReading, GateReason, GateSettings, face_size};
pub use pipeline::{FrameOutput, FrameStatus, RetargetError, Retargeter, Stage, StageTimes, Stats};
pub use repair::RepairReading;
pub use scale::SourceToTarget;
pub use settings::{Neutral, Provisional, RetargetSettings};
pub use stage_stats::{Percentiles, StagePercentiles, StageSamples, elapsed_ns, median_p99_us};
pub use weight_stats::{TargetWeight, WeightStats, WeightSummary};

#[cfg(test)]
mod tests;
