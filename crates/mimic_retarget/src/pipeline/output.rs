//! What one step writes ([`FrameOutput`]): the deformed mesh, `d`, the head pose and the stage
//! times, allocated once by [`Retargeter::new_output`](super::Retargeter::new_output) and reused;
//! [`FrameOutput::view`] is the borrowed frame the encoders and outputs read.

use super::{FrameStatus, StageTimes};
use glam::{Quat, Vec3};
use mimic_types::{FrameView, HeadPose};

/// The result of one step; allocate it once with [`Retargeter::new_output`](super::Retargeter::new_output) and reuse it.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameOutput {
    /// Timestamp of the frame (microseconds).
    pub timestamp_us: i64,
    /// What happened.
    pub status: FrameStatus,
    /// Deformed vertex positions (rest + `B d`), target units.
    pub positions: Vec<Vec3>,
    /// Vertex normals of `positions` (empty when normals are off).
    pub normals: Vec<Vec3>,
    /// Control displacements `d` in target units: what a GPU morph needs per frame.
    pub displacements: Vec<Vec3>,
    /// Head pose of the performer: neutral -> this frame, in source space.
    pub pose: HeadPose,
    /// The head rotation expressed in target axes.
    pub target_rotation: Quat,
    /// Controls filled in this frame.
    pub filled: u32,
    /// Time spent per stage.
    pub times: StageTimes,
}

impl FrameOutput {
    /// The frame as encoders see it (time, status, pose, `d`), borrowed.
    pub fn view(&self) -> FrameView<'_> {
        FrameView {
            timestamp_us: self.timestamp_us,
            status: self.status,
            pose: self.pose,
            target_rotation: self.target_rotation,
            displacements: &self.displacements,
        }
    }
}
