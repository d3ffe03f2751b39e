//! A synthetic face for tests, this crate's and (through the `test-fixtures` feature)
//! mimic_bench's: a bumpy 15 x 15 grid rig (cm) with 6 controls and a 12-point layout read off it.
#![allow(
    clippy::unwrap_used,
    reason = "a test fixture: its FDP names are constants that parse"
)]

use glam::Vec3;
use mimic_types::{
    Layout, LayoutControl, Mesh, Region, RegionBands, Rig, RigControl, SolverSettings,
};

/// Vertices along each side of the grid.
pub const GRID: usize = 15;

/// A 15 x 15 grid (cm) with a bump, 6 controls on it, and a layout whose points sit at
/// `SRC_SCALE` times the rig's positions (a metre-scale performer of the same face).
pub fn rig_and_layout() -> (Rig, Layout) {
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
    let controls = [
        ("4.1", v(4, 11), Region::Top),
        ("4.2", v(10, 11), Region::Top),
        ("9.3", v(7, 7), Region::Middle),
        ("8.3", v(10, 3), Region::Bottom),
        ("8.4", v(4, 3), Region::Bottom),
        ("2.1", v(7, 1), Region::Bottom),
    ];
    let rig = Rig {
        name: "grid".into(),
        units: "cm".into(),
        mesh: Mesh {
            positions: positions.clone(),
            triangles,
            ..Default::default()
        },
        controls: controls
            .iter()
            .map(|(f, vtx, r)| RigControl {
                fdp: f.parse().unwrap(),
                vertex: *vtx,
                region: *r,
            })
            .collect(),
        regions: RegionBands {
            top_from: 2.0,
            bottom_below: -2.0,
            band: 2.0,
        },
        frozen: vec![false; GRID * GRID],
        solver: SolverSettings::default(),
        parts: Default::default(),
    };
    // Layout points: the 6 controls, then 6 stable points (corners and sides of the grid).
    let stable_vertices = [v(0, 14), v(14, 14), v(0, 7), v(14, 7), v(0, 0), v(14, 0)];
    let point_vertices: Vec<u32> = controls
        .iter()
        .map(|c| c.1)
        .chain(stable_vertices)
        .collect();
    let layout = Layout {
        name: "grid12".into(),
        description: String::new(),
        point_count: point_vertices.len(),
        controls: controls
            .iter()
            .enumerate()
            .map(|(k, (f, _, r))| LayoutControl {
                fdp: f.parse().unwrap(),
                points: vec![k],
                region: *r,
                note: String::new(),
            })
            .collect(),
        stable: (6..12).collect(),
        undocumented: vec![],
        point_names: point_vertices
            .iter()
            .map(|v| format!("vertex {v}"))
            .collect(),
        candide_correspondences: vec![],
        gaze: None,
        canonical_neutral: None,
    };
    (rig, layout)
}

/// Source (performer, metres) units per rig unit (cm).
pub const SRC_SCALE: f32 = 0.01;

/// The layout's points on the rest face, in source units.
pub fn neutral_points(rig: &Rig, layout: &Layout) -> Vec<Vec3> {
    let stable = [(0, 14), (14, 14), (0, 7), (14, 7), (0, 0), (14, 0)];
    rig.controls
        .iter()
        .map(|c| rig.mesh.positions[c.vertex as usize])
        .chain(
            stable
                .iter()
                .map(|&(x, y)| rig.mesh.positions[y * GRID + x]),
        )
        .take(layout.point_count)
        .map(|p| p * SRC_SCALE)
        .collect()
}
