//! The camera: a perspective view that frames a bounding box.

use glam::{Mat4, Vec3};

/// A perspective camera looking from `eye` at `target`, y up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Camera position, rig units.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Vertical field of view, radians.
    pub fov_y: f32,
    /// Near clipping distance.
    pub near: f32,
    /// Far clipping distance.
    pub far: f32,
}

impl Camera {
    /// Frames the box `(lo, hi)` seen from the front (+z), turned `yaw_deg` about y (towards +x)
    /// and raised `pitch_deg` above it: the camera backs off until all eight corners lie inside a
    /// 30 degree field of view (square image) with a 4% margin.
    pub fn framing(lo: Vec3, hi: Vec3, yaw_deg: f32, pitch_deg: f32) -> Self {
        let target = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-6);
        let fov_y = 30f32.to_radians();
        let (yaw, pitch) = (yaw_deg.to_radians(), pitch_deg.to_radians());
        let dir = Vec3::new(
            yaw.sin() * pitch.cos(),
            pitch.sin(),
            yaw.cos() * pitch.cos(),
        );
        let right = Vec3::Y.cross(dir).normalize_or(Vec3::X);
        let up = dir.cross(right);
        // A corner at offset c from the target, seen from target + dir * t, is inside the view when
        // max(|c . right|, |c . up|) <= tan(fov / 2) * (t - c . dir).
        let tan = (fov_y * 0.5).tan() / 1.04;
        let mut distance = 0f32;
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            ) - target;
            let lateral = c.dot(right).abs().max(c.dot(up).abs());
            distance = distance.max(c.dot(dir) + lateral / tan);
        }
        let distance = distance.max(radius * 1e-3);
        Self {
            eye: target + dir * distance,
            target,
            fov_y,
            near: (distance - radius * 1.01).max(distance * 0.01),
            far: distance + radius * 1.01,
        }
    }

    /// The front view used by `mimic render`: 20 degrees to the subject's left, 8 degrees above.
    pub fn front(lo: Vec3, hi: Vec3) -> Self {
        Self::framing(lo, hi, 20.0, 8.0)
    }

    /// Projection times view for an image of the given aspect ratio (width / height), wgpu clip space.
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let view = Mat4::look_at_rh(self.eye, self.target, Vec3::Y);
        let proj = Mat4::perspective_rh(self.fov_y, aspect.max(1e-6), self.near, self.far);
        proj * view
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_keeps_the_box_in_view_and_centred() {
        let (lo, hi) = (Vec3::new(-8.0, -12.0, -10.0), Vec3::new(8.0, 12.0, 6.0));
        let cam = Camera::front(lo, hi);
        let vp = cam.view_proj(1.0);
        // The target projects to the image centre (exact up to f32 rounding of the matrices).
        let c = vp.project_point3((lo + hi) * 0.5);
        assert!(c.x.abs() < 1e-5 && c.y.abs() < 1e-5, "{c}");
        // Every corner lies inside the clip volume: |x|, |y| <= 1 and 0 <= z <= 1.
        for k in 0..8 {
            let p = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let q = vp.project_point3(p);
            assert!(q.x.abs() <= 1.0 && q.y.abs() <= 1.0, "{p} -> {q}");
            assert!((0.0..=1.0).contains(&q.z), "{p} -> {q}");
        }
        // A front view: the eye is in front of the face (+z) and above it.
        assert!(cam.eye.z > hi.z && cam.eye.y > cam.target.y);
    }
}
