//! `cargo run -p mimic_bench_tools`: the ICT-FaceKit face area decimated to about 3 000 vertices by
//! meshoptimizer's simplifier, written to `configs/meshes/ict-facekit-3k/`, and the rig
//! `configs/rigs/ict-face-3k.toml` on it: the ICT rig's solver and regions, each control on the
//! decimated vertex nearest the ICT control's position (docs/performance.md), with the ICT rig's
//! morph targets cut down to the same vertices (so the rig replays in `--mode blendshapes`).
//!
//! Run from the repository root; it overwrites both files. Not part of the per-frame code.

use anyhow::Context;
use glam::Vec3;
use std::path::Path;

/// Vertices wanted (the source method's targets have 2 994 and 3 324).
const TARGET_VERTICES: usize = 3000;

fn main() -> anyhow::Result<()> {
    let root = Path::new(".");
    let rig_path = root.join("configs/rigs/ict-face.toml");
    let rig = mimic_assets::load_rig(&rig_path)?;
    let (positions, triangles, old_of_new) = face_area(&rig);
    let (positions, triangles, kept) = decimate(&positions, &triangles, TARGET_VERTICES)?;
    let old_of_new: Vec<u32> = kept.iter().map(|&k| old_of_new[k as usize]).collect();
    let dir = root.join("configs/meshes/ict-facekit-3k");
    std::fs::create_dir_all(&dir)?;
    let mesh_path = dir.join("face_3k.obj");
    let header = format!(
        "ICT-FaceKit face area, decimated by meshoptimizer (meshopt crate) to {} vertices and {} triangles\n\
         by `cargo run -p mimic_bench_tools` from configs/meshes/ict-facekit/generic_neutral_mesh.obj\n\
         (the non-frozen vertices of configs/rigs/ict-face.toml). Derived from ICT-FaceKit:\n\
         MIT licence, Copyright (c) 2020 USC Institute for Creative Technologies (../ict-facekit/LICENSE).",
        positions.len(),
        triangles.len()
    );
    let mut file = std::io::BufWriter::new(std::fs::File::create(&mesh_path)?);
    mimic_assets::write_obj(&mut file, &header, &positions, None, &triangles)?;
    drop(file);
    let controls = nearest_distinct(&rig, &positions);
    let morphs = morph_targets(&rig_path, &dir, &old_of_new, &triangles)?;
    let text = rig_toml(&rig_path, &controls, &positions, &old_of_new, &morphs)?;
    std::fs::write(root.join("configs/rigs/ict-face-3k.toml"), text)?;
    println!(
        "wrote {} ({} vertices, {} triangles) and configs/rigs/ict-face-3k.toml ({} controls)",
        mesh_path.display(),
        positions.len(),
        triangles.len(),
        controls.len()
    );
    Ok(())
}

/// The non-frozen vertices of the rig and the triangles among them, renumbered; with the old
/// index of each new vertex.
fn face_area(rig: &mimic_types::Rig) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<u32>) {
    let n = rig.mesh.vertex_count();
    let mut new_of_old = vec![u32::MAX; n];
    let mut old_of_new = Vec::new();
    for v in (0..n).filter(|&v| !rig.frozen[v]) {
        new_of_old[v] = old_of_new.len() as u32;
        old_of_new.push(v as u32);
    }
    let triangles = rig
        .mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| new_of_old[v as usize] != u32::MAX))
        .map(|t| t.map(|v| new_of_old[v as usize]))
        .collect();
    let positions = old_of_new
        .iter()
        .map(|&v| rig.mesh.positions[v as usize])
        .collect();
    (positions, triangles, old_of_new)
}

/// Positions, triangles and, per vertex, the index it had in the input.
type Decimated = (Vec<Vec3>, Vec<[u32; 3]>, Vec<u32>);

/// Simplifies to about `target` vertices (border kept in place), drops unused vertices; returns
/// the new positions and triangles and the input index of each kept vertex.
fn decimate(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    target: usize,
) -> anyhow::Result<Decimated> {
    let flat: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    let bytes: Vec<u8> = flat
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0).context("vertex adapter")?;
    let indices: Vec<u32> = triangles.iter().flatten().copied().collect();
    // Index count roughly proportional to vertices; search the target count for the vertex goal.
    let (mut lo, mut hi) = (3usize, indices.len());
    let mut best: Option<(usize, Vec<u32>)> = None;
    for _ in 0..24 {
        let mid = (lo + hi) / 2 / 3 * 3;
        let out = meshopt::simplify(
            &indices,
            &adapter,
            mid,
            1.0,
            meshopt::SimplifyOptions::LockBorder,
            None,
        );
        let used = used_vertices(&out, positions.len()).len();
        if best
            .as_ref()
            .is_none_or(|(u, _)| used.abs_diff(target) < u.abs_diff(target))
        {
            best = Some((used, out));
        }
        if used < target {
            lo = mid + 3;
        } else {
            hi = mid;
        }
        if lo >= hi {
            break;
        }
    }
    let (_, out) = best.context("simplification gave nothing")?;
    let kept = used_vertices(&out, positions.len());
    let mut new_of_old = vec![u32::MAX; positions.len()];
    for (k, &v) in kept.iter().enumerate() {
        new_of_old[v as usize] = k as u32;
    }
    let tris = out
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]].map(|v| new_of_old[v as usize]))
        .collect();
    let pos = kept.iter().map(|&v| positions[v as usize]).collect();
    Ok((pos, tris, kept))
}

/// Vertices named by `indices`, ascending.
fn used_vertices(indices: &[u32], n: usize) -> Vec<u32> {
    let mut used = vec![false; n];
    indices.iter().for_each(|&v| used[v as usize] = true);
    (0..n as u32).filter(|&v| used[v as usize]).collect()
}

/// For each rig control, the nearest decimated vertex not taken by an earlier control, and
/// its distance.
fn nearest_distinct(rig: &mimic_types::Rig, positions: &[Vec3]) -> Vec<(u32, f32)> {
    let mut taken = vec![false; positions.len()];
    rig.control_positions()
        .iter()
        .map(|c| {
            let (v, d) = positions
                .iter()
                .enumerate()
                .filter(|(v, _)| !taken[*v])
                .map(|(v, p)| (v, p.distance(*c)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((0, f32::INFINITY));
            taken[v] = true;
            (v as u32, d)
        })
        .collect()
}

/// Each of the ICT rig's morph targets cut down to the decimated vertices (its positions at
/// `old_of_new`, on the decimated triangles), written beside the mesh; returns, per target, its
/// name and the OBJ's path relative to `configs/rigs/`.
fn morph_targets(
    ict: &Path,
    dir: &Path,
    old_of_new: &[u32],
    triangles: &[[u32; 3]],
) -> anyhow::Result<Vec<(String, String)>> {
    let text = std::fs::read_to_string(ict)?;
    let doc: toml::Table = toml::from_str(&text)?;
    let Some(list) = doc.get("morph_targets").and_then(|m| m.as_array()) else {
        return Ok(Vec::new());
    };
    let rigs = ict.parent().context("rig path has no folder")?;
    let mut out = Vec::with_capacity(list.len());
    for entry in list {
        let name = entry.get("name").and_then(|n| n.as_str());
        let obj = entry.get("obj").and_then(|o| o.as_str());
        let (Some(name), Some(obj)) = (name, obj) else {
            anyhow::bail!("ict-face.toml: a [[morph_targets]] entry lacks name or obj");
        };
        let shape = mimic_assets::load_obj(&rigs.join(obj))?;
        let picked: Vec<Vec3> = old_of_new
            .iter()
            .map(|&v| shape.positions.get(v as usize).copied())
            .collect::<Option<_>>()
            .with_context(|| format!("{obj}: fewer vertices than the ICT mesh"))?;
        let file = format!("{name}.obj");
        let header = format!(
            "ICT-FaceKit expression `{name}` ({obj}) on the decimated face area (face_3k.obj's vertices),\n\
             by `cargo run -p mimic_bench_tools`. Derived from ICT-FaceKit: MIT licence, Copyright (c) 2020\n\
             USC Institute for Creative Technologies (../ict-facekit/LICENSE)."
        );
        let mut w = std::io::BufWriter::new(std::fs::File::create(dir.join(&file))?);
        mimic_assets::write_obj(&mut w, &header, &picked, None, triangles)?;
        out.push((name.to_owned(), format!("../meshes/ict-facekit-3k/{file}")));
    }
    Ok(out)
}

/// The ICT rig file with the new mesh, name, controls and morph targets; no frozen ranges, no look
/// and no thin shell.
fn rig_toml(
    ict: &Path,
    controls: &[(u32, f32)],
    positions: &[Vec3],
    old_of_new: &[u32],
    morphs: &[(String, String)],
) -> anyhow::Result<String> {
    let text = std::fs::read_to_string(ict)?;
    let mut doc: toml::Table = toml::from_str(&text)?;
    doc.insert("name".into(), "ict-face-3k".into());
    doc.insert(
        "description".into(),
        format!(
            "Benchmark rig at the source method's scale: the ICT-FaceKit face area (the non-frozen vertices of ict-face) \
             decimated by meshoptimizer to {} vertices (configs/meshes/ict-facekit-3k/SOURCE.md, MIT, derived from ICT), \
             with ict-face's solver and regions. Each control is the decimated vertex nearest ict-face's control \
             vertex (made by `cargo run -p mimic_bench_tools`). Nothing is frozen: every vertex moves.",
            positions.len()
        )
        .into(),
    );
    doc.insert("mesh".into(), "../meshes/ict-facekit-3k/face_3k.obj".into());
    doc.remove("frozen");
    doc.remove("look");
    // The thin shell's sockets name ICT vertex numbers; the benchmark rig keeps the plain solver.
    if let Some(solver) = doc.get_mut("solver").and_then(|s| s.as_table_mut()) {
        solver.remove("shell");
        solver.remove("shell_blend");
    }
    let mut entries = toml::value::Array::new();
    for (name, obj) in morphs {
        let mut t = toml::Table::new();
        t.insert("name".into(), name.clone().into());
        t.insert("obj".into(), obj.clone().into());
        entries.push(t.into());
    }
    if entries.is_empty() {
        doc.remove("morph_targets");
    } else {
        doc.insert("morph_targets".into(), entries.into());
    }
    let list = doc
        .get_mut("controls")
        .and_then(|c| c.as_array_mut())
        .context("ict-face.toml has no [[controls]]")?;
    anyhow::ensure!(list.len() == controls.len(), "control count");
    for (c, &(v, dist)) in list.iter_mut().zip(controls) {
        let t = c.as_table_mut().context("control is not a table")?;
        let old = t
            .get("vertex")
            .and_then(|x| x.as_integer())
            .unwrap_or_default();
        t.insert("vertex".into(), i64::from(v).into());
        t.insert(
            "note".into(),
            format!(
                "decimated vertex nearest ict-face's vertex {old} ({:.2} mm away; ICT vertex {})",
                dist * 10.0,
                old_of_new[v as usize]
            )
            .into(),
        );
    }
    Ok(format!(
        "# Generated by `cargo run -p mimic_bench_tools` (crates/mimic_bench_tools); see docs/performance.md.\n{}",
        toml::to_string(&doc)?
    ))
}
