//! Hostile avatar files (glTF / GLB) end in a one-line error naming the file and the JSON pointer,
//! exit 1, for `mimic rig new` and `mimic info`: the seeds of the `avatar` fuzz target
//! (`tools/hostile_gltf.py`) and a 200 000-node chain made here.

use crate::{mimic, repo, text};
use std::path::Path;

/// A GLB of one triangle under `nodes` (JSON), the first node the scene's root.
fn glb(nodes: &str) -> Vec<u8> {
    let mut json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"buffers":[{{"byteLength":36}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}]}}"#
    )
    .into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Runs `mimic rig new FILE` and `mimic info FILE`: each must exit 1 with one line naming the file
/// and `pointer`.
fn refused(file: &Path, pointer: &str) {
    let out_toml = file.with_extension("toml");
    let f = file.to_str().unwrap();
    for args in [
        vec!["rig", "new", f, "-o", out_toml.to_str().unwrap()],
        vec!["info", f],
    ] {
        let out = mimic(&args);
        let (_, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(
            stderr.contains(f) && stderr.contains(pointer),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn hostile_node_graphs_and_indices_end_in_a_one_line_error() {
    let seeds = repo().join("fuzz/corpus/avatar");
    for (seed, pointer) in [
        ("self_child.glb", "/nodes/0/children/0"),
        ("cycle.glb", "/nodes/0/children"),
        ("diamond.glb", "/nodes/0/children/1"),
        ("two_parents.glb", "/nodes/1/children/0"),
        (
            "accessor_oob.glb",
            "/meshes/0/primitives/0/attributes/POSITION",
        ),
        ("count_huge.glb", "/accessors/0"),
    ] {
        refused(&seeds.join(seed), pointer);
    }
}

#[test]
fn a_200k_node_chain_and_a_deep_one_end_in_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    for (n, pointer) in [(200_000, "/nodes:"), (5_000, "/nodes/256:")] {
        let nodes: Vec<String> = (0..n)
            .map(|k| match k + 1 < n {
                true => format!(r#"{{"mesh":0,"children":[{}]}}"#, k + 1),
                false => r#"{"mesh":0}"#.to_string(),
            })
            .collect();
        let path = dir.path().join(format!("chain{n}.glb"));
        std::fs::write(&path, glb(&format!("[{}]", nodes.join(",")))).unwrap();
        refused(&path, pointer);
    }
}

#[test]
fn info_reads_an_exported_avatar_and_counts_shared_vertices_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ict.glb");
    let out = mimic(&["rig", "export", "ict-face", "-o", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out).1);
    let out = mimic(&["info", path.to_str().unwrap(), "--json"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let rig = mimic(&["info", "configs/rigs/ict-face.toml", "--json"]);
    let r: serde_json::Value = serde_json::from_str(&text(&rig).0).unwrap();
    assert_eq!(v["kind"], "avatar");
    assert_eq!(v["format"], "glb");
    // The export's 12 primitives share one vertex list (the rig's vertices, some split at UV seams):
    // counted once, not once per primitive.
    let (vertices, rig_vertices) = (
        v["vertices"].as_u64().unwrap(),
        r["vertices"].as_u64().unwrap(),
    );
    assert!(
        vertices >= rig_vertices && vertices < 2 * rig_vertices,
        "{v}"
    );
    assert_eq!(v["triangles"], r["triangles"], "{v}");
    assert!(v["primitives"].as_u64().unwrap() > 1, "{v}");
}
