//! Deformation transfer against exact truth: ICT's expression set made for heads the project
//! does not ship. A head is ICT's neutral plus a random sum of its identity shapes
//! (`configs/meshes/ict-facekit/identities.shapes`, weights N(0, 1) from a fixed seed); in
//! ICT's linear model its expressions are that head plus ICT's expression deltas, exactly. The
//! head's skin is re-meshed by vertex clustering on a voxel grid (each cluster and each of its
//! true shapes the mean of its members, so the truth stays exact and the transfer cannot lean
//! on ICT's vertex order), put in mm and turned; the template is registered onto it, the shapes
//! are transferred, and each is scored as `mean |made - true| / mean |true|` over the vertices
//! the true shape moves.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::{Quat, Vec3};
use mimic_assets::{PackedShape, ShapePack, load_shape_pack};
use mimic_rig::transfer::{TransferSettings, correspond, transfer_shapes};
use mimic_rig::{FindSettings, TemplateHead, register_template};
use mimic_types::Mesh;
use std::collections::HashMap;
use std::path::PathBuf;

fn configs() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}

/// ICT's skin: face, head and neck.
const SKIN: usize = 11248;

/// Standard normal draws from a fixed seed (xorshift64*, Box-Muller).
fn normals(seed: u64, count: usize) -> Vec<f32> {
    let mut state = seed.max(1);
    let mut uniform = || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        ((state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..count)
        .map(|_| {
            let (u, v) = (uniform(), uniform());
            ((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()) as f32
        })
        .collect()
}

/// A test head: its mesh and each expression's true deltas on it.
struct Head {
    mesh: Mesh,
    truth: Vec<Vec<Vec3>>,
}

/// ICT's skin with identity weights `w`, clustered on a `voxel` grid (cm), then scaled by
/// `scale` and turned by `turn`.
fn make_head(
    template: &Mesh,
    identities: &ShapePack,
    expressions: &[PackedShape],
    w: &[f32],
    voxel: f32,
    scale: f32,
    turn: Quat,
) -> Head {
    let skin: Vec<Vec3> = (0..SKIN)
        .map(|v| {
            template.positions[v]
                + identities
                    .shapes
                    .iter()
                    .zip(w)
                    .map(|(s, w)| s.deltas[v] * *w)
                    .sum::<Vec3>()
        })
        .collect();
    // Cluster of each skin vertex.
    let mut cell_of: HashMap<[i32; 3], u32> = HashMap::new();
    let cluster: Vec<u32> = skin
        .iter()
        .map(|p| {
            let q = (*p / voxel).floor();
            let key = [q.x as i32, q.y as i32, q.z as i32];
            let next = cell_of.len() as u32;
            *cell_of.entry(key).or_insert(next)
        })
        .collect();
    let k = cell_of.len();
    let mut count = vec![0f32; k];
    for c in &cluster {
        count[*c as usize] += 1.0;
    }
    let mean = |values: &dyn Fn(usize) -> Vec3| {
        let mut sum = vec![Vec3::ZERO; k];
        for (v, c) in cluster.iter().enumerate() {
            sum[*c as usize] += values(v);
        }
        sum.iter()
            .zip(&count)
            .map(|(s, n)| *s / *n)
            .collect::<Vec<_>>()
    };
    let positions = mean(&|v| skin[v]);
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for t in &template.triangles {
        if t.iter().any(|v| *v as usize >= SKIN) {
            continue;
        }
        let c = t.map(|v| cluster[v as usize]);
        if c[0] == c[1] || c[1] == c[2] || c[0] == c[2] {
            continue;
        }
        let mut key = c;
        key.sort_unstable();
        if seen.insert(key) {
            triangles.push(c);
        }
    }
    // Drop clusters no triangle uses.
    let mut used = vec![u32::MAX; k];
    let mut kept = Vec::new();
    for t in &mut triangles {
        for v in t.iter_mut() {
            if used[*v as usize] == u32::MAX {
                used[*v as usize] = kept.len() as u32;
                kept.push(*v as usize);
            }
            *v = used[*v as usize];
        }
    }
    let place = |p: Vec3| turn * (p * scale) + Vec3::new(40.0, -120.0, 15.0);
    let mesh = Mesh {
        positions: kept.iter().map(|c| place(positions[*c])).collect(),
        triangles,
        ..Mesh::default()
    };
    let truth = expressions
        .iter()
        .map(|e| {
            let m = mean(&|v| e.deltas[v]);
            kept.iter().map(|c| turn * (m[*c] * scale)).collect()
        })
        .collect();
    Head { mesh, truth }
}

/// Per shape that moves the skin (some vertex by 100 x `moved` or more): its name and ratio
/// over the vertices it moves by more than `moved`.
fn score(
    names: &[String],
    made: &[Vec<Vec3>],
    truth: &[Vec<Vec3>],
    moved: f32,
) -> Vec<(String, f32)> {
    names
        .iter()
        .zip(made.iter().zip(truth))
        .filter_map(|(name, (m, t))| {
            let (mut err, mut disp, mut n) = (0f64, 0f64, 0usize);
            for (a, b) in m.iter().zip(t) {
                if b.length() > moved {
                    err += f64::from(a.distance(*b));
                    disp += f64::from(b.length());
                    n += 1;
                }
            }
            let most = t.iter().map(|d| d.length()).fold(0.0, f32::max);
            (n > 0 && most >= 100.0 * moved).then(|| (name.clone(), (err / disp) as f32))
        })
        .collect()
}

fn median_max(v: &[(String, f32)]) -> (f32, f32) {
    let mut r: Vec<f32> = v.iter().map(|(_, r)| *r).collect();
    r.sort_by(f32::total_cmp);
    (r[r.len() / 2], r[r.len() - 1])
}

/// Makes, transfers and scores one head; prints the figures.
fn run(seed: u64, voxel: f32, scale: f32, turn: Quat) -> Vec<(String, f32)> {
    let template = TemplateHead::ict(&configs()).unwrap();
    let dir = configs().join("meshes/ict-facekit");
    let expressions = load_shape_pack(&dir.join("expressions.shapes")).unwrap();
    let identities = load_shape_pack(&dir.join("identities.shapes")).unwrap();
    let w = normals(seed, identities.shapes.len());
    let head = make_head(
        &template.mesh,
        &identities,
        &expressions.shapes,
        &w,
        voxel,
        scale,
        turn,
    );
    let started = std::time::Instant::now();
    let reg = register_template(&head.mesh, &template, &FindSettings::default()).unwrap();
    let registered = started.elapsed();
    let s = TransferSettings::default();
    let corr = correspond(&head.mesh, &template.mesh, &reg, &s);
    let shapes: Vec<&[Vec3]> = expressions.shapes.iter().map(|e| &e.deltas[..]).collect();
    let made = transfer_shapes(&head.mesh, &template.mesh, &shapes, &corr, &s).unwrap();
    let transferred = started.elapsed() - registered;
    let names: Vec<String> = expressions.shapes.iter().map(|e| e.name.clone()).collect();
    // Moved: more than 1e-3 cm (in the head's units).
    let scores = score(&names, &made.deltas, &head.truth, 1e-3 * scale);
    let (median, max) = median_max(&scores);
    let mut worst = scores.clone();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1));
    println!(
        "seed {seed}: {} vertices, {} triangles; {} of {} nodes matched; {} of {} triangles follow a source, {} vertices free; registration {registered:.2?}, correspondence and transfer of {} shapes {transferred:.2?}",
        head.mesh.vertex_count(),
        head.mesh.triangles.len(),
        reg.matched,
        reg.node_vertex.len(),
        made.following,
        head.mesh.triangles.len(),
        made.free,
        shapes.len()
    );
    println!(
        "seed {seed}: {} shapes scored, ratio median {median:.3}, max {max:.3}; worst {:?}",
        scores.len(),
        &worst[..5.min(worst.len())]
    );
    scores
}

/// The target: median <= 0.20 and max <= 0.50 over the shapes that move the skin.
fn check(scores: &[(String, f32)]) {
    let (median, max) = median_max(scores);
    assert!(scores.len() >= 50, "{} shapes scored", scores.len());
    assert!(median <= 0.20, "median {median}");
    assert!(max <= 0.50, "max {max}");
}

#[test]
fn icts_expressions_transfer_onto_a_remeshed_random_identity_in_mm_turned() {
    // Seed 41 is the head the anchor length (0.08 IOD) was chosen on.
    let turn = Quat::from_rotation_y(20f32.to_radians()) * Quat::from_rotation_x(0.1);
    check(&run(41, 0.4, 10.0, turn));
}

#[test]
fn icts_expressions_transfer_onto_a_second_head_held_out() {
    // A head no setting was chosen on: another seed, a finer grid, turned the other way.
    let turn = Quat::from_rotation_y(-15f32.to_radians()) * Quat::from_rotation_z(0.08);
    check(&run(2024, 0.3, 10.0, turn));
}

#[test]
fn the_expression_pack_holds_the_shipped_shapes_within_half_its_quantum() {
    let dir = configs().join("meshes/ict-facekit");
    let pack = load_shape_pack(&dir.join("expressions.shapes")).unwrap();
    assert_eq!(pack.shapes.len(), 57);
    let neutral = mimic_assets::load_obj(&dir.join("generic_neutral_mesh.obj")).unwrap();
    assert_eq!(pack.vertex_count, neutral.vertex_count());
    for name in ["jawOpen", "eyeBlink_L", "mouthFunnel"] {
        let obj = dir.join(format!("{name}.obj"));
        let mesh = mimic_assets::load_obj(&obj).unwrap();
        let want = mimic_assets::morph_target(name, &neutral, &mesh, &obj).unwrap();
        let got = pack.get(name).unwrap();
        for (a, b) in want.position_deltas.iter().zip(&got.deltas) {
            for (x, y) in a.to_array().into_iter().zip(b.to_array()) {
                // The OBJ's delta is itself a difference of two f32 coordinates (up to 20 cm):
                // its own rounding, 2 ulps of 20, comes on top of the pack's bound.
                let bound =
                    mimic_assets::pack_tolerance(pack.quantum, x) + 2.0 * 20.0 * f32::EPSILON;
                assert!((x - y).abs() <= bound, "{name}: {x} vs {y}");
            }
        }
    }
}
