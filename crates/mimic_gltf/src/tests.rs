//! Round trip: write a GLB, read it back by hand, and rebuild what a viewer would draw.

use crate::*;
use glam::{Quat, Vec2, Vec3};
use serde_json::Value;

/// Splits a GLB into its JSON and binary chunks, checking the container.
fn read_glb(bytes: &[u8]) -> (Value, Vec<u8>) {
    let u = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[0..4], b"glTF");
    assert_eq!(u(4), 2);
    assert_eq!(u(8), bytes.len());
    let json_len = u(12);
    assert_eq!(&bytes[16..20], b"JSON");
    assert_eq!(json_len % 4, 0);
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let at = 20 + json_len;
    assert_eq!(&bytes[at + 4..at + 8], b"BIN\0");
    let bin = bytes[at + 8..at + 8 + u(at)].to_vec();
    (json, bin)
}

fn view<'a>(json: &Value, bin: &'a [u8], v: usize) -> &'a [u8] {
    let v = &json["bufferViews"][v];
    let at = v["byteOffset"].as_u64().unwrap() as usize;
    &bin[at..at + v["byteLength"].as_u64().unwrap() as usize]
}

/// An accessor's floats (sparse ones rebuilt on zeros), as a viewer reads them.
fn floats(json: &Value, bin: &[u8], a: usize) -> Vec<f32> {
    let acc = &json["accessors"][a];
    let comps = match acc["type"].as_str().unwrap() {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        _ => 4,
    };
    let count = acc["count"].as_u64().unwrap() as usize;
    let f = |b: &[u8]| -> Vec<f32> {
        b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    let mut out = match acc.get("bufferView") {
        Some(v) => f(view(json, bin, v.as_u64().unwrap() as usize)),
        None => vec![0.0; count * comps],
    };
    if let Some(s) = acc.get("sparse") {
        let idx = view(
            json,
            bin,
            s["indices"]["bufferView"].as_u64().unwrap() as usize,
        );
        let vals = f(view(
            json,
            bin,
            s["values"]["bufferView"].as_u64().unwrap() as usize,
        ));
        for (k, i) in idx.chunks_exact(4).enumerate() {
            let i = u32::from_le_bytes(i.try_into().unwrap()) as usize;
            out[i * comps..(i + 1) * comps].copy_from_slice(&vals[k * comps..(k + 1) * comps]);
        }
    }
    assert_eq!(out.len(), count * comps);
    out
}

#[test]
fn the_glb_morphs_reproduce_b_d_on_every_vertex_including_seams() {
    // A quad strip of 6 vertices with a UV seam at vertex 2, and a basis of 2 controls: control
    // 0 moves vertices 0-4 (6 of the 7 glTF vertices: dense), control 1 only vertex 5 (sparse).
    let positions: Vec<Vec3> = (0..6)
        .map(|i| Vec3::new((i / 2) as f32, (i % 2) as f32, 0.1 * i as f32))
        .collect();
    let triangles = vec![[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]];
    let uvs: Vec<Vec2> = (0..7).map(|i| Vec2::new(i as f32 / 7.0, 0.5)).collect();
    let uv_triangles = vec![[0, 2, 1], [1, 2, 3], [6, 4, 3], [3, 4, 5]];
    let basis = mimic_solve::Basis::from_row_major(
        6,
        2,
        vec![1.0, 0.0, 0.5, 0.0, 0.25, 0.0, 0.1, 0.0, 0.2, 0.0, 0.0, 1.0],
    )
    .unwrap();
    let names = vec!["2.1".to_string(), "8.3".to_string()];
    let morphs = basis_morphs(&basis, &names);
    let s = 0.01;
    let frames = [
        [Vec3::new(1.0, 2.0, -1.0), Vec3::new(0.5, 0.0, 3.0)],
        [Vec3::new(-2.0, 0.5, 0.0), Vec3::new(0.0, -1.0, 1.0)],
    ];
    let mut take = Take::new(6, Interpolation::Linear, true);
    for (k, d) in frames.iter().enumerate() {
        let mut w = [0.0; 6];
        basis_weights(d, s, &mut w);
        take.push(
            1_000_000 + 40_000 * k as i64,
            &w,
            (Quat::from_rotation_y(0.1 * k as f32), Vec3::X * k as f32),
        );
    }
    let materials = [GltfMaterial {
        name: "skin".into(),
        base_color: [0.8, 0.6, 0.5, 1.0],
        blend: false,
        texture: None,
    }];
    let triangle_material = [Some(0), Some(0), None, Some(0)];
    let scene = Scene {
        name: "strip",
        mesh: GltfMesh {
            positions: &positions,
            triangles: &triangles,
            uvs: &uvs,
            uv_triangles: &uv_triangles,
            materials: &materials,
            triangle_material: &triangle_material,
            colors: &[],
            textures: &[],
        },
        metres_per_unit: s,
        morphs: &morphs,
        take: Some(&take),
        pivot: Vec3::new(1.0, 0.5, 0.0),
    };
    let mut bytes = Vec::new();
    let summary = write_glb(&scene, &mut bytes).unwrap();
    assert_eq!(summary.bytes, bytes.len());
    assert_eq!(
        (summary.vertices, summary.primitives, summary.targets),
        (7, 2, 6)
    );
    assert_eq!(
        summary.sparse_targets, 3,
        "control 8.3 moves one vertex of 7"
    );
    let (json, bin) = read_glb(&bytes);
    let mesh = &json["meshes"][0];
    assert_eq!(mesh["extras"]["targetNames"][4], "8.3.y");
    let prim = &mesh["primitives"][0];
    let pos = floats(
        &json,
        &bin,
        prim["attributes"]["POSITION"].as_u64().unwrap() as usize,
    );
    let targets: Vec<Vec<f32>> = prim["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| floats(&json, &bin, t["POSITION"].as_u64().unwrap() as usize))
        .collect();
    let anim = &json["animations"][0];
    let times = floats(
        &json,
        &bin,
        anim["samplers"][0]["input"].as_u64().unwrap() as usize,
    );
    assert_eq!(times, vec![0.0, 0.04]);
    let weights = floats(
        &json,
        &bin,
        anim["samplers"][0]["output"].as_u64().unwrap() as usize,
    );
    // glTF vertex 6 is rig vertex 2 again (the seam).
    let source = [0usize, 1, 2, 3, 4, 5, 2];
    for (k, d) in frames.iter().enumerate() {
        let mut u = vec![Vec3::ZERO; 6];
        basis.apply(d, &mut u);
        for (g, &i) in source.iter().enumerate() {
            let mut p = Vec3::from_slice(&pos[3 * g..3 * g + 3]);
            for (t, delta) in targets.iter().enumerate() {
                p += weights[k * 6 + t] * Vec3::from_slice(&delta[3 * g..3 * g + 3]);
            }
            let want = (positions[i] + u[i]) * s;
            // f32 sums of at most 6 terms of size <= 0.05 m: a few ulps of 0.05.
            assert!(
                (p - want).abs().max_element() <= 8.0 * f32::EPSILON * 0.05,
                "{g}: {p} vs {want}"
            );
        }
    }
    // The pose: the head node's rotation and its translation from the pivot.
    let rot = floats(
        &json,
        &bin,
        anim["samplers"][1]["output"].as_u64().unwrap() as usize,
    );
    assert!((Quat::from_slice(&rot[4..8]).dot(Quat::from_rotation_y(0.1))).abs() > 1.0 - 1e-6);
    let tr = floats(
        &json,
        &bin,
        anim["samplers"][2]["output"].as_u64().unwrap() as usize,
    );
    let near = |a: &[f32], b: [f32; 3]| (Vec3::from_slice(a) - Vec3::from(b)).length() <= 1e-6;
    assert!(near(&tr[3..6], [1.01, 0.005, 0.0]), "{tr:?}");
    let node: Vec<f32> = json["nodes"][1]["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    assert!(near(&node, [-0.01, -0.005, 0.0]), "{node:?}");
}

#[test]
fn a_take_with_the_wrong_target_count_is_refused() {
    let positions = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let take = {
        let mut t = Take::new(1, Interpolation::Step, false);
        t.push(0, &[1.0], (Quat::IDENTITY, Vec3::ZERO));
        t
    };
    let scene = Scene {
        name: "tri",
        mesh: GltfMesh {
            positions: &positions,
            triangles: &[[0, 1, 2]],
            uvs: &[],
            uv_triangles: &[],
            materials: &[],
            triangle_material: &[],
            colors: &[],
            textures: &[],
        },
        metres_per_unit: 1.0,
        morphs: &[],
        take: Some(&take),
        pivot: Vec3::ZERO,
    };
    let e = write_glb(&scene, &mut Vec::new()).unwrap_err();
    assert!(
        matches!(e, GltfError::TargetCount { take: 1, mesh: 0 }),
        "{e}"
    );
}

#[test]
fn mimics_ict_export_reads_its_shared_vertex_list_once() {
    let rig_path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
    let rig = mimic_assets::load_rig(&rig_path).unwrap();
    let mut glb = Vec::new();
    let summary =
        crate::write_rig_glb(&rig_path, &rig, &[], None, [0.8, 0.6, 0.5], &mut glb).unwrap();
    let a = mimic_avatar::parse_avatar(std::path::Path::new("ict-face.glb"), &glb, None).unwrap();
    let prims = &a.meshes[0].primitives;
    assert_eq!(prims.len(), summary.primitives);
    assert!(prims.len() >= 10, "{} primitives", prims.len());
    // Every primitive names the one vertex array: the head's vertices counted once, not per primitive.
    assert_eq!(a.vertex_arrays.len(), 1);
    assert!(prims.iter().all(|p| p.vertices == 0));
    assert_eq!(a.vertex_count(), summary.vertices);
    assert_eq!(a.vertex_count(), 28_911);
    let triangles: usize = prims.iter().map(|p| p.triangles().count()).sum();
    assert_eq!(triangles, rig.mesh.triangles.len());
    // Materials keep their names, and the vertex colours come through.
    assert!(a.material_named("M_Face").is_some());
    assert_eq!(a.vertex_arrays[0].colors.len(), a.vertex_count());
}

/// The ICT avatar fixture with its JSON edited by `edit` (extra bytes appended to the binary
/// chunk), read back as an avatar.
fn edited_fixture(edit: impl FnOnce(&mut Value, &mut Vec<u8>)) -> mimic_avatar::Avatar {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/avatar/ict_multimesh.glb");
    let bytes = std::fs::read(&path).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let mut doc: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let bin_len = u32::from_le_bytes(bytes[bin_at..bin_at + 4].try_into().unwrap()) as usize;
    let mut bin = bytes[bin_at + 8..bin_at + 8 + bin_len].to_vec();
    edit(&mut doc, &mut bin);
    doc["buffers"][0]["byteLength"] = serde_json::json!(bin.len());
    let mut glb = Vec::new();
    crate::glb::write_container(&doc, &bin, &mut glb).unwrap();
    mimic_avatar::parse_avatar(std::path::Path::new("edited.glb"), &glb, None).unwrap()
}

/// Appends `values` (f32) to `bin` as a view and a SCALAR accessor; returns the accessor.
fn add_floats(doc: &mut Value, bin: &mut Vec<u8>, values: &[f32]) -> usize {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let at = bin.len();
    bin.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    let views = doc["bufferViews"].as_array_mut().unwrap();
    views.push(serde_json::json!({"buffer": 0, "byteOffset": at, "byteLength": 4 * values.len()}));
    let view = views.len() - 1;
    let (lo, hi) = values
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    let accessors = doc["accessors"].as_array_mut().unwrap();
    accessors.push(serde_json::json!({
        "bufferView": view, "componentType": 5126, "count": values.len(), "type": "SCALAR",
        "min": [lo], "max": [hi],
    }));
    accessors.len() - 1
}

#[test]
fn the_head_pose_goes_on_the_head_joint_in_its_parents_frame_and_own_weight_keys_widen() {
    let neck_turn = Quat::from_rotation_z(0.3) * Quat::from_rotation_x(-0.2);
    let a = edited_fixture(|doc, bin| {
        let nodes = doc["nodes"].as_array_mut().unwrap();
        // Names that say head only loosely; a turned neck, so local and world keys differ.
        nodes[3]["name"] = serde_json::json!("J_HeadBone");
        nodes[2]["rotation"] = serde_json::json!(neck_turn.to_array());
        // The avatar's own clip keys the face's two targets.
        let times = add_floats(doc, bin, &[0.0, 1.0]);
        let values = add_floats(doc, bin, &[0.0, 0.5, 1.0, 0.0]);
        doc["animations"] = serde_json::json!([{
            "name": "own",
            "samplers": [{"input": times, "output": values}],
            "channels": [{"sampler": 0, "target": {"node": 4, "path": "weights"}}],
        }]);
    });
    let face = mimic_avatar::FaceMesh::of(&a, 0).unwrap();
    let head = a.node_named("J_HeadBone").unwrap();
    assert_eq!(head_node(&a, &face), head);
    let morph = Morph {
        name: "up".into(),
        positions: vec![(0, Vec3::Y), (5, Vec3::Y)],
        normals: Vec::new(),
    };
    let turns = [
        Quat::IDENTITY,
        Quat::from_rotation_y(0.4) * Quat::from_rotation_x(0.1),
    ];
    let moves = [Vec3::ZERO, Vec3::new(0.01, -0.02, 0.03)];
    let mut take = Take::new(1, Interpolation::Linear, true);
    for k in 0..2 {
        take.push(k as i64 * 500_000, &[k as f32], (turns[k], moves[k]));
    }
    let mut out = Vec::new();
    write_avatar_glb(&a, &face, &[morph], Some(&take), &mut out).unwrap();
    let b = mimic_avatar::parse_avatar(std::path::Path::new("out.glb"), &out, None).unwrap();
    // The own clip's keys widened: 2 own + 1 added per key.
    let own = &b.animations[0].channels[0];
    assert_eq!(own.values, [0.0, 0.5, 0.0, 1.0, 0.0, 0.0]);
    let mimic_take = b.animations.last().unwrap();
    let rot = mimic_take
        .channels
        .iter()
        .find(|c| c.path == mimic_avatar::ChannelPath::Rotation)
        .unwrap();
    let tr = mimic_take
        .channels
        .iter()
        .find(|c| c.path == mimic_avatar::ChannelPath::Translation)
        .unwrap();
    assert_eq!((rot.node, tr.node), (head, head));
    let parent = a.nodes[a.nodes[head].parent.unwrap()].world;
    let (_, parent_rot, _) = parent.to_scale_rotation_translation();
    let rest_world = parent_rot * a.nodes[head].rotation;
    for k in 0..2 {
        let q = Quat::from_slice(&rot.values[4 * k..4 * k + 4]);
        // The head's world rotation is the take's rotation times its rest world rotation.
        let world = parent_rot * q;
        assert!(
            world.abs_diff_eq(turns[k] * rest_world, 1e-5)
                || world.abs_diff_eq(-(turns[k] * rest_world), 1e-5)
        );
        let t = Vec3::from_slice(&tr.values[3 * k..3 * k + 3]);
        let moved = parent.transform_vector3(t - a.nodes[head].translation);
        assert!(
            (moved - moves[k]).length() <= 1e-6,
            "{moved} vs {}",
            moves[k]
        );
    }
}

#[test]
fn a_skeleton_without_head_names_puts_the_pose_on_the_joint_that_carries_the_face() {
    let a = edited_fixture(|doc, _| {
        for (k, name) in [(1, "a"), (2, "b"), (3, "c")] {
            doc["nodes"][k]["name"] = serde_json::json!(name);
        }
    });
    let face = mimic_avatar::FaceMesh::of(&a, 0).unwrap();
    // The fixture's face is skinned mostly to its third joint (the former `head`).
    assert_eq!(head_node(&a, &face), a.node_named("c").unwrap());
}

#[test]
fn a_see_through_shell_named_like_a_face_is_not_taken_for_the_face() {
    let a = edited_fixture(|doc, _| {
        // The lashes' mesh renamed `FaceShell` and drawn only by see-through materials; the head
        // renamed to say nothing.
        doc["meshes"][0]["name"] = serde_json::json!("Mesh0");
        doc["meshes"][3]["name"] = serde_json::json!("FaceShell");
        for p in doc["meshes"][3]["primitives"].as_array_mut().unwrap() {
            p["material"] = serde_json::json!(8);
        }
    });
    assert_eq!(a.materials[8].alpha_mode, mimic_avatar::AlphaMode::Blend);
    // Not the shell, though its name says face: the largest solid mesh, the head.
    assert_eq!(mimic_avatar::largest_mesh(&a), Some(0));
}
