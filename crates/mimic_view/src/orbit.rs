//! The orbit camera: yaw and pitch about the rig's centre from mouse drags, distance from the wheel.

use glam::Vec3;
use mimic_render::Camera;

/// Degrees turned per pixel of mouse drag.
pub const DEGREES_PER_PIXEL: f32 = 0.4;
/// Highest and lowest pitch, degrees (short of the poles, where "up" flips).
pub const PITCH_LIMIT: f32 = 85.0;
/// Closest and farthest zoom, as a factor of the framing distance.
pub const ZOOM_RANGE: (f32, f32) = (0.25, 4.0);

/// Where the camera sits around the rig: angles from the front view and a distance factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// Turn about y, degrees, towards +x (the subject's left).
    pub yaw: f32,
    /// Height above the horizontal, degrees.
    pub pitch: f32,
    /// Distance as a factor of the distance that frames the rig (1: it just fits).
    pub zoom: f32,
}

impl Default for Orbit {
    /// The view of `mimic render` ([`Camera::front`]): 20 degrees left, 8 above, framed.
    fn default() -> Self {
        Self {
            yaw: 20.0,
            pitch: 8.0,
            zoom: 1.0,
        }
    }
}

impl Orbit {
    /// A mouse drag of `(dx, dy)` pixels: right turns the camera to the subject's right, down
    /// raises it (the head seems to follow the mouse).
    pub fn drag(&mut self, dx: f32, dy: f32) {
        self.yaw = (self.yaw - dx * DEGREES_PER_PIXEL).rem_euclid(360.0);
        self.pitch = (self.pitch + dy * DEGREES_PER_PIXEL).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// A wheel turn of `lines` (positive: away from the user, zooms in by 10% a line).
    pub fn wheel(&mut self, lines: f32) {
        self.zoom = (self.zoom * 0.9f32.powf(lines)).clamp(ZOOM_RANGE.0, ZOOM_RANGE.1);
    }

    /// The camera for the rig's bounding box `(lo, hi)`.
    pub fn camera(&self, lo: Vec3, hi: Vec3) -> Camera {
        let framed = Camera::framing(lo, hi, self.yaw, self.pitch);
        let radius = ((hi - lo).length() * 0.5).max(1e-6);
        let distance = (framed.eye - framed.target).length() * self.zoom;
        Camera {
            eye: framed.target + (framed.eye - framed.target) * self.zoom,
            near: (distance - radius * 1.01).max(distance * 0.01),
            far: distance + radius * 1.01,
            ..framed
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_the_render_front_view() {
        let (lo, hi) = (Vec3::new(-8.0, -12.0, -10.0), Vec3::new(8.0, 12.0, 6.0));
        let (a, b) = (Orbit::default().camera(lo, hi), Camera::front(lo, hi));
        assert_eq!((a.eye, a.target, a.fov_y), (b.eye, b.target, b.fov_y));
        // The clipping planes agree up to f32 rounding of the distance.
        assert!((a.near - b.near).abs() < 1e-4 && (a.far - b.far).abs() < 1e-4);
    }

    #[test]
    fn drag_turns_and_pitch_stops_short_of_the_poles() {
        let mut o = Orbit::default();
        o.drag(50.0, 0.0);
        assert!((o.yaw - 0.0).abs() < 1e-4, "{}", o.yaw);
        o.drag(25.0, 0.0);
        assert!((o.yaw - 350.0).abs() < 1e-3, "wraps into 0..360: {}", o.yaw);
        o.drag(0.0, 1000.0);
        assert_eq!(o.pitch, PITCH_LIMIT);
        o.drag(0.0, -5000.0);
        assert_eq!(o.pitch, -PITCH_LIMIT);
    }

    #[test]
    fn wheel_scales_the_distance_within_its_range() {
        let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let far = Orbit::default().camera(lo, hi);
        let mut o = Orbit::default();
        o.wheel(1.0);
        let near = o.camera(lo, hi);
        let d = |c: &Camera| (c.eye - c.target).length();
        assert!((d(&near) / d(&far) - 0.9).abs() < 1e-5);
        // The box stays between the clipping planes.
        let radius = 3f32.sqrt();
        assert!(near.near < d(&near) - radius && near.far > d(&near) + radius);
        o.wheel(100.0);
        assert_eq!(o.zoom, ZOOM_RANGE.0);
        o.wheel(-100.0);
        assert_eq!(o.zoom, ZOOM_RANGE.1);
    }
}
