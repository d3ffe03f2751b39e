//! Pinhole camera in the recording convention (x right, y up, z toward the camera, metres).

use glam::{DVec2, DVec3};

/// Pinhole intrinsics; pixel y grows downward, camera y upward, the camera looks along -z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Focal length in pixels.
    pub focal_px: f64,
    /// Principal point x (pixels).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
}

impl Camera {
    /// Kinect for Windows v1 colour camera, nominal: f = 531.15 px, centre (320, 240).
    pub const KINECT_V1_COLOUR: Camera = Camera {
        focal_px: 531.15,
        cx: 320.0,
        cy: 240.0,
    };

    /// Pixel of a camera-space point (in front of the camera: z < 0).
    pub fn project(&self, p: DVec3) -> DVec2 {
        let d = -p.z;
        DVec2::new(
            self.cx + self.focal_px * p.x / d,
            self.cy - self.focal_px * p.y / d,
        )
    }

    /// Camera-space point of a pixel at depth `depth` (metres, > 0).
    pub fn back_project(&self, pixel: DVec2, depth: f64) -> DVec3 {
        DVec3::new(
            (pixel.x - self.cx) * depth / self.focal_px,
            -(pixel.y - self.cy) * depth / self.focal_px,
            -depth,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn back_projection_inverts_projection() {
        let c = Camera::KINECT_V1_COLOUR;
        let px = DVec2::new(302.5, 211.0);
        let p = c.back_project(px, 1.2);
        assert!((c.project(p) - px).length() < 1e-9);
        // A point right of and above the optical axis lands right of and above the centre (pixel y down).
        let q = c.project(DVec3::new(0.1, 0.1, -1.0));
        assert!(q.x > 320.0 && q.y < 240.0);
        assert!((q.x - (320.0 + 53.115)).abs() < 1e-9);
    }
}
