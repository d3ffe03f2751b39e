//! An OpenSeeFace face as an `openseeface68` landmark frame, and back (for `mimic send
//! --openseeface`).
//!
//! The frame's points are OpenSeeFace's pose-free 3D points 0-67 (the 66 iBUG-like points and the
//! two pupils; the eyeball centres 68-69 are not kept), turned into the recording convention
//! (metres, x image right = the subject's left, y up, z toward the camera) and placed with the
//! face's head pose ([`crate::osf_pose::head_pose`]: its quaternion, corrected and refined on the
//! 2D landmarks), `R p + t`, so the retargeter's rigid fit sees the head turn as in a Kinect
//! recording. The datagram packs `(x, -y, -z)` of the tracker's points with x to the subject's
//! right, y down and z away from the camera, so the pose-free recording point is `(-x, -y, -z) *
//! METRES_PER_UNIT`. A face whose 3D fit failed (`success` 0: all-zero points), or whose pose is
//! unusable (a non-unit quaternion), is a lost frame with no points. A pupil is invalid when its
//! confidence is under 0.20 or its eye is closed (openness under 0.30), the thresholds under which
//! OpenSeeFace itself does not draw it; any non-finite point is invalid.

use crate::openseeface::{OsfFace, POINTS_2D};
use crate::osf_pose::{Camera, HeadPose, head_pose, osf_pose_fields};
use glam::{DQuat, Vec3};
use mimic_types::LandmarkFrame;

/// Layout name of OpenSeeFace's 68 points.
pub const LAYOUT: &str = "openseeface68";
/// Points per frame.
pub const POINT_COUNT: usize = POINTS_2D;
/// Metres per OpenSeeFace reference-model unit: the model's jaw points 0 and 16 are 0.91 units
/// apart, taken as 0.15 m (the width of an adult face at the ears' height; OpenFace_Test.csv's
/// iBUG 0-16 distance is 0.151 m).
pub const METRES_PER_UNIT: f32 = 0.15 / 0.91;
/// Confidence under which a pupil is invalid.
pub const PUPIL_MIN_CONFIDENCE: f32 = 0.20;
/// Eye openness under which that eye's pupil is invalid.
pub const PUPIL_MIN_OPENNESS: f32 = 0.30;

/// The recording-convention point of OpenSeeFace 3D point `p` (as packed).
pub fn to_recording(p: [f32; 3]) -> Vec3 {
    Vec3::new(-p[0], -p[1], -p[2]) * METRES_PER_UNIT
}

/// The packed OpenSeeFace 3D point of recording point `v` (inverse of [`to_recording`]).
pub fn from_recording(v: Vec3) -> [f32; 3] {
    let p = -v / METRES_PER_UNIT;
    [p.x, p.y, p.z]
}

/// Fills `frame` (reusing its buffers, allocation-free) with face `f` at time `t_us`: the
/// pose-free points placed with the face's head pose.
pub fn fill_frame(f: &OsfFace, t_us: i64, frame: &mut LandmarkFrame) {
    frame.timestamp_us = t_us;
    frame.points.clear();
    frame.valid.clear();
    let pose = if f.success == 1 { head_pose(f) } else { None };
    frame.tracked = pose.is_some();
    let Some(fit) = pose else {
        return;
    };
    for (i, p) in f.points_3d.iter().take(POINT_COUNT).enumerate() {
        let v = fit.pose.apply(to_recording(*p));
        let mut ok = v.is_finite();
        if i >= 66 {
            let eye = f.eye_open[i - 66];
            ok &= f.confidence[i] >= PUPIL_MIN_CONFIDENCE && eye >= PUPIL_MIN_OPENNESS;
        }
        frame.points.push(v);
        frame.valid.push(ok);
    }
}

/// Face `f` at time `t_us` as a new frame.
pub fn to_frame(f: &OsfFace, t_us: i64) -> LandmarkFrame {
    let mut frame = LandmarkFrame {
        timestamp_us: t_us,
        points: Vec::with_capacity(POINT_COUNT),
        valid: Vec::with_capacity(POINT_COUNT),
        tracked: false,
    };
    fill_frame(f, t_us, &mut frame);
    frame
}

/// Depth (metres) a frame is placed at when its nose tip is not in front of the camera (a
/// recording of pose-free points).
pub const SEND_MIN_DEPTH_M: f32 = 0.5;

/// A face block carrying `frame` (an `openseeface68` frame) as face `face_id` of a `width` x
/// `height` image, as OpenSeeFace would send it: the frame's points relative to its nose tip (30)
/// as the pose-free 3D points, the pose an identity rotation with the nose tip's position as the
/// translation (its depth at least [`SEND_MIN_DEPTH_M`]), packed as OpenSeeFace's behind-camera
/// quaternion and translation ([`osf_pose_fields`]), the 2D points the perspective projection of
/// the placed points through [`Camera::centred`]; confidence 1 for valid points and 0 for the
/// others; euler angles 0. [`to_frame`] of it gives back the frame's points (up to a translation
/// when the depth was raised). A lost frame is a failed fit (`success` 0, zero points).
pub fn to_face(frame: &LandmarkFrame, face_id: i32, width: f32, height: f32) -> OsfFace {
    let mut f = OsfFace {
        timestamp: frame.timestamp_us as f64 * 1e-6,
        face_id,
        width,
        height,
        eye_open: [1.0, 1.0],
        quaternion: [0.0, 0.0, 0.0, 1.0],
        ..OsfFace::default()
    };
    let nose = frame.points.get(30).copied().unwrap_or(Vec3::NAN);
    let nose_ok = frame.valid.get(30).copied().unwrap_or(false) && nose.is_finite();
    if !frame.tracked || frame.points.len() < POINT_COUNT || !nose_ok {
        f.pnp_error = 99999.0;
        return f;
    }
    f.success = 1;
    let pose = HeadPose {
        rotation: DQuat::IDENTITY,
        translation: Vec3::new(nose.x, nose.y, nose.z.min(-SEND_MIN_DEPTH_M)).as_dvec3(),
    };
    (f.quaternion, f.translation) = osf_pose_fields(&pose);
    let cam = Camera::centred(width, height);
    for i in 0..POINT_COUNT {
        let v = frame.points[i];
        let ok = frame.valid.get(i).copied().unwrap_or(false) && v.is_finite();
        let local = v - nose;
        let image = cam.project(pose.apply(local).as_dvec3());
        let ok = ok && image.is_some();
        f.points_3d[i] = if ok { from_recording(local) } else { [0.0; 3] };
        f.confidence[i] = if ok { 1.0 } else { 0.0 };
        let [x, y] = image.unwrap_or([0.0; 2]);
        f.points_2d[i] = [x as f32, y as f32];
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversion_inverts_and_keeps_sides() {
        // SOURCE.md's packet 0: 3D 0 (subject's right jaw top) and 16 (left), chin 8, nose tip 30.
        let right_jaw = to_recording([0.5074, -0.4181, 1.0102]);
        let left_jaw = to_recording([-0.3423, -0.1582, 0.6132]);
        let chin = to_recording([0.1401, 0.6354, 0.3948]);
        let nose = to_recording([0.0, 0.0, -0.0454]);
        assert!(
            left_jaw.x > right_jaw.x,
            "the subject's left is image right (+x)"
        );
        assert!(chin.y < nose.y, "y is up");
        assert!(nose.z > right_jaw.z, "z is toward the camera");
        let back = from_recording(right_jaw);
        for (a, b) in back.iter().zip([0.5074, -0.4181, 1.0102]) {
            assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0));
        }
    }

    #[test]
    fn a_failed_fit_is_a_lost_frame_and_pupils_follow_the_eyes() {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let mut f = OsfFace {
            success: 1,
            eye_open: [0.1, 1.0],
            width: 640.0,
            height: 480.0,
            // A frontal face 5 units behind the camera, as OpenSeeFace's solvePnP leaves it.
            quaternion: [h, h, 0.0, 0.0],
            translation: [0.0, 0.0, -5.0],
            ..OsfFace::default()
        };
        f.confidence = [1.0; POINTS_2D];
        let frame = to_frame(&f, 5);
        assert!(frame.tracked);
        assert_eq!(frame.points.len(), POINT_COUNT);
        assert!(!frame.valid[66], "right eye closed: its pupil is invalid");
        assert!(frame.valid[67]);
        let mut no_pose = f.clone();
        no_pose.quaternion = [0.0; 4];
        assert!(!to_frame(&no_pose, 6).tracked, "no usable pose: lost");
        f.success = 0;
        let lost = to_frame(&f, 6);
        assert!(!lost.tracked && lost.points.is_empty());
        assert_eq!(to_face(&lost, 0, 640.0, 480.0).success, 0);
    }

    #[test]
    fn a_sent_frame_comes_back_with_its_points() {
        // A turned head 0.8 m away (yaw 0.4, pitch -0.2, roll 0.15 rad) on a plausible face: the
        // reference-like points of a 15 cm wide face, with depth.
        let rot = glam::Quat::from_euler(glam::EulerRot::YXZ, 0.4, -0.2, 0.15);
        let mut rng = mimic_testkit::Lcg::new(11);
        let mut frame = LandmarkFrame {
            timestamp_us: 40_000,
            points: Vec::new(),
            valid: vec![true; POINT_COUNT],
            tracked: true,
        };
        for i in 0..POINT_COUNT {
            let a = i as f32 * 0.37;
            let local = Vec3::new(
                0.075 * a.cos(),
                0.09 * (a * 1.7).sin(),
                -0.06 * (1.0 - a.cos().abs()) + 0.01 * rng.next_f32(),
            );
            frame
                .points
                .push(rot * local + Vec3::new(0.02, -0.03, -0.8));
        }
        frame.valid[66] = false;
        let face = to_face(&frame, 0, 640.0, 480.0);
        assert_eq!(face.confidence[66], 0.0);
        let back = to_frame(&face, 40_000);
        assert!(back.tracked);
        for i in 0..POINT_COUNT {
            if i == 66 {
                assert!(!back.valid[i], "sent with confidence 0: invalid");
                continue;
            }
            // f32 storage of units of 0.165 m, then the pose: a few ulps of 1 m.
            let tol = 1e-5;
            assert!(
                (back.points[i] - frame.points[i]).length() <= tol,
                "point {i}: {} vs {}",
                back.points[i],
                frame.points[i]
            );
        }
    }
}
