//! What happened to a frame ([`FrameStatus`], with its one-byte code on the wire and in CSVs) and
//! the borrowed view of a retargeted frame that encoders read ([`FrameView`]).

use crate::HeadPose;
use glam::{Quat, Vec3};

/// What happened to a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameStatus {
    /// Used to build the neutral; the output is the rest mesh.
    Calibrating,
    /// Tracked and retargeted.
    Tracked,
    /// Tracking lost (or too few stable points): last pose held, expression easing to neutral.
    Lost,
    /// Unusable (a tracked frame with the wrong point count): the output was left unchanged.
    Rejected,
}

impl FrameStatus {
    /// The status's code in viewer messages, metrics and weights CSVs (docs/protocol.md):
    /// 0 calibrating, 1 tracked, 2 lost, 3 rejected.
    pub fn code(self) -> u8 {
        match self {
            FrameStatus::Calibrating => 0,
            FrameStatus::Tracked => 1,
            FrameStatus::Lost => 2,
            FrameStatus::Rejected => 3,
        }
    }

    /// The status of a code; any code past 2 reads as rejected (what a viewer shows for it).
    pub fn from_code(code: u8) -> Self {
        match code {
            0 => FrameStatus::Calibrating,
            1 => FrameStatus::Tracked,
            2 => FrameStatus::Lost,
            _ => FrameStatus::Rejected,
        }
    }
}

/// A retargeted frame as encoders see it: time, status, head pose and the control displacements
/// `d` (borrowed from the pipeline's output, no copy).
#[derive(Clone, Copy, Debug)]
pub struct FrameView<'a> {
    /// Frame time in microseconds.
    pub timestamp_us: i64,
    /// What happened to the frame.
    pub status: FrameStatus,
    /// Head pose in camera space.
    pub pose: HeadPose,
    /// The head's rotation in the target's axes.
    pub target_rotation: Quat,
    /// Control displacements `d` in target units, one per control.
    pub displacements: &'a [Vec3],
}

#[cfg(test)]
mod tests {
    use super::FrameStatus;

    #[test]
    fn codes_round_trip_and_past_codes_read_rejected() {
        for s in [
            FrameStatus::Calibrating,
            FrameStatus::Tracked,
            FrameStatus::Lost,
            FrameStatus::Rejected,
        ] {
            assert_eq!(FrameStatus::from_code(s.code()), s);
        }
        assert_eq!(FrameStatus::from_code(0).code(), 0);
        assert_eq!(FrameStatus::from_code(200), FrameStatus::Rejected);
    }
}
