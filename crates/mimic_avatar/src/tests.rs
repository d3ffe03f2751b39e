//! The avatar reader on the multi-mesh ICT fixture, VRM 0.x and 1.0
//! files and the hostile seeds of the `avatar` fuzz corpus.

use super::*;
use std::path::{Path, PathBuf};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn load(rel: &str) -> Avatar {
    load_avatar(&repo(rel)).unwrap()
}

#[test]
fn the_ict_fixture_reads_every_mesh_material_skin_and_colour() {
    let a = load("tests/data/avatar/ict_multimesh.glb");
    let names: Vec<_> = a
        .meshes
        .iter()
        .map(|m| m.name.as_deref().unwrap())
        .collect();
    assert_eq!(names, ["Head", "Eyes", "Teeth", "EyeLashes"]);
    // Head: face and back of the head share one vertex list; eyes' four primitives share theirs.
    let head = &a.meshes[0];
    assert_eq!(head.primitives.len(), 2);
    assert_eq!(head.primitives[0].vertices, head.primitives[1].vertices);
    assert_eq!(a.meshes[1].primitives.len(), 4);
    assert_eq!(a.vertex_arrays.len(), 4);
    let face = &a.vertex_arrays[head.primitives[0].vertices];
    assert_eq!(face.colors.len(), face.positions.len());
    assert_eq!(face.tex_coords.len(), face.positions.len());
    assert_eq!(face.joints.len(), face.positions.len());
    // COLOR_0 is normalized u8: skin tones, redder at the lips, alpha 1.
    assert!(
        face.colors
            .iter()
            .all(|c| (0.5..=1.0).contains(&c.x) && c.w == 1.0)
    );
    assert!(face.colors.iter().any(|c| c.y < 0.5) && face.colors.iter().any(|c| c.y > 0.6));
    for w in &face.weights {
        assert!((w.x + w.y + w.z + w.w - 1.0).abs() < 1e-5);
    }
    assert_eq!(head.target_names, ["jawOpen", "eyeBlink_L"]);
    assert_eq!(head.primitives[0].targets, head.primitives[1].targets);
    assert_eq!(a.morph_targets.len(), 2);
    let jaw = &a.morph_targets[head.primitives[0].targets[0]];
    let drop = jaw.positions.iter().map(|d| -d.y).fold(0.0, f32::max);
    assert!((0.02..0.06).contains(&drop), "jawOpen moves {drop} m down");
    // Materials: names and alpha modes.
    let mat = |n: &str| &a.materials[a.material_named(n).unwrap()];
    assert_eq!(a.materials.len(), 10);
    assert_eq!(mat("M_Face").alpha_mode, AlphaMode::Opaque);
    assert_eq!(mat("M_EyeLashes").alpha_mode, AlphaMode::Blend);
    assert!(mat("M_EyeLashes").double_sided);
    assert_eq!(mat("M_EyeOcclusion").alpha_mode, AlphaMode::Blend);
    assert_eq!(
        mat("M_LacrimalFluid").alpha_mode,
        AlphaMode::Mask { cutoff: 0.3 }
    );
    // The face's texture with its sampler and image bytes.
    let t = mat("M_Face").base_color_texture.unwrap();
    let tex = &a.textures[t.texture];
    assert_eq!(tex.sampler.wrap_s, 33648);
    assert_eq!(tex.sampler.mag_filter, Some(9729));
    let img = &a.images[tex.image];
    assert_eq!(img.mime_type.as_deref(), Some("image/png"));
    assert!(img.bytes.starts_with(b"\x89PNG"));
    // Skin: root, neck, head; inverse bind matrices undo the joints' world transforms.
    assert_eq!(a.skins.len(), 1);
    let skin = &a.skins[0];
    let joint_names: Vec<_> = skin
        .joints
        .iter()
        .map(|&j| a.nodes[j].name.as_deref().unwrap())
        .collect();
    assert_eq!(joint_names, ["root", "neck", "head"]);
    assert_eq!(skin.skeleton, Some(skin.joints[0]));
    for (&j, ibm) in skin.joints.iter().zip(&skin.inverse_bind_matrices) {
        let id = *ibm * a.nodes[j].world;
        assert!(id.abs_diff_eq(Mat4::IDENTITY, 1e-5), "{id}");
    }
    // Hierarchy: the rigid parts hang under the head joint; the skinned mesh node is a root.
    let head_joint = a.node_named("head").unwrap();
    for n in ["Eyes", "Teeth", "EyeLashes"] {
        assert_eq!(a.nodes[a.node_named(n).unwrap()].parent, Some(head_joint));
    }
    let head_node = a.node_named("Head").unwrap();
    assert_eq!(a.nodes[head_node].skin, Some(0));
    assert_eq!(a.scene_roots, [a.node_named("Avatar").unwrap(), head_node]);
    // The eyes' world positions sit inside the head, in front (ICT's eyes at z about +3 cm).
    let eyes = a.node_named("Eyes").unwrap();
    let v = &a.vertex_arrays[a.meshes[1].primitives[0].vertices];
    let c = v.positions.iter().copied().sum::<Vec3>() / v.positions.len() as f32;
    let w = a.nodes[eyes].world.transform_point3(c);
    assert!(w.z > 0.0 && w.y.abs() < 0.1, "eye centre {w}");
    // The document stays whole.
    assert_eq!(a.document["skins"][0]["name"], "Armature");
}

#[test]
fn vrm_0x_gives_bones_expressions_and_look_at() {
    let a = load("tests/data/vrm/mimic_vrm0.vrm");
    let vrm = a.vrm.as_ref().unwrap();
    assert_eq!(vrm.version, VrmVersion::V0);
    let name = |n: Option<usize>| a.nodes[n.unwrap()].name.clone().unwrap();
    assert_eq!(name(vrm.head()), "J_Bip_C_Head");
    assert_eq!(name(vrm.neck()), "J_Bip_C_Neck");
    assert_eq!(name(vrm.left_eye()), "J_Adj_L_FaceEye");
    assert_eq!(name(vrm.right_eye()), "J_Adj_R_FaceEye");
    let blink = vrm.expression("blink").unwrap();
    assert_eq!(blink.name, "Blink");
    assert_eq!(
        blink.binds,
        [MorphBind {
            mesh: 0,
            node: None,
            index: 0,
            weight: 1.0
        }]
    );
    // VRM 0.x presets map to VRM 1.0's names: a -> aa, joy -> happy.
    let aa = vrm.expression("aa").unwrap();
    assert_eq!((aa.name.as_str(), aa.binds[0].index), ("A", 1));
    assert!((aa.binds[0].weight - 0.8).abs() < 1e-6);
    assert_eq!(vrm.expression("happy").unwrap().name, "Joy");
    let look = vrm.look_at.unwrap();
    assert_eq!(look.kind, LookAtKind::Bone);
    assert_eq!(look.offset_from_head, Vec3::new(0.0, 0.06, 0.0));
    assert_eq!(look.horizontal_outer.unwrap().output_scale, 12.0);
    assert_eq!(a.meshes[0].target_names, ["blink", "aa"]);
    assert_eq!(a.document["extensions"]["MIMIC_unknown_test"]["kept"], true);
}

#[test]
fn vrm_1_gives_bones_expressions_and_look_at() {
    let a = load("tests/data/vrm/mimic_vrm1.vrm");
    let vrm = a.vrm.as_ref().unwrap();
    assert_eq!(vrm.version, VrmVersion::V1);
    let name = |n: Option<usize>| a.nodes[n.unwrap()].name.clone().unwrap();
    assert_eq!(name(vrm.head()), "J_Bip_C_Head");
    assert_eq!(name(vrm.neck()), "J_Bip_C_Neck");
    assert_eq!(name(vrm.left_eye()), "J_Adj_L_FaceEye");
    assert_eq!(name(vrm.right_eye()), "J_Adj_R_FaceEye");
    let face = a.node_named("Face").unwrap();
    let blink = vrm.expression("blink").unwrap();
    assert_eq!(blink.preset.as_deref(), Some("blink"));
    assert_eq!(
        blink.binds,
        [MorphBind {
            mesh: 0,
            node: Some(face),
            index: 0,
            weight: 1.0
        }]
    );
    assert_eq!(vrm.expression("aa").unwrap().binds[0].index, 1);
    assert!(vrm.expression("happy").unwrap().binds.is_empty());
    let custom = vrm.expression("mouthSmileLeft").unwrap();
    assert_eq!(
        (custom.preset.as_ref(), custom.binds[0].weight),
        (None, 0.25)
    );
    let look = vrm.look_at.unwrap();
    assert_eq!(look.kind, LookAtKind::Bone);
    assert_eq!(look.horizontal_inner.unwrap().output_scale, 8.0);
    // World transforms compose down the chain: the head at 1.0 + 0.4 + 0.1 m.
    let head = vrm.head().unwrap();
    assert!((a.nodes[head].world.w_axis.y - 1.5).abs() < 1e-6);
}

#[test]
fn the_vrm_consortiums_1_0_sample_reads_with_its_bones_and_expressions() {
    let a = load("tests/data/vrm/VRMC_vrm_expressions_isBinary_Overrides.vrm");
    let vrm = a.vrm.as_ref().unwrap();
    assert_eq!(vrm.version, VrmVersion::V1);
    assert_eq!(vrm.head(), Some(0));
    assert_eq!(vrm.neck(), Some(1));
    assert_eq!(vrm.bones.len(), 22);
    // Its expressions move textures, not morph targets (textureTransformBinds stay in the document).
    let happy = vrm.expression("happy").unwrap();
    assert!(happy.is_binary && happy.binds.is_empty());
    assert!(vrm.expression("blink").is_some());
    assert_eq!(vrm.look_at.unwrap().kind, LookAtKind::Expression);
    assert!(
        a.document
            .pointer("/extensions/VRMC_vrm/expressions/preset/happy/textureTransformBinds")
            .is_some()
    );
    assert_eq!(a.meshes.len(), 4);
    assert!(matches!(a.materials[1].alpha_mode, AlphaMode::Mask { .. }));
    assert!(a.images.iter().all(|i| !i.bytes.is_empty()));
}

#[test]
fn a_gltf_with_its_bin_and_image_beside_it_reads_and_a_path_outside_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let glb = std::fs::read(repo("tests/data/vrm/mimic_vrm1.vrm")).unwrap();
    let chunks = super::container::split(&glb).unwrap();
    let mut doc: serde_json::Value = serde_json::from_slice(chunks.json).unwrap();
    doc["buffers"][0]["uri"] = "face data.bin".into();
    doc["images"] = serde_json::json!([{"uri": "skin.png"}]);
    doc["textures"] = serde_json::json!([{"source": 0}]);
    std::fs::write(dir.path().join("face data.bin"), chunks.bin.unwrap()).unwrap();
    std::fs::write(dir.path().join("skin.png"), b"\x89PNG\r\n\x1a\nrest").unwrap();
    let path = dir.path().join("face.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let a = load_avatar(&path).unwrap();
    assert_eq!(a.vertex_count(), 7);
    assert_eq!(a.images[0].uri.as_deref(), Some("skin.png"));
    assert_eq!(a.images[0].mime_type.as_deref(), Some("image/png"));
    // `%20` decodes; `..` and absolute paths are refused with the pointer of the URI.
    doc["buffers"][0]["uri"] = "face%20data.bin".into();
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    load_avatar(&path).unwrap();
    doc["buffers"][0]["uri"] = "../face data.bin".into();
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let e = load_avatar(&path).unwrap_err();
    assert_eq!(e.pointer, "/buffers/0/uri");
    // A data URI is read.
    let b64 = |b: &[u8]| {
        const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut s = String::new();
        for c in b.chunks(3) {
            let n = c
                .iter()
                .enumerate()
                .fold(0u32, |n, (k, &x)| n | u32::from(x) << (16 - 8 * k));
            for k in 0..=c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            }
        }
        s
    };
    doc["buffers"][0]["uri"] = format!(
        "data:application/octet-stream;base64,{}",
        b64(chunks.bin.unwrap())
    )
    .into();
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    assert_eq!(load_avatar(&path).unwrap().vertex_count(), 7);
}

#[test]
fn hostile_files_give_one_line_errors_naming_file_and_pointer() {
    let dir = repo("fuzz/corpus/avatar");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        match parse_avatar(Path::new(&name), &bytes, None) {
            // sparse_oob's sparse index (0, read from the positions' view) is in range here.
            Ok(a) => assert!(
                [
                    "ok.glb",
                    "candide3_rig.glb",
                    "sparse_oob.glb",
                    "vrm0.vrm",
                    "vrm1.vrm"
                ]
                .contains(&name.as_str()),
                "{name} read: {} vertices",
                a.vertex_count()
            ),
            Err(e) => {
                let line = e.to_string();
                assert!(!line.contains('\n'), "{line}");
                assert!(line.starts_with(&format!("{name}: /")), "{line}");
                assert!(e.pointer.starts_with('/'), "{line}");
                seen += 1;
            }
        }
    }
    assert!(seen >= 12, "{seen} hostile seeds refused");
    // Cut-off and malformed containers.
    let ok = std::fs::read(dir.join("ok.glb")).unwrap();
    for cut in [0, 4, 11, 12, 19, 24, ok.len() - 1] {
        let e = parse_avatar(Path::new("cut.glb"), &ok[..cut], None).unwrap_err();
        assert!(e.to_string().starts_with("cut.glb: "), "{e}");
    }
    let mut huge = ok.clone();
    huge[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(parse_avatar(Path::new("h.glb"), &huge, None).is_err());
}

#[test]
fn bad_binds_and_indices_name_their_pointer() {
    let glb = std::fs::read(repo("tests/data/vrm/mimic_vrm1.vrm")).unwrap();
    let chunks = super::container::split(&glb).unwrap();
    let doc: serde_json::Value = serde_json::from_slice(chunks.json).unwrap();
    let rebuild = |doc: &serde_json::Value| {
        let mut j = serde_json::to_vec(doc).unwrap();
        while !j.len().is_multiple_of(4) {
            j.push(b' ');
        }
        let bin = chunks.bin.unwrap();
        let mut out = b"glTF".to_vec();
        out.extend(2u32.to_le_bytes());
        out.extend(((28 + j.len() + bin.len()) as u32).to_le_bytes());
        out.extend((j.len() as u32).to_le_bytes());
        out.extend(b"JSON");
        out.extend(&j);
        out.extend((bin.len() as u32).to_le_bytes());
        out.extend(b"BIN\0");
        out.extend(bin);
        out
    };
    let err = |doc: &serde_json::Value| {
        parse_avatar(Path::new("x.vrm"), &rebuild(doc), None)
            .unwrap_err()
            .pointer
    };
    parse_avatar(Path::new("x.vrm"), &rebuild(&doc), None).unwrap();
    let mut d = doc.clone();
    d["extensions"]["VRMC_vrm"]["expressions"]["preset"]["blink"]["morphTargetBinds"][0]["index"] =
        5.into();
    assert_eq!(
        err(&d),
        "/extensions/VRMC_vrm/expressions/preset/blink/morphTargetBinds/0/index"
    );
    let mut d = doc.clone();
    d["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["head"]["node"] = 99.into();
    assert_eq!(
        err(&d),
        "/extensions/VRMC_vrm/humanoid/humanBones/head/node"
    );
    let mut d = doc.clone();
    d["extensions"]["VRMC_vrm"]["expressions"]["preset"]["aa"]["morphTargetBinds"][0]["node"] =
        3.into();
    assert_eq!(
        err(&d),
        "/extensions/VRMC_vrm/expressions/preset/aa/morphTargetBinds/0/node"
    );
    // A required compression extension is named.
    let mut d = doc.clone();
    d["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    d["extensionsUsed"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    assert_eq!(err(&d), "/extensionsRequired/0");
    // Other required extensions are kept in the document, not refused.
    let mut d = doc.clone();
    d["extensionsRequired"] = serde_json::json!(["KHR_texture_transform", "KHR_materials_unlit"]);
    d["extensionsUsed"] =
        serde_json::json!(["KHR_texture_transform", "KHR_materials_unlit", "VRMC_vrm"]);
    let a = parse_avatar(Path::new("x.vrm"), &rebuild(&d), None).unwrap();
    assert_eq!(a.document["extensionsRequired"][1], "KHR_materials_unlit");
    // An index past the vertices (the index view holds u16s; 7 vertices).
    let mut d = doc.clone();
    d["accessors"][1]["count"] = 18.into();
    d["accessors"][1]["byteOffset"] = 0.into();
    let mut bytes = rebuild(&d);
    let bin_at = bytes.len() - chunks.bin.unwrap().len();
    let view = d["bufferViews"][1]["byteOffset"].as_u64().unwrap() as usize;
    bytes[bin_at + view..bin_at + view + 2].copy_from_slice(&9u16.to_le_bytes());
    let e = parse_avatar(Path::new("x.vrm"), &bytes, None).unwrap_err();
    assert_eq!(e.pointer, "/meshes/0/primitives/0/indices", "{e}");
}
