//! The face frame: a coordinate system fixed to the face, with the inter-ocular distance as unit.

use glam::{Mat3, Vec3};

/// Origin between the inner eye corners, x along the eye line (subject's left), y up
/// perpendicular to it (along the face's profile line, from the menton to the nasion, made
/// perpendicular to x), z out of the face; one
/// unit is the inter-ocular distance (IOD: between the eye centres, each the midpoint of its
/// eye's corners). A moved, rotated or uniformly scaled head has the same face coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceFrame {
    /// Midpoint of the inner eye corners, mesh coordinates.
    pub origin: Vec3,
    /// Unit axes x (subject's left), y (up), z (out of the face), in mesh coordinates.
    pub axes: [Vec3; 3],
    /// Inter-ocular distance in mesh units.
    pub iod: f32,
}

/// The points a face frame is built from (mesh coordinates).
#[derive(Clone, Copy, Debug)]
pub struct FramePoints {
    /// Outer corner of the subject's right eye (iBUG 36, FDP 3.12).
    pub right_outer: Vec3,
    /// Inner corner of the right eye (iBUG 39, FDP 3.8).
    pub right_inner: Vec3,
    /// Inner corner of the left eye (iBUG 42, FDP 3.11).
    pub left_inner: Vec3,
    /// Outer corner of the left eye (iBUG 45, FDP 3.7).
    pub left_outer: Vec3,
    /// A point low on the midline (the menton, iBUG 8).
    pub low: Vec3,
    /// A point high on the midline (the nasion, iBUG 27).
    pub high: Vec3,
}

impl FaceFrame {
    /// The frame of these points; `None` when they are degenerate (eyes on one point, the
    /// profile line along the eye line).
    pub fn new(p: &FramePoints) -> Option<Self> {
        let left = (p.left_inner + p.left_outer) * 0.5;
        let right = (p.right_inner + p.right_outer) * 0.5;
        let iod = left.distance(right);
        let origin = (p.left_inner + p.right_inner) * 0.5;
        let x = (left - right).try_normalize()?;
        let up = p.high - p.low;
        let y = (up - x * x.dot(up)).try_normalize()?;
        let z = x.cross(y);
        (iod.is_finite() && iod > 0.0).then_some(Self {
            origin,
            axes: [x, y, z],
            iod,
        })
    }

    /// Face coordinates (IOD units) of a mesh point.
    pub fn to_face(&self, p: Vec3) -> Vec3 {
        let d = p - self.origin;
        Vec3::new(
            self.axes[0].dot(d),
            self.axes[1].dot(d),
            self.axes[2].dot(d),
        ) / self.iod
    }

    /// Mesh point of face coordinates `q`.
    pub fn to_mesh(&self, q: Vec3) -> Vec3 {
        self.origin + Mat3::from_cols(self.axes[0], self.axes[1], self.axes[2]) * q * self.iod
    }

    /// Angle in degrees between the frame's up axis and the mesh's +y (rig regions are heights
    /// along the mesh's y, so a large angle means the regions cut the face slantwise).
    pub fn tilt_degrees(&self) -> f32 {
        self.axes[1]
            .dot(Vec3::Y)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn points(f: impl Fn(Vec3) -> Vec3) -> FramePoints {
        FramePoints {
            right_outer: f(Vec3::new(-4.5, 3.4, 8.6)),
            right_inner: f(Vec3::new(-1.8, 3.25, 9.2)),
            left_inner: f(Vec3::new(1.8, 3.25, 9.2)),
            left_outer: f(Vec3::new(4.5, 3.4, 8.6)),
            low: f(Vec3::new(0.0, -7.5, 10.4)),
            high: f(Vec3::new(0.0, 3.75, 10.7)),
        }
    }

    #[test]
    fn frame_of_a_symmetric_face() {
        let f = FaceFrame::new(&points(|p| p)).unwrap();
        assert!((f.iod - 6.3).abs() < 1e-5, "{}", f.iod);
        assert!(f.origin.abs_diff_eq(Vec3::new(0.0, 3.25, 9.2), 1e-6));
        assert!(f.axes[0].abs_diff_eq(Vec3::X, 1e-6));
        // y leans forward by the nasion's lead over the menton: atan(0.3 / 11.25).
        let lean = (0.3f32 / 11.25).atan();
        assert!(f.axes[1].abs_diff_eq(Vec3::new(0.0, lean.cos(), lean.sin()), 1e-5));
        assert!((f.tilt_degrees() - lean.to_degrees()).abs() < 1e-3);
        assert!(f.axes[2].z > 0.9);
        let p = Vec3::new(1.0, -2.0, 11.0);
        assert!(f.to_mesh(f.to_face(p)).abs_diff_eq(p, 1e-5));
        assert!(
            FaceFrame::new(&FramePoints {
                low: Vec3::new(-2.5, 3.25, 9.2),
                high: Vec3::new(2.5, 3.25, 9.2),
                ..points(|p| p)
            })
            .is_none()
        );
    }

    #[test]
    fn face_coordinates_ignore_a_similarity() {
        let a = FaceFrame::new(&points(|p| p)).unwrap();
        let rot = Quat::from_rotation_y(20f32.to_radians()) * Quat::from_rotation_x(0.3);
        let t = |p: Vec3| rot * (p * 10.0) + Vec3::new(5.0, -40.0, 7.0);
        let b = FaceFrame::new(&points(t)).unwrap();
        assert!((b.iod - 10.0 * a.iod).abs() < 1e-3);
        for p in [Vec3::new(1.0, -2.0, 11.0), Vec3::new(-3.0, 5.0, 2.0)] {
            let (qa, qb) = (a.to_face(p), b.to_face(t(p)));
            assert!(qa.abs_diff_eq(qb, 1e-5), "{qa} {qb}");
        }
    }
}
