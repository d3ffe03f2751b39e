//! Tests of [`GazeTracker`] on synthetic gazes of MediaPipe's canonical face (irises turned by a
//! known angle about a known eyeball centre, the head moved rigidly), blinks, winks, lost pupils,
//! the filter and hold, and [`eye_look_weights`].

use super::*;
use glam::{EulerRot, Quat};
use std::path::PathBuf;

const DEG: f32 = std::f32::consts::PI / 180.0;
/// The synthetic eyeball's radius (cm): the centre of rotation lies this far behind the iris.
const EYE_RADIUS_CM: f32 = 1.2;
/// The accuracy: a known gaze is read within 3 degrees.
const TOL: f32 = 3.0 * DEG;
/// MediaPipe's iris points: centre then ring, per eye.
const LEFT_IRIS: [usize; 5] = [473, 474, 475, 476, 477];
const RIGHT_IRIS: [usize; 5] = [468, 469, 470, 471, 472];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn layout(name: &str) -> Layout {
    mimic_assets::load_layout(&repo().join(format!("configs/layouts/{name}.toml"))).unwrap()
}

/// MediaPipe's canonical face with irises (cm, x = the subject's left, y up, z forward).
fn canonical() -> Vec<Vec3> {
    let text =
        std::fs::read_to_string(repo().join("configs/models/mediapipe/face_model_with_iris.obj"))
            .unwrap();
    let v: Vec<Vec3> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(c[0], c[1], c[2])
        })
        .collect();
    assert_eq!(v.len(), 478);
    v
}

/// The canonical face with each eye's iris turned to `gaze` (`[left, right]`, the model's axes:
/// yaw about +y toward +x, pitch up) about a centre [`EYE_RADIUS_CM`] behind the iris centre,
/// then the whole head moved by `head`.
fn posed(neutral: &[Vec3], gaze: [EyeGaze; 2], head: &Affine3A) -> LandmarkFrame {
    let mut p = neutral.to_vec();
    for (g, iris) in gaze.iter().zip([LEFT_IRIS, RIGHT_IRIS]) {
        let centre = neutral[iris[0]] - EYE_RADIUS_CM * Vec3::Z;
        let turn = Quat::from_rotation_y(g.yaw) * Quat::from_rotation_x(-g.pitch);
        for i in iris {
            p[i] = centre + turn * (neutral[i] - centre);
        }
    }
    let points = p.into_iter().map(|q| head.transform_point3(q)).collect();
    LandmarkFrame::new(0, points)
}

/// A head turned and moved (cm).
fn head() -> Affine3A {
    Affine3A::from_rotation_translation(
        Quat::from_euler(EulerRot::YXZ, 0.35, -0.2, 0.12),
        Vec3::new(4.0, -3.0, 45.0),
    )
}

fn tracker(filter: bool) -> (GazeTracker, Vec<Vec3>) {
    let points = GazePoints::of(&layout("mediapipe478")).unwrap();
    let settings = GazeSettings {
        filter: filter.then(GazeSettings::default).and_then(|s| s.filter),
        ..GazeSettings::default()
    };
    let mut t = GazeTracker::new(points, settings);
    let neutral = canonical();
    t.set_neutral(&neutral, &vec![true; neutral.len()]);
    assert!(t.has_neutral());
    (t, neutral)
}

fn both(yaw_deg: f32, pitch_deg: f32) -> [EyeGaze; 2] {
    let g = EyeGaze {
        yaw: yaw_deg * DEG,
        pitch: pitch_deg * DEG,
    };
    [g, g]
}

fn err(a: EyeGaze, b: EyeGaze) -> f32 {
    (a.yaw - b.yaw).abs().max((a.pitch - b.pitch).abs())
}

#[test]
fn known_gazes_read_within_three_degrees_under_head_motion() {
    let (mut t, neutral) = tracker(false);
    let head = head();
    let back = head.inverse();
    let mut worst = 0.0f32;
    let mut cases = vec![];
    for yaw in [-20.0, -10.0, 0.0, 10.0, 20.0] {
        for pitch in [-15.0, 0.0, 15.0] {
            cases.push(both(yaw, pitch));
        }
    }
    // Vergence: the eyes turned toward each other, and apart.
    cases.push([
        EyeGaze {
            yaw: -8.0 * DEG,
            pitch: 5.0 * DEG,
        },
        EyeGaze {
            yaw: 8.0 * DEG,
            pitch: 5.0 * DEG,
        },
    ]);
    cases.push([
        EyeGaze {
            yaw: 25.0 * DEG,
            pitch: -20.0 * DEG,
        },
        EyeGaze {
            yaw: 18.0 * DEG,
            pitch: -20.0 * DEG,
        },
    ]);
    for want in cases {
        let got = t.step(&posed(&neutral, want, &head), &back, 1.0 / 30.0);
        assert_eq!(t.trusted(), [true, true]);
        for e in [LEFT, RIGHT] {
            let d = err(got[e], want[e]);
            worst = worst.max(d);
            assert!(d <= TOL, "eye {e}: {got:?} vs {want:?}");
        }
    }
    // The neutral itself, moved, reads straight ahead (to rounding).
    let g = t.step(&posed(&neutral, both(0.0, 0.0), &head), &back, 1.0 / 30.0);
    assert!(err(g[0], EyeGaze::default()) < 0.1 * DEG, "{g:?}");
    println!("synthetic gaze: worst error {:.2} degrees", worst / DEG);
}

#[test]
fn a_mirrored_source_keeps_the_subjects_left() {
    // A mirrored camera (x -> -x) swaps handedness; the layout's labels still say which eye is
    // which, so a look to the subject's left stays yaw > 0.
    let (_, neutral) = tracker(false);
    let mirror = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
    let neutral_m: Vec<Vec3> = neutral
        .iter()
        .map(|p| mirror.transform_point3(*p))
        .collect();
    let mut t = GazeTracker::new(
        GazePoints::of(&layout("mediapipe478")).unwrap(),
        GazeSettings {
            filter: None,
            ..GazeSettings::default()
        },
    );
    t.set_neutral(&neutral_m, &vec![true; 478]);
    let want = both(15.0, 10.0);
    let g = t.step(
        &posed(&neutral, want, &mirror),
        &Affine3A::IDENTITY,
        1.0 / 30.0,
    );
    for e in [LEFT, RIGHT] {
        assert!(err(g[e], want[e]) <= TOL, "{g:?}");
    }
}

/// `frame` with eye `iris`'s lids closed (the upper-lid middle moved onto the lower one, in the
/// head frame before `head`) and its iris dropped by `drop_cm`, as MediaPipe draws a blink.
fn close_eye(
    frame: &mut LandmarkFrame,
    head: &Affine3A,
    upper: usize,
    lower: usize,
    iris: [usize; 5],
    drop_cm: f32,
) {
    let drop = head.transform_vector3(-drop_cm * Vec3::Y);
    frame.points[upper] = frame.points[lower];
    for i in iris {
        frame.points[i] += drop;
    }
}

#[test]
fn a_blink_holds_the_gaze_instead_of_looking_down() {
    let (mut t, neutral) = tracker(false);
    let head = head();
    let back = head.inverse();
    let want = both(15.0, -5.0);
    let before = t.step(&posed(&neutral, want, &head), &back, 1.0 / 30.0);
    let mut blink = posed(&neutral, want, &head);
    close_eye(&mut blink, &head, 386, 374, LEFT_IRIS, 0.4);
    close_eye(&mut blink, &head, 159, 145, RIGHT_IRIS, 0.4);
    let during = t.step(&blink, &back, 1.0 / 30.0);
    assert_eq!(t.trusted(), [false, false]);
    assert!(t.openness()[0] < 0.1, "{:?}", t.openness());
    assert_eq!(during, before);
    // Without the rule the same frame reads far down: the test is not vacuous.
    let mut open_always = tracker(false).0;
    open_always.settings.closed_below = f32::NEG_INFINITY;
    let raw = open_always.step(&blink, &back, 1.0 / 30.0);
    assert!(raw[0].pitch < before[0].pitch - 10.0 * DEG, "{raw:?}");
    // Eyes open again: the gaze reads again.
    let after = t.step(&posed(&neutral, both(-10.0, 5.0), &head), &back, 1.0 / 30.0);
    assert!(err(after[0], both(-10.0, 5.0)[0]) <= TOL, "{after:?}");
}

#[test]
fn during_a_wink_the_open_eye_drives_both() {
    let (mut t, neutral) = tracker(false);
    let head = head();
    let back = head.inverse();
    t.step(&posed(&neutral, both(-12.0, 0.0), &head), &back, 1.0 / 30.0);
    let right = EyeGaze {
        yaw: 10.0 * DEG,
        pitch: 8.0 * DEG,
    };
    let mut wink = posed(&neutral, [EyeGaze::default(), right], &head);
    close_eye(&mut wink, &head, 386, 374, LEFT_IRIS, 0.4);
    let g = t.step(&wink, &back, 1.0 / 30.0);
    assert_eq!(t.trusted(), [false, true]);
    assert_eq!(g[LEFT], g[RIGHT]);
    assert!(err(g[RIGHT], right) <= TOL, "{g:?}");
}

#[test]
fn an_invalid_pupil_is_not_read() {
    let (mut t, neutral) = tracker(false);
    let head = head();
    let back = head.inverse();
    let first = t.step(&posed(&neutral, both(5.0, 5.0), &head), &back, 1.0 / 30.0);
    // The left iris lost: the left eye takes the right's gaze.
    let right = EyeGaze {
        yaw: -15.0 * DEG,
        pitch: 0.0,
    };
    let mut f = posed(&neutral, [both(20.0, 20.0)[0], right], &head);
    f.valid[LEFT_IRIS[2]] = false;
    let g = t.step(&f, &back, 1.0 / 30.0);
    assert_eq!(t.trusted(), [false, true]);
    assert!(
        err(g[LEFT], right) <= TOL && err(g[RIGHT], right) <= TOL,
        "{g:?}"
    );
    // Both lost (a NaN counts as invalid): the gaze holds.
    let mut f = posed(&neutral, both(-20.0, -20.0), &head);
    f.valid[RIGHT_IRIS[0]] = false;
    f.points[LEFT_IRIS[0]] = Vec3::NAN;
    assert_eq!(t.step(&f, &back, 1.0 / 30.0), g);
    // An untracked frame reads nothing either.
    let mut lost = posed(&neutral, both(-20.0, -20.0), &head);
    lost.tracked = false;
    assert_eq!(t.step(&lost, &back, 1.0 / 30.0), g);
    assert_ne!(first, g);
}

#[test]
fn readings_are_clamped_to_the_limits() {
    let (mut t, neutral) = tracker(false);
    let s = *t.settings();
    let g = t.step(
        &posed(&neutral, both(60.0, 0.0), &Affine3A::IDENTITY),
        &Affine3A::IDENTITY,
        1.0 / 30.0,
    );
    assert_eq!(g[0].yaw, s.yaw_limit);
    let g = t.step(
        &posed(&neutral, both(0.0, -50.0), &Affine3A::IDENTITY),
        &Affine3A::IDENTITY,
        1.0 / 30.0,
    );
    assert_eq!(g[1].pitch, -s.pitch_down_limit);
    assert!((s.yaw_limit / DEG - 35.0).abs() < 1e-4);
    assert!((s.pitch_up_limit / DEG - 25.0).abs() < 1e-4);
}

#[test]
fn the_filter_settles_and_hold_eases_toward_straight() {
    let (mut t, neutral) = tracker(true);
    let want = both(12.0, -6.0);
    let f = posed(&neutral, want, &Affine3A::IDENTITY);
    let first = t.step(&f, &Affine3A::IDENTITY, 1.0 / 30.0);
    assert!(err(first[0], want[0]) <= TOL, "the first sample passes");
    t.step(
        &posed(&neutral, both(0.0, 0.0), &Affine3A::IDENTITY),
        &Affine3A::IDENTITY,
        1.0 / 30.0,
    );
    let mut g = [EyeGaze::default(); 2];
    for _ in 0..90 {
        g = t.step(&f, &Affine3A::IDENTITY, 1.0 / 30.0);
    }
    assert!(err(g[0], want[0]) <= TOL, "{g:?}");
    let half = t.hold(0.5);
    assert_eq!(half[0], g[0].scaled(0.5));
    assert_eq!(t.hold(1.0), half);
    assert_eq!(t.hold(0.0), [EyeGaze::default(); 2]);
    t.reset();
    assert_eq!(t.last(), [EyeGaze::default(); 2]);
    assert!(t.has_neutral(), "reset keeps the neutral");
}

#[test]
fn without_a_usable_neutral_nothing_is_read() {
    let points = GazePoints::of(&layout("mediapipe478")).unwrap();
    let mut t = GazeTracker::new(points, GazeSettings::default());
    let neutral = canonical();
    let f = posed(&neutral, both(20.0, 0.0), &Affine3A::IDENTITY);
    assert_eq!(
        t.step(&f, &Affine3A::IDENTITY, 0.03),
        [EyeGaze::default(); 2]
    );
    let mut valid = vec![true; 478];
    valid[263] = false;
    t.set_neutral(&neutral, &valid);
    assert!(!t.has_neutral());
    t.set_neutral(&neutral[..100], &valid);
    assert!(!t.has_neutral());
    assert_eq!(
        t.step(&f, &Affine3A::IDENTITY, 0.03),
        [EyeGaze::default(); 2]
    );
}

#[test]
fn layouts_with_pupils_have_gaze_points_and_the_others_none() {
    for name in ["mediapipe478", "openseeface68"] {
        let g = GazePoints::of(&layout(name)).unwrap();
        assert!(g.eye(LEFT).is_some() && g.eye(RIGHT).is_some());
    }
    for name in ["ibug68", "kinect121", "kinect-gfe100"] {
        assert!(GazePoints::of(&layout(name)).is_none(), "{name}");
    }
    // The left eye's points are the mirror (x -> -x) of the right's on the canonical model.
    let n = canonical();
    let g = GazePoints::of(&layout("mediapipe478")).unwrap();
    let (l, r) = (g.eye(LEFT).unwrap(), g.eye(RIGHT).unwrap());
    let m = |p: Vec3| Vec3::new(-p.x, p.y, p.z);
    let mean = |ps: &[usize]| ps.iter().map(|&p| n[p]).sum::<Vec3>() / ps.len() as f32;
    let pairs = [
        (mean(&l.pupil), mean(&r.pupil)),
        (n[l.outer], n[r.outer]),
        (n[l.inner], n[r.inner]),
        (mean(&l.upper), mean(&r.upper)),
        (mean(&l.lower), mean(&r.lower)),
    ];
    for (a, b) in pairs {
        assert!(a.distance(m(b)) < 1e-4, "{a} vs {b}");
    }
    assert!(
        n[l.outer].x > n[l.inner].x,
        "the left outer corner is further left"
    );
}

#[test]
fn eye_look_weights_follow_arkit_names_and_sides() {
    for n in EYE_LOOK_NAMES {
        assert!(mimic_types::arkit::ARKIT_NAMES.contains(&n), "{n}");
    }
    let mut w = [0.0; 8];
    let g = [
        EyeGaze {
            yaw: -15.0 * DEG,
            pitch: 12.5 * DEG,
        },
        EyeGaze {
            yaw: -60.0 * DEG,
            pitch: -50.0 * DEG,
        },
    ];
    eye_look_weights(g, &mut w);
    let at = |name: &str| w[EYE_LOOK_NAMES.iter().position(|n| *n == name).unwrap()];
    // Left eye toward the subject's right: toward the nose, "in".
    assert!((at("eyeLookInLeft") - 0.5).abs() < 1e-5);
    assert_eq!(at("eyeLookOutLeft"), 0.0);
    assert!((at("eyeLookUpLeft") - 0.5).abs() < 1e-5);
    assert_eq!(at("eyeLookDownLeft"), 0.0);
    // Right eye toward the subject's right: away from the nose, "out"; clamped at 1.
    assert_eq!(at("eyeLookOutRight"), 1.0);
    assert_eq!(at("eyeLookInRight"), 0.0);
    assert_eq!(at("eyeLookDownRight"), 1.0);
    assert_eq!(at("eyeLookUpRight"), 0.0);
    eye_look_weights([EyeGaze::default(); 2], &mut w);
    assert_eq!(w, [0.0; 8]);
}

#[test]
fn direction_matches_the_documented_convention() {
    let g = EyeGaze {
        yaw: 30.0 * DEG,
        pitch: 0.0,
    };
    let d = g.direction();
    assert!((d - Vec3::new(0.5, 0.0, 0.75f32.sqrt())).length() < 1e-6);
    let up = EyeGaze {
        yaw: 0.0,
        pitch: 90.0 * DEG,
    };
    assert!((up.direction() - Vec3::Y).length() < 1e-6);
}

#[test]
fn binocular_draws_the_eyes_toward_their_mean() {
    let (mut t, neutral) = tracker(false);
    let want = [both(-10.0, 4.0)[0], both(10.0, -4.0)[0]];
    let f = posed(&neutral, want, &Affine3A::IDENTITY);
    let own = t.step(&f, &Affine3A::IDENTITY, 1.0 / 30.0);
    t.settings.binocular = 1.0;
    let shared = t.step(&f, &Affine3A::IDENTITY, 1.0 / 30.0);
    assert_eq!(shared[LEFT], shared[RIGHT]);
    let mean = 0.5 * (own[LEFT].yaw + own[RIGHT].yaw);
    assert!((shared[LEFT].yaw - mean).abs() < 1e-6, "{own:?} {shared:?}");
    assert!(
        own[LEFT].yaw < -7.0 * DEG && own[RIGHT].yaw > 7.0 * DEG,
        "{own:?}"
    );
}
