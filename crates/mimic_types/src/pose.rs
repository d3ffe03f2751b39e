//! Rigid head pose.

use glam::{Affine3A, Mat3, Mat3A, Mat4, Quat, Vec3, Vec3A};
use serde::{Deserialize, Serialize};

/// Rigid head motion of a frame relative to the neutral: `x_frame = scale * rotation * x_neutral + translation`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeadPose {
    /// Rotation from the neutral head to this frame's head.
    pub rotation: Quat,
    /// Translation, in the source's units.
    pub translation: Vec3,
    /// Uniform scale (1 for a rigid fit).
    pub scale: f32,
}

impl Default for HeadPose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl HeadPose {
    /// No motion.
    pub const IDENTITY: HeadPose = HeadPose {
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
        scale: 1.0,
    };

    /// Maps a neutral-space point into this frame.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        self.rotation * (p * self.scale) + self.translation
    }

    /// Maps a point of this frame back into neutral space.
    pub fn inverse_apply(&self, p: Vec3) -> Vec3 {
        (self.rotation.inverse() * (p - self.translation)) / self.scale
    }

    /// [`HeadPose::inverse_apply`] as one affine map, for mapping many points back: a matrix
    /// product per point instead of a quaternion product and a division.
    pub fn inverse_affine(&self) -> Affine3A {
        let m = Mat3A::from_quat(self.rotation.inverse()) * (1.0 / self.scale);
        Affine3A {
            matrix3: m,
            translation: -(m * Vec3A::from(self.translation)),
        }
    }

    /// The pose as a 4x4 matrix.
    pub fn to_mat4(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            Vec3::splat(self.scale),
            self.rotation,
            self.translation,
        )
    }
}

/// The head's translation in the rig's axes and units: how far the centroid of a frame's
/// `points` (source space) moved from where the inverse of its head `pose` puts it on the
/// neutral face, mapped by `to_target` (the source-to-target map of displacements). `None`
/// without points.
pub fn head_translation(
    points: impl IntoIterator<Item = Vec3>,
    pose: &HeadPose,
    to_target: Mat3,
) -> Option<Vec3> {
    let (sum, n) = points
        .into_iter()
        .fold((Vec3::ZERO, 0usize), |(s, n), p| (s + p, n + 1));
    if n == 0 {
        return None;
    }
    let c = sum / n as f32;
    Some(to_target * (c - pose.inverse_apply(c)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_undoes_apply() {
        let pose = HeadPose {
            rotation: Quat::from_euler(glam::EulerRot::XYZ, 0.2, -0.4, 0.1),
            translation: Vec3::new(1.0, -2.0, 3.0),
            scale: 1.5,
        };
        let p = Vec3::new(0.3, 0.7, -1.1);
        let q = pose.inverse_apply(pose.apply(p));
        // f32 round trip: a few ulps of |p| and |t|.
        assert!((q - p).length() < 1e-5, "{q} vs {p}");
        assert!((pose.to_mat4().transform_point3(p) - pose.apply(p)).length() < 1e-5);
    }

    #[test]
    fn inverse_affine_is_inverse_apply() {
        let mut seed = 7u64;
        let mut next = || mimic_testkit::lcg(&mut seed);
        for _ in 0..100 {
            let pose = HeadPose {
                rotation: Quat::from_euler(glam::EulerRot::XYZ, 3.0 * next(), 3.0 * next(), next())
                    .normalize(),
                translation: Vec3::new(next(), next(), next()) * 2.0,
                scale: 1.0 + 0.5 * next(),
            };
            let inverse = pose.inverse_affine();
            let p = Vec3::new(next(), next(), next());
            let (a, b) = (inverse.transform_point3(p), pose.inverse_apply(p));
            // Both are f32 sums of terms up to (|p| + |t|) / scale: a few ulps of that.
            let size = (p.length() + pose.translation.length()) / pose.scale;
            assert!((a - b).length() <= 16.0 * f32::EPSILON * size, "{a} vs {b}");
            // And it undoes apply.
            let q = pose.apply(p);
            let back = inverse.transform_point3(q);
            let size = (q.length() + pose.translation.length()) / pose.scale;
            assert!(
                (back - p).length() <= 32.0 * f32::EPSILON * size,
                "{back} vs {p}"
            );
        }
    }
}
