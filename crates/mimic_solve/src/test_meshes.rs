//! Generated meshes and rigs for the unit tests.

use glam::Vec3;
use mimic_types::{ControlName, Fdp, Mesh, RegionBands, Rig, RigControl, SolverSettings};

pub use mimic_testkit::lcg;

/// `nx x ny` vertices on the unit square (x right, y up), z a Gaussian bump of height `bump`;
/// `jitter` moves interior vertices in the plane by up to that fraction of a cell (seeded).
pub fn grid(nx: usize, ny: usize, bump: f32, jitter: f32, seed: u64) -> Mesh {
    let mut s = seed;
    let mut positions = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let mut x = i as f32 / (nx - 1) as f32;
            let mut y = j as f32 / (ny - 1) as f32;
            if i > 0 && j > 0 && i + 1 < nx && j + 1 < ny {
                x += jitter * lcg(&mut s) / (nx - 1) as f32;
                y += jitter * lcg(&mut s) / (ny - 1) as f32;
            }
            let z = bump * (-((x - 0.5).powi(2) + (y - 0.5).powi(2)) / 0.08).exp();
            positions.push(Vec3::new(x, y, z));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let b = a + 1;
            let c = a + nx as u32;
            let d = c + 1;
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    Mesh {
        positions,
        triangles,
        ..Default::default()
    }
}

/// `nx x ny` vertices of an equilateral triangular lattice in the z = 0 plane (odd rows shifted by
/// half a cell), interior vertices jittered by up to `jitter` of the spacing (seeded).
pub fn tri_lattice(nx: usize, ny: usize, jitter: f32, seed: u64) -> Mesh {
    let mut s = seed;
    let h = 3f32.sqrt() / 2.0;
    let mut positions = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let mut p = Vec3::new(i as f32 + 0.5 * (j % 2) as f32, j as f32 * h, 0.0);
            if i > 0 && j > 0 && i + 1 < nx && j + 1 < ny {
                p += Vec3::new(lcg(&mut s), lcg(&mut s), 0.0) * jitter;
            }
            positions.push(p);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
            if j % 2 == 0 {
                triangles.push([a, b, c]);
                triangles.push([b, d, c]);
            } else {
                triangles.push([a, d, c]);
                triangles.push([a, b, d]);
            }
        }
    }
    Mesh {
        positions,
        triangles,
        ..Default::default()
    }
}

/// The `j`-th FDP MPEG-4 defines (groups 2..=11 in order), to name test controls uniquely;
/// past the 89 FDPs, the point control `test:j` (any count of controls).
pub fn fdp(j: usize) -> ControlName {
    const SIZES: [u8; 10] = [14, 14, 6, 4, 4, 1, 10, 15, 15, 6];
    let mut k = j;
    for (g, &size) in SIZES.iter().enumerate() {
        if k < size as usize {
            return Fdp::new(g as u8 + 2, k as u8 + 1).unwrap().into();
        }
        k -= size as usize;
    }
    ControlName::point("test", j).unwrap()
}

/// A rig on `mesh` with controls at `vertices`, regions by height (thirds of [0, 1] with `band`).
pub fn rig(mesh: Mesh, vertices: &[u32], band: f32) -> Rig {
    let regions = RegionBands {
        top_from: 2.0 / 3.0,
        bottom_below: 1.0 / 3.0,
        band,
    };
    let controls = vertices
        .iter()
        .enumerate()
        .map(|(j, &v)| RigControl {
            fdp: fdp(j),
            vertex: v,
            region: regions.region_at(mesh.positions[v as usize].y),
        })
        .collect();
    let n = mesh.vertex_count();
    Rig {
        name: "test".into(),
        units: "m".into(),
        mesh,
        controls,
        regions,
        frozen: vec![false; n],
        solver: SolverSettings::default(),
        parts: Default::default(),
    }
}

/// Vertex indices of an evenly spread `cx x cy` lattice of controls on an `nx x ny` grid, inset from the border.
pub fn control_lattice(nx: usize, ny: usize, cx: usize, cy: usize) -> Vec<u32> {
    let mut out = Vec::new();
    for b in 0..cy {
        for a in 0..cx {
            let i = 1 + a * (nx - 3) / (cx - 1).max(1);
            let j = 1 + b * (ny - 3) / (cy - 1).max(1);
            out.push((j * nx + i) as u32);
        }
    }
    out
}

/// `m` seeded random displacements with coordinates in [-scale, scale).
pub fn random_d(seed: &mut u64, m: usize, scale: f32) -> Vec<Vec3> {
    (0..m)
        .map(|_| Vec3::new(lcg(seed), lcg(seed), lcg(seed)) * scale)
        .collect()
}
