//! The keys of a performance: per frame, its time, the morph weights and the head pose.

use glam::{Quat, Vec3};

/// How the animation interpolates between keys.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interpolation {
    /// Linear between keys (glTF `LINEAR`).
    #[default]
    Linear,
    /// Each key held until the next (glTF `STEP`).
    Step,
}

impl Interpolation {
    /// The glTF name.
    pub fn gltf_name(self) -> &'static str {
        match self {
            Interpolation::Linear => "LINEAR",
            Interpolation::Step => "STEP",
        }
    }
}

/// A performance as animation keys: one per frame, at its time in seconds from the first frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Take {
    /// Interpolation of every channel.
    pub interpolation: Interpolation,
    target_count: usize,
    first_us: Option<i64>,
    times: Vec<f32>,
    weights: Vec<f32>,
    pose: bool,
    rotations: Vec<Quat>,
    translations: Vec<Vec3>,
    skipped: usize,
    non_finite: usize,
}

impl Take {
    /// An empty take of `target_count` weights per key, with head pose keys when `pose`.
    pub fn new(target_count: usize, interpolation: Interpolation, pose: bool) -> Self {
        Self {
            interpolation,
            target_count,
            first_us: None,
            times: Vec::new(),
            weights: Vec::new(),
            pose,
            rotations: Vec::new(),
            translations: Vec::new(),
            skipped: 0,
            non_finite: 0,
        }
    }

    /// Adds the key of a frame at `timestamp_us`: its weights (one per target) and head pose
    /// (rotation, and translation in metres, in the rig's axes; ignored without pose keys).
    /// A frame whose time (f32 seconds) is not after the last key's is skipped (glTF needs
    /// strictly increasing key times) and counted; non-finite values are written as 0 (or
    /// identity) and counted. Returns whether the key was added.
    ///
    /// # Panics
    /// If `weights` is not one per target.
    pub fn push(&mut self, timestamp_us: i64, weights: &[f32], pose: (Quat, Vec3)) -> bool {
        assert_eq!(weights.len(), self.target_count, "one weight per target");
        let first = *self.first_us.get_or_insert(timestamp_us);
        let t = (timestamp_us.saturating_sub(first) as f64 * 1e-6) as f32;
        if self.times.last().is_some_and(|last| t <= *last) || t < 0.0 {
            self.skipped += 1;
            return false;
        }
        self.times.push(t);
        let mut bad = false;
        self.weights.extend(weights.iter().map(|w| {
            bad |= !w.is_finite();
            if w.is_finite() { *w } else { 0.0 }
        }));
        if self.pose {
            let (r, p) = pose;
            let r = if r.is_finite() && r.length() > 0.0 {
                r.normalize()
            } else {
                bad = true;
                Quat::IDENTITY
            };
            let p = if p.is_finite() {
                p
            } else {
                bad = true;
                Vec3::ZERO
            };
            self.rotations.push(r);
            self.translations.push(p);
        }
        self.non_finite += usize::from(bad);
        true
    }

    /// Keys so far.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Whether there are no keys.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Weights per key.
    pub fn target_count(&self) -> usize {
        self.target_count
    }

    /// Seconds from the first key to the last.
    pub fn duration_s(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }

    /// Key times, seconds from the first frame.
    pub fn times(&self) -> &[f32] {
        &self.times
    }

    /// Weights, key-major (`weights()[k * target_count + t]`).
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// Head rotation per key (empty without pose keys).
    pub fn rotations(&self) -> &[Quat] {
        &self.rotations
    }

    /// Head translation per key, metres (empty without pose keys).
    pub fn translations(&self) -> &[Vec3] {
        &self.translations
    }

    /// Whether the take has head pose keys.
    pub fn has_pose(&self) -> bool {
        self.pose
    }

    /// Frames skipped because their time was not after the previous key's.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// Keys with a non-finite value (written as 0 or identity).
    pub fn non_finite(&self) -> usize {
        self.non_finite
    }
}

pub use mimic_types::pose::head_translation;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat3;
    use mimic_types::HeadPose;

    #[test]
    fn keys_strictly_increase_and_bad_values_are_replaced() {
        let mut take = Take::new(2, Interpolation::Linear, true);
        let pose = (Quat::IDENTITY, Vec3::ZERO);
        assert!(take.push(1_000_000, &[0.5, 1.0], pose));
        assert!(take.push(1_033_333, &[f32::NAN, 1.0], pose));
        assert!(!take.push(1_033_333, &[0.0, 0.0], pose));
        assert!(take.push(
            2_000_000,
            &[0.0, 0.0],
            (Quat::from_xyzw(0.0, 0.0, 0.0, 2.0), Vec3::X)
        ));
        assert_eq!(take.times(), &[0.0, 0.033_333, 1.0]);
        assert_eq!(take.weights()[2], 0.0);
        assert_eq!((take.skipped(), take.non_finite()), (1, 1));
        assert_eq!(take.rotations()[2], Quat::IDENTITY);
        assert_eq!(take.duration_s(), 1.0);
    }

    #[test]
    fn a_rigid_move_of_the_points_is_the_translation_of_their_centroid() {
        let neutral = [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(-1.0, 0.5, 0.2),
            Vec3::new(0.0, 2.0, -1.0),
        ];
        let pose = HeadPose {
            rotation: Quat::from_rotation_y(0.3),
            translation: Vec3::new(0.1, -0.2, 0.05),
            scale: 1.0,
        };
        let moved: Vec<Vec3> = neutral.iter().map(|p| pose.apply(*p)).collect();
        let c0 = neutral.iter().copied().sum::<Vec3>() / 3.0;
        let c1 = moved.iter().copied().sum::<Vec3>() / 3.0;
        let t = head_translation(moved, &pose, Mat3::from_diagonal(Vec3::splat(2.0))).unwrap();
        assert!(
            (t - 2.0 * (c1 - c0)).length() <= 1e-5 * (1.0 + c1.length()),
            "{t}"
        );
        assert_eq!(head_translation([], &pose, Mat3::IDENTITY), None);
    }
}
