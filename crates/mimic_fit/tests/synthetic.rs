//! The fitter on a synthetic CANDIDE-3 performance with known pose, shape and AU curves,
//! observed through the `kinect-gfe100` correspondences as a Kinect would: pixels with noise,
//! depth with noise, and depth missing at random.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::{DQuat, DVec2, DVec3};
use mimic_fit::{
    AUV_COUNT, Camera, Candide3, FitSettings, Fitter, OddParts, PointObservation, Pose,
};
use mimic_testkit::XorShift64Star;
use mimic_types::ModelCorrespondence;
use std::path::PathBuf;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn model() -> Candide3 {
    let bytes = std::fs::read(repo().join("configs/models/candide3/candide3.wfm")).unwrap();
    Candide3::parse(&String::from_utf8_lossy(&bytes)).unwrap()
}

fn correspondences() -> (Vec<ModelCorrespondence>, usize) {
    let l = mimic_assets::load_layout(&repo().join("configs/layouts/kinect-gfe100.toml")).unwrap();
    (l.candide_correspondences, l.point_count)
}

const FRAMES: usize = 150;
const NEUTRAL_FRAMES: usize = 10;
const PIXEL_NOISE: f64 = 0.5;
const DEPTH_NOISE_M: f64 = 0.002;
const MISSING_DEPTH: f64 = 0.3;

fn true_pose(i: usize) -> Pose {
    let t = i as f64 / 15.0;
    let yaw = 0.25 * (0.7 * t).sin();
    let pitch = 0.15 * (0.45 * t + 0.3).sin();
    let roll = 0.08 * (0.3 * t).cos();
    Pose {
        rotation: DQuat::from_euler(glam::EulerRot::YXZ, yaw, pitch, roll),
        translation: DVec3::new(
            0.05 * (0.2 * t).sin(),
            0.03 * (0.25 * t).cos(),
            -1.2 + 0.1 * (0.15 * t).sin(),
        ),
        scale: 0.095,
    }
}

fn true_au(i: usize) -> Vec<f64> {
    if i < NEUTRAL_FRAMES {
        return vec![0.0; AUV_COUNT];
    }
    let t = (i - NEUTRAL_FRAMES) as f64 / 15.0;
    let fitted = FitSettings::default().units;
    (0..AUV_COUNT)
        .map(|k| {
            if !fitted.contains(&k) {
                return 0.0;
            }
            let w = 0.6 + 0.17 * k as f64;
            let a = (w * t + k as f64).sin();
            // Half of the units only ever rise (like a jaw drop), half swing both ways.
            if k % 2 == 0 {
                0.7 * a.max(0.0)
            } else {
                0.5 * a
            }
        })
        .collect()
}

struct Sequence {
    obs: Vec<Vec<PointObservation>>,
    shape: Vec<f64>,
}

fn sequence(model: &Candide3, corr: &[ModelCorrespondence], point_count: usize) -> Sequence {
    let camera = Camera::KINECT_V1_COLOUR;
    let mut rng = XorShift64Star(0x9E37_79B9_7F4A_7C15);
    let shape: Vec<f64> = (0..model.shape_units.len())
        .map(|_| 0.3 * (2.0 * rng.uniform() - 1.0))
        .collect();
    // A fitter only used to pose the model: its `vertices` is the model's forward map.
    let mut forward = Fitter::new(
        model.clone(),
        corr,
        point_count,
        camera,
        FitSettings::default(),
    )
    .unwrap();
    forward.set_shape(&shape);
    let mut verts = Vec::new();
    let obs = (0..FRAMES)
        .map(|i| {
            forward.vertices(&true_pose(i), &true_au(i), &[], &mut verts);
            let mut frame = vec![PointObservation::default(); point_count];
            for (point, x) in points(corr, &verts) {
                let pixel =
                    camera.project(x) + DVec2::new(rng.normal(), rng.normal()) * PIXEL_NOISE;
                let position = (rng.uniform() >= MISSING_DEPTH)
                    .then(|| camera.back_project(pixel, -x.z + DEPTH_NOISE_M * rng.normal()));
                frame[point] = PointObservation {
                    pixel: Some(pixel),
                    position,
                };
            }
            frame
        })
        .collect();
    Sequence { obs, shape }
}

#[test]
fn recovers_pose_and_au_curves_of_a_synthetic_performance() {
    let model = model();
    let (corr, point_count) = correspondences();
    let seq = sequence(&model, &corr, point_count);
    let mut fitter = Fitter::new(
        model,
        &corr,
        point_count,
        Camera::KINECT_V1_COLOUR,
        FitSettings::default(),
    )
    .unwrap();
    let first: Vec<&[PointObservation]> = seq.obs[..NEUTRAL_FRAMES]
        .iter()
        .map(|f| f.as_slice())
        .collect();
    assert_eq!(fitter.estimate_shape(&first), NEUTRAL_FRAMES);
    // Shape units the correspondences see (not: 6 cheeks z, 9 nose pointing up, 13 chin width, which
    // move only unobserved vertices or points the GFE list leaves out). Noise alone pins each to
    // ~0.5 px / (5 px per unit * sqrt(10 frames * 68 points)) ~ 0.004; what limits them is the coupling
    // with the pose of 10 nearly equal frames: the vertical-position units (eyes, nose, mouth) move a
    // feature by 0.1 model units per unit, and a pitch error of 0.5 deg (the pose bound's scale)
    // moves features 0.2 units in front of the others by 0.2 * 0.009 = 0.0017 units, i.e. 0.02 in
    // the coefficient, plus the 2 px ridge's pull toward 0 (<= 4 / (25 * 68) ~ 0.2 % per unit, and
    // with several units sharing each feature, up to a few times that of 0.3). Bound 0.1 (measured 0.06).
    let observable = [0, 1, 2, 3, 4, 5, 7, 8, 10, 11, 12];
    let shape_err = observable
        .iter()
        .map(|&j| (fitter.shape()[j] - seq.shape[j]).abs())
        .fold(0.0, f64::max);
    let mut au_sq = [0.0f64; AUV_COUNT];
    let (mut rot_max, mut trans_max, mut res_max) = (0.0f64, 0.0f64, 0.0f64);
    for (i, obs) in seq.obs.iter().enumerate() {
        let r = fitter.fit(obs);
        assert!(r.tracked, "frame {i} lost: {r:?}");
        let truth = true_pose(i);
        rot_max = rot_max.max(r.pose.rotation.angle_between(truth.rotation).to_degrees());
        trans_max = trans_max.max((r.pose.translation - truth.translation).length());
        res_max = res_max.max(r.residual_px);
        for (k, (a, b)) in r.au.iter().zip(true_au(i)).enumerate() {
            au_sq[k] += (a - b) * (a - b);
        }
    }
    let au_rms: Vec<f64> = au_sq.iter().map(|s| (s / FRAMES as f64).sqrt()).collect();
    eprintln!(
        "shape max err {shape_err:.3}, rotation max {rot_max:.2} deg, translation max {:.1} mm, residual max {res_max:.2} px, AU rms {au_rms:.3?}",
        trans_max * 1e3
    );
    assert!(
        shape_err < 0.1,
        "shape error {shape_err}: {:?} vs {:?}",
        fitter.shape(),
        seq.shape
    );
    // Tolerances. A unit AU moves its vertices by ~0.1-0.26 model units = 0.1 * 0.095 m * 531 px / 1.2 m
    // ~ 4-11 px; with 0.5 px pixel noise on the ~4-12 points an AU moves, its standard error is about
    // 0.5 / (4 px * sqrt(4)) ~ 0.06 for the weakest unit, and the priors (1 px ridge, 0.5 px smoothing
    // against ~10-40 px^2 of data information) bias it by at most ~10 %. So RMS <= 0.15 (about 2.5 sigma
    // of the weakest unit plus the bias) per unit.
    for (k, e) in au_rms.iter().enumerate() {
        assert!(*e < 0.15, "AU {k} RMS error {e}");
    }
    // Pose: ~70 points at 0.5 px on a ~45 px face give rotation to ~0.5 / 45 / sqrt(70) rad ~ 0.1 deg per
    // axis and depth to ~1.2 m * 0.5 / 45 / sqrt(70) ~ 2 mm. Pitch is coupled to the shape units the
    // correspondences barely see: "nose pointing up" lifts the nose tip (vertex 5, 0.21 model units in
    // front of the eye corners) by 0.05 units per unit; its estimate is off by up to 0.1 (half the
    // truth's 0.2), a 0.005 unit lift the fit can take as a pitch of 0.005 / 0.21 rad = 1.4 deg, and
    // the vertical AUs add ~0.05 * 0.1 / 0.4 rad ~ 0.7 deg. Bound: 3 deg (measured max 1.9 deg), 10 mm.
    assert!(rot_max < 3.0, "rotation error {rot_max} deg");
    assert!(trans_max < 0.010, "translation error {trans_max} m");
    // The residual is the pixel noise: RMS of a 2D N(0, 0.5 px) offset is 0.5 * sqrt(2) = 0.71 px; allow 1.5x.
    assert!(
        res_max < 1.5 * PIXEL_NOISE * 2f64.sqrt(),
        "residual {res_max}"
    );
}

#[test]
fn frames_with_too_few_points_are_lost_not_invented() {
    let model = model();
    let (corr, point_count) = correspondences();
    let seq = sequence(&model, &corr, point_count);
    let mut fitter = Fitter::new(
        model,
        &corr,
        point_count,
        Camera::KINECT_V1_COLOUR,
        FitSettings::default(),
    )
    .unwrap();
    assert!(fitter.fit(&seq.obs[0]).tracked);
    // Keep only 8 correspondences (fewer than min_points = 12).
    let mut sparse = seq.obs[1].clone();
    for c in corr.iter().skip(8) {
        sparse[c.point] = PointObservation::default();
    }
    let r = fitter.fit(&sparse);
    assert!(!r.tracked);
    assert_eq!(r.points_used, 8);
    // The next full frame is fitted again from a cold start.
    assert!(fitter.fit(&seq.obs[2]).tracked);
}

/// Camera-space position of each correspondence of `corr` on the posed vertices `verts`.
fn points(corr: &[ModelCorrespondence], verts: &[DVec3]) -> Vec<(usize, DVec3)> {
    corr.iter()
        .map(|c| {
            let x: DVec3 = c
                .blend()
                .unwrap()
                .iter()
                .map(|&(v, w)| verts[v] * f64::from(w))
                .sum();
            (c.point, x)
        })
        .collect()
}

/// A one-sided smile: a still, neutral face whose subject's-left mouth corner (GFE points 54 and
/// 64, CANDIDE-3 vertex 31 and its inner lip) alone moves 6 px outwards and 3 px up. With the odd
/// parts fitted (after the pose, the default, or jointly) the left corner of the model follows and
/// the right (vertex 64) stays; fitted symmetric, both corners move alike.
#[test]
fn a_one_sided_smile_stays_one_sided() {
    let model = model();
    let (corr, point_count) = correspondences();
    let camera = Camera::KINECT_V1_COLOUR;
    let pose = true_pose(0);
    let forward = Fitter::new(
        model.clone(),
        &corr,
        point_count,
        camera,
        FitSettings::default(),
    )
    .unwrap();
    let mut verts = Vec::new();
    forward.vertices(&pose, &[0.0; AUV_COUNT], &[], &mut verts);
    let neutral_points = points(&corr, &verts);
    let frame = |smile: f64| -> Vec<PointObservation> {
        let mut obs = vec![PointObservation::default(); point_count];
        for &(point, x) in &neutral_points {
            let mut pixel = camera.project(x);
            if point == 54 || point == 64 {
                // Subject's left is image right (+x); up is -y in the image.
                pixel += DVec2::new(6.0, -3.0) * smile;
            }
            obs[point] = PointObservation {
                pixel: Some(pixel),
                position: Some(camera.back_project(pixel, -x.z)),
            };
        }
        obs
    };
    let corner_moves = |odd: OddParts| -> (f64, f64) {
        let settings = FitSettings {
            odd,
            ..FitSettings::default()
        };
        let mut f = Fitter::new(model.clone(), &corr, point_count, camera, settings).unwrap();
        let neutral = frame(0.0);
        f.estimate_shape(&[neutral.as_slice(); 3]);
        let r0 = f.fit(&neutral);
        let mut v0 = Vec::new();
        f.vertices(&r0.pose, &r0.au, &r0.au_odd, &mut v0);
        let mut r = r0;
        for k in 1..=10 {
            r = f.fit(&frame(f64::from(k) / 10.0));
        }
        assert!(r.tracked);
        assert_eq!(
            r.au_odd.len(),
            if odd == OddParts::Off { 0 } else { AUV_COUNT }
        );
        let mut v1 = Vec::new();
        f.vertices(&r.pose, &r.au, &r.au_odd, &mut v1);
        // Image-plane motion of the two corners (pixels).
        let moved = |v: usize| (camera.project(v1[v]) - camera.project(v0[v])).length();
        (moved(31), moved(64))
    };
    assert_eq!(FitSettings::default().odd, OddParts::AfterPose);
    let (left, right) = corner_moves(OddParts::AfterPose);
    let (joint_left, joint_right) = corner_moves(OddParts::Joint);
    let (sym_left, sym_right) = corner_moves(OddParts::Off);
    eprintln!(
        "one-sided smile of 6.7 px: the fit moves the corners {left:.2} / {right:.2} px with the odd parts after the pose, \
         {joint_left:.2} / {joint_right:.2} px jointly, {sym_left:.2} / {sym_right:.2} px symmetric"
    );
    // The tracked corner moved sqrt(36 + 9) = 6.7 px. With odd parts: the left corner follows at
    // least 0.3 of it (the fitted units move the corner sideways and down, not up, and the
    // neighbours that did not move hold it back) and the right corner at most a tenth of the left.
    for (what, l, r) in [
        ("after the pose", left, right),
        ("jointly", joint_left, joint_right),
    ] {
        assert!(l > 0.3 * 45f64.sqrt(), "{what}: left corner {l} px");
        assert!(r < 0.1 * l, "{what}: right corner {r} px vs left {l} px");
    }
    // Symmetric (the fit before): the right corner moves too, at least half as much as the left
    // (the model's units are mirror images, the pose takes some of it).
    assert!(
        sym_right > 0.5 * sym_left,
        "symmetric fit: {sym_left} vs {sym_right} px"
    );
}

/// A neutral face turning its head (yaw 0 to 25 degrees and back, the GFE captures' range),
/// seen with the synthetic performance's pixel and depth noise: the odd parts fitted after the
/// pose stay near 0, since the pose is fitted without them and a turn leaves no one-sided image
/// residual. (Fitted jointly, the odd parts are free to trade off against the yaw: a turn moves
/// one half of the face towards the camera, as an odd part does.)
#[test]
fn a_head_turn_on_a_neutral_face_gives_no_odd_parts() {
    let model = model();
    let (corr, point_count) = correspondences();
    let camera = Camera::KINECT_V1_COLOUR;
    let mut rng = XorShift64Star(0x2545_F491_4F6C_DD1D);
    let forward = Fitter::new(
        model.clone(),
        &corr,
        point_count,
        camera,
        FitSettings::default(),
    )
    .unwrap();
    let turn_frames = 60;
    let mut verts = Vec::new();
    let frames: Vec<Vec<PointObservation>> = (0..NEUTRAL_FRAMES + turn_frames)
        .map(|i| {
            let phase = i.saturating_sub(NEUTRAL_FRAMES) as f64 / turn_frames as f64;
            let yaw = 25f64.to_radians() * (std::f64::consts::PI * phase).sin();
            let pose = Pose {
                rotation: DQuat::from_rotation_y(yaw),
                ..true_pose(0)
            };
            forward.vertices(&pose, &[0.0; AUV_COUNT], &[], &mut verts);
            let mut obs = vec![PointObservation::default(); point_count];
            for (point, x) in points(&corr, &verts) {
                let pixel =
                    camera.project(x) + DVec2::new(rng.normal(), rng.normal()) * PIXEL_NOISE;
                let position = (rng.uniform() >= MISSING_DEPTH)
                    .then(|| camera.back_project(pixel, -x.z + DEPTH_NOISE_M * rng.normal()));
                obs[point] = PointObservation {
                    pixel: Some(pixel),
                    position,
                };
            }
            obs
        })
        .collect();
    let largest_odd = |odd: OddParts| -> f64 {
        let settings = FitSettings {
            odd,
            ..FitSettings::default()
        };
        let mut f = Fitter::new(model.clone(), &corr, point_count, camera, settings).unwrap();
        let neutral: Vec<&[PointObservation]> =
            frames[..NEUTRAL_FRAMES].iter().map(Vec::as_slice).collect();
        f.estimate_shape(&neutral);
        let mut largest = 0.0f64;
        for (i, obs) in frames.iter().enumerate() {
            let r = f.fit(obs);
            assert!(r.tracked, "frame {i} lost");
            largest = r.au_odd.iter().fold(largest, |m, b| m.max(b.abs()));
        }
        largest
    };
    let after = largest_odd(OddParts::AfterPose);
    let joint = largest_odd(OddParts::Joint);
    eprintln!(
        "head turn to 25 deg: largest |odd coefficient| {after:.3} after the pose, {joint:.3} jointly"
    );
    // Bound: the odd parts see only pixel noise. An odd part moves ~4-11 px per unit on 4-12
    // points (as an AU does, on one half of the face); 0.5 px noise then pins it to
    // ~0.5 / (4 px * sqrt(4)) ~ 0.06 for the weakest unit (one standard error, before the 3 px
    // ridge and the 2 px temporal prior shrink it further). The largest of 7 units over 70 frames
    // is then within ~3 standard errors: 0.2. A one-sided smile of the size above gives ~0.5.
    assert!(
        after < 0.2,
        "largest odd coefficient {after} on a pure head turn"
    );
}
