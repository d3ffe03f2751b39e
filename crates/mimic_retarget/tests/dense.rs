//! Dense control sets: a rig driven by 81 of a layout's own points (`grid87:k`, no FDPs), with
//! every per-control stage (select, stabilise, scale, gate, filter, lost-point holding) checked
//! at a count that is not the 38 of the MPEG-4 set.
#![allow(clippy::unwrap_used, reason = "tests")]

use glam::{Quat, Vec3};
use mimic_retarget::{FrameStatus, GateSettings, Neutral, RetargetSettings, Retargeter};
use mimic_types::{
    ControlName, LandmarkFrame, Layout, Mesh, RegionBands, Rig, RigControl, SolverSettings,
};

const GRID: usize = 15;
/// The performer's face is the rig's at this scale (metres against centimetres).
const SRC_SCALE: f32 = 0.01;

/// A 15 x 15 bumpy grid (cm); controls on the 81 inner vertices 3..=11 x 3..=11, named as points
/// 0..81 of layout `grid87`, whose points 81..87 are six stable points on the grid's border.
fn rig_and_layout() -> (Rig, Layout, Vec<u32>) {
    let mut positions = Vec::new();
    for y in 0..GRID {
        for x in 0..GRID {
            let (fx, fy) = (x as f32 - 7.0, y as f32 - 7.0);
            positions.push(Vec3::new(fx, fy, 3.0 * (-(fx * fx + fy * fy) / 30.0).exp()));
        }
    }
    let mut triangles = Vec::new();
    for y in 0..GRID - 1 {
        for x in 0..GRID - 1 {
            let i = (y * GRID + x) as u32;
            let g = GRID as u32;
            triangles.push([i, i + 1, i + g + 1]);
            triangles.push([i, i + g + 1, i + g]);
        }
    }
    let v = |x: usize, y: usize| (y * GRID + x) as u32;
    let regions = RegionBands {
        top_from: 2.0,
        bottom_below: -2.0,
        band: 2.0,
    };
    let mut point_vertices = Vec::new();
    for y in 3..=11 {
        for x in 3..=11 {
            point_vertices.push(v(x, y));
        }
    }
    let controls: Vec<RigControl> = point_vertices
        .iter()
        .enumerate()
        .map(|(k, &vertex)| RigControl {
            fdp: ControlName::point("grid87", k).unwrap(),
            vertex,
            region: regions.region_at(positions[vertex as usize].y),
        })
        .collect();
    point_vertices.extend([v(0, 14), v(14, 14), v(0, 7), v(14, 7), v(0, 0), v(14, 0)]);
    let rig = Rig {
        name: "grid".into(),
        units: "cm".into(),
        mesh: Mesh {
            positions,
            triangles,
            ..Default::default()
        },
        controls,
        regions,
        frozen: vec![false; GRID * GRID],
        solver: SolverSettings::default(),
        parts: Default::default(),
    };
    let layout = Layout {
        name: "grid87".into(),
        description: String::new(),
        point_count: point_vertices.len(),
        controls: vec![],
        stable: (81..87).collect(),
        undocumented: vec![],
        point_names: vec![],
        candide_correspondences: vec![],
        gaze: None,
        canonical_neutral: None,
    };
    layout.validate().unwrap();
    rig.validate().unwrap();
    (rig, layout, point_vertices)
}

fn neutral(rig: &Rig, point_vertices: &[u32]) -> Vec<Vec3> {
    point_vertices
        .iter()
        .map(|&v| rig.mesh.positions[v as usize] * SRC_SCALE)
        .collect()
}

fn plain() -> RetargetSettings {
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

fn setup(settings: RetargetSettings) -> (Retargeter, Vec<Vec3>) {
    let (rig, layout, pv) = rig_and_layout();
    let basis = mimic_solve::build_basis(&rig, &rig.solver).unwrap();
    let r = Retargeter::new(&rig, &layout, basis, settings).unwrap();
    (r, neutral(&rig, &pv))
}

/// A smooth expression: every control point moves by a field that varies over the face.
fn expression(k: usize, p: Vec3) -> Vec3 {
    let s = 0.002 * (k as f32 * 0.37).sin();
    Vec3::new(s * (p.y * 30.0).sin(), s * (p.x * 40.0).cos(), 0.5 * s)
}

#[test]
fn every_point_control_follows_its_own_point_under_head_motion() {
    let (mut r, neutral) = setup(plain());
    assert_eq!(r.basis().control_count(), 81);
    let mut out = r.new_output();
    assert_eq!(out.displacements.len(), 81);
    r.step(&LandmarkFrame::new(0, neutral.clone()), &mut out);
    let s = *r.source_to_target().unwrap();
    assert!((s.scale - 1.0 / SRC_SCALE).abs() < 0.01, "{s:?}");
    for k in 1..20 {
        let rot = Quat::from_euler(glam::EulerRot::YXZ, 0.02 * k as f32, -0.01 * k as f32, 0.0);
        let t = Vec3::new(0.01, -0.02, 0.3) * k as f32 * 0.1;
        let e: Vec<Vec3> = neutral.iter().take(81).map(|p| expression(k, *p)).collect();
        let moved: Vec<Vec3> = neutral
            .iter()
            .enumerate()
            .map(|(i, p)| rot * (*p + e.get(i).copied().unwrap_or(Vec3::ZERO)) + t)
            .collect();
        assert_eq!(
            r.step(&LandmarkFrame::new(k as i64 * 33_000, moved), &mut out),
            FrameStatus::Tracked
        );
        // d = e / SRC_SCALE per control; the pose fit on metre-scale f32 points leaves ~1e-6 m,
        // times the scale of 100: 1e-3 cm.
        for (j, (d, e)) in out.displacements.iter().zip(&e).enumerate() {
            assert!(
                (*d - *e / SRC_SCALE).length() < 1e-3,
                "frame {k} control {j}: {d} vs {}",
                *e / SRC_SCALE
            );
        }
    }
}

#[test]
fn a_lost_point_holds_its_control_alone() {
    let (mut r, neutral) = setup(plain());
    let mut out = r.new_output();
    r.step(&LandmarkFrame::new(0, neutral.clone()), &mut out);
    let mut moved = neutral.clone();
    for p in moved.iter_mut().take(81) {
        *p += Vec3::new(0.0, 0.001, 0.0);
    }
    r.step(&LandmarkFrame::new(33_000, moved.clone()), &mut out);
    let held = out.displacements[40];
    for p in moved.iter_mut().take(81) {
        *p += Vec3::new(0.0, 0.001, 0.0);
    }
    let mut f = LandmarkFrame::new(66_000, moved);
    f.valid[40] = false;
    r.step(&f, &mut out);
    assert_eq!(out.filled, 1);
    assert_eq!(out.displacements[40], held);
    for (j, d) in out.displacements.iter().enumerate() {
        if j != 40 {
            assert!((*d - Vec3::new(0.0, 0.2, 0.0)).length() < 1e-3, "{j}: {d}");
        }
    }
    assert_eq!(r.stats().filled_controls, 1);
}

#[test]
fn the_gate_bounds_each_point_control_by_its_region() {
    // The outlier limit (0.8 of the controls' RMS radius) would hold the control first.
    let settings = RetargetSettings {
        gate: GateSettings::default(),
        outlier_fraction: 10.0,
        ..plain()
    };
    let (mut r, neutral) = setup(settings);
    let mut out = r.new_output();
    r.step(&LandmarkFrame::new(0, neutral.clone()), &mut out);
    // No eye corners in the set: the face size is 1.25 x the RMS radius of the controls.
    let (rig, _, _) = rig_and_layout();
    let at = rig.control_positions();
    let centre = at.iter().fold(Vec3::ZERO, |a, p| a + *p) / at.len() as f32;
    let rms = (at.iter().map(|p| p.distance_squared(centre)).sum::<f32>() / at.len() as f32).sqrt();
    assert!((r.face_size() - 1.25 * rms).abs() < 1e-4 * rms);
    // A bottom-region control (row y = 3: y = -4 cm) may move max(max_jaw, max_lip) IOD.
    let g = GateSettings::default();
    let bound = g.max_jaw.max(g.max_lip) * r.face_size();
    let mut t = 33_000;
    let mut step = |scale: f32| {
        let mut f = neutral.clone();
        f[4].y -= scale * bound * SRC_SCALE;
        let s = r.step(&LandmarkFrame::new(t, f), &mut out);
        t += 33_000;
        (s, r.gate_reading().reason.is_some())
    };
    assert_eq!(step(0.9), (FrameStatus::Tracked, false));
    assert_eq!(step(1.1), (FrameStatus::Tracked, true));
    assert_eq!(r.stats().gated, 1);
}

#[test]
fn the_jitter_filter_runs_per_point_control() {
    let settings = RetargetSettings {
        filter: Some(mimic_retarget::OneEuroSettings::default()),
        ..plain()
    };
    let (mut r, neutral) = setup(settings);
    let (mut plain_r, _) = setup(plain());
    let mut out = r.new_output();
    let mut plain_out = plain_r.new_output();
    r.step(&LandmarkFrame::new(0, neutral.clone()), &mut out);
    plain_r.step(&LandmarkFrame::new(0, neutral.clone()), &mut plain_out);
    // Noise on control 10 only: the filter shrinks its frame-to-frame change; every other
    // control stays exactly still (no filter state shared between controls).
    let mut seed = 11u32;
    let mut rnd = move || {
        seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    let (mut moved_f, mut moved_p) = (0.0f32, 0.0f32);
    let (mut last_f, mut last_p) = (Vec3::ZERO, Vec3::ZERO);
    for k in 1..60 {
        let mut f = neutral.clone();
        f[10] += Vec3::new(rnd(), rnd(), rnd()) * 0.0005;
        r.step(&LandmarkFrame::new(k * 33_000, f.clone()), &mut out);
        plain_r.step(&LandmarkFrame::new(k * 33_000, f), &mut plain_out);
        moved_f += out.displacements[10].distance(last_f);
        moved_p += plain_out.displacements[10].distance(last_p);
        last_f = out.displacements[10];
        last_p = plain_out.displacements[10];
        for (j, d) in out.displacements.iter().enumerate() {
            if j != 10 {
                assert!(d.length() < 1e-3, "{j}: {d}");
            }
        }
    }
    assert!(
        moved_f < 0.7 * moved_p,
        "filtered {moved_f} vs raw {moved_p}"
    );
}

#[test]
fn another_layouts_point_is_refused_by_name() {
    let (rig, mut layout, _) = rig_and_layout();
    layout.name = "other".into();
    let basis = mimic_solve::build_basis(&rig, &rig.solver).unwrap();
    let e = Retargeter::new(&rig, &layout, basis, plain()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "rig control grid87:0 has no counterpart in layout `other`"
    );
}
