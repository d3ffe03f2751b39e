//! OpenSeeFace's head pose in the recording convention (x image right, y up, z toward the
//! camera, metres), from its quaternion and a small perspective-n-point refinement.
//!
//! OpenSeeFace runs solvePnP on (row, column) image points: its camera axes are (down, right,
//! forward) and its reference model's (the subject's right, up, out of the face), both
//! left-handed, so its rotation `R = M(q)^T` (`matrix_to_quaternion` packs the quaternion of the
//! transpose) is proper between them. Its iterative solvePnP starts from a zero translation and
//! settles behind the camera (`t_z < 0`): that solution is the point reflection of a face mirrored
//! in depth, which projects like the face. Mirroring the depth back gives the proper in-front pose
//! `diag(-1, -1, 1) R`, `-t`; in the recording convention (camera `A = [[0,1,0],[-1,0,0],[0,0,-1]]`,
//! model `D = diag(-1, 1, 1)`, the packed point's `(-x, -y, -z)`)
//!
//! `R_rec = A diag(-1, -1, 1) M(q)^T D`, `t_rec = (-t_y, t_x, t_z)` (model units to metres),
//!
//! and, for a fit already in front (`t_z > 0`), `R_rec = A M(q)^T D`, `t_rec = (t_y, -t_x, -t_z)`.
//! Mirroring the depth is exact only under weak perspective, so that seed is refined by
//! Levenberg-Marquardt on the reprojection of the frame's own pose-free points 0-65 onto its 2D
//! landmarks, through a pinhole with focal length = image width (OpenSeeFace's) and the principal
//! point at the image centre (OpenSeeFace lays it on its transposed axes, a bug not copied here).
//! The refined pose is kept when it reprojects better than the seed. Everything here is on the
//! stack: no allocation per frame.

use crate::openseeface::OsfFace;
use crate::osf_frames::{METRES_PER_UNIT, to_recording};
use glam::{DMat3, DQuat, DVec3, Quat, Vec3};

/// Points the pose is fitted on: OpenSeeFace's 66 landmarks (not the pupils).
pub const FIT_POINTS: usize = 66;
/// Levenberg-Marquardt iterations at most.
pub const MAX_ITERATIONS: usize = 40;
/// The refinement stops when a step lowers the RMS error by under this fraction of it (a
/// millionth: some 1e-5 px on `megamind.osf`).
pub const STOP_GAIN: f64 = 1e-6;

/// A pinhole camera in image pixels (x right, y down) looking down the recording's -z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Focal length in pixels.
    pub focal: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

impl Camera {
    /// The camera the pose is fitted with: focal length = `width` (OpenSeeFace's), principal
    /// point at the image centre.
    pub fn centred(width: f32, height: f32) -> Self {
        Self {
            focal: f64::from(width),
            cx: f64::from(width) * 0.5,
            cy: f64::from(height) * 0.5,
        }
    }

    /// OpenSeeFace's own camera as it acts on (x, y) pixels: its principal point `(width/2,
    /// height/2)` laid on (row, column) puts it at image `(height/2, width/2)`.
    pub fn openseeface(width: f32, height: f32) -> Self {
        Self {
            focal: f64::from(width),
            cx: f64::from(height) * 0.5,
            cy: f64::from(width) * 0.5,
        }
    }

    /// The image point of camera-space point `p` (recording convention), or `None` when `p` is
    /// not in front of the camera.
    pub fn project(&self, p: DVec3) -> Option<[f64; 2]> {
        let d = -p.z;
        (d > 1e-9).then(|| {
            [
                self.cx + self.focal * p.x / d,
                self.cy - self.focal * p.y / d,
            ]
        })
    }
}

/// A rigid head pose, model to camera, in the recording convention (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadPose {
    /// Rotation, model to camera.
    pub rotation: DQuat,
    /// Translation, metres.
    pub translation: DVec3,
}

impl HeadPose {
    /// The camera-space point of model point `p`.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        (self.rotation * p.as_dvec3() + self.translation).as_vec3()
    }

    /// The rotation in single precision.
    pub fn rotation_f32(&self) -> Quat {
        self.rotation.as_quat()
    }
}

/// How the frame's pose was found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseFit {
    /// The pose the frame's points are placed with.
    pub pose: HeadPose,
    /// The corrected quaternion's pose (the refinement's seed).
    pub seed: HeadPose,
    /// RMS reprojection error (pixels) of `pose` over the fitted points.
    pub rms_px: f64,
    /// RMS reprojection error (pixels) of `seed`.
    pub seed_rms_px: f64,
    /// Points fitted.
    pub points: usize,
}

/// `A diag(-1, -1, 1)`: OpenSeeFace's camera axes, the depth mirror undone, to the recording's.
fn behind_to_recording() -> DMat3 {
    DMat3::from_cols(DVec3::Y, -DVec3::X, -DVec3::Z)
}

/// `A`: OpenSeeFace's camera axes (down, right, forward) to the recording's.
fn camera_to_recording() -> DMat3 {
    DMat3::from_cols(-DVec3::Y, DVec3::X, -DVec3::Z)
}

/// `D`: the recording's model axes to OpenSeeFace's reference model's (its own inverse).
fn model_axes() -> DMat3 {
    DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0))
}

/// The proper in-front pose of OpenSeeFace's quaternion `q` (x, y, z, w) and translation `t`
/// (model units), or `None` when they are not finite, `q` is far from unit length or `t_z` is 0.
pub fn seed_pose(q: [f32; 4], t: [f32; 3]) -> Option<HeadPose> {
    let q = DQuat::from_xyzw(
        f64::from(q[0]),
        f64::from(q[1]),
        f64::from(q[2]),
        f64::from(q[3]),
    );
    let t = DVec3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2]));
    if !q.is_finite() || !t.is_finite() || (q.length() - 1.0).abs() > 1e-2 || t.z == 0.0 {
        return None;
    }
    let r_osf = DMat3::from_quat(q.normalize()).transpose();
    let s = f64::from(METRES_PER_UNIT);
    let (r, t_rec) = if t.z < 0.0 {
        (
            behind_to_recording() * r_osf * model_axes(),
            DVec3::new(-t.y, t.x, t.z) * s,
        )
    } else {
        (
            camera_to_recording() * r_osf * model_axes(),
            DVec3::new(t.y, -t.x, -t.z) * s,
        )
    };
    Some(HeadPose {
        rotation: DQuat::from_mat3(&r).normalize(),
        translation: t_rec,
    })
}

/// The quaternion (x, y, z, w) and translation (model units) OpenSeeFace would send for `pose`,
/// as its solvePnP does, behind the camera: the inverse of [`seed_pose`] (for a pose in front,
/// `pose.translation.z < 0`).
pub fn osf_pose_fields(pose: &HeadPose) -> ([f32; 4], [f32; 3]) {
    // R_rec = B M^T D  =>  M = D R_rec^T B, with B = A diag(-1, -1, 1).
    let m = model_axes() * DMat3::from_quat(pose.rotation).transpose() * behind_to_recording();
    let q = DQuat::from_mat3(&m).normalize();
    let t = pose.translation / f64::from(METRES_PER_UNIT);
    (
        [q.x as f32, q.y as f32, q.z as f32, q.w as f32],
        [t.y as f32, -t.x as f32, t.z as f32],
    )
}

/// Model points (recording convention, metres) and their image points, the points to use.
pub struct Correspondences<'a> {
    /// Model points.
    pub model: &'a [Vec3],
    /// Image points, pixels (x right, y down).
    pub image: &'a [[f32; 2]],
    /// Which points take part.
    pub used: &'a [bool],
}

impl Correspondences<'_> {
    fn pairs(&self) -> impl Iterator<Item = (DVec3, [f64; 2])> + '_ {
        self.model
            .iter()
            .zip(self.image)
            .zip(self.used)
            .filter(|(_, u)| **u)
            .map(|((m, i), _)| (m.as_dvec3(), [f64::from(i[0]), f64::from(i[1])]))
    }

    /// Points taking part.
    pub fn count(&self) -> usize {
        self.pairs().count()
    }

    /// RMS reprojection error (pixels) of `pose` through `cam`: infinite when a point is not in
    /// front of the camera, `None` with no points.
    pub fn rms_px(&self, cam: &Camera, pose: &HeadPose) -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0usize);
        for (m, i) in self.pairs() {
            let Some(p) = cam.project(pose.rotation * m + pose.translation) else {
                return Some(f64::INFINITY);
            };
            sum += (p[0] - i[0]).powi(2) + (p[1] - i[1]).powi(2);
            n += 1;
        }
        (n > 0).then(|| (sum / n as f64).sqrt())
    }

    /// Normal equations `J^T J`, `J^T r` and the squared error at `pose`, for the update
    /// `rotation <- exp(w) rotation`, `translation <- translation + dt`, parameters `(w, dt)`.
    fn normal_equations(&self, cam: &Camera, pose: &HeadPose) -> Option<([f64; 36], [f64; 6])> {
        let mut jtj = [0.0; 36];
        let mut jtr = [0.0; 6];
        for (m, i) in self.pairs() {
            let q = pose.rotation * m;
            let p = q + pose.translation;
            let proj = cam.project(p)?;
            let d = -p.z;
            // d(u)/dP and d(v)/dP of u = cx + f x / d, v = cy - f y / d, d = -z.
            let du = DVec3::new(cam.focal / d, 0.0, cam.focal * p.x / (d * d));
            let dv = DVec3::new(0.0, -cam.focal / d, -cam.focal * p.y / (d * d));
            for (g, r) in [(du, proj[0] - i[0]), (dv, proj[1] - i[1])] {
                // dP/dw = w x q, so d/dw (g . P) = q x g.
                let w = q.cross(g);
                let row = [w.x, w.y, w.z, g.x, g.y, g.z];
                for a in 0..6 {
                    jtr[a] += row[a] * r;
                    for b in 0..6 {
                        jtj[a * 6 + b] += row[a] * row[b];
                    }
                }
            }
        }
        Some((jtj, jtr))
    }
}

/// Solves the symmetric positive-definite 6 x 6 system `a x = b` (Cholesky), `None` when `a`
/// is not positive definite.
fn solve6(a: &[f64; 36], b: &[f64; 6]) -> Option<[f64; 6]> {
    let mut l = [0.0; 36];
    for i in 0..6 {
        for j in 0..=i {
            let mut s = a[i * 6 + j];
            for k in 0..j {
                s -= l[i * 6 + k] * l[j * 6 + k];
            }
            if i == j {
                if s.is_nan() || s <= 0.0 {
                    return None;
                }
                l[i * 6 + i] = s.sqrt();
            } else {
                l[i * 6 + j] = s / l[j * 6 + j];
            }
        }
    }
    let mut y = [0.0; 6];
    for i in 0..6 {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * 6 + k] * y[k];
        }
        y[i] = s / l[i * 6 + i];
    }
    let mut x = [0.0; 6];
    for i in (0..6).rev() {
        let mut s = y[i];
        for k in i + 1..6 {
            s -= l[k * 6 + i] * x[k];
        }
        x[i] = s / l[i * 6 + i];
    }
    Some(x)
}

/// Levenberg-Marquardt from `seed` on the reprojection of `c` through `cam`; with `rotate` false
/// only the translation moves (a baseline). Returns the pose and its RMS error (pixels), `None`
/// with under 4 points or a seed not in front of the camera.
pub fn refine(
    c: &Correspondences<'_>,
    cam: &Camera,
    seed: HeadPose,
    rotate: bool,
) -> Option<(HeadPose, f64)> {
    if c.count() < 4 {
        return None;
    }
    let mut pose = seed;
    let mut err = c.rms_px(cam, &pose)?;
    if !err.is_finite() {
        return None;
    }
    let mut lambda = 1e-3;
    for _ in 0..MAX_ITERATIONS {
        let Some((mut jtj, mut jtr)) = c.normal_equations(cam, &pose) else {
            break;
        };
        if !rotate {
            for a in 0..3 {
                for b in 0..6 {
                    jtj[a * 6 + b] = 0.0;
                    jtj[b * 6 + a] = 0.0;
                }
                jtj[a * 6 + a] = 1.0;
                jtr[a] = 0.0;
            }
        }
        let mut damped = jtj;
        for a in 0..6 {
            damped[a * 6 + a] *= 1.0 + lambda;
        }
        let neg = jtr.map(|x| -x);
        let Some(dx) = solve6(&damped, &neg) else {
            lambda *= 10.0;
            continue;
        };
        let w = DVec3::new(dx[0], dx[1], dx[2]);
        let trial = HeadPose {
            rotation: (DQuat::from_scaled_axis(w) * pose.rotation).normalize(),
            translation: pose.translation + DVec3::new(dx[3], dx[4], dx[5]),
        };
        match c.rms_px(cam, &trial) {
            Some(e) if e < err => {
                let gain = err - e;
                pose = trial;
                err = e;
                lambda = (lambda * 0.1).max(1e-12);
                if gain <= STOP_GAIN * err.max(1e-9) {
                    break;
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > 1e12 {
                    break;
                }
            }
        }
    }
    Some((pose, err))
}

/// The landmarks the pose is fitted on: 0-65 with finite points, `used` filled (allocation-free).
pub fn fit_points(f: &OsfFace, model: &mut [Vec3; FIT_POINTS], used: &mut [bool; FIT_POINTS]) {
    for i in 0..FIT_POINTS {
        let m = to_recording(f.points_3d[i]);
        let im = f.points_2d[i];
        model[i] = m;
        used[i] = m.is_finite() && im[0].is_finite() && im[1].is_finite();
    }
}

/// The head pose of a tracked face (`success` 1): the corrected quaternion refined on its own
/// pose-free points and 2D landmarks (through [`Camera::centred`]); `None` when the face has no
/// usable quaternion and translation or too few points.
pub fn head_pose(f: &OsfFace) -> Option<PoseFit> {
    let seed = seed_pose(f.quaternion, f.translation)?;
    let mut model = [Vec3::ZERO; FIT_POINTS];
    let mut used = [false; FIT_POINTS];
    fit_points(f, &mut model, &mut used);
    let c = Correspondences {
        model: &model,
        image: &f.points_2d[..FIT_POINTS],
        used: &used,
    };
    let cam = Camera::centred(f.width, f.height);
    let seed_rms_px = c.rms_px(&cam, &seed)?;
    let (pose, rms_px) = match refine(&c, &cam, seed, true) {
        Some((p, e)) if e < seed_rms_px => (p, e),
        _ => (seed, seed_rms_px),
    };
    Some(PoseFit {
        pose,
        seed,
        rms_px,
        seed_rms_px,
        points: c.count(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn angle_between(a: DQuat, b: DQuat) -> f64 {
        a.angle_between(b)
    }

    #[test]
    fn frontal_osf_pose_is_identity_and_fields_invert() {
        // A frontal face in OpenSeeFace's (behind-camera) convention: rmat maps model x (the
        // subject's right) to camera y (column) and y (up) to camera x (row), z to -z, the
        // 180-degree turn about (1, 1, 0) / sqrt 2; its quaternion is that of the transpose.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let seed = seed_pose([h, h, 0.0, 0.0], [0.0, 0.0, -5.0]).unwrap();
        assert!(angle_between(seed.rotation, DQuat::IDENTITY) < 1e-6);
        let s = f64::from(METRES_PER_UNIT);
        assert!((seed.translation - DVec3::new(0.0, 0.0, -5.0 * s)).length() < 1e-6);
        let pose = HeadPose {
            rotation: DQuat::from_euler(glam::EulerRot::YXZ, 0.3, -0.2, 0.1),
            translation: DVec3::new(0.05, -0.02, -0.7),
        };
        let (q, t) = osf_pose_fields(&pose);
        assert!(t[2] < 0.0, "sent behind the camera, as OpenSeeFace does");
        let back = seed_pose(q, t).unwrap();
        assert!(angle_between(back.rotation, pose.rotation) < 1e-6);
        assert!((back.translation - pose.translation).length() < 1e-6);
    }

    #[test]
    fn an_in_front_fit_is_taken_as_it_is() {
        // The same frontal face solved in front: rmat = the axis swap with z kept (its own
        // transpose), det +1 between the two left-handed frames.
        let m = DMat3::from_cols(-DVec3::Y, -DVec3::X, -DVec3::Z);
        let q = DQuat::from_mat3(&m.transpose());
        let seed = seed_pose(
            [q.x as f32, q.y as f32, q.z as f32, q.w as f32],
            [0.0, 0.0, 5.0],
        )
        .unwrap();
        assert!(angle_between(seed.rotation, DQuat::IDENTITY) < 1e-6);
        assert!(seed.translation.z < 0.0);
        assert!(seed_pose([0.0; 4], [0.0, 0.0, 1.0]).is_none());
    }

    #[test]
    fn solve6_solves() {
        let mut a = [0.0; 36];
        for i in 0..6 {
            for j in 0..6 {
                a[i * 6 + j] = 1.0 / (1.0 + (i + j) as f64) + if i == j { 1.0 } else { 0.0 };
            }
        }
        let x = [1.0, -2.0, 0.5, 3.0, 0.0, -1.0];
        let mut b = [0.0; 6];
        for i in 0..6 {
            b[i] = (0..6).map(|j| a[i * 6 + j] * x[j]).sum();
        }
        let got = solve6(&a, &b).unwrap();
        for (g, w) in got.iter().zip(x) {
            assert!((g - w).abs() < 1e-9, "{got:?}");
        }
    }
}
