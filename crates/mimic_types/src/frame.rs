//! One tracked frame of landmarks.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Landmarks of one tracked frame, in the recording's units and camera space.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LandmarkFrame {
    /// Capture time in microseconds since the recording's epoch.
    pub timestamp_us: i64,
    /// Landmark positions; the layout says what each index is.
    pub points: Vec<Vec3>,
    /// Per-point validity (false: the tracker had no value, e.g. Kinect depth 0).
    pub valid: Vec<bool>,
    /// False when the tracker lost the face for this frame.
    pub tracked: bool,
}

impl LandmarkFrame {
    /// A tracked frame whose points are all valid.
    pub fn new(timestamp_us: i64, points: Vec<Vec3>) -> Self {
        let valid = vec![true; points.len()];
        Self {
            timestamp_us,
            points,
            valid,
            tracked: true,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the frame holds no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Whether point `i` exists, is marked valid and is finite.
    #[inline]
    pub fn is_valid(&self, i: usize) -> bool {
        match (self.points.get(i), self.valid.get(i)) {
            (Some(p), Some(true)) => p.is_finite(),
            _ => false,
        }
    }

    /// Number of valid points.
    pub fn valid_count(&self) -> usize {
        (0..self.points.len()).filter(|&i| self.is_valid(i)).count()
    }
}
