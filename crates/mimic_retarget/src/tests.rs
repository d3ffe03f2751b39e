//! Pipeline tests on a synthetic face: a bumpy grid rig and a 12-point layout read off it.

use crate::*;
use glam::{Quat, Vec3};
use mimic_types::LandmarkFrame;

use crate::fixtures::{GRID, SRC_SCALE};
pub(crate) use crate::fixtures::{neutral_points, rig_and_layout};

fn frame(t_us: i64, points: Vec<Vec3>) -> LandmarkFrame {
    LandmarkFrame::new(t_us, points)
}

fn setup(settings: RetargetSettings) -> (Retargeter, Vec<Vec3>) {
    let (rig, layout) = rig_and_layout();
    let basis = mimic_solve::build_basis(&rig, &rig.solver).unwrap();
    let neutral = neutral_points(&rig, &layout);
    (
        Retargeter::new(&rig, &layout, basis, settings).unwrap(),
        neutral,
    )
}

/// No jitter filter and no plausibility gate: one frame's `d` is that frame's alone.
pub(crate) fn plain() -> RetargetSettings {
    RetargetSettings {
        neutral: Neutral::FirstFrames(1),
        filter: None,
        gate: GateSettings {
            enabled: false,
            ..GateSettings::default()
        },
        ..Default::default()
    }
}

/// [`plain`] with the gate at its defaults.
fn gated() -> RetargetSettings {
    RetargetSettings {
        gate: GateSettings::default(),
        ..plain()
    }
}

#[test]
fn rigid_head_motion_gives_no_expression() {
    let (mut r, neutral) = setup(plain());
    let mut out = r.new_output();
    assert_eq!(
        r.step(&frame(0, neutral.clone()), &mut out),
        FrameStatus::Calibrating
    );
    for k in 1..30 {
        let rot = Quat::from_euler(
            glam::EulerRot::YXZ,
            0.03 * k as f32,
            -0.01 * k as f32,
            0.005 * k as f32,
        );
        let t = Vec3::new(0.01, -0.02, 0.5) * k as f32 * 0.1;
        let moved: Vec<Vec3> = neutral.iter().map(|p| rot * *p + t).collect();
        assert_eq!(
            r.step(&frame(k * 33_000, moved), &mut out),
            FrameStatus::Tracked
        );
        // f32 pose fit on metre-scale points: residual ~1e-6 m, times the scale of 100 -> < 1e-3 cm.
        for d in &out.displacements {
            assert!(d.length() < 1e-3, "frame {k}: {d}");
        }
        let q = out.pose.rotation;
        assert!(q.angle_between(rot) < 1e-3, "pose rotation off");
    }
    assert_eq!(r.stats().tracked, 29);
}

#[test]
fn expression_maps_through_the_similarity() {
    let (mut r, neutral) = setup(plain());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let s = *r.source_to_target().unwrap();
    // Same face, scaled by 100: scale 100, identity rotation, no mirror.
    assert!((s.scale - 100.0).abs() < 0.01 && !s.mirrored, "{s:?}");
    let rot = Quat::from_rotation_y(0.3);
    let mut moved: Vec<Vec3> = neutral.iter().map(|p| rot * *p).collect();
    let e = Vec3::new(0.0, -0.004, 0.001); // the chin drops 4 mm
    moved[5] += rot * e;
    r.step(&frame(33_000, moved), &mut out);
    // Chin control moves by 100 * e in target cm; the others stay (tolerance: 1e-3 cm as above).
    assert!(
        (out.displacements[5] - e * 100.0).length() < 1e-3,
        "{}",
        out.displacements[5]
    );
    for j in 0..5 {
        assert!(out.displacements[j].length() < 1e-3);
    }
    // The RBF reproduces control displacements exactly: the chin vertex moved by d.
    let chin = 7 + GRID;
    let moved_by = out.positions[chin] - r.rest_positions()[chin];
    assert!((moved_by - out.displacements[5]).length() < 1e-3);
    assert!(out.positions.iter().all(|p| p.is_finite()));
    assert!(out.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
}

#[test]
fn frame_deltas_sum_to_the_neutral_relative_displacement() {
    let (mut r, neutral) = setup(plain());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let mut sum = [Vec3::ZERO; 6];
    let mut seed = 7u32;
    let mut rnd = move || {
        seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    for k in 1..100 {
        let rot = Quat::from_rotation_z(0.01 * rnd());
        let mut pts: Vec<Vec3> = neutral.iter().map(|p| rot * *p).collect();
        for p in pts.iter_mut().take(6) {
            *p += Vec3::new(rnd(), rnd(), rnd()) * 0.004;
        }
        r.step(&frame(k * 33_000, pts), &mut out);
        for (s, d) in sum.iter_mut().zip(r.frame_delta()) {
            *s += *d;
        }
    }
    // Running sum of 99 f32 deltas of size ~4e-3 m: drift bounded by 99 * 4e-3 * 2^-23 * few ~ 1e-7.
    for (s, e) in sum.iter().zip(r.source_displacement()) {
        assert!((*s - *e).length() < 1e-5, "{s} vs {e}");
    }
}

#[test]
fn lost_tracking_holds_then_eases_to_neutral() {
    let settings = RetargetSettings {
        lost_hold_secs: 0.1,
        lost_ease_secs: 0.2,
        ..plain()
    };
    let (mut r, neutral) = setup(settings);
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let mut smile = neutral.clone();
    smile[3] += Vec3::new(0.005, 0.002, 0.0);
    r.step(&frame(100_000, smile), &mut out);
    let held = out.displacements[3];
    assert!(held.length() > 0.4);
    let lost = |t| LandmarkFrame {
        tracked: false,
        ..frame(t, neutral.clone())
    };
    // Lost at t = 0.2 s: hold for 0.1 s, then linear ease over 0.2 s.
    for (t_us, k) in [
        (200_000, 1.0),
        (300_000, 1.0),
        (400_000, 0.5),
        (500_000, 0.0),
        (900_000, 0.0),
    ] {
        assert_eq!(r.step(&lost(t_us), &mut out), FrameStatus::Lost);
        assert!(
            (out.displacements[3] - held * k).length() < 1e-5,
            "t {t_us}: {}",
            out.displacements[3]
        );
    }
    assert_eq!(r.stats().lost, 5);
}

#[test]
fn missing_controls_are_held_and_bad_frames_rejected() {
    let (mut r, neutral) = setup(plain());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let mut open = neutral.clone();
    open[5] += Vec3::new(0.0, -0.01, 0.0);
    r.step(&frame(33_000, open.clone()), &mut out);
    let before = out.displacements[5];
    let mut f = frame(66_000, open);
    f.valid[5] = false;
    r.step(&f, &mut out);
    assert_eq!(out.filled, 1);
    assert_eq!(out.displacements[5], before);
    let positions = out.positions.clone();
    let short = frame(99_000, neutral[..11].to_vec());
    assert_eq!(r.step(&short, &mut out), FrameStatus::Rejected);
    assert_eq!(
        out.positions, positions,
        "a rejected frame leaves the output alone"
    );
    let s = r.stats();
    assert_eq!(
        (
            s.frames,
            s.calibrating,
            s.tracked,
            s.rejected,
            s.filled_controls
        ),
        (4, 1, 2, 1, 1)
    );
}

#[test]
fn neutral_is_averaged_over_first_frames_despite_head_motion() {
    let settings = RetargetSettings {
        neutral: Neutral::FirstFrames(3),
        filter: None,
        ..Default::default()
    };
    let (mut r, neutral) = setup(settings);
    let mut out = r.new_output();
    for k in 0..3 {
        let rot = Quat::from_rotation_y(0.1 * k as f32);
        let pts: Vec<Vec3> = neutral.iter().map(|p| rot * *p).collect();
        assert_eq!(
            r.step(&frame(k * 33_000, pts), &mut out),
            FrameStatus::Calibrating
        );
    }
    r.step(&frame(100_000, neutral.clone()), &mut out);
    assert_eq!(out.status, FrameStatus::Tracked);
    for d in &out.displacements {
        assert!(d.length() < 1e-3);
    }
}

#[test]
fn step_output_is_allocation_stable() {
    // The output buffers keep their allocations across steps (no reallocation per frame).
    let (mut r, neutral) = setup(RetargetSettings {
        neutral: Neutral::FirstFrames(1),
        ..Default::default()
    });
    let mut out = r.new_output();
    let ptrs = (
        out.positions.as_ptr(),
        out.normals.as_ptr(),
        out.displacements.as_ptr(),
    );
    for k in 0..10 {
        r.step(&frame(k * 33_000, neutral.clone()), &mut out);
    }
    assert_eq!(
        ptrs,
        (
            out.positions.as_ptr(),
            out.normals.as_ptr(),
            out.displacements.as_ptr()
        )
    );
}

#[test]
fn lost_frames_without_points_are_lost_not_rejected() {
    let (mut r, neutral) = setup(plain());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let mut open = neutral.clone();
    open[5] += Vec3::new(0.0, -0.004, 0.0);
    r.step(&frame(33_000, open), &mut out);
    let held = out.displacements.clone();
    // The documented forms: no points at all (OpenFace's failed frames, UDP P = 0), and a
    // point list of another length, which a lost frame does not need either.
    let empty = LandmarkFrame {
        timestamp_us: 66_000,
        points: vec![],
        valid: vec![],
        tracked: false,
    };
    assert_eq!(r.step(&empty, &mut out), FrameStatus::Lost);
    assert_eq!(out.displacements, held, "held right after the loss");
    let short = LandmarkFrame {
        tracked: false,
        ..frame(99_000, neutral[..3].to_vec())
    };
    assert_eq!(r.step(&short, &mut out), FrameStatus::Lost);
    let s = r.stats();
    assert_eq!((s.lost, s.rejected, s.tracked), (2, 0, 1));
}

#[test]
fn gate_holds_a_head_that_turns_faster_than_a_head_does_until_it_comes_back() {
    let (mut r, neutral) = setup(gated());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let mut smile = neutral.clone();
    smile[3] += Vec3::new(0.001, 0.0005, 0.0);
    // Ease into the smile slowly enough for the speed clamp.
    for k in 1..=10 {
        r.step(&frame(k * 66_000, smile.clone()), &mut out);
    }
    assert_eq!(r.gate_reading().reason, None);
    let held = out.displacements.clone();
    assert!(held[3].length() > 0.05);
    // 40 degrees in one 66 ms frame (600 deg/s), with the chin dropped 2 cm: held.
    let turn = Quat::from_rotation_x(40f32.to_radians());
    let mut bad: Vec<Vec3> = smile.iter().map(|p| turn * *p).collect();
    bad[5] += turn * Vec3::new(0.0, -0.02, 0.0);
    for k in 11..=13 {
        assert_eq!(
            r.step(&frame(k * 66_000, bad.clone()), &mut out),
            FrameStatus::Tracked
        );
        assert_eq!(r.gate_reading().reason, Some(GateReason::Turn), "frame {k}");
        assert_eq!(
            out.displacements, held,
            "frame {k}: the last expression is held"
        );
    }
    // Back where it was: accepted again.
    r.step(&frame(14 * 66_000, smile.clone()), &mut out);
    assert_eq!(r.gate_reading().reason, None);
    let s = r.stats();
    assert_eq!((s.gated, s.tracked), (3, 14));
}

#[test]
fn gate_clamps_control_speed_and_counts_jumps() {
    let (mut r, neutral) = setup(gated());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    r.step(&frame(66_000, neutral.clone()), &mut out);
    let mut open = neutral.clone();
    // 1.5 cm of chin drop (on the cm rig) in one frame: faster than a face moves.
    open[5] += Vec3::new(0.0, -0.015, 0.0);
    let face = r.face_size();
    let g = GateSettings::default();
    let step = (g.step_floor + g.max_control_speed * 0.066) * face;
    let mut last = 0.0;
    for k in 2..40 {
        r.step(&frame(k * 66_000, open.clone()), &mut out);
        let now = out.displacements[5].length();
        assert!(
            now - last <= step * 1.001,
            "frame {k}: {last} -> {now} (step {step})"
        );
        last = now;
    }
    assert!((last - 1.5).abs() < 1e-3, "reaches the target: {last}");
    let s = r.stats();
    assert!(s.clamped >= 2, "{s:?}");
    assert_eq!(s.jumps, 0, "{s:?}");
    assert_eq!(s.gated, 0, "{s:?}");
    // Without the gate the same step is one jump.
    let (mut r, neutral) = setup(plain());
    r.step(&frame(0, neutral.clone()), &mut out);
    r.step(&frame(66_000, open.clone()), &mut out);
    assert_eq!((r.stats().jumps, r.stats().clamped), (1, 0));
}

#[test]
fn gate_holds_a_control_beyond_its_bound() {
    let (mut r, neutral) = setup(gated());
    let mut out = r.new_output();
    r.step(&frame(0, neutral.clone()), &mut out);
    let mut far = neutral.clone();
    // The nose control (9.3) 0.55 face sizes up: past its bound (0.5), short of the outlier
    // limit that would fill the control instead.
    let bound = GateSettings::default().max_other;
    far[2] += Vec3::new(0.0, 1.1 * bound * r.face_size() * SRC_SCALE, 0.0);
    r.step(&frame(66_000, far), &mut out);
    assert_eq!(r.gate_reading().reason, Some(GateReason::Displacement));
    // The reading is the largest displacement over its bound: this control's 1.1, within the
    // roundings of the map to the target, the squared ratio and its square root (8 eps).
    let reading = r.gate_reading().displacement;
    assert!(
        (reading - 1.1).abs() <= 8.0 * f32::EPSILON * 1.1,
        "{reading}"
    );
    assert!(out.displacements.iter().all(|d| d.length() < 1e-6));
    assert_eq!(r.stats().gated, 1);
}

#[test]
fn gate_settings_load_from_an_empty_table() {
    let g: GateSettings = serde_json::from_str("{}").unwrap();
    assert_eq!(g, GateSettings::default());
    let g: GateSettings = serde_json::from_str(r#"{"max_rotation_deg": 30}"#).unwrap();
    assert_eq!(g.max_rotation_deg, 30.0);
    assert!(serde_json::from_str::<GateSettings>(r#"{"max_rotaton_deg": 30}"#).is_err());
}

mod mesh;
